// Text from a server (or from anyone on the LCM network) made safe to print on a terminal. A scene name,
// a reason, a job id or an event's text is chosen by whoever sent it: printed raw, "ESC ] 0 ; ... BEL"
// retitles the reader's terminal, "ESC [ 2 J" clears it, and a bidirectional override shows
// "ctl\u202Elive" as "ctlevil". Every string the remote commands print from server data goes through one
// of these two functions.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace moreau::cli {

namespace terminal_detail {

// The code point of the UTF-8 sequence at s[i] and its length; length 0 when the bytes there are not
// valid UTF-8 (a stray continuation byte, a truncated or overlong sequence, a surrogate, beyond U+10FFFF).
inline std::size_t decode_utf8(std::string_view s, std::size_t i, std::uint32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  std::size_t len = 0;
  std::uint32_t min = 0;
  if ((c & 0xE0) == 0xC0) {
    len = 2, cp = c & 0x1F, min = 0x80;
  } else if ((c & 0xF0) == 0xE0) {
    len = 3, cp = c & 0x0F, min = 0x800;
  } else if ((c & 0xF8) == 0xF0) {
    len = 4, cp = c & 0x07, min = 0x10000;
  } else {
    return 0;
  }
  if (i + len > s.size()) return 0;
  for (std::size_t k = 1; k < len; ++k) {
    if ((b(i + k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b(i + k) & 0x3F);
  }
  if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return len;
}

// Characters a terminal acts on or that reorder what is shown: C0 controls, DEL, C1 controls, and the
// bidirectional embeddings, overrides and isolates (U+202A-U+202E, U+2066-U+2069).
inline bool unsafe(std::uint32_t cp) {
  return cp < 0x20 || cp == 0x7F || (cp >= 0x80 && cp <= 0x9F) || (cp >= 0x202A && cp <= 0x202E) || (cp >= 0x2066 && cp <= 0x2069);
}

inline const char* hex_digits() { return "0123456789abcdef"; }

}  // namespace terminal_detail

// One field for a person to read, as visible text: C0 controls (tab and newline included), DEL and
// bytes that are not valid UTF-8 become \xNN; C1 controls and bidirectional controls become \u{NNNN}
// (\u{9b}, \u{202e}); a backslash becomes \\, so that what is shown can be told from a sent escape.
// Everything else (printable ASCII, other UTF-8) is kept as it is.
inline std::string terminal_safe(std::string_view s) {
  using namespace terminal_detail;
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    std::uint32_t cp = 0;
    const std::size_t len = decode_utf8(s, i, cp);
    if (len == 0 || (len == 1 && unsafe(cp))) {
      const unsigned char c = static_cast<unsigned char>(s[i]);
      out += "\\x";
      out += hex_digits()[c >> 4];
      out += hex_digits()[c & 0xF];
      ++i;
      continue;
    }
    if (unsafe(cp)) {
      char buf[16];
      std::size_t n = 0;
      for (std::uint32_t v = cp; v; v >>= 4) buf[n++] = hex_digits()[v & 0xF];
      out += "\\u{";
      while (n) out += buf[--n];
      out += '}';
    } else if (cp == '\\') {
      out += "\\\\";
    } else {
      out.append(s.substr(i, len));
    }
    i += len;
  }
  return out;
}

// A JSON text (a server's answer, printed whole: `moreau result ID`, `--json`) made safe the same way
// while staying the same JSON: the unsafe characters can only stand inside strings in valid JSON, where
// the escape \uNNNN means the same character. Tab, newline and carriage return are kept (the text's own
// white space); bytes that are not valid UTF-8 become \ufffd (the replacement character).
inline std::string terminal_safe_json(std::string_view s) {
  using namespace terminal_detail;
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    std::uint32_t cp = 0;
    const std::size_t len = decode_utf8(s, i, cp);
    if (len == 0) {
      out += "\\ufffd";
      ++i;
      continue;
    }
    if (unsafe(cp) && cp != '\t' && cp != '\n' && cp != '\r') {
      out += "\\u";
      for (int shift = 12; shift >= 0; shift -= 4) out += hex_digits()[(cp >> shift) & 0xF];
    } else {
      out.append(s.substr(i, len));
    }
    i += len;
  }
  return out;
}

}  // namespace moreau::cli
