// FNV-1a, 64 bits (Fowler, Noll, Vo; offset basis 14695981039346656037, prime 1099511628211), as 16
// lowercase hex digits: the one content hash of the project, for the server's ETags and a campaign's spec
// hash. Not cryptographic: it names content, it does not authenticate it.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

namespace moreau::platform {

inline std::string fnv1a64_hex(std::string_view bytes) {
  std::uint64_t h = 14695981039346656037ull;
  for (const char c : bytes) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ull;
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

}  // namespace moreau::platform
