// Loads the raster module (libmoreau_render_gl.so: the OSMesa backend, and with it LLVM, some 60 MB, and
// the PNG codec over libpng) at the first PNG, so that a process that draws nothing, or only SVG, never
// maps it. Where the module is looked for,
// in order: $MOREAU_RENDER_GL (a path); next to the executable; ../lib/moreau/ from the executable (an
// installed tree: bin/ and lib/moreau/); the build tree it was built in.
#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "backends.h"

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

std::vector<std::string> candidates() {
  std::vector<std::string> out;
  if (const char* env = std::getenv("MOREAU_RENDER_GL"); env && *env) out.emplace_back(env);
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    out.push_back((exe.parent_path() / kModule).string());
    out.push_back((exe.parent_path().parent_path() / "lib" / "moreau" / kModule).string());
  }
#ifdef MOREAU_RENDER_GL_BUILD_PATH
  out.emplace_back(MOREAU_RENDER_GL_BUILD_PATH);
#endif
  return out;
}

RasterModule load() {
  std::string tried;
  for (const std::string& path : candidates()) {
    if (::access(path.c_str(), R_OK) != 0) {
      tried += "\n  " + path + " (not found)";
      continue;
    }
    // RTLD_LOCAL: the module's own copies of the font code stay its own.
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      tried += "\n  " + path + ": " + ::dlerror();
      continue;
    }
    RasterModule m;
    m.rasterize = reinterpret_cast<decltype(m.rasterize)>(::dlsym(handle, "moreau_render_gl_rasterize"));
    m.encode_png = reinterpret_cast<decltype(m.encode_png)>(::dlsym(handle, "moreau_render_gl_encode_png"));
    m.decode_png = reinterpret_cast<decltype(m.decode_png)>(::dlsym(handle, "moreau_render_gl_decode_png"));
    if (m.rasterize && m.encode_png && m.decode_png) return m;
    tried += "\n  " + path + ": not the module of this build (an entry point is missing)";
    ::dlclose(handle);
  }
  throw std::runtime_error(std::string("PNG figures need the raster module ") + kModule +
                           " (SVG figures do not); it was not found or could not be loaded:" + tried);
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
