// Loads the raster module (libmoreau_render_gl.so: the OSMesa backend, and with it LLVM, some 60 MB, and
// the PNG codec over libpng) at the first PNG, so that a process that draws nothing, or only SVG, never
// maps it. The module is looked for as install_paths.h says, $MOREAU_RENDER_GL first.
#include <dlfcn.h>

#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "backends.h"
#include "moreau/platform/install_paths.h"

namespace moreau::render::detail {
namespace {

// The module's entry points (gl_backend.cc, png.cc). Each returns 0, or 1 with the reason in its last
// argument: no exception crosses between the module and its loader, which may each carry a C++ runtime
// of their own (moreau links libstdc++ statically; the module and OSMesa's LLVM use the shared one).
struct RasterModule {
  int (*rasterize)(const Scene*, Image*, std::string*) = nullptr;
  int (*encode_png)(const Image*, const PngOptions*, std::vector<std::uint8_t>*, std::string*) = nullptr;
  int (*decode_png)(const std::uint8_t*, std::size_t, Image*, std::string*) = nullptr;
};
constexpr const char* kModule = "libmoreau_render_gl.so";

RasterModule load() {
  std::string tried;  // MOREAU_RENDER_GL_BUILD_PATH: defined by render/CMakeLists.txt
  void* handle = platform::open_module(platform::install_candidates(kModule, "MOREAU_RENDER_GL", MOREAU_RENDER_GL_BUILD_PATH),
                                       {"moreau_render_gl_rasterize", "moreau_render_gl_encode_png", "moreau_render_gl_decode_png"}, tried);
  if (!handle)
    throw std::runtime_error(std::string("PNG figures need the raster module ") + kModule +
                             " (SVG figures do not); it was not found or could not be loaded:" + tried);
  RasterModule m;
  m.rasterize = reinterpret_cast<decltype(m.rasterize)>(::dlsym(handle, "moreau_render_gl_rasterize"));
  m.encode_png = reinterpret_cast<decltype(m.encode_png)>(::dlsym(handle, "moreau_render_gl_encode_png"));
  m.decode_png = reinterpret_cast<decltype(m.decode_png)>(::dlsym(handle, "moreau_render_gl_decode_png"));
  return m;
}

// Loaded once; a failure is not remembered, so that the next figure tries again and says why.
const RasterModule& raster_module() {
  static std::mutex mu;
  static RasterModule m;
  std::lock_guard lock(mu);
  if (!m.rasterize) m = load();
  return m;
}

}  // namespace

Image rasterize(const Scene& scene) {
  Image image;
  std::string error;
  if (raster_module().rasterize(&scene, &image, &error) != 0) throw std::runtime_error(error);
  return image;
}

}  // namespace moreau::render::detail

namespace moreau::render {

std::vector<std::uint8_t> encode_png(const Image& image, const PngOptions& options) {
  if (image.width <= 0 || image.height <= 0 || image.rgba.size() != static_cast<std::size_t>(image.width) * image.height * 4)
    throw std::invalid_argument("encode_png: image size does not match its pixel data");
  std::vector<std::uint8_t> out;
  std::string error;
  if (detail::raster_module().encode_png(&image, &options, &out, &error) != 0) throw std::runtime_error(error);
  return out;
}

Image decode_png(std::span<const std::uint8_t> png) {
  Image image;
  std::string error;
  if (detail::raster_module().decode_png(png.data(), png.size(), &image, &error) != 0) throw std::runtime_error(error);
  return image;
}

}  // namespace moreau::render
