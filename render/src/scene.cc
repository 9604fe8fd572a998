// Layout: from a Figure to positioned primitives (scene.h), and compute_layout (layout.h).
#include "scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "font.h"
#include "moreau/platform/number_text.h"

namespace moreau::render {
namespace detail {
namespace {

constexpr Rgba kText{26, 26, 26, 255};
constexpr Rgba kFrame{38, 38, 38, 255};
constexpr Rgba kGridMajor{226, 226, 226, 255};
constexpr Rgba kMarker{85, 85, 85, 255};
constexpr Rgba kLegendFill{255, 255, 255, 235};
constexpr Rgba kLegendBorder{200, 200, 200, 255};

Rgba to_rgba(Rgb c) { return {c.r, c.g, c.b, 255}; }

// Sizes derived from the figure size, so a figure reads the same at 800x500 and 1600x1000.
struct Style {
  int tick_px = 14, label_px = 15, title_px = 16, figure_title_px = 19, legend_px = 14;
  double line_width = 1.75, frame_width = 1, tick_length = 5, pad = 10;
};

Style style_for(const Figure& f) {
  Style s;
  const double base = std::sqrt(static_cast<double>(f.width_px) * f.height_px) * 0.0142;
  s.tick_px = std::clamp(static_cast<int>(std::lround(base)), 11, 26);
  s.label_px = static_cast<int>(std::lround(s.tick_px * 1.08));
  s.title_px = static_cast<int>(std::lround(s.tick_px * 1.12));
  s.figure_title_px = static_cast<int>(std::lround(s.tick_px * 1.3));
  s.legend_px = std::max(11, static_cast<int>(std::lround(s.tick_px * 0.95)));
  s.line_width = std::max(1.6, s.tick_px * 0.13);
  s.frame_width = std::max(1.0, std::round(s.tick_px / 18.0));
  s.tick_length = std::round(s.tick_px * 0.35);
  s.pad = std::round(s.tick_px * 0.75);
  return s;
}

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool empty() const { return !(lo <= hi); }
};

Limits axis_limits(const Axis& axis, Range data, const std::string& where) {
  if (data.empty()) data = axis.scale == Scale::log ? Range{1, 10} : Range{0, 1};
  Limits lim = auto_limits(data.lo, data.hi, axis.scale, axis.padding);
  if (axis.min) lim.lo = *axis.min;
  if (axis.max) lim.hi = *axis.max;
  if (!(lim.hi > lim.lo)) {  // one explicit side beyond the data
    if (axis.scale == Scale::log) {
      if (axis.min)
        lim.hi = lim.lo * 10;
      else
        lim.lo = lim.hi / 10;
    } else {
      const double w = std::max(1.0, std::abs(axis.min ? lim.lo : lim.hi) * 0.1);
      if (axis.min)
        lim.hi = lim.lo + w;
      else
        lim.lo = lim.hi - w;
    }
  }
  // Both ends and the span must be representable, and the span resolvable in double precision.
  const bool log = axis.scale == Scale::log;
  const double a = log ? std::log10(lim.lo) : lim.lo, b = log ? std::log10(lim.hi) : lim.hi;
  const double span = b - a;
  if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(span) ||
      !(span > 1e-12 * std::max({std::abs(a), std::abs(b), log ? 1.0 : 0.0}))) {
    throw FigureError(where + ": the range [" + platform::significant(lim.lo, 12) + ", " + platform::significant(lim.hi, 12) + "] is too " +
                      (std::isfinite(span) ? "narrow" : "wide") + " to draw");
  }
  return lim;
}

// Tick labels as drawn: a trailing "10⁻³" becomes "10" with the superscript "−3" (a superscript run
// is larger and clearer than the Unicode superscript digits), and hyphens become minus signs.
std::pair<std::string, std::string> display_label(const std::string& label) {
  std::string out;
  for (char c : label) out += c == '-' ? std::string("\u2212") : std::string(1, c);
  const std::size_t ten = label.rfind("10");
  if (ten == std::string::npos || ten + 2 == label.size()) return {out, {}};
  std::string sup;
  for (char32_t c : decode_utf8(std::string_view(label).substr(ten + 2))) {
    if (c == U'\u207B')
      sup += "\u2212";
    else if (c == U'\u2070')
      sup += '0';
    else if (c == U'\u00B9')
      sup += '1';
    else if (c == U'\u00B2')
      sup += '2';
    else if (c == U'\u00B3')
      sup += '3';
    else if (c >= U'\u2074' && c <= U'\u2079')
      sup += static_cast<char>('4' + (c - U'\u2074'));
    else
      return {out, {}};
  }
  return {label.substr(0, ten + 2), sup};
}

double label_width(const std::string& label, int px) {
  const auto [text, sup] = display_label(label);
  return text_extent(text, sup, px, false);
}

std::vector<Tick> make_ticks(Scale scale, double lo, double hi, int max_ticks) {
  return scale == Scale::log ? log_ticks(lo, hi, max_ticks) : linear_ticks(lo, hi, max_ticks);
}

// Largest tick set along x whose labels do not crowd each other.
std::vector<Tick> fit_x_ticks(const Axis& axis, const AxisMap& map, double length, const Style& st) {
  int max_ticks = std::clamp(static_cast<int>(length / (st.tick_px * 5.0)), 2, 12);
  std::vector<Tick> ticks;
  for (; max_ticks >= 2; --max_ticks) {
    ticks = make_ticks(axis.scale, map.lo, map.hi, max_ticks);
    bool ok = true;
    double prev_right = -std::numeric_limits<double>::infinity();
    for (const Tick& t : ticks) {
      if (t.label.empty()) continue;
      const double w = label_width(t.label, st.tick_px);
      const double px = map.to_pixel(t.value);
      if (px - w / 2 < prev_right + st.tick_px * 1.2) {
        ok = false;
        break;
      }
      prev_right = px + w / 2;
    }
    if (ok) break;
  }
  return ticks;
}

std::vector<Tick> fit_y_ticks(const Axis& axis, const AxisMap& map, double length, const Style& st) {
  const int max_ticks = std::clamp(static_cast<int>(length / (st.tick_px * 2.6)) + 1, 2, 10);
  return make_ticks(axis.scale, map.lo, map.hi, max_ticks);
}

struct LegendEntry {
  enum class Kind { line, dots, line_dots, tick };
  std::string label;
  Kind kind = Kind::line;
  Rgba color;
};

// Vertical budget of one panel's slot: title band above the plot, ticks and labels below.
struct PanelGeometry {
  double slot_top = 0, slot_height = 0;
  double title_height = 0, bottom_height = 0;
};

class Builder {
 public:
  explicit Builder(const Figure& f) : f_(f), st_(style_for(f)) {}

  Scene build() {
    validate(f_);
    lay_out_and_draw();
    // A legend with data under it at every place inside its plot moves out, to the right of the plots
    // (all panels alike, so their plot areas stay aligned), or, when that would take more than a third of
    // the width, above the plots it belongs to, in rows as wide as the plot: the figure is drawn again.
    if (legend_right_width_ > 0) {
      legend_right_width_ = legend_beside_width_;
      if (legend_right_width_ < 0.35 * f_.width_px) {
        legend_outside_ = Outside::right;
      } else {
        legend_outside_ = Outside::above;
        legend_band_height_ = legend_band_wanted_;
        // A band taller than half its plot would leave too little plot: that legend stays inside.
        for (std::size_t p = 0; p < legend_band_height_.size(); ++p)
          if (legend_band_height_[p] > scene_.layout.panels[p].plot.h / 2) legend_band_height_[p] = 0;
      }
      if (legend_outside_ == Outside::right ||
          std::any_of(legend_band_height_.begin(), legend_band_height_.end(), [](double h) { return h > 0; })) {
        Scene inside = std::move(scene_);
        scene_ = Scene{};
        try {
          lay_out_and_draw();
        } catch (const FigureError&) {  // too small for the legends outside: keep the first drawing
          scene_ = std::move(inside);
        }
      }
    }
    if (!f_.title.empty()) {
      const FontMetrics m = font_metrics(st_.figure_title_px, true);
      const auto& first = scene_.layout.panels.front().plot;
      double cx = first.x + first.w / 2;
      const double w = text_width(f_.title, st_.figure_title_px, true);
      cx = std::clamp(cx, w / 2 + st_.pad, f_.width_px - w / 2 - st_.pad);
      add(Text{f_.title, {}, std::round(cx), st_.pad * 0.8 + m.ascender, st_.figure_title_px, true, false, Text::Align::center, kText});
    }
    return std::move(scene_);
  }

 private:
  void lay_out_and_draw() {
    scene_.width = f_.width_px;
    scene_.height = f_.height_px;
    place_panels();
    for (std::size_t p = 0; p < f_.panels.size(); ++p) draw_panel(p);
  }

  template <class T>
  void add(T item) {
    scene_.items.emplace_back(std::move(item));
  }

  void add_rect(double x, double y, double w, double h, Rgba c, std::optional<Rect> clip = std::nullopt) {
    add(FillRect{Rect{x, y, w, h}, c, clip});
  }

  // Vertical placement of the panels, the common left margin, then the x ticks.
  void place_panels() {
    const std::size_t n = f_.panels.size();
    const FontMetrics tick_m = font_metrics(st_.tick_px, false);
    const FontMetrics label_m = font_metrics(st_.label_px, false);
    const FontMetrics title_m = font_metrics(st_.title_px, true);
    const FontMetrics fig_m = font_metrics(st_.figure_title_px, true);

    double top = st_.pad * 0.6;
    if (!f_.title.empty()) top = st_.pad * 0.8 + fig_m.line_height() + st_.pad * 0.9;
    const double bottom = st_.pad * 0.5;
    const double slot = (f_.height_px - top - bottom) / static_cast<double>(n);

    scene_.layout.width = f_.width_px;
    scene_.layout.height = f_.height_px;
    scene_.layout.panels.resize(n);
    bool any_y_label = false;
    for (const Panel& p : f_.panels) any_y_label |= !p.y_label.empty();

    for (std::size_t i = 0; i < n; ++i) {
      const Panel& panel = f_.panels[i];
      PanelGeometry g;
      g.slot_top = top + slot * static_cast<double>(i);
      g.slot_height = slot;
      g.title_height = panel.title.empty() ? st_.pad * 0.7 : title_m.line_height() + st_.pad * 0.5;
      if (legend_outside_ == Outside::above) g.title_height += band_height(i);
      g.bottom_height = st_.frame_width + st_.tick_length + st_.tick_px * 0.3 + tick_m.line_height();
      if (!panel.x_label.empty()) g.bottom_height += st_.tick_px * 0.3 + label_m.line_height();
      if (i + 1 < n) g.bottom_height += st_.pad * 0.9;
      PanelLayout& pl = scene_.layout.panels[i];
      const double y0 = std::round(g.slot_top + g.title_height);
      const double y1 = std::round(g.slot_top + slot - g.bottom_height);
      if (y1 - y0 < 24) {
        throw FigureError("figure height " + std::to_string(f_.height_px) + " px is too small for " + std::to_string(n) +
                          " panel(s): the plot area of panel " + std::to_string(i) + " would be " +
                          std::to_string(static_cast<int>(y1 - y0)) + " px tall");
      }
      pl.plot.y = y0;
      pl.plot.h = y1 - y0;

      Range xr, yr;
      for (const Series& s : panel.series) {
        for (double v : s.x) xr.add(v);
        for (double v : s.y) yr.add(v);
      }
      const std::string where = "panel " + std::to_string(i) + (panel.title.empty() ? std::string() : " '" + panel.title + "'");
      const Limits xl = axis_limits(panel.x_axis, xr, where + ", x axis");
      const Limits yl = axis_limits(panel.y_axis, yr, where + ", y axis");
      pl.x = AxisMap{panel.x_axis.scale, xl.lo, xl.hi, 0, 1};
      pl.y = AxisMap{panel.y_axis.scale, yl.lo, yl.hi, pl.plot.bottom(), pl.plot.y};
      pl.y_ticks = fit_y_ticks(panel.y_axis, pl.y, pl.plot.h, st_);
    }

    double widest = 0;
    for (const PanelLayout& pl : scene_.layout.panels)
      for (const Tick& t : pl.y_ticks)
        if (!t.label.empty()) widest = std::max(widest, label_width(t.label, st_.tick_px));
    double left = st_.pad + widest + st_.tick_px * 0.3 + st_.tick_length + st_.frame_width;
    if (any_y_label) left += label_m.line_height() + st_.tick_px * 0.45;
    left = std::round(left);

    double right = std::round(st_.pad * 1.3);
    if (legend_outside_ == Outside::right) right += legend_right_width_ + std::round(st_.legend_px * 0.8);
    for (int pass = 0; pass < 2; ++pass) {
      double overflow = 0;
      for (std::size_t i = 0; i < n; ++i) {
        PanelLayout& pl = scene_.layout.panels[i];
        pl.plot.x = left;
        pl.plot.w = f_.width_px - left - right;
        if (pl.plot.w < 24) {
          throw FigureError("figure width " + std::to_string(f_.width_px) + " px is too small for the axis labels of panel " +
                            std::to_string(i));
        }
        pl.x.pixel_lo = pl.plot.x;
        pl.x.pixel_hi = pl.plot.right();
        pl.x_ticks = fit_x_ticks(f_.panels[i].x_axis, pl.x, pl.plot.w, st_);
        for (const Tick& t : pl.x_ticks) {
          if (t.label.empty()) continue;
          const double edge = pl.x.to_pixel(t.value) + label_width(t.label, st_.tick_px) / 2.0;
          overflow = std::max(overflow, edge - (f_.width_px - st_.pad * 0.5));
        }
      }
      if (overflow <= 0) break;
      right = std::round(right + overflow);
    }
  }

  void draw_panel(std::size_t index) {
    const Panel& panel = f_.panels[index];
    const PanelLayout& pl = scene_.layout.panels[index];
    const Rect plot = pl.plot;
    const double fw = st_.frame_width;
    const FontMetrics tick_m = font_metrics(st_.tick_px, false);
    const FontMetrics label_m = font_metrics(st_.label_px, false);

    // Grid.
    for (const Tick& t : pl.y_ticks) {
      const double py = std::floor(pl.y.to_pixel(t.value));
      if (!t.major || py < plot.y + 1 || py > plot.bottom() - 2) continue;
      add_rect(plot.x, py, plot.w, 1, kGridMajor);
    }
    for (const Tick& t : pl.x_ticks) {
      const double px = std::floor(pl.x.to_pixel(t.value));
      if (!t.major || px < plot.x + 1 || px > plot.right() - 2) continue;
      add_rect(px, plot.y, 1, plot.h, kGridMajor);
    }

    // Series.
    std::vector<Point> obstacles;  // for the legend placement
    std::vector<LegendEntry> legend;
    for (std::size_t s = 0; s < panel.series.size(); ++s) {
      const Series& series = panel.series[s];
      const Rgba color = to_rgba(palette_color(series.color.value_or(static_cast<int>(s))));
      const std::size_t n = series.x.size();
      std::vector<double> px(n), py(n);
      bool monotonic = true;
      for (std::size_t i = 0; i < n; ++i) {
        px[i] = pl.x.to_pixel(series.x[i]);
        py[i] = pl.y.to_pixel(series.y[i]);
        if (i > 0 && series.x[i] < series.x[i - 1]) monotonic = false;
      }
      const bool line = series.style != SeriesStyle::points;
      const bool dots = series.style != SeriesStyle::line;
      if (line) {
        Stroke stroke;
        stroke.color = color;
        stroke.width = st_.line_width;
        stroke.series = true;
        stroke.clip = plot;
        for (std::size_t i : decimate(px, py, !monotonic)) stroke.points.push_back({px[i], py[i]});
        sample_obstacles(stroke.points, obstacles);
        add(std::move(stroke));
      }
      if (dots) {
        Dots d;
        d.color = color;
        d.radius = std::max(3.0, st_.line_width * 1.9);
        d.clip = plot;
        std::unordered_set<std::uint64_t> seen;
        for (std::size_t i = 0; i < n; ++i) {
          const auto cx = static_cast<std::int64_t>(std::floor(px[i])), cy = static_cast<std::int64_t>(std::floor(py[i]));
          const auto key = (static_cast<std::uint64_t>(cx) << 32) ^ static_cast<std::uint64_t>(cy & 0xffffffff);
          if (seen.insert(key).second) d.centers.push_back({px[i], py[i]});
        }
        sample_obstacles(d.centers, obstacles);
        add(std::move(d));
      }
      if (!series.label.empty()) {
        const auto kind = line && dots ? LegendEntry::Kind::line_dots : line ? LegendEntry::Kind::line : LegendEntry::Kind::dots;
        legend.push_back({series.label, kind, color});
      }
    }

    // Markers: rug ticks along the bottom, dashed lines across.
    std::vector<Rect> label_boxes;
    {
      std::unordered_set<std::int64_t> seen_cols;
      const double tick_h = std::round(st_.tick_px * 0.75);
      const double tick_w = std::max(1.0, std::round(st_.line_width * 0.8));
      for (const Marker& m : panel.markers) {
        if (m.kind != Marker::Kind::tick) continue;
        const double px = pl.x.to_pixel(m.x);
        if (px < plot.x - 0.5 || px > plot.right() + 0.5) continue;
        const Rgba c = m.color ? to_rgba(palette_color(*m.color)) : kMarker;
        const auto col = static_cast<std::int64_t>(std::floor(px));
        if (!seen_cols.insert(col).second) continue;
        add_rect(std::round(px - tick_w / 2), plot.bottom() - tick_h, tick_w, tick_h, c, plot);
        obstacles.push_back({px, plot.bottom() - tick_h / 2});
        if (!m.label.empty() && std::none_of(legend.begin(), legend.end(),
                                             [&](const LegendEntry& e) { return e.kind == LegendEntry::Kind::tick && e.label == m.label; }))
          legend.push_back({m.label, LegendEntry::Kind::tick, c});
      }
      const FontMetrics lm = font_metrics(st_.legend_px, false);
      for (const Marker& m : panel.markers) {
        if (m.kind != Marker::Kind::line) continue;
        const double px = pl.x.to_pixel(m.x);
        if (px < plot.x - 0.5 || px > plot.right() + 0.5) continue;
        const Rgba c = m.color ? to_rgba(palette_color(*m.color)) : kMarker;
        Stroke s;
        s.points = {{px, plot.y}, {px, plot.bottom()}};
        s.color = c;
        s.width = std::max(1.0, st_.line_width * 0.75);
        s.dashed = true;
        s.clip = plot;
        add(std::move(s));
        if (m.label.empty()) continue;
        const double w = text_width(m.label, st_.legend_px, false);
        const double gap = std::round(st_.legend_px * 0.4);
        double x = std::round(px + gap);
        auto align = Text::Align::left;
        if (x + w > plot.right() - gap) {
          x = std::round(px - gap);
          align = Text::Align::right;
        }
        double y = std::round(plot.y + st_.legend_px * 0.45 + lm.ascender);
        const double row = std::round(lm.line_height() * 1.2);
        Rect box;
        for (int attempt = 0; attempt < 20; ++attempt) {
          const double x0 = align == Text::Align::left ? x : x - w;
          box = Rect{x0 - 3, y - lm.ascender - 2, w + 6, static_cast<double>(lm.line_height()) + 4};
          const bool clash = std::any_of(label_boxes.begin(), label_boxes.end(), [&](const Rect& r) {
            return box.x < r.right() && r.x < box.right() && box.y < r.bottom() && r.y < box.bottom();
          });
          if (!clash) break;
          y += row;
        }
        label_boxes.push_back(box);
        pending_texts_.push_back({box, Text{m.label, {}, x, y, st_.legend_px, false, false, align, kText}});
      }
    }

    // Axes box.
    add_rect(plot.x - fw, plot.y - fw, plot.w + 2 * fw, fw, kFrame);
    add_rect(plot.x - fw, plot.bottom(), plot.w + 2 * fw, fw, kFrame);
    add_rect(plot.x - fw, plot.y, fw, plot.h, kFrame);
    add_rect(plot.right(), plot.y, fw, plot.h, kFrame);

    // Ticks and tick labels.
    const double tl = st_.tick_length;
    double x_labels_bottom = plot.bottom() + fw + tl;
    for (const Tick& t : pl.x_ticks) {
      const double px = pl.x.to_pixel(t.value);
      const double col = std::clamp(std::floor(px), plot.x - fw, plot.right());
      const double len = t.major ? tl : std::round(tl * 0.6);
      add_rect(col, plot.bottom() + fw, fw, len, kFrame);
      if (t.label.empty()) continue;
      const double base = plot.bottom() + fw + tl + std::round(st_.tick_px * 0.3) + tick_m.ascender;
      auto [text, sup] = display_label(t.label);
      add(Text{text, sup, std::round(px), base, st_.tick_px, false, false, Text::Align::center, kText});
      x_labels_bottom = base + tick_m.descender;
    }
    for (const Tick& t : pl.y_ticks) {
      const double py = pl.y.to_pixel(t.value);
      const double row = std::clamp(std::floor(py), plot.y - fw, plot.bottom());
      const double len = t.major ? tl : std::round(tl * 0.6);
      add_rect(plot.x - fw - len, row, len, fw, kFrame);
      if (t.label.empty()) continue;
      const double x = plot.x - fw - tl - std::round(st_.tick_px * 0.3);
      auto [text, sup] = display_label(t.label);
      add(Text{text, sup, x, std::round(py + tick_m.cap_height / 2.0), st_.tick_px, false, false, Text::Align::right, kText});
    }

    // Axis labels and panel title.
    if (!panel.x_label.empty()) {
      const double base = std::round(x_labels_bottom + st_.tick_px * 0.3 + label_m.ascender);
      add(Text{panel.x_label, {}, std::round(plot.x + plot.w / 2), base, st_.label_px, false, false, Text::Align::center, kText});
    }
    if (!panel.y_label.empty()) {
      add(Text{panel.y_label,
               {},
               std::round(st_.pad + label_m.ascender),
               std::round(plot.y + plot.h / 2),
               st_.label_px,
               false,
               true,
               Text::Align::center,
               kText});
    }
    if (!panel.title.empty()) {
      const FontMetrics tm = font_metrics(st_.title_px, true);
      // Just above the axes box: the descenders clear it by a third of the padding.
      const double band = legend_outside_ == Outside::above ? band_height(index) : 0.0;
      const double base = std::round(plot.y - band - fw - st_.pad * 0.3 - tm.descender);
      add(Text{panel.title, {}, std::round(plot.x + plot.w / 2), base, st_.title_px, true, false, Text::Align::center, kText});
    }

    // Marker labels on a light backing so grid and lines do not run through them.
    for (auto& [box, text] : pending_texts_) {
      add_rect(box.x, box.y, box.w, box.h, Rgba{255, 255, 255, 215});
      add(std::move(text));
    }
    pending_texts_.clear();

    if (panel.legend && !legend.empty()) draw_legend(index, plot, legend, obstacles, label_boxes);
  }

  // Every vertex of a line counts against a legend position; dense sets are subsampled.
  static void sample_obstacles(const std::vector<Point>& pts, std::vector<Point>& out) {
    const std::size_t stride = std::max<std::size_t>(1, pts.size() / 4000);
    for (std::size_t i = 0; i < pts.size(); i += stride) out.push_back(pts[i]);
    // Segments can cross a box without a vertex inside: add midpoints of long segments.
    for (std::size_t i = 1; i < pts.size(); i += stride) {
      const double dx = pts[i].x - pts[i - 1].x, dy = pts[i].y - pts[i - 1].y;
      const int k = static_cast<int>(std::min(32.0, std::hypot(dx, dy) / 12.0));
      for (int j = 1; j < k; ++j) out.push_back({pts[i - 1].x + dx * j / k, pts[i - 1].y + dy * j / k});
    }
  }

  double band_height(std::size_t panel) const { return panel < legend_band_height_.size() ? legend_band_height_[panel] : 0.0; }

  void draw_legend(std::size_t index, const Rect& plot, const std::vector<LegendEntry>& entries, const std::vector<Point>& obstacles,
                   const std::vector<Rect>& label_boxes) {
    const Panel& panel = f_.panels[index];
    const int fpx = st_.legend_px;
    const FontMetrics m = font_metrics(fpx, false);
    const double row = std::round(m.line_height() * 1.2);
    const double inner = std::round(fpx * 0.55);
    const double sample_w = std::round(fpx * 2.2);
    const double gap = std::round(fpx * 0.5);
    const double inset = std::round(fpx * 0.6);
    const double col_gap = std::round(fpx * 1.2);

    const std::size_t n = entries.size();
    // Column-major grid of entries; more columns while the legend is tall for the plot and the
    // wider legend still fits (a short plot gets a legend in one row).
    auto width_for = [&](std::size_t cols, std::size_t rows, std::vector<double>& col_w) {
      col_w.assign(cols, 0);
      for (std::size_t i = 0; i < n; ++i)
        col_w[i / rows] = std::max(col_w[i / rows], sample_w + gap + text_width(entries[i].label, fpx, false));
      double w = 2 * inner;
      for (double c : col_w) w += c;
      return std::round(w + col_gap * static_cast<double>(cols - 1));
    };
    auto height_for = [&](std::size_t rows) { return static_cast<double>(rows) * row + 2 * inner; };
    std::size_t cols = 1, rows = n;
    std::vector<double> col_w;
    double w = width_for(cols, rows, col_w);
    // Beside the plot: as many columns as its height needs. Above it: as many as its width holds.
    auto columns_beside = [&] {
      std::size_t c = 1;
      while (c < n && height_for((n + c - 1) / c) > plot.h) ++c;
      return c;
    };
    auto columns_above = [&] {
      std::size_t c = 1;
      std::vector<double> cw;
      while (c < n && width_for(c + 1, (n + c) / (c + 1), cw) <= plot.w * 0.95) ++c;
      return c;
    };
    const bool above = legend_outside_ == Outside::above && band_height(index) > 0;
    const bool outside = legend_outside_ == Outside::right || above;
    if (outside) {
      cols = above ? columns_above() : columns_beside();
      rows = (n + cols - 1) / cols;
      w = width_for(cols, rows, col_w);
    }
    while (!outside && cols < n && height_for(rows) > plot.h * 0.45) {
      const std::size_t c2 = cols + 1, r2 = (n + c2 - 1) / c2;
      std::vector<double> cw2;
      const double w2 = width_for(c2, r2, cw2);
      if (w2 > plot.w - 2 * inset && height_for(rows) <= plot.h * 0.8) break;
      cols = c2;
      rows = r2;
      col_w = cw2;
      w = w2;
    }
    const double h = std::round(static_cast<double>(rows) * row + 2 * inner - (row - m.line_height()));

    const double cx = plot.x + (plot.w - w) / 2, cy = plot.y + (plot.h - h) / 2;
    const Rect upper_right{plot.right() - inset - w, plot.y + inset, w, h};
    const Rect upper_left{plot.x + inset, plot.y + inset, w, h};
    const Rect lower_left{plot.x + inset, plot.bottom() - inset - h, w, h};
    const Rect lower_right{plot.right() - inset - w, plot.bottom() - inset - h, w, h};
    Rect box = upper_right;
    switch (panel.legend_place) {
      case LegendPlace::upper_left: box = upper_left; break;
      case LegendPlace::lower_left: box = lower_left; break;
      case LegendPlace::lower_right: box = lower_right; break;
      default: break;
    }
    double best_score = 0;
    if (panel.legend_place == LegendPlace::best && !outside) {
      // Corners first (preferred on a tie), then the middles of the edges.
      const Rect candidates[] = {upper_right,
                                 upper_left,
                                 lower_left,
                                 lower_right,
                                 {cx, plot.y + inset, w, h},
                                 {cx, plot.bottom() - inset - h, w, h},
                                 {plot.x + inset, cy, w, h},
                                 {plot.right() - inset - w, cy, w, h}};
      double best = std::numeric_limits<double>::infinity();
      for (const Rect& r : candidates) {
        double score = 0;
        for (const Point& q : obstacles)
          if (r.contains(q.x, q.y)) score += 1;
        for (const Rect& lb : label_boxes)
          if (r.x < lb.right() && lb.x < r.right() && r.y < lb.bottom() && lb.y < r.bottom()) score += 1e6;
        if (score < best - 0.5) {
          best = score;
          box = r;
        }
      }
      best_score = best;
    }
    if (legend_outside_ == Outside::right) {
      box = Rect{plot.right() + st_.frame_width + std::round(fpx * 0.8), plot.y, w, h};
    } else if (above) {
      box = Rect{plot.x, plot.y - st_.frame_width - std::round(fpx * 0.4) - h, w, h};
    } else if (legend_outside_ == Outside::none) {
      // Measured for a place beside the plot (where every legend goes if one has no free place inside)
      // and above it (where only those without a free place go).
      std::vector<double> cw;
      const std::size_t beside = columns_beside(), over = columns_above();
      legend_beside_width_ = std::max(legend_beside_width_, width_for(beside, (n + beside - 1) / beside, cw));
      if (panel.legend_place == LegendPlace::best && best_score > 0) {
        legend_right_width_ = legend_beside_width_;
        legend_band_wanted_.resize(f_.panels.size(), 0.0);
        legend_band_wanted_[index] = std::round(height_for((n + over - 1) / over) - (row - m.line_height()) + fpx * 0.4);
      }
    }
    box.x = std::round(box.x);
    box.y = std::round(box.y);

    add_rect(box.x, box.y, box.w, box.h, kLegendFill);
    add_rect(box.x, box.y, box.w, 1, kLegendBorder);
    add_rect(box.x, box.bottom() - 1, box.w, 1, kLegendBorder);
    add_rect(box.x, box.y + 1, 1, box.h - 2, kLegendBorder);
    add_rect(box.right() - 1, box.y + 1, 1, box.h - 2, kLegendBorder);

    double x0 = box.x + inner;
    for (std::size_t c = 0; c < cols; ++c) {
      for (std::size_t r = 0; r < rows; ++r) {
        const std::size_t i = c * rows + r;
        if (i >= n) break;
        const LegendEntry& e = entries[i];
        const double top = box.y + inner + static_cast<double>(r) * row;
        const double base = top + m.ascender;
        const double mid = base - m.cap_height / 2.0;
        switch (e.kind) {
          case LegendEntry::Kind::line:
          case LegendEntry::Kind::line_dots: {
            Stroke s;
            s.points = {{x0, mid}, {x0 + sample_w, mid}};
            s.color = e.color;
            s.width = st_.line_width;
            add(std::move(s));
            if (e.kind == LegendEntry::Kind::line) break;
            [[fallthrough]];
          }
          case LegendEntry::Kind::dots: {
            Dots d;
            d.centers = {{x0 + sample_w / 2, mid}};
            d.color = e.color;
            d.radius = std::max(3.0, st_.line_width * 1.9);
            add(std::move(d));
            break;
          }
          case LegendEntry::Kind::tick: {
            const double th = std::round(fpx * 0.75);
            const double tw = std::max(1.0, std::round(st_.line_width * 0.8));
            add_rect(std::round(x0 + sample_w / 2 - tw / 2), std::round(mid - th / 2), tw, th, e.color);
            break;
          }
        }
        add(Text{e.label, {}, x0 + sample_w + gap, base, fpx, false, false, Text::Align::left, kText});
      }
      x0 += col_w[c] + col_gap;
    }
  }

  const Figure& f_;
  Style st_;
  Scene scene_;
  // Set by a first drawing whose legends found no free place inside their plots: the width the widest
  // of them needs beside its plot, and the height of each one's band above its plot; the second
  // drawing puts every legend beside its plot, or those legends above theirs.
  enum class Outside { none, right, above };
  Outside legend_outside_ = Outside::none;
  double legend_right_width_ = 0, legend_beside_width_ = 0;
  std::vector<double> legend_band_wanted_, legend_band_height_;  // per panel: the band above it
  std::vector<std::pair<Rect, Text>> pending_texts_;
};

}  // namespace

Scene build_scene(const Figure& figure) { return Builder(figure).build(); }

int text_extent(const std::string& text, const std::string& superscript, int px, bool bold) {
  int w = text_width(text, px, bold);
  if (!superscript.empty()) w += text_width(superscript, superscript_px(px), bold);
  return w;
}

}  // namespace detail

FigureLayout compute_layout(const Figure& figure) { return detail::build_scene(figure).layout; }

}  // namespace moreau::render
