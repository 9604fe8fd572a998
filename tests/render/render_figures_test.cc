// render/: the figure builders (state, energy, step, phase, work, order) on synthetic trajectories.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "moreau/render/figures.h"
#include "moreau/render/render.h"
#include "synthetic.h"

using namespace moreau::render;
using ::testing::HasSubstr;

namespace {

TimeSeriesData small_trajectory() { return synthetic::trajectory(2001); }

std::size_t count_markers(const Panel& p, Marker::Kind kind) {
  return static_cast<std::size_t>(std::count_if(p.markers.begin(), p.markers.end(), [&](const Marker& m) { return m.kind == kind; }));
}

std::vector<SchemeRuns> power_law_study() {
  std::vector<SchemeRuns> runs(2);
  runs[0].scheme = "first";
  runs[1].scheme = "second";
  for (int k = 0; k < 6; ++k) {
    const double h = 0.1 / std::pow(2.0, k);
    runs[0].h.push_back(h);
    runs[0].error.push_back(3.0 * h);
    runs[0].run_time_s.push_back(1e-3 / h);
    runs[1].h.push_back(h);
    runs[1].error.push_back(0.5 * h * h);
    runs[1].run_time_s.push_back(3e-3 / h);
  }
  return runs;
}

}  // namespace

TEST(RenderFigures, StateFigureHasPositionAndVelocityPanels) {
  const TimeSeriesData d = small_trajectory();
  const Figure f = state_figure(d);
  ASSERT_EQ(f.panels.size(), 2u);
  const Panel& q = f.panels[0];
  const Panel& v = f.panels[1];
  ASSERT_EQ(q.series.size(), 2u);
  ASSERT_EQ(v.series.size(), 2u);
  EXPECT_EQ(q.series[0].label, "ball height");
  EXPECT_EQ(v.series[1].label, "oscillator v");
  EXPECT_EQ(q.series[0].x.size(), d.t.size());
  EXPECT_EQ(q.series[1].color, 1);
  // One convergence line per panel, labelled in the first; impacts as ticks.
  EXPECT_EQ(count_markers(q, Marker::Kind::line), 1u);
  EXPECT_EQ(count_markers(v, Marker::Kind::line), 1u);
  EXPECT_EQ(count_markers(q, Marker::Kind::tick), d.impact_times.size());
  const auto conv = std::find_if(q.markers.begin(), q.markers.end(), [](const Marker& m) { return m.kind == Marker::Kind::line; });
  EXPECT_DOUBLE_EQ(conv->x, *d.converged_time);
  EXPECT_THAT(conv->label, HasSubstr("converged t=4.06"));
  // Time runs edge to edge.
  EXPECT_EQ(q.x_axis.min, 0.0);
  EXPECT_EQ(q.x_axis.max, 5.0);
  validate(f);
}

// A scene's units reach the axes: time as "t [s]", and metres and radians never share an axis (the
// manipulator's x1 and th2): one panel per unit, each coordinate keeping its colour in every panel.
TEST(RenderFigures, UnitsAreOnTheAxesAndNoAxisMixesThem) {
  TimeSeriesData d = small_trajectory();
  const Figure plain = state_figure(d);
  EXPECT_EQ(plain.panels[0].x_label, "t");
  EXPECT_EQ(plain.panels[0].y_label, "q");
  d.t_unit = "s";
  d.q_units = {"m", "rad"};
  d.v_units = {"m/s", "rad/s"};
  const Figure f = state_figure(d);
  ASSERT_EQ(f.panels.size(), 4u);
  const std::vector<std::string> y_labels = {f.panels[0].y_label, f.panels[1].y_label, f.panels[2].y_label, f.panels[3].y_label};
  EXPECT_EQ(y_labels, (std::vector<std::string>{"q [m]", "q [rad]", "v [m/s]", "v [rad/s]"}));
  for (const Panel& p : f.panels) {
    EXPECT_EQ(p.x_label, "t [s]");
    ASSERT_EQ(p.series.size(), 1u);
  }
  EXPECT_EQ(f.panels[0].title, "Positions [m]");
  EXPECT_EQ(f.panels[1].series[0].label, "oscillator x");
  EXPECT_EQ(f.panels[1].series[0].color, 1);  // coordinate 1's colour, in its own panel too
  EXPECT_EQ(f.panels[3].series[0].color, 1);
  // The convergence line is labelled once, in the first panel.
  EXPECT_THAT(f.panels[0].markers.back().label, HasSubstr("converged"));
  EXPECT_EQ(f.panels[1].markers.back().label, "");
  // One unit for both: one panel, the unit on its axis.
  d.q_units = {"rad", "rad"};
  d.v_units = {"rad/s", "rad/s"};
  const Figure same = state_figure(d);
  ASSERT_EQ(same.panels.size(), 2u);
  EXPECT_EQ(same.panels[0].y_label, "q [rad]");
  EXPECT_EQ(same.panels[0].title, "Positions");
  // The other time figures and the phase plane.
  EXPECT_EQ(energy_figure(d).panels[0].x_label, "t [s]");
  EXPECT_EQ(step_figure(d).panels[0].y_label, "h [s]");
  // The phase portrait: a panel per coordinate, each with its own units.
  d.q_units = {"m", "rad"};
  d.v_units = {"m/s", "rad/s"};
  const Figure mixed = phase_figure(d);
  ASSERT_EQ(mixed.panels.size(), 2u);
  EXPECT_EQ(mixed.panels[0].x_label, "ball height [m]");
  EXPECT_EQ(mixed.panels[0].y_label, "ball velocity [m/s]");
  EXPECT_EQ(mixed.panels[1].x_label, "oscillator x [rad]");
  EXPECT_EQ(mixed.panels[0].series[0].label, "(ball height, ball velocity)");
  validate(f);
  validate(mixed);
}

// robust_y: one spike (a joint-limit impact) would set the axis; the axis spans the bulk instead, the
// spike is clipped and counted in its series' label, and a panel without outliers keeps its usual axis.
TEST(RenderFigures, RobustYRangeClipsASpikeAndSaysSo) {
  TimeSeriesData d;
  for (int k = 0; k < 1000; ++k) d.t.push_back(0.001 * k);
  d.q = {std::vector<double>(1000), std::vector<double>(1000)};
  d.v = d.q;
  for (int k = 0; k < 1000; ++k) {
    d.q[0][static_cast<std::size_t>(k)] = std::sin(0.01 * k);
    d.q[1][static_cast<std::size_t>(k)] = 0.5 * std::cos(0.01 * k);
    d.v[0][static_cast<std::size_t>(k)] = 0.01 * std::cos(0.01 * k);
    d.v[1][static_cast<std::size_t>(k)] = -0.005 * std::sin(0.01 * k);
  }
  d.v[1][500] = 48.0;  // the spike
  FigureOptions o;
  o.robust_y = true;
  const Figure f = state_figure(d, o);
  const Panel& v = f.panels.at(1);
  ASSERT_TRUE(v.y_axis.max.has_value());
  EXPECT_LT(*v.y_axis.max, 0.05);
  EXPECT_GT(*v.y_axis.max, 0.0095);  // the bulk: |v| up to 0.01
  EXPECT_EQ(v.series[1].label, "v2 (1 value beyond the axis)");
  EXPECT_EQ(v.series[0].label, "v1");
  EXPECT_FALSE(f.panels.at(0).y_axis.max.has_value());  // positions: no outlier, the usual axis
  validate(f);
  EXPECT_FALSE(state_figure(d).panels.at(1).y_axis.max.has_value());  // not asked: the whole range
}

TEST(RenderFigures, StateFigureSelectsCoordinatesAndTimeWindow) {
  const TimeSeriesData d = small_trajectory();
  FigureOptions o;
  o.coordinates = {1};
  o.t0 = 1.0;
  o.t1 = 2.0;
  const Figure f = state_figure(d, o);
  ASSERT_EQ(f.panels[0].series.size(), 1u);
  const Series& s = f.panels[0].series[0];
  EXPECT_EQ(s.label, "oscillator x");
  EXPECT_EQ(f.panels[0].x_axis.min, 1.0);
  EXPECT_EQ(f.panels[0].x_axis.max, 2.0);
  // The window's samples plus one neighbour each side.
  EXPECT_LT(s.x.front(), 1.0);
  EXPECT_GT(s.x.back(), 2.0);
  EXPECT_LT(s.x.size(), 450u);
  for (const Marker& m : f.panels[0].markers) {
    EXPECT_GE(m.x, 1.0);
    EXPECT_LE(m.x, 2.0);
  }
}

TEST(RenderFigures, BuilderErrorsAreClear) {
  TimeSeriesData d = small_trajectory();
  FigureOptions o;
  o.coordinates = {5};
  try {
    state_figure(d, o);
    FAIL();
  } catch (const FigureError& e) {
    EXPECT_THAT(e.what(), HasSubstr("coordinate index 5 is out of range (the data has 2 coordinates)"));
  }
  d.q[1].pop_back();
  try {
    state_figure(d);
    FAIL();
  } catch (const FigureError& e) {
    EXPECT_THAT(e.what(), HasSubstr("q[1] has 2000 values but t has 2001"));
  }
  d = small_trajectory();
  o = {};
  o.t0 = 10;
  o.t1 = 11;
  EXPECT_THROW(state_figure(d, o), FigureError);
  d.h = {1, 2, 3};
  EXPECT_THROW(step_figure(d), FigureError);
}

TEST(RenderFigures, EnergyOnALogAxisDropsZerosAndSaysSo) {
  const TimeSeriesData d = small_trajectory();
  const Figure f = energy_figure(d);
  ASSERT_EQ(f.panels.size(), 1u);
  const Panel& p = f.panels[0];
  EXPECT_EQ(p.y_axis.scale, Scale::log);
  ASSERT_EQ(p.series.size(), 1u);
  const std::size_t zeros = static_cast<std::size_t>(std::count(d.energy.begin(), d.energy.end(), 0.0));
  ASSERT_GT(zeros, 0u);
  EXPECT_EQ(p.series[0].x.size(), d.t.size() - zeros);
  EXPECT_THAT(p.series[0].label, HasSubstr("ball energy (" + std::to_string(zeros) + " values"));
  EXPECT_THAT(p.series[0].label, HasSubstr("not shown"));
  validate(f);

  TimeSeriesData zero = d;
  std::fill(zero.energy.begin(), zero.energy.end(), 0.0);
  const Figure g = energy_figure(zero);
  EXPECT_EQ(g.panels[0].y_axis.scale, Scale::linear);
  EXPECT_THAT(g.panels[0].series[0].label, HasSubstr("linear axis"));
  validate(g);
}

// With the mechanical energy given, it is drawn first on a linear axis (it may be negative: the
// manipulator's starts at -1.75), the convergence labelled there, and the kinetic energy below on its log axis.
TEST(RenderFigures, EnergyFigureDrawsTheMechanicalEnergyAboveTheKinetic) {
  TimeSeriesData d = small_trajectory();
  d.mechanical_energy.resize(d.t.size());
  for (std::size_t k = 0; k < d.t.size(); ++k) d.mechanical_energy[k] = d.energy[k] - 2.0;
  const Figure f = energy_figure(d);
  ASSERT_EQ(f.panels.size(), 2u);
  EXPECT_EQ(f.panels[0].title, "Mechanical energy");
  EXPECT_EQ(f.panels[0].y_axis.scale, Scale::linear);
  EXPECT_EQ(f.panels[0].series[0].y.front(), d.energy.front() - 2.0);
  EXPECT_THAT(f.panels[0].markers.back().label, HasSubstr("converged"));
  EXPECT_EQ(f.panels[1].title, "Kinetic energy");
  EXPECT_EQ(f.panels[1].y_axis.scale, Scale::log);
  EXPECT_EQ(f.panels[1].markers.back().label, "");
  validate(f);
  d.mechanical_energy.pop_back();
  EXPECT_THROW(energy_figure(d), FigureError);
}

// Each phase curve's first and last states are marked (start and end, in colours of their own), and a
// two-state system's switching line c . x = 0 is drawn across the box its state plane spans.
TEST(RenderFigures, PhaseCurvesMarkStartAndEndAndTheSwitchingLine) {
  TimeSeriesData d;
  d.t = {0, 1, 2, 3};
  d.q = {{-1.0, 2.0, 1.0, 0.5}, {2.0, -2.0, 1.0, 0.0}};
  d.v = {{0, 0, 0, 0}, {0, 0, 0, 0}};
  d.q_names = {"x1", "x2"};
  d.state_space = true;
  d.switching_line = {1.0, 2.0};  // x1 + 2 x2 = 0: points r (2, -1)
  const Figure f = phase_figure(d);
  ASSERT_EQ(f.panels.size(), 1u);
  const Panel& p = f.panels[0];
  ASSERT_EQ(p.series.size(), 4u);
  EXPECT_EQ(p.series[0].label, "switching line C x = 0");  // under the curve
  EXPECT_EQ(p.series[1].label, "(x1, x2)");
  // Inside the box [-1, 2] x [-2, 2]: r in [-1/2, 1], from (-1, 1/2) to (2, -1).
  EXPECT_EQ(p.series[0].x, (std::vector<double>{-1.0, 2.0}));
  EXPECT_EQ(p.series[0].y, (std::vector<double>{0.5, -1.0}));
  for (std::size_t k = 0; k < 2; ++k) EXPECT_EQ(p.series[0].x[k] + 2.0 * p.series[0].y[k], 0.0);
  EXPECT_EQ(p.series[2].label, "start");
  EXPECT_EQ(p.series[2].x, (std::vector<double>{-1.0}));
  EXPECT_EQ(p.series[2].y, (std::vector<double>{2.0}));
  EXPECT_EQ(p.series[3].label, "end");
  EXPECT_EQ(p.series[3].x, (std::vector<double>{0.5}));
  EXPECT_EQ(p.series[3].y, (std::vector<double>{0.0}));
  EXPECT_NE(p.series[2].color, p.series[1].color);
  EXPECT_NE(p.series[3].color, p.series[1].color);
  validate(f);
  // A line that misses the box is left out.
  d.q[0] = {1.0, 2.0, 3.0, 4.0};
  d.q[1] = {1.0, 2.0, 3.0, 4.0};
  EXPECT_EQ(phase_figure(d).panels[0].series.size(), 3u);
  // Seven coordinates: seven panels, the figure taller than the 800 px asked.
  TimeSeriesData seven = small_trajectory();
  seven.q.resize(7, seven.q[0]);
  seven.v.resize(7, seven.v[0]);
  const Figure tall = phase_figure(seven);
  EXPECT_EQ(tall.panels.size(), 7u);
  for (const Panel& panel : tall.panels) {  // no curve in a marker's colour
    EXPECT_NE(panel.series[0].color, panel.series[1].color);
    EXPECT_NE(panel.series[0].color, panel.series[2].color);
  }
  EXPECT_EQ(tall.height_px, 220 * 7 + 80);
  validate(tall);
}

TEST(RenderFigures, StepAndPhaseFigures) {
  const TimeSeriesData d = small_trajectory();
  const Figure s = step_figure(d);
  ASSERT_EQ(s.panels[0].series.size(), 1u);
  EXPECT_EQ(s.panels[0].series[0].y.size(), d.h.size());
  EXPECT_EQ(s.panels[0].x_axis.max, d.t.back());
  validate(s);

  FigureOptions o;
  o.coordinates = {0};
  const Figure p = phase_figure(d, o);
  ASSERT_EQ(p.panels.size(), 1u);
  ASSERT_EQ(p.panels[0].series.size(), 3u);  // the curve, its start and its end
  EXPECT_EQ(p.panels[0].series[0].x, d.q[0]);
  EXPECT_EQ(p.panels[0].series[0].y, d.v[0]);
  EXPECT_EQ(p.panels[0].x_label, "ball height");
  EXPECT_EQ(p.panels[0].y_label, "ball velocity");
  validate(p);
}

TEST(RenderFigures, StateSpaceSystemsAreLabelledAsSuchWithTheirStatePlane) {
  // Three states x, their rates, one output: the state figure has three panels named for what they are,
  // and the phase portrait pairs states with states (x_i, x_i+1), never a state with its rate.
  TimeSeriesData d;
  for (int k = 0; k <= 100; ++k) d.t.push_back(0.01 * k);
  d.q = {d.t, d.t, d.t};
  for (auto& x : d.q[1]) x = -x;
  for (auto& x : d.q[2]) x = 2 * x;
  d.v = {std::vector<double>(d.t.size(), 1.0), std::vector<double>(d.t.size(), -1.0), std::vector<double>(d.t.size(), 2.0)};
  d.q_names = {"x1", "x2", "x3"};
  d.v_names = {"x1_dot", "x2_dot", "x3_dot"};
  d.q_title = "State x";
  d.q_axis = "x";
  d.v_title = "State rate dx/dt";
  d.v_axis = "dx/dt";
  d.y = {std::vector<double>(d.t.size(), 0.5)};
  d.y_names = {"y"};
  d.y_title = "Output y = C x";
  d.state_space = true;
  const Figure f = state_figure(d);
  ASSERT_EQ(f.panels.size(), 3u);
  EXPECT_EQ(f.panels[0].title, "State x");
  EXPECT_EQ(f.panels[0].y_label, "x");
  EXPECT_EQ(f.panels[1].title, "State rate dx/dt");
  EXPECT_EQ(f.panels[2].title, "Output y = C x");
  ASSERT_EQ(f.panels[2].series.size(), 1u);
  EXPECT_EQ(f.panels[2].series[0].label, "y");
  EXPECT_EQ(f.panels[2].series[0].y, d.y[0]);
  validate(f);
  const Figure p = phase_figure(d);
  ASSERT_EQ(p.panels.size(), 2u);  // (x1, x2) and (x2, x3), a panel each
  EXPECT_EQ(p.panels[0].series[0].label, "(x1, x2)");
  EXPECT_EQ(p.panels[0].series[0].x, d.q[0]);
  EXPECT_EQ(p.panels[0].series[0].y, d.q[1]);
  EXPECT_EQ(p.panels[1].series[0].label, "(x2, x3)");
  EXPECT_EQ(p.panels[0].x_label, "x1");
  EXPECT_EQ(p.panels[0].y_label, "x2");
  validate(p);
  FigureOptions one;
  one.coordinates = {1};
  const Figure p1 = phase_figure(d, one);
  ASSERT_EQ(p1.panels.size(), 1u);
  EXPECT_EQ(p1.panels[0].series[0].label, "(x2, x3)");
  EXPECT_EQ(p1.panels[0].x_label, "x2");
  EXPECT_EQ(p1.panels[0].y_label, "x3");
  // One state: its plane is (x, dx/dt), named by the axes given.
  TimeSeriesData d1 = d;
  d1.q.resize(1);
  d1.v.resize(1);
  d1.q_names.resize(1);
  d1.v_names.resize(1);
  const Figure single = phase_figure(d1);
  ASSERT_EQ(single.panels.size(), 1u);
  EXPECT_EQ(single.panels[0].series[0].label, "(x1, x1_dot)");
}

// A tracking run's figure: q with q_d, e, |sigma| on a log axis and u. sigma is 0.0 exactly from t = 3
// (samples 3, 4, 5): the log panel drops those, says how many, and marks where the final run of zeros
// starts; an exact zero before it (sample 1) is counted but starts no mark.
TEST(RenderFigures, TrackingFigureShowsTheExactZerosOfSigma) {
  TimeSeriesData d;
  d.t = {0, 1, 2, 3, 4, 5};
  d.q_names = {"x"};
  d.q = {{1.0, 0.5, 0.3, 0.2, 0.1, 0.05}};
  d.v = {{0, 0, 0, 0, 0, 0}};
  d.signal_names = {"qd_x", "e_x", "sigma_x", "u_x"};
  d.signals = {{0, 0, 0, 0, 0, 0}, {1.0, 0.5, 0.3, 0.2, 0.1, 0.05}, {2.0, 0.0, -0.5, 0.0, 0.0, 0.0}, {-1, -1, 1, 0.5, 0.5, 0.5}};
  const Figure f = tracking_figure(d);
  ASSERT_EQ(f.panels.size(), 4u);
  EXPECT_EQ(f.panels[0].series.size(), 2u);  // q and its reference
  const Panel& sigma = f.panels[2];
  EXPECT_EQ(sigma.y_axis.scale, Scale::log);
  ASSERT_EQ(sigma.series.size(), 1u);
  EXPECT_EQ(sigma.series[0].y, (std::vector<double>{2.0, 0.5}));  // |sigma| where it is not 0
  EXPECT_THAT(sigma.series[0].label, HasSubstr("4 samples exactly 0"));
  ASSERT_EQ(sigma.markers.size(), 1u);
  EXPECT_DOUBLE_EQ(sigma.markers[0].x, 3.0);
  EXPECT_EQ(f.panels[3].series[0].y, d.signals[3]);
  // A trajectory without the signals is refused by name.
  d.signal_names.clear();
  d.signals.clear();
  EXPECT_THROW(tracking_figure(d), FigureError);
}

// Two tracking runs side by side: e, |sigma| and u, one colour per run, each series named by its run.
TEST(RenderFigures, TrackingComparisonDrawsEachRunInItsColour) {
  TimeSeriesData a;
  a.t = {0, 1, 2};
  a.q_names = {"x"};
  a.q = {{1.0, 0.5, 0.2}};
  a.v = {{0, 0, 0}};
  a.signal_names = {"qd_x", "e_x", "sigma_x", "u_x"};
  a.signals = {{0, 0, 0}, {1.0, 0.5, 0.2}, {0.5, 0.0, 0.0}, {-1, 0.5, 0.5}};
  TimeSeriesData b = a;
  b.signals[2] = {0.5, -0.1, 0.1};
  b.signals[3] = {-1, 4, -4};
  const Figure f = tracking_comparison_figure({{"implicit", a}, {"explicit", b}});
  ASSERT_EQ(f.panels.size(), 3u);
  for (const Panel& p : f.panels) {
    ASSERT_EQ(p.series.size(), 2u) << p.title;
    EXPECT_EQ(p.series[0].color, 0);
    EXPECT_EQ(p.series[1].color, 1);
    EXPECT_THAT(p.series[0].label, HasSubstr("implicit"));
    EXPECT_THAT(p.series[1].label, HasSubstr("explicit"));
  }
  EXPECT_EQ(f.panels[2].series[1].y, b.signals[3]);
  EXPECT_EQ(f.panels[1].series[0].y, (std::vector<double>{0.5}));  // |sigma|, its exact zeros dropped
  a.signals.clear();
  EXPECT_THROW(tracking_comparison_figure({{"implicit", a}, {"explicit", b}}), FigureError);
}

TEST(RenderFigures, FitOrderRecoversThePowerLaw) {
  const auto runs = power_law_study();
  const OrderFit a = fit_order(runs[0].h, runs[0].error);
  EXPECT_NEAR(a.slope, 1.0, 1e-12);
  EXPECT_NEAR(a.intercept, std::log10(3.0), 1e-12);
  EXPECT_EQ(a.points, 6u);
  const OrderFit b = fit_order(runs[1].h, runs[1].error);
  EXPECT_NEAR(b.slope, 2.0, 1e-12);
  // Zero errors are skipped; fewer than two usable points give NaN.
  EXPECT_EQ(fit_order({0.1, 0.05, 0.025}, {1e-2, 0.0, 2.5e-3}).points, 2u);
  EXPECT_TRUE(std::isnan(fit_order({0.1}, {1e-2}).slope));
  EXPECT_TRUE(std::isnan(fit_order({0.1, 0.1}, {1e-2, 2e-2}).slope));
}

// The order figure's guides: slopes 1 and 2 through the first scheme's smallest-h run (h = 0.1 / 32,
// error 3 h), across the h drawn; none on the work figure, whose x is run time.
TEST(RenderFigures, OrderFigureHasGuidesOfSlopeOneAndTwo) {
  const auto runs = power_law_study();
  const Figure f = order_figure(runs);
  const Panel& p = f.panels.at(0);
  ASSERT_EQ(p.series.size(), 4u);
  const double h0 = 0.1 / 32, e0 = 3.0 * h0;
  for (int order : {1, 2}) {
    const Series& g = p.series[static_cast<std::size_t>(order) + 1];
    EXPECT_EQ(g.label, "slope " + std::to_string(order) + " (guide)");
    ASSERT_EQ(g.x.size(), 2u);
    EXPECT_DOUBLE_EQ(g.x[0], h0);
    EXPECT_DOUBLE_EQ(g.x[1], 0.1);
    EXPECT_DOUBLE_EQ(g.y[0], e0);
    EXPECT_NEAR(std::log10(g.y[1] / g.y[0]) / std::log10(g.x[1] / g.x[0]), order, 1e-12);
  }
  EXPECT_EQ(work_figure(runs).panels.at(0).series.size(), 2u);
  validate(f);
}

TEST(RenderFigures, OrderAndWorkFiguresAreLogLog) {
  const auto runs = power_law_study();
  const Figure o = order_figure(runs);
  const Panel& p = o.panels[0];
  EXPECT_EQ(p.x_axis.scale, Scale::log);
  EXPECT_EQ(p.y_axis.scale, Scale::log);
  ASSERT_EQ(p.series.size(), 4u);  // the two schemes, then the two guides
  EXPECT_EQ(p.series[0].label, "first (slope 1.00)");
  EXPECT_EQ(p.series[1].label, "second (slope 2.00)");
  EXPECT_TRUE(std::is_sorted(p.series[0].x.begin(), p.series[0].x.end()));
  validate(o);

  const Figure w = work_figure(runs);
  EXPECT_EQ(w.panels[0].series[1].label, "second");
  EXPECT_TRUE(std::is_sorted(w.panels[0].series[1].x.begin(), w.panels[0].series[1].x.end()));
  EXPECT_EQ(w.panels[0].x_label, "run time [s]");
  validate(w);

  auto bad = runs;
  bad[0].run_time_s.pop_back();
  EXPECT_THROW(work_figure(bad), FigureError);
}

TEST(RenderFigures, EveryKindRendersToPngAndSvg) {
  const TimeSeriesData d = small_trajectory();
  FigureOptions o;
  o.width_px = 480;
  o.height_px = 360;
  const Figure figures[] = {state_figure(d, o),
                            energy_figure(d, o),
                            step_figure(d, o),
                            phase_figure(d, o),
                            work_figure(power_law_study(), o),
                            order_figure(power_law_study(), o)};
  for (const Figure& f : figures) {
    const Image im = decode_png(render_png_bytes(f));
    EXPECT_EQ(im.width, 480);
    EXPECT_EQ(im.height, 360);
    EXPECT_THAT(render_svg(f), HasSubstr("<polyline"));
  }
}

// A system of many coordinates (a stack of balls): without a choice, 16 evenly spaced from the first to
// the last are drawn and the titles say so; a choice is drawn whole.
TEST(RenderFigures, ManyCoordinatesDrawSixteenEvenlySpacedAndSaySo) {
  TimeSeriesData d = small_trajectory();
  const std::vector<double> q0 = d.q[0], v0 = d.v[0];
  d.q.assign(40, q0);
  d.v.assign(40, v0);
  d.q_names.clear();
  d.v_names.clear();
  d.q_units.clear();
  d.v_units.clear();
  for (int i = 0; i < 40; ++i) {
    d.q_names.push_back("y" + std::to_string(i + 1));
    d.v_names.push_back("y" + std::to_string(i + 1) + "_dot");
  }
  const Figure f = state_figure(d);
  ASSERT_EQ(f.panels.size(), 2u);
  ASSERT_EQ(f.panels[0].series.size(), 16u);
  EXPECT_EQ(f.panels[0].series.front().label, "y1");
  EXPECT_EQ(f.panels[0].series.back().label, "y40");
  EXPECT_THAT(f.panels[0].title, HasSubstr("(16 of 40 coordinates, evenly spaced)"));
  FigureOptions o;
  o.coordinates = {3, 4};
  const Figure chosen = state_figure(d, o);
  ASSERT_EQ(chosen.panels[0].series.size(), 2u);
  EXPECT_THAT(chosen.panels[0].title, ::testing::Not(HasSubstr("of 40")));
  validate(f);
}
