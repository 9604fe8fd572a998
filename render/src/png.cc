// PNG encoding and decoding with libpng, in memory. Built into the raster module (libmoreau_render_gl.so),
// so that only a process that writes or reads a PNG loads libpng; render.h's encode_png and decode_png
// reach these through gl_loader.cc.
#include <png.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include "backends.h"
#include "moreau/render/render.h"

namespace moreau::render {
namespace {

void on_error(png_structp, png_const_charp msg) { throw std::runtime_error(std::string("libpng: ") + msg); }
void on_warning(png_structp, png_const_charp) {}

void append(png_structp png, png_bytep data, png_size_t n) {
  auto* out = static_cast<std::vector<std::uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + n);
}
void no_flush(png_structp) {}

struct Reader {
  std::span<const std::uint8_t> data;
  std::size_t pos = 0;
};

void read_bytes(png_structp png, png_bytep out, png_size_t n) {
  auto* r = static_cast<Reader*>(png_get_io_ptr(png));
  if (r->pos + n > r->data.size()) png_error(png, "truncated PNG data");
  std::memcpy(out, r->data.data() + r->pos, n);
  r->pos += n;
}

// The image's size was checked by encode_png (gl_loader.cc).
std::vector<std::uint8_t> encode_png_with_libpng(const Image& image, const PngOptions& options) {
  std::vector<std::uint8_t> out;
  out.reserve(static_cast<std::size_t>(image.width) * image.height / 8);
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, on_error, on_warning);
  if (!png) throw std::runtime_error("libpng: cannot create write struct");
  png_infop info = png_create_info_struct(png);
  try {
    if (!info) throw std::runtime_error("libpng: cannot create info struct");
    png_set_write_fn(png, &out, append, no_flush);
    png_set_IHDR(png, info, static_cast<png_uint_32>(image.width), static_cast<png_uint_32>(image.height), 8, PNG_COLOR_TYPE_RGB,
                 PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, std::clamp(options.compression_level, 0, 9));
    // Plots are mostly flat colour: the Up filter turns repeated rows into zeros, which the fast
    // zlib levels compress well, at a fraction of the cost of trying every filter per row.
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_UP);
    png_write_info(png, info);
    png_set_filler(png, 0, PNG_FILLER_AFTER);  // the input rows are RGBA; the alpha byte is dropped
    std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
    for (int r = 0; r < image.height; ++r)
      rows[static_cast<std::size_t>(r)] = const_cast<png_bytep>(image.rgba.data() + static_cast<std::size_t>(r) * image.width * 4);
    png_write_image(png, rows.data());
    png_write_end(png, nullptr);
  } catch (...) {
    png_destroy_write_struct(&png, &info);
    throw;
  }
  png_destroy_write_struct(&png, &info);
  return out;
}

Image decode_png_with_libpng(std::span<const std::uint8_t> data) {
  if (data.size() < 8 || png_sig_cmp(data.data(), 0, 8) != 0) throw std::runtime_error("decode_png: not a PNG");
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, on_error, on_warning);
  if (!png) throw std::runtime_error("libpng: cannot create read struct");
  png_infop info = png_create_info_struct(png);
  Reader reader{data, 0};
  Image image;
  try {
    if (!info) throw std::runtime_error("libpng: cannot create info struct");
    png_set_read_fn(png, &reader, read_bytes);
    png_read_info(png, info);
    const int color = png_get_color_type(png, info);
    const int depth = png_get_bit_depth(png, info);
    if (depth == 16) png_set_strip_16(png);
    if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (color == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
    if (color == PNG_COLOR_TYPE_GRAY || color == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    if (!(color & PNG_COLOR_MASK_ALPHA) && !png_get_valid(png, info, PNG_INFO_tRNS)) png_set_filler(png, 0xff, PNG_FILLER_AFTER);
    png_read_update_info(png, info);
    image.width = static_cast<int>(png_get_image_width(png, info));
    image.height = static_cast<int>(png_get_image_height(png, info));
    if (png_get_rowbytes(png, info) != static_cast<std::size_t>(image.width) * 4)
      throw std::runtime_error("decode_png: unexpected row size");
    image.rgba.resize(static_cast<std::size_t>(image.width) * image.height * 4);
    std::vector<png_bytep> rows(static_cast<std::size_t>(image.height));
    for (int r = 0; r < image.height; ++r)
      rows[static_cast<std::size_t>(r)] = image.rgba.data() + static_cast<std::size_t>(r) * image.width * 4;
    png_read_image(png, rows.data());
    png_read_end(png, nullptr);
  } catch (...) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw;
  }
  png_destroy_read_struct(&png, &info, nullptr);
  return image;
}

}  // namespace
}  // namespace moreau::render

// Entry points of the raster module (gl_loader.cc, backends.h's module_entry).
extern "C" __attribute__((visibility("default"))) int moreau_render_gl_encode_png(const moreau::render::Image* image,
                                                                                  const moreau::render::PngOptions* options,
                                                                                  std::vector<std::uint8_t>* out, std::string* error) {
  return moreau::render::detail::module_entry(error, [&] { *out = moreau::render::encode_png_with_libpng(*image, *options); });
}

extern "C" __attribute__((visibility("default"))) int moreau_render_gl_decode_png(const std::uint8_t* data, std::size_t size,
                                                                                  moreau::render::Image* image, std::string* error) {
  return moreau::render::detail::module_entry(
      error, [&] { *image = moreau::render::decode_png_with_libpng(std::span<const std::uint8_t>(data, size)); });
}
