// Rendering a Figure: PNG through OSMesa (offscreen OpenGL, no display needed) and SVG text.
//
// All functions validate the figure first (FigureError on bad input) and are safe to call from
// several threads at once: the OpenGL part is serialised on one offscreen context, the layout and
// the PNG encoding run in parallel.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "moreau/render/figure.h"

namespace moreau::render {

// An 8-bit RGBA image, rows top-down.
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgba;  // width * height * 4

  const std::uint8_t* pixel(int x, int y) const { return &rgba[(static_cast<std::size_t>(y) * width + x) * 4]; }
};

struct PngOptions {
  // zlib level 0-9. Plots compress well even at fast levels; 2 keeps encoding time small.
  int compression_level = 2;
};

// Draws the figure (4x multisampled, resolved) and returns the pixels.
Image render_rgba(const Figure& figure);

// PNG (8-bit RGB) of the figure, in memory (e.g. an HTTP response body) or written to a file.
std::vector<std::uint8_t> render_png_bytes(const Figure& figure, const PngOptions& options = {});
void render_png(const Figure& figure, const std::string& path, const PngOptions& options = {});

// SVG document of the figure: one <polyline> per series, text as <text> elements.
std::string render_svg(const Figure& figure);

// PNG encoding and decoding of an Image (the decoder accepts any PNG libpng reads and returns RGBA).
std::vector<std::uint8_t> encode_png(const Image& image, const PngOptions& options = {});
Image decode_png(std::span<const std::uint8_t> png);

}  // namespace moreau::render
