// Figure builders for the plots Moreau draws. They take plain data (no integrator types) and return
// a Figure description, to be rendered with render.h.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "moreau/render/figure.h"

namespace moreau::render {

// A simulated trajectory. q[i] and v[i] hold coordinate i over time (same length as t). h holds the
// step sizes: either one per entry of t, or one per step (t.size() - 1, step k from t[k]).
struct TimeSeriesData {
  std::vector<double> t, h;
  std::vector<std::string> q_names, v_names;  // optional; default q1, q2, ... and v1, v2, ...
  std::vector<std::vector<double>> q, v;
  std::vector<double> energy;
  // The mechanical energy E = 1/2 <M v, v> + V(q) at each sample, when the system has a potential (empty
  // otherwise): what the energy balance and Lemma 3 speak of; a staircase for Newton impacts, where the
  // kinetic energy alone falls to 0 at every apex. The energy figure draws it above `energy`.
  std::vector<double> mechanical_energy;
  std::string mechanical_energy_label = "E = 1/2 <M v, v> + V(q)";
  std::optional<double> converged_time;  // finite-time convergence, marked by a dashed line
  std::vector<double> impact_times;      // marked by ticks along the time axis
  std::string energy_label;              // default "energy"

  // Titles and axis names of the two groups of coordinates: a mechanical system's positions q and
  // velocities v (the defaults), or a state-space (Lur'e) system's state x and its rate dx/dt.
  std::string q_title = "Positions", q_axis = "q", v_title = "Velocities", v_axis = "v";
  // An optional third group, a third panel of the state figure (a Lur'e system's output y = C x).
  std::vector<std::vector<double>> y;
  std::vector<std::string> y_names;  // default y1, y2, ...
  std::string y_title = "Outputs", y_axis = "y";
  // The phase portrait of a state-space system is its state plane, (x_i, x_{i+1}); with one state,
  // (x, dx/dt). Otherwise (the default) the mechanical phase plane (q_i, v_i).
  bool state_space = false;
  // A two-state system's switching line c1 x1 + c2 x2 = 0 (a Lur'e system's C x = 0 with one output),
  // drawn across its state plane; empty for other systems.
  std::vector<double> switching_line;
  // Units (a scene's /units): of time ("s"; empty: none given, the axis is "t") and of each coordinate's
  // position and velocity ("m", "m/s"; "" where none is given). Every time axis reads "t [s]", and a panel
  // never mixes units on one axis: the state figure draws one panel per unit among the coordinates shown.
  std::string t_unit;
  std::vector<std::string> q_units, v_units;
  // Named columns beside the state (a tracking run's qd_<q>, e_<q>, sigma_<q>, u_<q>: tracking_figure).
  std::vector<std::string> signal_names;
  std::vector<std::vector<double>> signals;
};

struct FigureOptions {
  int width_px = 1200;
  int height_px = 800;
  std::string title;
  std::vector<std::size_t> coordinates;  // indices into q/v; empty = all
  std::optional<double> t0, t1;          // time window; unset = the data's extent
  std::optional<Scale> y_scale;          // unset = the figure kind's default
  std::string x_label, y_label;          // empty = the figure kind's (work and order figures)
  // The state figure's y axes over the bulk of the values, not their extremes: each panel's axis spans the
  // 1st to the 99th percentile of its values (widened by a tenth on each side), so that one spike (a
  // 48 rad/s joint-limit impact) does not flatten every other line; the values beyond are clipped at the
  // axis and each series' label says how many.
  bool robust_y = false;
};

// Positions (top panel) and velocities (bottom panel) against time, one line per coordinate.
Figure state_figure(const TimeSeriesData& data, const FigureOptions& options = {});
// Energy against time, log y axis by default. A log axis cannot show values <= 0: they are dropped,
// and the legend label says how many. With a mechanical energy (TimeSeriesData::mechanical_energy), it
// comes first, in a panel of its own on a linear axis (it may be negative), and `energy` below it.
Figure energy_figure(const TimeSeriesData& data, const FigureOptions& options = {});
// Step size h_k against t_k, log y axis by default.
Figure step_figure(const TimeSeriesData& data, const FigureOptions& options = {});
// Phase portrait: v against q, one panel per coordinate (the figure taller than asked beyond three), each
// with its own units, its start and end marked; a state-space system's state plane (x_i, x_i+1), with its
// switching line where TimeSeriesData::switching_line gives one.
Figure phase_figure(const TimeSeriesData& data, const FigureOptions& options = {});
// A tracking run (signals qd_<q>, e_<q>, sigma_<q>, u_<q> for each position name q): q with q_d, the
// error e, |sigma| on a log axis (log y by default; its exact zeros, which a log axis cannot show, are
// counted in the legend and the start of the final run of them is marked), and the control u.
Figure tracking_figure(const TimeSeriesData& data, const FigureOptions& options = {});
// Several tracking runs of one scene side by side (the implicit and the explicit controller, two periods):
// e, |sigma| (log y by default, exact zeros dropped) and u, one colour per run, each series named
// "<run label> <coordinate>". Every run must have the tracking signals and the same coordinates.
Figure tracking_comparison_figure(const std::vector<std::pair<std::string, TimeSeriesData>>& runs, const FigureOptions& options = {});

// One scheme of a convergence or work-precision study: a run per step size.
struct SchemeRuns {
  std::string scheme;
  std::vector<double> h, error, run_time_s;  // equal lengths (run_time_s may be empty for order_figure)
};

// Error against run time, log-log, one line per scheme.
Figure work_figure(const std::vector<SchemeRuns>& runs, const FigureOptions& options = {});
// Error against h, log-log, one line per scheme; the legend gives the fitted order. Guides of slope 1 and
// 2 pass through the first scheme's run at the smallest h, across the h drawn.
Figure order_figure(const std::vector<SchemeRuns>& runs, const FigureOptions& options = {});

// Least-squares fit of log10(error) = slope * log10(h) + intercept over the pairs where both are
// positive and finite. NaN slope if fewer than two such pairs or all h equal.
struct OrderFit {
  double slope = 0, intercept = 0;
  std::size_t points = 0;
};
OrderFit fit_order(const std::vector<double>& h, const std::vector<double>& error);

}  // namespace moreau::render
