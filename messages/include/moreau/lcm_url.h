// What can be told about an LCM URL before LCM opens it. LCM itself only prints "Failed to open ..." and
// reports "not good"; the server and `moreau watch` say why instead.
#pragma once

#include <filesystem>
#include <string>

namespace moreau {

// Why `url` cannot be opened, when that is known in advance: a file:// log whose directory does not exist
// (mode w or a, LCM's write modes) or whose file does not exist (mode r, LCM's default). Empty when nothing
// is known to be wrong (every other provider: udpm://, memq://, tcpq://).
inline std::string lcm_url_problem(const std::string& url) {
  const std::string scheme = "file://";
  if (url.compare(0, scheme.size(), scheme) != 0) return "";
  // Strings are built with += below: GCC 12 warns (-Wrestrict, a false positive) on "literal" + string here.
  const std::string rest = url.substr(scheme.size());
  const std::string path = rest.substr(0, rest.find('?'));
  std::string mode = "r";
  if (const auto q = rest.find('?'); q != std::string::npos) {
    std::string query = "&";
    query += rest.substr(q + 1);
    if (const auto m = query.find("&mode="); m != std::string::npos) mode = query.substr(m + 6, query.find('&', m + 1) - (m + 6));
  }
  if (path.empty()) return "the file:// URL names no file";
  const std::filesystem::path file(path);
  std::error_code ec;
  if (mode.find('w') != std::string::npos || mode.find('a') != std::string::npos) {
    const std::filesystem::path dir = file.has_parent_path() ? file.parent_path() : std::filesystem::path(".");
    if (!std::filesystem::is_directory(dir, ec)) {
      std::string why = "the directory ";
      why += dir.string();
      why += " does not exist";
      return why;
    }
    return "";
  }
  if (!std::filesystem::exists(file, ec)) {
    std::string why = "the log file ";
    why += file.string();
    why += " does not exist";
    return why;
  }
  return "";
}

}  // namespace moreau
