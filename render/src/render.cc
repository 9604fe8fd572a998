// Public entry points (render.h).
#include "moreau/render/render.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "backends.h"

namespace moreau::render {

Image render_rgba(const Figure& figure) { return detail::rasterize(detail::build_scene(figure)); }

std::vector<std::uint8_t> render_png_bytes(const Figure& figure, const PngOptions& options) {
  return encode_png(render_rgba(figure), options);
}

void render_png(const Figure& figure, const std::string& path, const PngOptions& options) {
  const std::vector<std::uint8_t> bytes = render_png_bytes(figure, options);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::runtime_error("cannot open " + path + " for writing: " + std::strerror(errno));
  const std::size_t written = std::fwrite(bytes.data(), 1, bytes.size(), f);
  const bool closed = std::fclose(f) == 0;
  if (written != bytes.size() || !closed) throw std::runtime_error("cannot write " + path);
}

std::string render_svg(const Figure& figure) { return detail::write_svg(detail::build_scene(figure)); }

}  // namespace moreau::render
