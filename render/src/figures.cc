// Figure builders (figures.h): plain trajectory and study data -> Figure descriptions.
#include "moreau/render/figures.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>

#include "moreau/platform/number_text.h"

namespace moreau::render {
namespace {

// Numbers in messages and labels: 3 significant digits.
std::string fmt(double v) { return platform::significant(v, 3); }

std::string coordinate_name(const std::vector<std::string>& names, std::size_t i, const char* prefix) {
  if (i < names.size() && !names[i].empty()) return names[i];
  return prefix + std::to_string(i + 1);
}

// "q [m]", or "q" without a unit.
std::string with_unit(const std::string& quantity, const std::string& unit) {
  return unit.empty() ? quantity : quantity + " [" + unit + "]";
}

std::string unit_of(const std::vector<std::string>& units, std::size_t i) { return i < units.size() ? units[i] : std::string(); }

// The coordinates of `coords` grouped by their unit, in the order each unit first appears.
std::vector<std::pair<std::string, std::vector<std::size_t>>> by_unit(const std::vector<std::size_t>& coords,
                                                                      const std::vector<std::string>& units) {
  std::vector<std::pair<std::string, std::vector<std::size_t>>> groups;
  for (const std::size_t i : coords) {
    const std::string u = unit_of(units, i);
    auto g = std::find_if(groups.begin(), groups.end(), [&](const auto& x) { return x.first == u; });
    if (g == groups.end())
      groups.push_back({u, {i}});
    else
      g->second.push_back(i);
  }
  return groups;
}

// The one unit of the coordinates `coords`, or "" when they have none or several.
std::string common_unit(const std::vector<std::size_t>& coords, const std::vector<std::string>& units) {
  const auto groups = by_unit(coords, units);
  return groups.size() == 1 ? groups[0].first : std::string();
}

// A phase curve's start and end markers: black and reddish purple, apart from the curves' colours (blue,
// vermillion, green, ... for up to three curves before purple comes round).
constexpr int kStartColour = 6, kEndColour = 3;
// The curves' colours: the palette without the markers' two.
int phase_curve_colour(std::size_t k) {
  static constexpr int kCurves[] = {0, 1, 2, 4, 5, 7};
  return kCurves[k % std::size(kCurves)];
}

// The segment of the line c . (x, y) = 0 (TimeSeriesData::switching_line) inside the box the curve `s`
// spans, as a series; empty when there is no line or it misses the box.
Series switching_line(const TimeSeriesData& d, const Series& s) {
  Series line;
  if (d.switching_line.size() != 2 || s.x.empty()) return line;
  const double c1 = d.switching_line[0], c2 = d.switching_line[1];
  if (!(std::isfinite(c1) && std::isfinite(c2)) || (c1 == 0 && c2 == 0)) return line;
  const auto [x_lo, x_hi] = std::minmax_element(s.x.begin(), s.x.end());
  const auto [y_lo, y_hi] = std::minmax_element(s.y.begin(), s.y.end());
  // Points r (c2, -c1) of the line, r in [r_lo, r_hi]: the interval where both coordinates are in the box.
  double r_lo = -std::numeric_limits<double>::infinity(), r_hi = std::numeric_limits<double>::infinity();
  const double dir[2] = {c2, -c1}, lo[2] = {*x_lo, *y_lo}, hi[2] = {*x_hi, *y_hi};
  for (int i = 0; i < 2; ++i) {
    if (dir[i] == 0) {
      if (lo[i] > 0 || hi[i] < 0) return line;
      continue;
    }
    const double a = lo[i] / dir[i], b = hi[i] / dir[i];
    r_lo = std::max(r_lo, std::min(a, b));
    r_hi = std::min(r_hi, std::max(a, b));
  }
  if (!(r_lo < r_hi)) return line;
  line.label = "switching line C x = 0";
  line.color = kStartColour;
  line.x = {r_lo * dir[0], r_hi * dir[0]};
  line.y = {r_lo * dir[1], r_hi * dir[1]};
  return line;
}

// FigureOptions::robust_y on one panel: its y axis from the 1st to the 99th percentile of all its finite
// values, widened by a tenth of that span on each side (and to the extremes when they are within it);
// each series' label counts its values beyond the axis (drawn clipped at its edge).
void clip_to_bulk(Panel& p) {
  std::vector<double> all;
  for (const Series& s : p.series)
    for (const double y : s.y)
      if (std::isfinite(y)) all.push_back(y);
  if (all.size() < 100) return;  // too few values for percentiles to mean anything
  auto at = [&](double fraction) {
    const auto k = static_cast<std::ptrdiff_t>(fraction * static_cast<double>(all.size() - 1));
    std::nth_element(all.begin(), all.begin() + k, all.end());
    return all[static_cast<std::size_t>(k)];
  };
  const double lo = at(0.01), hi = at(0.99);
  const double margin = 0.1 * std::max(hi - lo, 1e-12 * std::max(std::abs(lo), std::abs(hi)));
  const double a = lo - margin, b = hi + margin;
  const auto [min_it, max_it] = std::minmax_element(all.begin(), all.end());
  if (*min_it >= a && *max_it <= b) return;  // nothing far out: the usual axis
  p.y_axis.min = std::max(a, *min_it);
  p.y_axis.max = std::min(b, *max_it);
  for (Series& s : p.series) {
    const auto beyond = std::count_if(s.y.begin(), s.y.end(), [&](double y) { return y < *p.y_axis.min || y > *p.y_axis.max; });
    if (beyond) s.label += " (" + std::to_string(beyond) + (beyond == 1 ? " value" : " values") + " beyond the axis)";
  }
}

void require(bool ok, const std::string& what) {
  if (!ok) throw FigureError(what);
}

// The indices [begin, end) of the samples inside the time window, plus one neighbour on each side
// so lines run to the edges of the plot.
struct Window {
  std::size_t begin = 0, end = 0;
  double t0 = 0, t1 = 0;
};

Window time_window(const std::vector<double>& t, const FigureOptions& o, const char* who) {
  require(!t.empty(), std::string(who) + ": no time samples (t is empty)");
  Window w;
  w.t0 = o.t0.value_or(t.front());
  w.t1 = o.t1.value_or(t.back());
  require(std::isfinite(w.t0) && std::isfinite(w.t1) && w.t0 <= w.t1,
          std::string(who) + ": time window [" + fmt(w.t0) + ", " + fmt(w.t1) + "] is empty or not finite");
  const auto first = std::lower_bound(t.begin(), t.end(), w.t0);
  const auto last = std::upper_bound(t.begin(), t.end(), w.t1);
  w.begin = static_cast<std::size_t>(first - t.begin());
  w.end = static_cast<std::size_t>(last - t.begin());
  // A window between two samples still shows the segment joining them.
  require(w.begin < w.end || (w.begin > 0 && w.begin < t.size()), std::string(who) + ": time window [" + fmt(w.t0) + ", " + fmt(w.t1) +
                                                                      "] contains no samples (data spans [" + fmt(t.front()) + ", " +
                                                                      fmt(t.back()) + "])");
  if (w.begin > 0) --w.begin;
  if (w.end < t.size()) ++w.end;
  return w;
}

std::vector<double> slice(const std::vector<double>& v, const Window& w) {
  return {v.begin() + static_cast<std::ptrdiff_t>(w.begin), v.begin() + static_cast<std::ptrdiff_t>(w.end)};
}

Axis time_axis(const Window& w) {
  Axis a;
  a.padding = 0;
  if (w.t1 > w.t0) {
    a.min = w.t0;
    a.max = w.t1;
  }
  return a;
}

// Coordinates a figure draws when none are chosen: all of them up to this many; beyond, this many evenly
// spaced from the first to the last (a stack of 10,000 balls as 20,000 curves would be unreadable and
// cost the renderer gigabytes), said in the panels' titles (kSubsetNote).
constexpr std::size_t kMaxDefaultCoordinates = 16;

std::vector<std::size_t> pick_coordinates(const TimeSeriesData& d, const FigureOptions& o, const char* who) {
  const std::size_t n = std::max(d.q.size(), d.v.size());
  std::vector<std::size_t> idx = o.coordinates;
  if (idx.empty() && n > kMaxDefaultCoordinates) {
    for (std::size_t k = 0; k < kMaxDefaultCoordinates; ++k)
      idx.push_back((k * (n - 1) + (kMaxDefaultCoordinates - 1) / 2) / (kMaxDefaultCoordinates - 1));
  } else if (idx.empty()) {
    idx.resize(n);
    std::iota(idx.begin(), idx.end(), std::size_t{0});
  }
  for (std::size_t i : idx)
    require(i < n, std::string(who) + ": coordinate index " + std::to_string(i) + " is out of range (the data has " + std::to_string(n) +
                       " coordinates)");
  require(!idx.empty(), std::string(who) + ": no coordinates to plot");
  return idx;
}

void check_length(const std::vector<double>& v, std::size_t n, const std::string& what, const char* who) {
  require(v.size() == n, std::string(who) + ": " + what + " has " + std::to_string(v.size()) + " values but t has " + std::to_string(n));
}

// On a log axis, values <= 0 cannot be drawn: drop those points and say so in the label.
void keep_positive_y(Series& s) {
  std::size_t kept = 0, dropped = 0;
  for (std::size_t i = 0; i < s.y.size(); ++i) {
    if (s.y[i] > 0) {
      s.x[kept] = s.x[i];
      s.y[kept] = s.y[i];
      ++kept;
    } else {
      ++dropped;
    }
  }
  s.x.resize(kept);
  s.y.resize(kept);
  if (dropped) s.label += " (" + std::to_string(dropped) + (dropped == 1 ? " value" : " values") + " \u2264 0 not shown)";
}

void keep_positive_xy(Series& s, const char* what) {
  std::size_t kept = 0, dropped = 0;
  for (std::size_t i = 0; i < s.y.size(); ++i) {
    if (s.x[i] > 0 && s.y[i] > 0 && std::isfinite(s.x[i]) && std::isfinite(s.y[i])) {
      s.x[kept] = s.x[i];
      s.y[kept] = s.y[i];
      ++kept;
    } else {
      ++dropped;
    }
  }
  s.x.resize(kept);
  s.y.resize(kept);
  if (dropped) s.label += " (" + std::to_string(dropped) + " " + what + " not shown)";
}

void add_events(Panel& panel, const TimeSeriesData& d, const Window& w, bool label_convergence) {
  for (double t : d.impact_times)
    if (t >= w.t0 && t <= w.t1) panel.markers.push_back({t, "impacts", Marker::Kind::tick, std::nullopt});
  if (d.converged_time && *d.converged_time >= w.t0 && *d.converged_time <= w.t1) {
    panel.markers.push_back(
        {*d.converged_time, label_convergence ? "converged t=" + fmt(*d.converged_time) : std::string(), Marker::Kind::line, std::nullopt});
  }
}

Figure base_figure(const FigureOptions& o) {
  Figure f;
  f.width_px = o.width_px;
  f.height_px = o.height_px;
  f.title = o.title;
  return f;
}

// Drops empty series (e.g. all values dropped on a log axis) so the figure still renders.
void drop_empty(Panel& p) {
  std::erase_if(p.series, [](const Series& s) { return s.x.empty(); });
}

}  // namespace

Figure state_figure(const TimeSeriesData& d, const FigureOptions& o) {
  const char* who = "state_figure";
  const Window w = time_window(d.t, o, who);
  const std::vector<std::size_t> coords = pick_coordinates(d, o, who);
  const Scale scale = o.y_scale.value_or(Scale::linear);
  Figure f = base_figure(o);
  const std::vector<double> t = slice(d.t, w);

  // One panel of `data` over the coordinates `shown` (their colours are their places in `coords`, the same
  // in every panel).
  auto make_panel = [&](const std::vector<std::vector<double>>& data, const std::vector<std::string>& names, const std::string& prefix,
                        const std::string& title, const std::string& y_label, bool first, const std::vector<std::size_t>& shown) {
    Panel p;
    p.title = title;
    p.x_label = with_unit("t", d.t_unit);
    p.y_label = y_label;
    p.x_axis = time_axis(w);
    p.y_axis.scale = scale;
    for (const std::size_t i : shown) {
      if (i >= data.size()) continue;
      check_length(data[i], d.t.size(), prefix + "[" + std::to_string(i) + "]", who);
      Series s;
      s.label = coordinate_name(names, i, prefix.c_str());
      s.x = t;
      s.y = slice(data[i], w);
      const auto at = std::find(coords.begin(), coords.end(), i);
      s.color = static_cast<int>(at != coords.end() ? at - coords.begin() : static_cast<std::ptrdiff_t>(i));
      if (scale == Scale::log) keep_positive_y(s);
      p.series.push_back(std::move(s));
    }
    drop_empty(p);
    if (o.robust_y && scale == Scale::linear) clip_to_bulk(p);
    add_events(p, d, w, first);
    return p;
  };
  // Positions, then velocities: a panel per unit among the coordinates shown (metres and radians never
  // share an axis), titled with the unit when there are several.
  auto add_group = [&](const std::vector<std::vector<double>>& data, const std::vector<std::string>& names,
                       const std::vector<std::string>& units, const std::string& axis, const std::string& title) {
    const auto groups = by_unit(coords, units);
    for (const auto& [unit, shown] : groups)
      f.panels.push_back(make_panel(data, names, axis, groups.size() > 1 ? with_unit(title, unit) : title, with_unit(axis, unit),
                                    f.panels.empty(), shown));
  };
  // Some of many coordinates (pick_coordinates): the titles say so.
  const std::size_t n = std::max(d.q.size(), d.v.size());
  const std::string subset = o.coordinates.empty() && coords.size() < n
                                 ? " (" + std::to_string(coords.size()) + " of " + std::to_string(n) + " coordinates, evenly spaced)"
                                 : "";
  if (!d.q.empty()) add_group(d.q, d.q_names, d.q_units, d.q_axis, d.q_title + subset);
  if (!d.v.empty()) add_group(d.v, d.v_names, d.v_units, d.v_axis, d.v_title + subset);
  // Outputs: every one of them (the coordinate choice indexes q and v).
  if (!d.y.empty()) {
    std::vector<std::size_t> all(d.y.size());
    std::iota(all.begin(), all.end(), std::size_t{0});
    f.panels.push_back(make_panel(d.y, d.y_names, d.y_axis, d.y_title, d.y_axis, false, all));
  }
  require(!f.panels.empty(), std::string(who) + ": neither positions nor velocities given");
  return f;
}

Figure tracking_figure(const TimeSeriesData& d, const FigureOptions& o) {
  const char* who = "tracking_figure";
  const Window w = time_window(d.t, o, who);
  const std::vector<std::size_t> coords = pick_coordinates(d, o, who);
  // Coordinate i's signals are columns 4 i .. 4 i + 3, named qd_, e_, sigma_, u_ and its name (the
  // position names here may carry units, "x1 [m]"; the signals' names do not).
  auto column = [&](const std::string& prefix, std::size_t slot, std::size_t i) -> const std::vector<double>& {
    const std::size_t j = 4 * i + slot;
    if (j >= d.signal_names.size() || j >= d.signals.size() || d.signal_names[j].rfind(prefix, 0) != 0)
      throw FigureError(std::string(who) + ": no column " + prefix + "<coordinate " + std::to_string(i) +
                        "> (the trajectory of a scene with /system/tracking has one)");
    check_length(d.signals[j], d.t.size(), d.signal_names[j], who);
    return d.signals[j];
  };
  Figure f = base_figure(o);
  const std::vector<double> t = slice(d.t, w);
  auto panel = [&](const std::string& title, const std::string& y_label) {
    Panel p;
    p.title = title;
    p.x_label = with_unit("t", d.t_unit);
    p.y_label = y_label;
    p.x_axis = time_axis(w);
    return p;
  };
  auto series = [&](const std::string& label, const std::vector<double>& y, int color, SeriesStyle style = SeriesStyle::line) {
    Series s;
    s.label = label;
    s.x = t;
    s.y = slice(y, w);
    s.color = color;
    s.style = style;
    return s;
  };
  const std::string q_unit = common_unit(coords, d.q_units);
  Panel q = panel("Positions q and reference q_d", with_unit("q", q_unit));
  Panel e = panel("Tracking error e = q - q_d", with_unit("e", q_unit));
  Panel sigma = panel("Sliding variable |sigma|", "|sigma|");
  sigma.y_axis.scale = o.y_scale.value_or(Scale::log);
  Panel u = panel("Control u", "u");
  std::optional<double> on_surface_from;  // the start of the final run of exact zeros of every sigma_i
  std::vector<bool> zero(t.size(), true);
  for (std::size_t k = 0; k < coords.size(); ++k) {
    const std::size_t i = coords[k];
    const std::string name = coordinate_name(d.q_names, i, "q");
    const int color = static_cast<int>(k);
    check_length(d.q.at(i), d.t.size(), "q[" + std::to_string(i) + "]", who);
    q.series.push_back(series(name, d.q[i], color));
    q.series.push_back(series(name + " reference", column("qd_", 0, i), color, SeriesStyle::points));
    e.series.push_back(series(name, column("e_", 1, i), color));  // the unit of q
    // sigma and u have units of their own (q's per second, a force or torque): named by their columns.
    Series s = series(d.signal_names[4 * i + 2], column("sigma_", 2, i), color);
    const std::string sigma_name = s.label;
    std::size_t zeros = 0;
    for (std::size_t j = 0; j < s.y.size(); ++j) {
      zeros += s.y[j] == 0.0;
      zero[j] = zero[j] && s.y[j] == 0.0;
      s.y[j] = std::abs(s.y[j]);
    }
    if (sigma.y_axis.scale == Scale::log) {
      keep_positive_y(s);
      if (zeros > 0) s.label = sigma_name + " (" + std::to_string(zeros) + " samples exactly 0, not drawn)";
    }
    sigma.series.push_back(std::move(s));
    u.series.push_back(series(d.signal_names[4 * i + 3], column("u_", 3, i), color));
  }
  for (std::size_t j = zero.size(); j-- > 0 && zero[j];) on_surface_from = t[j];
  if (on_surface_from && !zero.empty() && zero.back())
    sigma.markers.push_back(Marker{*on_surface_from, "sigma = 0 exactly from t=" + fmt(*on_surface_from), Marker::Kind::line, {}});
  drop_empty(sigma);
  for (Panel* p : {&q, &e, &sigma, &u})
    if (!p->series.empty()) f.panels.push_back(std::move(*p));
  return f;
}

Figure tracking_comparison_figure(const std::vector<std::pair<std::string, TimeSeriesData>>& runs, const FigureOptions& o) {
  const char* who = "tracking_comparison_figure";
  require(!runs.empty(), std::string(who) + ": no runs");
  Figure f = base_figure(o);
  Panel e, sigma, u;
  e.title = "Tracking error e = q - q_d";
  sigma.title = "Sliding variable |sigma| (exact zeros not drawn)";
  u.title = "Control u";
  e.y_label = "e";
  sigma.y_label = "|sigma|";
  u.y_label = "u";
  sigma.y_axis.scale = o.y_scale.value_or(Scale::log);
  for (std::size_t r = 0; r < runs.size(); ++r) {
    const auto& [label, d] = runs[r];
    // Each run's own figure checks its columns; its panels hold one series per coordinate.
    FigureOptions each = o;
    each.title.clear();
    each.y_scale = sigma.y_axis.scale;
    // Panels q with q_d, e, |sigma|, u; |sigma| is left out when it is 0.0 throughout on a log axis.
    const Figure one = tracking_figure(d, each);
    require(one.panels.size() == 4 || one.panels.size() == 3, std::string(who) + ": run '" + label + "' has no tracking signals");
    const auto take = [&](const Panel& from, Panel& to) {
      for (Series s : from.series) {
        s.label = label + " " + s.label;
        s.color = static_cast<int>(r);
        to.series.push_back(std::move(s));
      }
      if (to.x_axis.min == std::nullopt && to.x_axis.max == std::nullopt) to.x_axis = from.x_axis;
      to.x_label = from.x_label;
    };
    take(one.panels[1], e);
    if (one.panels.size() == 4) take(one.panels[2], sigma);
    take(one.panels.back(), u);
  }
  drop_empty(sigma);
  for (Panel* p : {&e, &sigma, &u})
    if (!p->series.empty()) f.panels.push_back(std::move(*p));
  return f;
}

Figure energy_figure(const TimeSeriesData& d, const FigureOptions& o) {
  const char* who = "energy_figure";
  const Window w = time_window(d.t, o, who);
  check_length(d.energy, d.t.size(), "energy", who);
  Figure f = base_figure(o);
  if (!d.mechanical_energy.empty()) {
    check_length(d.mechanical_energy, d.t.size(), "mechanical energy", who);
    Panel m;
    m.title = "Mechanical energy";
    m.x_label = with_unit("t", d.t_unit);
    m.y_label = "E";
    m.x_axis = time_axis(w);
    Series s;
    s.label = d.mechanical_energy_label;
    s.x = slice(d.t, w);
    s.y = slice(d.mechanical_energy, w);
    m.series.push_back(std::move(s));
    add_events(m, d, w, true);
    f.panels.push_back(std::move(m));
  }
  Panel p;
  const std::string label = d.energy_label.empty() ? "energy" : d.energy_label;
  p.x_label = with_unit("t", d.t_unit);
  p.y_label = label;
  p.x_axis = time_axis(w);
  p.y_axis.scale = o.y_scale.value_or(Scale::log);
  Series s;
  s.label = label;
  s.x = slice(d.t, w);
  s.y = slice(d.energy, w);
  if (p.y_axis.scale == Scale::log) {
    keep_positive_y(s);
    if (s.x.empty()) {  // nothing positive: a log axis would be empty, fall back to linear
      s.label = label;
      s.x = slice(d.t, w);
      s.y = slice(d.energy, w);
      p.y_axis.scale = Scale::linear;
      s.label += " (no positive values: linear axis)";
    }
  }
  p.series.push_back(std::move(s));
  add_events(p, d, w, f.panels.empty());
  if (!f.panels.empty()) p.title = "Kinetic energy";
  f.panels.push_back(std::move(p));
  return f;
}

Figure step_figure(const TimeSeriesData& d, const FigureOptions& o) {
  const char* who = "step_figure";
  require(!d.h.empty(), std::string(who) + ": no step sizes (h is empty)");
  require(d.h.size() == d.t.size() || d.h.size() + 1 == d.t.size(),
          std::string(who) + ": h has " + std::to_string(d.h.size()) + " values; expected " + std::to_string(d.t.size()) +
              " (one per sample) or " + std::to_string(d.t.size() - 1) + " (one per step)");
  const std::vector<double> t(d.t.begin(), d.t.begin() + static_cast<std::ptrdiff_t>(d.h.size()));
  FigureOptions oo = o;
  if (!oo.t1) oo.t1 = d.t.back();
  const Window w = time_window(t, oo, who);
  Figure f = base_figure(o);
  Panel p;
  p.x_label = with_unit("t", d.t_unit);
  p.y_label = with_unit("h", d.t_unit);
  p.x_axis = time_axis(w);
  p.y_axis.scale = o.y_scale.value_or(Scale::log);
  Series s;
  s.label = "step size h\u2096";
  s.x = slice(t, w);
  s.y = slice(d.h, w);
  s.style = s.x.size() <= 300 ? SeriesStyle::line_points : SeriesStyle::line;
  if (p.y_axis.scale == Scale::log) keep_positive_y(s);
  p.series.push_back(std::move(s));
  drop_empty(p);
  add_events(p, d, w, true);
  f.panels.push_back(std::move(p));
  return f;
}

Figure phase_figure(const TimeSeriesData& d, const FigureOptions& o) {
  const char* who = "phase_figure";
  const Window w = time_window(d.t, o, who);
  const std::vector<std::size_t> coords = pick_coordinates(d, o, who);
  Figure f = base_figure(o);
  // The curves: (x, y) series of one or two coordinate groups, named (x name, y name).
  struct Curve {
    const std::vector<double>*x, *y;
    std::string x_name, y_name, x_what, y_what, x_unit, y_unit;
  };
  std::vector<Curve> curves;
  if (d.state_space && d.q.size() >= 2) {
    // The state plane: (x_i, x_{i+1}) for each chosen state that has a next one (else the last two).
    auto state_pair = [&](std::size_t i) {
      return Curve{&d.q[i],
                   &d.q[i + 1],
                   coordinate_name(d.q_names, i, d.q_axis.c_str()),
                   coordinate_name(d.q_names, i + 1, d.q_axis.c_str()),
                   d.q_axis + "[" + std::to_string(i) + "]",
                   d.q_axis + "[" + std::to_string(i + 1) + "]",
                   unit_of(d.q_units, i),
                   unit_of(d.q_units, i + 1)};
    };
    for (const std::size_t i : coords)
      if (i + 1 < d.q.size()) curves.push_back(state_pair(i));
    if (curves.empty()) curves.push_back(state_pair(d.q.size() - 2));
  } else {
    // The mechanical phase plane (q_i, v_i); a state-space system with one state: (x, dx/dt).
    for (const std::size_t i : coords) {
      require(i < d.q.size() && i < d.v.size(), std::string(who) + ": coordinate " + std::to_string(i) + " needs both q and v");
      curves.push_back({&d.q[i], &d.v[i], coordinate_name(d.q_names, i, d.q_axis.c_str()), coordinate_name(d.v_names, i, d.v_axis.c_str()),
                        "q[" + std::to_string(i) + "]", "v[" + std::to_string(i) + "]", unit_of(d.q_units, i), unit_of(d.v_units, i)});
    }
  }
  // One panel per curve (small multiples: seven overlaid pairs are unreadable, and two coordinates may
  // have different units), each curve in its colour, its start and end marked.
  for (std::size_t k = 0; k < curves.size(); ++k) {
    const Curve& c = curves[k];
    check_length(*c.x, d.t.size(), c.x_what, who);
    check_length(*c.y, d.t.size(), c.y_what, who);
    Panel p;
    p.x_label = with_unit(c.x_name, c.x_unit);
    p.y_label = with_unit(c.y_name, c.y_unit);
    p.y_axis.scale = o.y_scale.value_or(Scale::linear);
    Series s;
    s.label = "(" + c.x_name + ", " + c.y_name + ")";
    s.x = slice(*c.x, w);
    s.y = slice(*c.y, w);
    s.color = phase_curve_colour(k);
    if (p.y_axis.scale == Scale::log) keep_positive_y(s);
    if (!s.x.empty()) {
      const std::size_t first = 0, last = s.x.size() - 1;
      Series start, end;
      start.label = "start";
      start.style = end.style = SeriesStyle::points;
      start.color = kStartColour;
      start.x = {s.x[first]};
      start.y = {s.y[first]};
      end.label = "end";
      end.color = kEndColour;
      end.x = {s.x[last]};
      end.y = {s.y[last]};
      // The switching line of a two-state Lur'e system, c1 x1 + c2 x2 = 0, across the states visited,
      // drawn first: a curve sliding along it stays visible on top.
      Series line = switching_line(d, s);
      if (!line.x.empty()) p.series.push_back(std::move(line));
      p.series.push_back(std::move(s));
      p.series.push_back(std::move(start));
      p.series.push_back(std::move(end));
    }
    drop_empty(p);
    f.panels.push_back(std::move(p));
  }
  // Each panel keeps a readable height: the figure grows beyond three of them.
  if (f.panels.size() > 3) f.height_px = std::max(o.height_px, std::min(220 * static_cast<int>(f.panels.size()) + 80, max_figure_px));
  return f;
}

OrderFit fit_order(const std::vector<double>& h, const std::vector<double>& error) {
  OrderFit fit;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  const std::size_t n = std::min(h.size(), error.size());
  for (std::size_t i = 0; i < n; ++i) {
    if (!(h[i] > 0 && error[i] > 0 && std::isfinite(h[i]) && std::isfinite(error[i]))) continue;
    const double x = std::log10(h[i]), y = std::log10(error[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    ++fit.points;
  }
  const double m = static_cast<double>(fit.points);
  const double den = m * sxx - sx * sx;
  if (fit.points < 2 || !(std::abs(den) > 1e-12 * std::max(1.0, m * sxx))) {
    fit.slope = fit.intercept = std::numeric_limits<double>::quiet_NaN();
    return fit;
  }
  fit.slope = (m * sxy - sx * sy) / den;
  fit.intercept = (sy - fit.slope * sx) / m;
  return fit;
}

namespace {

// The order figure's guides: black and reddish purple, after the schemes' blue, vermillion and green.
constexpr int kGuideOne = 6, kGuideTwo = 3;

Figure study_figure(const std::vector<SchemeRuns>& runs, const FigureOptions& o, bool work) {
  const char* who = work ? "work_figure" : "order_figure";
  require(!runs.empty(), std::string(who) + ": no schemes");
  Figure f = base_figure(o);
  Panel p;
  p.x_label = !o.x_label.empty() ? o.x_label : work ? "run time [s]" : "step size h";
  p.y_label = !o.y_label.empty() ? o.y_label : "error";
  p.x_axis.scale = Scale::log;
  p.y_axis.scale = o.y_scale.value_or(Scale::log);
  for (std::size_t k = 0; k < runs.size(); ++k) {
    const SchemeRuns& r = runs[k];
    const std::vector<double>& xs = work ? r.run_time_s : r.h;
    require(xs.size() == r.error.size(), std::string(who) + ": scheme '" + r.scheme + "' has " + std::to_string(xs.size()) +
                                             (work ? " run times" : " step sizes") + " but " + std::to_string(r.error.size()) + " errors");
    Series s;
    s.label = r.scheme.empty() ? "scheme " + std::to_string(k + 1) : r.scheme;
    if (!work) {
      const OrderFit fit = fit_order(r.h, r.error);
      if (std::isfinite(fit.slope)) s.label += " (slope " + platform::fixed(fit.slope, 2) + ")";
    }
    std::vector<std::size_t> order(xs.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return xs[a] < xs[b]; });
    for (std::size_t i : order) {
      s.x.push_back(xs[i]);
      s.y.push_back(r.error[i]);
    }
    s.style = SeriesStyle::line_points;
    s.color = static_cast<int>(k);
    keep_positive_xy(s, "runs with zero error or time");
    p.series.push_back(std::move(s));
  }
  drop_empty(p);
  require(!p.series.empty(), std::string(who) + ": no run has a positive error");
  // Reference slopes 1 and 2 on the order figure, through the first scheme's run at the smallest h and
  // across the h drawn, so that a measured order reads against them.
  if (!work && p.y_axis.scale == Scale::log) {
    double h_lo = std::numeric_limits<double>::infinity(), h_hi = 0.0;
    for (const Series& s : p.series)
      for (const double h : s.x) {
        h_lo = std::min(h_lo, h);
        h_hi = std::max(h_hi, h);
      }
    const Series& first = p.series.front();
    const double h0 = first.x.front(), e0 = first.y.front();  // sorted by h: its smallest
    if (h_hi > h_lo) {
      for (const int order : {1, 2}) {
        Series guide;
        guide.label = "slope " + std::to_string(order) + " (guide)";
        guide.color = order == 1 ? kGuideOne : kGuideTwo;
        guide.x = {h_lo, h_hi};
        guide.y = {e0 * std::pow(h_lo / h0, order), e0 * std::pow(h_hi / h0, order)};
        p.series.push_back(std::move(guide));
      }
    }
  }
  f.panels.push_back(std::move(p));
  return f;
}

}  // namespace

Figure work_figure(const std::vector<SchemeRuns>& runs, const FigureOptions& o) { return study_figure(runs, o, true); }

Figure order_figure(const std::vector<SchemeRuns>& runs, const FigureOptions& o) { return study_figure(runs, o, false); }

}  // namespace moreau::render
