// Test support: whether a text (an SVG figure, any XML the product writes) is XML 1.0 text, checked
// from the specification (section 2.2, "Characters"), apart from the writer's own escaping.
#pragma once

#include <cctype>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

namespace moreau::test_support {

// Why `xml` is not XML 1.0 text, or "" when it is: its bytes must be UTF-8 (shortest form, no surrogate)
// and every character a Char of XML 1.0 (tab, LF, CR, U+0020-U+D7FF, U+E000-U+FFFD, U+10000-U+10FFFF); every
// '&' must start a reference the SVG may use, and every '<' a tag (a name, '/', '?' or '!').
// Written apart from the writer's escaping, from the XML 1.0 specification (section 2.2, "Characters").
inline std::string xml_1_0_problem(const std::string& xml) {
  for (std::size_t i = 0; i < xml.size();) {
    const auto b = [&](std::size_t k) { return static_cast<unsigned char>(xml[k]); };
    std::uint32_t cp = b(i);
    std::size_t len = 1;
    if (cp >= 0x80) {
      len = cp >= 0xF0 && cp <= 0xF4 ? 4 : cp >= 0xE0 && cp <= 0xEF ? 3 : cp >= 0xC2 && cp <= 0xDF ? 2 : 0;
      if (len == 0 || i + len > xml.size()) return "not UTF-8 at byte " + std::to_string(i);
      cp &= len == 2 ? 0x1F : len == 3 ? 0x0F : 0x07;
      for (std::size_t k = 1; k < len; ++k) {
        if ((b(i + k) & 0xC0) != 0x80) return "not UTF-8 at byte " + std::to_string(i);
        cp = (cp << 6) | (b(i + k) & 0x3F);
      }
      if ((len == 3 && cp < 0x800) || (len == 4 && (cp < 0x10000 || cp > 0x10FFFF)))
        return "overlong or out-of-range UTF-8 at byte " + std::to_string(i);
    }
    const bool is_char = cp == 0x9 || cp == 0xA || cp == 0xD || (cp >= 0x20 && cp <= 0xD7FF) || (cp >= 0xE000 && cp <= 0xFFFD) ||
                         (cp >= 0x10000 && cp <= 0x10FFFF);
    if (!is_char) {
      char hex[16];
      std::snprintf(hex, sizeof hex, "U+%04X", static_cast<unsigned>(cp));
      return std::string("character ") + hex + " at byte " + std::to_string(i) + " is not an XML 1.0 Char";
    }
    if (cp == '<') {
      const char next = i + 1 < xml.size() ? xml[i + 1] : '\0';
      if (!(std::isalpha(static_cast<unsigned char>(next)) || next == '/' || next == '?' || next == '!'))
        return "a '<' that starts no tag at byte " + std::to_string(i);
    }
    if (cp == '&') {
      static const char* const refs[] = {"&amp;", "&lt;", "&gt;", "&quot;", "&apos;"};
      bool known = false;
      for (const char* r : refs) known = known || xml.compare(i, std::strlen(r), r) == 0;
      if (!known) return "a bare '&' at byte " + std::to_string(i);
    }
    i += len;
  }
  return "";
}

}  // namespace moreau::test_support
