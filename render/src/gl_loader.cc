// Loads the OpenGL backend (libmoreau_render_gl.so: OSMesa, and with it LLVM, some 60 MB) at the first
// PNG, so that a process that draws nothing, or only SVG, never maps it. Where the module is looked for,
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

using RasterizeFn = void (*)(const Scene*, Image*);
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

RasterizeFn load() {
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
    if (auto fn = reinterpret_cast<RasterizeFn>(::dlsym(handle, "moreau_render_gl_rasterize"))) return fn;
    tried += "\n  " + path + ": no moreau_render_gl_rasterize";
    ::dlclose(handle);
  }
  throw std::runtime_error(std::string("PNG figures need the OpenGL module ") + kModule +
                           " (SVG figures do not); it was not found or could not be loaded:" + tried);
}

}  // namespace

Image rasterize(const Scene& scene) {
  // Loaded once; a failure is not remembered, so that the next figure tries again and says why.
  static std::mutex mu;
  static RasterizeFn fn = nullptr;
  {
    std::lock_guard lock(mu);
    if (!fn) fn = load();
  }
  Image image;
  fn(&scene, &image);
  return image;
}

}  // namespace moreau::render::detail
