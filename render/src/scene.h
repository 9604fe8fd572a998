// The drawing both backends consume: the figure laid out into primitives in pixel coordinates
// (origin top-left, y down). Built once per render by build_scene().
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "moreau/render/figure.h"
#include "moreau/render/layout.h"

namespace moreau::render::detail {

struct Rgba {
  std::uint8_t r = 0, g = 0, b = 0, a = 255;
};

struct Point {
  double x = 0, y = 0;
};

// A filled axis-aligned rectangle (background, grid lines, ticks, axes box, legend box).
struct FillRect {
  Rect rect;
  Rgba color;
  std::optional<Rect> clip;
};

// A stroked polyline. Series lines are flagged so the SVG backend can write them as <polyline>.
struct Stroke {
  std::vector<Point> points;
  Rgba color;
  double width = 1;
  bool dashed = false;
  bool series = false;
  std::optional<Rect> clip;
};

// Filled discs (data points).
struct Dots {
  std::vector<Point> centers;
  Rgba color;
  double radius = 2;
  std::optional<Rect> clip;
};

// A line of text anchored at (x, y): a point on the baseline, at the start, centre or end of the
// text as read (`align`). Vertical text is rotated 90 degrees counter-clockwise (read bottom to
// top, like a y-axis label); its baseline is then the vertical line through x.
struct Text {
  enum class Align { left, center, right };
  std::string text;
  std::string superscript;  // drawn after text, smaller and raised (the exponent of 10^k)
  double x = 0, y = 0;
  int size_px = 12;
  bool bold = false;
  bool vertical = false;
  Align align = Align::left;
  Rgba color;
};

using Item = std::variant<FillRect, Stroke, Dots, Text>;

// Size and rise of the superscript run of a text of size px.
inline int superscript_px(int px) { return static_cast<int>(px * 0.74 + 0.5); }
inline int superscript_rise(int px) { return static_cast<int>(px * 0.42 + 0.5); }
// Width in pixels of a text with its superscript.
int text_extent(const std::string& text, const std::string& superscript, int px, bool bold);

struct Scene {
  int width = 0, height = 0;
  FigureLayout layout;
  std::vector<Item> items;  // in drawing order
};

// Validates and lays out the figure. Throws FigureError.
Scene build_scene(const Figure& figure);

}  // namespace moreau::render::detail
