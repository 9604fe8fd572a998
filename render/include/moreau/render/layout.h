// Layout shared by the PNG and SVG backends: ticks, limits, the data -> pixel mapping, the placement
// of the plot areas, and the decimation of dense series.
//
// Pixel coordinates: origin at the top-left corner of the image, x to the right, y downwards; the
// pixel in column i, row j covers [i, i+1) x [j, j+1). A value v lands in row floor(y.to_pixel(v)).
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "moreau/render/figure.h"

namespace moreau::render {

struct Tick {
  double value = 0;
  std::string label;  // empty for minor ticks
  bool major = true;
};

// Step from the 1-2-5 sequence (times a power of ten) giving at most max_ticks ticks over [lo, hi].
double nice_step(double lo, double hi, int max_ticks);
// Ticks at the multiples of nice_step(lo, hi, max_ticks) inside [lo, hi], labelled by format_tick.
std::vector<Tick> linear_ticks(double lo, double hi, int max_ticks);
// Major ticks at the decades 10^k inside [lo, hi] (every n-th decade if there are more than
// max_major), labelled 10^k with superscript digits ("10⁻³"); minor ticks at 2..9 x 10^k when each
// decade is shown. A range of less than two decades falls back to 1-2-5 ticks with plain labels.
std::vector<Tick> log_ticks(double lo, double hi, int max_major);
// "10⁻³" (UTF-8, superscript digits and minus).
std::string decade_label(int exponent);
// A tick label for v on a linear axis with the given step: as many decimals as the step needs, or
// 2.5e-5 style when the axis' largest magnitude is >= 1e5 or the step < 1e-4 (0 is then "0").
// magnitude: the largest |tick| on the axis (0: |v|), so all labels of an axis share one style.
std::string format_tick(double v, double step, double magnitude = 0);

struct Limits {
  double lo = 0, hi = 1;
};
// Limits covering [data_min, data_max] plus padding (a fraction of the range; in log space on a log
// axis). A degenerate range is widened around the value.
Limits auto_limits(double data_min, double data_max, Scale scale, double padding);

// Maps data values along one axis to pixel coordinates: lo -> pixel_lo, hi -> pixel_hi, linear in
// the value or (log axis) in log10 of the value. For a y axis pixel_lo > pixel_hi.
struct AxisMap {
  Scale scale = Scale::linear;
  double lo = 0, hi = 1;
  double pixel_lo = 0, pixel_hi = 1;
  double to_pixel(double v) const;
  double from_pixel(double p) const;
};

struct Rect {
  double x = 0, y = 0, w = 0, h = 0;
  double right() const { return x + w; }
  double bottom() const { return y + h; }
  bool contains(double px, double py) const { return px >= x && px <= x + w && py >= y && py <= y + h; }
};

struct PanelLayout {
  Rect plot;  // the plot area inside the axes box, in pixels
  AxisMap x, y;
  std::vector<Tick> x_ticks, y_ticks;
};

struct FigureLayout {
  int width = 0, height = 0;
  std::vector<PanelLayout> panels;
};

// Validates the figure and places it: exactly the mapping the renderers use, so a test can predict
// where a value lands.
FigureLayout compute_layout(const Figure& figure);

// Decimation of a dense polyline already mapped to pixels: consecutive points that fall into the
// same pixel column are reduced to the first, minimum, maximum and last of the run (in their
// original order), so a 100k-point series keeps 2-4 vertices per column and draws the same pixels.
// Returns the indices kept, increasing. With by_rows as well, a second pass does the same along
// rows (for curves that are not monotonic in x, e.g. phase portraits).
std::vector<std::size_t> decimate(std::span<const double> px, std::span<const double> py, bool by_rows = false);

}  // namespace moreau::render
