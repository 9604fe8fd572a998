// FreeType text: UTF-8 decoding, metrics for the layout, glyph bitmaps for the PNG backend.
// Process-wide cache guarded by a mutex; entries are never evicted, so the references handed out
// stay valid.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::render::detail {

std::u32string decode_utf8(std::string_view s);

struct Glyph {
  int advance = 0;  // 26.6 fixed point
  int width = 0, height = 0;
  int left = 0, top = 0;               // bitmap offset from the pen position (top: above the baseline)
  std::vector<std::uint8_t> coverage;  // width * height, rows top-down
};

struct FontMetrics {
  int ascender = 0;    // pixels above the baseline
  int descender = 0;   // pixels below the baseline (positive)
  int cap_height = 0;  // height of 'H'
  int line_height() const { return ascender + descender; }
};

struct PlacedGlyph {
  const Glyph* glyph = nullptr;
  std::uint32_t key = 0;  // code point
  int pen_x = 0;          // pixels from the start of the text
};

struct ShapedText {
  std::vector<PlacedGlyph> glyphs;
  int width = 0;  // pixels
};

FontMetrics font_metrics(int px, bool bold);
ShapedText shape_text(std::string_view utf8, int px, bool bold);
int text_width(std::string_view utf8, int px, bool bold);

}  // namespace moreau::render::detail
