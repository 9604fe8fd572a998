// The two backends behind render.h.
#pragma once

#include <exception>
#include <string>
#include <string_view>

#include "moreau/render/render.h"
#include "scene.h"

namespace moreau::render::detail {

// PNG pixels through OSMesa. rasterize() (gl_loader.cc) loads the OpenGL module,
// libmoreau_render_gl.so, at its first call and runs rasterize_with_opengl() (gl_backend.cc) in it.
Image rasterize(const Scene& scene);
Image rasterize_with_opengl(const Scene& scene);
std::string write_svg(const Scene& scene);  // svg_backend.cc

// Text as XML 1.0 character data or an attribute value (svg_backend.cc), whatever it holds: & < > "
// as references, and every character XML 1.0 forbids (C0 controls but tab, newline and carriage return;
// U+FFFE, U+FFFF; bytes that are not UTF-8, surrogates included) or discourages (DEL, C1 controls) as
// U+FFFD, the replacement character. A figure's title is a scene name a client chose: a control byte in
// it made the SVG invalid XML that no viewer would open. Every text the SVG writer puts out goes through it.
std::string xml_text(std::string_view text);

// The body of an entry point of the raster module (gl_backend.cc, png.cc): runs f and returns 0, or 1
// with the message of what it threw in *error. No exception leaves the module: the executable that loads
// it may carry a C++ runtime of its own (moreau links libstdc++ statically), so the loader throws the
// message on its side (gl_loader.cc).
template <class F>
int module_entry(std::string* error, F&& f) noexcept {
  try {
    f();
    return 0;
  } catch (const std::exception& e) {
    *error = e.what();
  } catch (...) {
    *error = "unknown failure in the raster module";
  }
  return 1;
}

}  // namespace moreau::render::detail
