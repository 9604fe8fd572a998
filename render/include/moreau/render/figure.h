// A figure description: plain data, no graphics state. Both backends (PNG via OSMesa, SVG) draw the
// same description through the same layout, so a figure looks alike in either format.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace moreau::render {

enum class Scale { linear, log };

struct Axis {
  Scale scale = Scale::linear;
  // Explicit limits; an unset side is derived from the data (plus padding).
  std::optional<double> min, max;
  // Fraction of the data range added on each automatically limited side (in decades on a log axis).
  double padding = 0.04;
};

enum class SeriesStyle { line, points, line_points };

struct Series {
  std::string label;  // empty: not listed in the legend
  std::vector<double> x, y;
  SeriesStyle style = SeriesStyle::line;
  std::optional<int> color;  // index into palette(); default: the series' position in its panel
};

// A vertical marker at a given x. A `line` marker is a dashed line across the plot with its label
// written next to it (e.g. "converged t=3.2"); `tick` markers are short rug ticks along the bottom
// of the plot (e.g. impacts), listed once per distinct label in the legend.
struct Marker {
  enum class Kind { line, tick };
  double x = 0;
  std::string label;
  Kind kind = Kind::line;
  std::optional<int> color;  // index into palette(); default: dark grey
};

enum class LegendPlace { best, upper_right, upper_left, lower_left, lower_right };

struct Panel {
  std::string title, x_label, y_label;
  Axis x_axis, y_axis;
  std::vector<Series> series;
  std::vector<Marker> markers;
  bool legend = true;
  LegendPlace legend_place = LegendPlace::best;
};

// Panels are stacked vertically and share the figure width; their plot areas are aligned.
struct Figure {
  int width_px = 1200;
  int height_px = 800;
  std::string title;
  std::vector<Panel> panels;
};

inline constexpr int min_figure_px = 64;
inline constexpr int max_figure_px = 8192;

// Thrown for a figure that cannot be drawn; the message names the panel and series at fault.
class FigureError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// Checks sizes, data (non-empty, x/y of equal length, finite, positive on log axes), limits and
// colour indices. Throws FigureError on the first problem found. The renderers call it first.
void validate(const Figure& figure);

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};

// The series colours: Okabe-Ito, safe for the common colour-vision deficiencies, ordered so that
// neighbours differ most. Series colour indices wrap around.
const std::vector<Rgb>& palette();
Rgb palette_color(int index);

}  // namespace moreau::render
