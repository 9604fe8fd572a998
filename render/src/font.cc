#include "font.h"

#include <ft2build.h>
#include FT_FREETYPE_H

#ifdef MOREAU_RENDER_FREETYPE_AT_FIRST_USE
#include <dlfcn.h>
#endif

#include <cmath>
#include <cstdlib>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <unordered_map>

#include "moreau/render/figure.h"

#ifndef MOREAU_RENDER_FONT_DIR
#define MOREAU_RENDER_FONT_DIR "/usr/share/fonts/truetype/dejavu"
#endif

namespace moreau::render::detail {
namespace {

// The FreeType functions this file calls. moreau_render (MOREAU_RENDER_FREETYPE_AT_FIRST_USE) opens
// libfreetype when the first text is laid out, so that a process that draws nothing never maps it nor
// what it needs (libpng, zlib, brotli): they cost a command line run about a millisecond of start-up.
// The raster module links it as usual.
struct FreeTypeApi {
  decltype(&FT_Init_FreeType) init_freetype = nullptr;
  decltype(&FT_New_Face) new_face = nullptr;
  decltype(&FT_Set_Pixel_Sizes) set_pixel_sizes = nullptr;
  decltype(&FT_Get_Kerning) get_kerning = nullptr;
  decltype(&FT_Get_Char_Index) get_char_index = nullptr;
  decltype(&FT_Load_Glyph) load_glyph = nullptr;
};

#ifdef MOREAU_RENDER_FREETYPE_AT_FIRST_USE
FreeTypeApi open_freetype() {
  constexpr const char* kLibrary = "libfreetype.so.6";
  void* handle = ::dlopen(kLibrary, RTLD_NOW | RTLD_LOCAL);
  if (!handle) throw std::runtime_error(std::string("cannot load FreeType (") + kLibrary + "): " + ::dlerror());
  FreeTypeApi api;
  const auto bind = [&](auto& fn, const char* name) {
    fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(::dlsym(handle, name));
    if (!fn) throw std::runtime_error(std::string(kLibrary) + " has no " + name);
  };
  bind(api.init_freetype, "FT_Init_FreeType");
  bind(api.new_face, "FT_New_Face");
  bind(api.set_pixel_sizes, "FT_Set_Pixel_Sizes");
  bind(api.get_kerning, "FT_Get_Kerning");
  bind(api.get_char_index, "FT_Get_Char_Index");
  bind(api.load_glyph, "FT_Load_Glyph");
  return api;
}
#else
FreeTypeApi open_freetype() {
  return {&FT_Init_FreeType, &FT_New_Face, &FT_Set_Pixel_Sizes, &FT_Get_Kerning, &FT_Get_Char_Index, &FT_Load_Glyph};
}
#endif

}  // namespace

std::u32string decode_utf8(std::string_view s) {
  std::u32string out;
  out.reserve(s.size());
  std::size_t i = 0;
  while (i < s.size()) {
    const auto c = static_cast<unsigned char>(s[i]);
    int len = 0;
    char32_t cp = 0;
    if (c < 0x80) {
      cp = c;
      len = 1;
    } else if ((c & 0xE0) == 0xC0) {
      cp = c & 0x1F;
      len = 2;
    } else if ((c & 0xF0) == 0xE0) {
      cp = c & 0x0F;
      len = 3;
    } else if ((c & 0xF8) == 0xF0) {
      cp = c & 0x07;
      len = 4;
    } else {
      out.push_back(U'\uFFFD');
      ++i;
      continue;
    }
    if (i + len > s.size()) {
      out.push_back(U'\uFFFD');
      break;
    }
    bool ok = true;
    for (int k = 1; k < len; ++k) {
      const auto cc = static_cast<unsigned char>(s[i + k]);
      if ((cc & 0xC0) != 0x80) {
        ok = false;
        break;
      }
      cp = (cp << 6) | (cc & 0x3F);
    }
    if (!ok) {
      out.push_back(U'\uFFFD');
      ++i;
      continue;
    }
    out.push_back(cp);
    i += len;
  }
  return out;
}

namespace {

class FontCache {
 public:
  static FontCache& instance() {
    static FontCache* cache = new FontCache();  // intentionally never destroyed
    return *cache;
  }

  FontMetrics metrics(int px, bool bold) {
    std::lock_guard lock(mutex_);
    auto key = std::make_pair(px, bold);
    auto it = metrics_.find(key);
    if (it != metrics_.end()) return it->second;
    FT_Face face = face_for(bold, px);
    FontMetrics m;
    m.ascender = static_cast<int>(std::ceil(face->size->metrics.ascender / 64.0));
    m.descender = static_cast<int>(std::ceil(-face->size->metrics.descender / 64.0));
    m.cap_height = glyph_locked(U'H', px, bold).top;
    metrics_.emplace(key, m);
    return m;
  }

  ShapedText shape(std::string_view utf8, int px, bool bold) {
    const std::u32string text = decode_utf8(utf8);
    std::lock_guard lock(mutex_);
    ShapedText out;
    out.glyphs.reserve(text.size());
    long pen = 0;  // 26.6
    FT_UInt prev = 0;
    FT_Face face = nullptr;
    for (char32_t cp : text) {
      const Entry& e = glyph_entry(cp, px, bold);
      if (prev && e.index && has_kerning(bold)) {
        if (!face) face = face_for(bold, px);
        pen += kerning(face, bold, px, prev, e.index);
      }
      out.glyphs.push_back({&e.glyph, static_cast<std::uint32_t>(cp), static_cast<int>(std::lround(pen / 64.0))});
      pen += e.glyph.advance;
      prev = e.index;
    }
    out.width = static_cast<int>(std::lround(pen / 64.0));
    return out;
  }

 private:
  struct Entry {
    Glyph glyph;
    FT_UInt index = 0;
  };

  FontCache() : ft_(open_freetype()) {
    if (ft_.init_freetype(&library_)) throw std::runtime_error("FreeType initialisation failed");
    const char* env = std::getenv("MOREAU_FONT_DIR");
    const std::string dir = env && *env ? env : MOREAU_RENDER_FONT_DIR;
    const std::string files[2] = {dir + "/DejaVuSans.ttf", dir + "/DejaVuSans-Bold.ttf"};
    for (int b = 0; b < 2; ++b) {
      if (ft_.new_face(library_, files[b].c_str(), 0, &faces_[b])) {
        if (b == 1) {  // no bold face: use the regular one
          faces_[1] = faces_[0];
          continue;
        }
        throw std::runtime_error("cannot load font " + files[b] + " (install fonts-dejavu-core or set MOREAU_FONT_DIR)");
      }
    }
  }

  bool has_kerning(bool bold) const { return FT_HAS_KERNING(faces_[bold ? 1 : 0]); }

  FT_Face face_for(bool bold, int px) {
    const int slot = (bold && faces_[1] != faces_[0]) ? 1 : 0;
    if (current_px_[slot] != px) {
      ft_.set_pixel_sizes(faces_[slot], 0, static_cast<FT_UInt>(px));
      current_px_[slot] = px;
    }
    return faces_[slot];
  }

  long kerning(FT_Face face, bool bold, int px, FT_UInt a, FT_UInt b) {
    const auto key = std::make_tuple(bold, px, a, b);
    auto it = kerning_.find(key);
    if (it != kerning_.end()) return it->second;
    FT_Vector delta{0, 0};
    ft_.get_kerning(face, a, b, FT_KERNING_DEFAULT, &delta);
    kerning_.emplace(key, delta.x);
    return delta.x;
  }

  const Glyph& glyph_locked(char32_t cp, int px, bool bold) { return glyph_entry(cp, px, bold).glyph; }

  const Entry& glyph_entry(char32_t cp, int px, bool bold) {
    const std::uint64_t key = (static_cast<std::uint64_t>(cp) << 24) | (static_cast<std::uint64_t>(px) << 1) | (bold ? 1u : 0u);
    auto it = glyphs_.find(key);
    if (it != glyphs_.end()) return it->second;
    FT_Face face = face_for(bold, px);
    Entry e;
    e.index = ft_.get_char_index(face, cp);
    if (ft_.load_glyph(face, e.index, FT_LOAD_RENDER | FT_LOAD_TARGET_NORMAL) == 0) {
      const FT_GlyphSlot g = face->glyph;
      e.glyph.advance = static_cast<int>(g->advance.x);
      e.glyph.width = static_cast<int>(g->bitmap.width);
      e.glyph.height = static_cast<int>(g->bitmap.rows);
      e.glyph.left = g->bitmap_left;
      e.glyph.top = g->bitmap_top;
      e.glyph.coverage.resize(static_cast<std::size_t>(e.glyph.width) * e.glyph.height);
      for (int r = 0; r < e.glyph.height; ++r) {
        const unsigned char* src = g->bitmap.buffer + static_cast<std::ptrdiff_t>(r) * g->bitmap.pitch;
        std::copy(src, src + e.glyph.width, e.glyph.coverage.begin() + static_cast<std::ptrdiff_t>(r) * e.glyph.width);
      }
    }
    return glyphs_.emplace(key, std::move(e)).first->second;
  }

  std::mutex mutex_;
  const FreeTypeApi ft_;
  FT_Library library_ = nullptr;
  FT_Face faces_[2] = {nullptr, nullptr};
  int current_px_[2] = {0, 0};
  std::unordered_map<std::uint64_t, Entry> glyphs_;
  std::map<std::pair<int, bool>, FontMetrics> metrics_;
  std::map<std::tuple<bool, int, FT_UInt, FT_UInt>, long> kerning_;
};

}  // namespace

FontMetrics font_metrics(int px, bool bold) { return FontCache::instance().metrics(px, bold); }

ShapedText shape_text(std::string_view utf8, int px, bool bold) { return FontCache::instance().shape(utf8, px, bold); }

int text_width(std::string_view utf8, int px, bool bold) { return shape_text(utf8, px, bold).width; }

}  // namespace moreau::render::detail
