#include "conditional.h"

#include "moreau/platform/fnv1a.h"

#include <cstdint>
#include <cstdio>

namespace moreau::server {
namespace {

std::string hash_hex(std::string_view bytes) { return platform::fnv1a64_hex(bytes); }

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

std::string_view opaque(std::string_view tag) {
  if (tag.substr(0, 2) == "W/") tag.remove_prefix(2);
  return tag;
}

}  // namespace

// Appended, not "literal" + std::string: GCC 12 reports a false -Wrestrict for that (GCC bug 105329).
std::string strong_etag(std::string_view bytes) { return std::string("\"").append(hash_hex(bytes)).append("\""); }

std::string weak_etag(std::string_view identity) { return std::string("W/\"").append(hash_hex(identity)).append("\""); }

bool if_none_match(std::string_view header, std::string_view etag) {
  if (trim(header) == "*") return true;
  while (!header.empty()) {
    const auto comma = header.find(',');
    const std::string_view tag = trim(header.substr(0, comma));
    if (!tag.empty() && opaque(tag) == opaque(etag)) return true;
    if (comma == std::string_view::npos) break;
    header.remove_prefix(comma + 1);
  }
  return false;
}

}  // namespace moreau::server
