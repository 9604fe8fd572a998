// The two backends behind render.h.
#pragma once

#include <string>

#include "moreau/render/render.h"
#include "scene.h"

namespace moreau::render::detail {

// PNG pixels through OSMesa. rasterize() (gl_loader.cc) loads the OpenGL module,
// libmoreau_render_gl.so, at its first call and runs rasterize_with_opengl() (gl_backend.cc) in it.
Image rasterize(const Scene& scene);
Image rasterize_with_opengl(const Scene& scene);
std::string write_svg(const Scene& scene);  // svg_backend.cc

}  // namespace moreau::render::detail
