#include "moreau/render/figure.h"

#include <cmath>
#include <sstream>

#include "moreau/platform/number_text.h"

namespace moreau::render {
namespace {

std::string panel_name(const Figure& f, std::size_t p) {
  std::ostringstream os;
  os << "panel " << p;
  if (!f.panels[p].title.empty()) os << " '" << f.panels[p].title << "'";
  return os.str();
}

std::string series_name(const Panel& panel, std::size_t s) {
  std::ostringstream os;
  os << "series " << s;
  if (!panel.series[s].label.empty()) os << " '" << panel.series[s].label << "'";
  return os.str();
}

[[noreturn]] void fail(const std::string& where, const std::string& what) { throw FigureError(where + ": " + what); }

void check_axis(const Axis& axis, const std::string& where, const char* name) {
  const std::string w = where + ", " + name + " axis";
  if (axis.min && !std::isfinite(*axis.min)) fail(w, "minimum is not finite");
  if (axis.max && !std::isfinite(*axis.max)) fail(w, "maximum is not finite");
  if (axis.min && axis.max && !(*axis.min < *axis.max)) {
    std::ostringstream os;
    os << "minimum " << platform::significant(*axis.min, 6) << " is not below maximum " << platform::significant(*axis.max, 6);
    fail(w, os.str());
  }
  if (axis.scale == Scale::log) {
    if (axis.min && *axis.min <= 0) fail(w, "log scale needs a positive minimum, got " + platform::significant(*axis.min, 6));
    if (axis.max && *axis.max <= 0) fail(w, "log scale needs a positive maximum, got " + platform::significant(*axis.max, 6));
  }
  if (!std::isfinite(axis.padding) || axis.padding < 0 || axis.padding > 1) fail(w, "padding must be within [0, 1]");
}

void check_values(const std::vector<double>& v, Scale scale, const std::string& where, const char* name) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      std::ostringstream os;
      os << name << "[" << i << "] is " << platform::non_finite_text(v[i]) << " (NaN and Inf cannot be drawn)";
      fail(where, os.str());
    }
    if (scale == Scale::log && v[i] <= 0) {
      std::ostringstream os;
      os << name << "[" << i << "] = " << platform::significant(v[i], 6) << " is not positive, but the " << name << " axis is logarithmic";
      fail(where, os.str());
    }
  }
}

void check_color(const std::optional<int>& c, const std::string& where) {
  if (c && *c < 0) fail(where, "colour index " + std::to_string(*c) + " is negative");
}

}  // namespace

void validate(const Figure& f) {
  auto check_size = [](int v, const char* what) {
    if (v < min_figure_px || v > max_figure_px) {
      std::ostringstream os;
      os << "figure " << what << " " << v << " px is outside [" << min_figure_px << ", " << max_figure_px << "]";
      throw FigureError(os.str());
    }
  };
  check_size(f.width_px, "width");
  check_size(f.height_px, "height");
  if (f.panels.empty()) throw FigureError("figure has no panels");
  for (std::size_t p = 0; p < f.panels.size(); ++p) {
    const Panel& panel = f.panels[p];
    const std::string pw = panel_name(f, p);
    check_axis(panel.x_axis, pw, "x");
    check_axis(panel.y_axis, pw, "y");
    for (std::size_t s = 0; s < panel.series.size(); ++s) {
      const Series& series = panel.series[s];
      const std::string sw = pw + ", " + series_name(panel, s);
      if (series.x.empty() && series.y.empty()) fail(sw, "is empty (no data points)");
      if (series.x.size() != series.y.size()) {
        std::ostringstream os;
        os << "x has " << series.x.size() << " values but y has " << series.y.size();
        fail(sw, os.str());
      }
      check_values(series.x, panel.x_axis.scale, sw, "x");
      check_values(series.y, panel.y_axis.scale, sw, "y");
      check_color(series.color, sw);
    }
    for (std::size_t m = 0; m < panel.markers.size(); ++m) {
      const Marker& marker = panel.markers[m];
      const std::string mw = pw + ", marker " + std::to_string(m) + (marker.label.empty() ? std::string() : " '" + marker.label + "'");
      if (!std::isfinite(marker.x)) fail(mw, "position is not finite");
      if (panel.x_axis.scale == Scale::log && marker.x <= 0) fail(mw, "position is not positive on a log x axis");
      check_color(marker.color, mw);
    }
  }
}

const std::vector<Rgb>& palette() {
  // Okabe & Ito (2008), "Color Universal Design"; yellow last (weak on white).
  static const std::vector<Rgb> colors = {
      {0x00, 0x72, 0xB2},  // blue
      {0xD5, 0x5E, 0x00},  // vermillion
      {0x00, 0x9E, 0x73},  // bluish green
      {0xCC, 0x79, 0xA7},  // reddish purple
      {0xE6, 0x9F, 0x00},  // orange
      {0x56, 0xB4, 0xE9},  // sky blue
      {0x00, 0x00, 0x00},  // black
      {0xF0, 0xE4, 0x42},  // yellow
  };
  return colors;
}

Rgb palette_color(int index) {
  const auto& p = palette();
  const int n = static_cast<int>(p.size());
  return p[static_cast<std::size_t>(((index % n) + n) % n)];
}

}  // namespace moreau::render
