#include "moreau/platform/number_text.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <system_error>

namespace moreau::platform {
namespace {

// Room for any %.<17>f: a sign, the 309 integer digits of the largest double, the point and 17 decimals.
constexpr std::size_t kFixedMaxChars = 1 + 309 + 1 + 17;

// The text std::to_chars wrote into buf, or the one spelling when v is not finite.
template <class Write>
std::string text_of(double v, Write&& write) {
  if (!std::isfinite(v)) return std::string(non_finite_text(v));
  char buf[kFixedMaxChars + 8];
  const std::to_chars_result r = write(buf, buf + sizeof buf);
  if (r.ec != std::errc()) throw std::length_error("a number's text does not fit its buffer");  // sized above: unreachable
  return std::string(buf, r.ptr);
}

}  // namespace

std::string_view non_finite_text(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v < 0 ? "-inf" : "inf";
  return {};
}

char* write_shortest(char* first, char* last, double v) {
  if (!std::isfinite(v)) {
    const std::string_view word = non_finite_text(v);
    if (static_cast<std::size_t>(last - first) < word.size()) throw std::length_error("no room for a number's text");
    return std::copy(word.begin(), word.end(), first);
  }
  const std::to_chars_result r = std::to_chars(first, last, v);
  if (r.ec != std::errc()) throw std::length_error("no room for a number's text");
  return r.ptr;
}

std::string shortest(double v) {
  char buf[kShortestMaxChars];
  return std::string(buf, write_shortest(buf, buf + sizeof buf, v));
}

std::string significant(double v, int digits) {
  const int p = std::clamp(digits, 1, 17);
  return text_of(v, [&](char* first, char* last) { return std::to_chars(first, last, v, std::chars_format::general, p); });
}

std::string fixed(double v, int decimals) {
  const int p = std::clamp(decimals, 0, 17);
  return text_of(v, [&](char* first, char* last) { return std::to_chars(first, last, v, std::chars_format::fixed, p); });
}

}  // namespace moreau::platform
