// The two backends behind render.h.
#pragma once

#include <string>

#include "moreau/render/render.h"
#include "scene.h"

namespace moreau::render::detail {

Image rasterize(const Scene& scene);     // gl_backend.cc
std::string write_svg(const Scene& scene);  // svg_backend.cc

}  // namespace moreau::render::detail
