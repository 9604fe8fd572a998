// analysis/figures: the bridge from a scene's results to render/'s series, labelled for the kind of system,
// and the figure kinds' names (figure_kind.h).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <iterator>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "moreau/analysis/figure_kind.h"
#include "moreau/analysis/figures.h"
#include "moreau/render/render.h"
#include "moreau/scene/simulation.h"

using moreau::render::TimeSeriesData;
using moreau::scene::label_for_system;
using moreau::scene::Simulation;

namespace {

// A trajectory of n states with made-up values (the labelling does not run the scene).
TimeSeriesData states(std::size_t n, std::size_t rows) {
  TimeSeriesData d;
  for (std::size_t k = 0; k < rows; ++k) d.t.push_back(0.1 * static_cast<double>(k));
  for (std::size_t i = 0; i < n; ++i) {
    std::vector<double> x;
    for (std::size_t k = 0; k < rows; ++k) x.push_back(static_cast<double>(i + 1) * (1.0 + static_cast<double>(k)) * (i % 2 ? -1.0 : 1.0));
    d.q.push_back(x);
    d.v.push_back(std::vector<double>(rows, 0.0));
  }
  return d;
}

}  // namespace

TEST(SceneFigures, LureOutputIsCTimesTheStateAndTheLabelsSaySo) {
  // lure-relay-2state: C = [1 2], so y = x1 + 2 x2 (its description says so too); no P given.
  const Simulation sim = Simulation::from_file("scenes/lure-relay-2state.json");
  TimeSeriesData d = states(2, 5);
  label_for_system(d, sim);
  ASSERT_EQ(d.y.size(), 1u);
  for (std::size_t k = 0; k < d.t.size(); ++k) EXPECT_EQ(d.y[0][k], d.q[0][k] + 2.0 * d.q[1][k]) << k;
  EXPECT_EQ(d.y_names, std::vector<std::string>{"y"});
  EXPECT_EQ(d.q_title, "State x");
  EXPECT_EQ(d.y_title, "Output y = C x");
  EXPECT_TRUE(d.state_space);
  EXPECT_EQ(d.energy_label, "W = 1/2 x^T P x (storage, P from the positive realness test)");
  // Two states, one output: the switching line C x = x1 + 2 x2 = 0 of its state plane.
  EXPECT_EQ(d.switching_line, (std::vector<double>{1.0, 2.0}));
}

TEST(SceneFigures, LagrangianSystemsKeepTheMechanicalLabels) {
  const Simulation sim = Simulation::from_file("scenes/manipulator.json");
  TimeSeriesData d = states(2, 3);
  d.energy_label = "E = 1/2 <M v, v>";
  label_for_system(d, sim);
  EXPECT_TRUE(d.y.empty());
  EXPECT_EQ(d.q_title, "Positions");
  EXPECT_EQ(d.v_title, "Velocities");
  EXPECT_FALSE(d.state_space);
  EXPECT_EQ(d.energy_label, "E = 1/2 <M v, v>");
  // A scene without /units: no unit anywhere.
  TimeSeriesData plain = states(1, 3);
  label_for_system(plain, Simulation::from_file("scenes/coulomb-oscillator.json"));
  EXPECT_EQ(plain.t_unit, "");
  EXPECT_TRUE(plain.q_units.empty());
}

// The energy figure of an impacting system shows what Lemma 3 speaks of: the mechanical energy
// 1/2 m v^2 + m g y of the bouncing ball (here from its closed form, m = 1 and g = 9.81 as in the scene),
// on a linear axis above the kinetic energy.
TEST(SceneFigures, TheMechanicalEnergyOfABallIsHalfMVSquaredPlusMGY) {
  const Simulation sim = Simulation::from_file("scenes/bouncing-ball-e0.5.json");
  TimeSeriesData d = states(1, 5);
  d.energy.assign(d.t.size(), 0.0);
  for (std::size_t k = 0; k < d.t.size(); ++k) {
    d.q[0][k] = 0.25 * static_cast<double>(k);
    d.v[0][k] = 1.5 - static_cast<double>(k);
    d.energy[k] = 0.5 * d.v[0][k] * d.v[0][k];
  }
  label_for_system(d, sim);
  ASSERT_EQ(d.mechanical_energy.size(), d.t.size());
  for (std::size_t k = 0; k < d.t.size(); ++k)
    EXPECT_NEAR(d.mechanical_energy[k], 0.5 * d.v[0][k] * d.v[0][k] + 9.81 * d.q[0][k], 1e-12) << k;
  const moreau::render::Figure f = moreau::render::energy_figure(d);
  ASSERT_EQ(f.panels.size(), 2u);
  EXPECT_EQ(f.panels[0].y_axis.scale, moreau::render::Scale::linear);
  EXPECT_EQ(f.panels[0].series[0].label, "E = 1/2 <M v, v> + V(q)");
  EXPECT_EQ(f.panels[1].title, "Kinetic energy");
  EXPECT_EQ(f.panels[1].y_axis.scale, moreau::render::Scale::log);
  // A system without a potential keeps the one kinetic panel.
  TimeSeriesData plain = states(1, 5);
  plain.energy.assign(plain.t.size(), 1.0);
  label_for_system(plain, Simulation::from_file("scenes/damped-relay.json"));
  EXPECT_TRUE(plain.mechanical_energy.empty());
}

// The scene's /units reach the figure's data by coordinate name, velocities per time unit; a unit the
// scene gives for time is kept, and a member that is not a string is ignored.
TEST(SceneFigures, TheScenesUnitsGoToTheAxes) {
  TimeSeriesData d = states(2, 3);
  label_for_system(d, Simulation::from_file("scenes/manipulator-fig6.4.json"));
  EXPECT_EQ(d.t_unit, "s");
  EXPECT_EQ(d.q_units, (std::vector<std::string>{"m", "rad"}));
  EXPECT_EQ(d.v_units, (std::vector<std::string>{"m/s", "rad/s"}));
  const moreau::render::Figure f = moreau::render::state_figure(d);
  ASSERT_EQ(f.panels.size(), 4u);
  EXPECT_EQ(f.panels[1].y_label, "q [rad]");
  EXPECT_EQ(f.panels[3].x_label, "t [s]");
  TimeSeriesData e = states(2, 3);
  label_for_system(e, Simulation::from_file("scenes/manipulator.json", {"units={\"th2\": \"deg\", \"t\": \"ms\", \"x1\": 3}"}));
  EXPECT_EQ(e.t_unit, "ms");
  EXPECT_EQ(e.q_units, (std::vector<std::string>{"", "deg"}));
  EXPECT_EQ(e.v_units, (std::vector<std::string>{"", "deg/ms"}));
}

namespace {

using moreau::scene::CampaignFigure;
using moreau::scene::default_figure;
using moreau::scene::figure_from_name;
using moreau::scene::figure_name;
using moreau::scene::figure_name_list;
using moreau::scene::FigureFormat;
using moreau::scene::FigureNames;
using moreau::scene::StudyFigure;
using moreau::scene::TrajectoryFigure;

// Every kind of the table named, and read back from its name; nothing else is a name.
template <class Kind>
void expect_names_read_both_ways(const std::vector<std::string>& names) {
  ASSERT_EQ(std::size(FigureNames<Kind>::kTable), names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    const Kind kind = FigureNames<Kind>::kTable[i].first;
    EXPECT_EQ(figure_name(kind), names[i]);
    EXPECT_EQ(figure_from_name<Kind>(names[i]), kind) << names[i];
    EXPECT_EQ(figure_from_name<Kind>(names[i] + " "), std::nullopt) << names[i];
    EXPECT_EQ(static_cast<std::size_t>(kind), i) << "the table lists the enumerators in order";
  }
  EXPECT_EQ(figure_from_name<Kind>(""), std::nullopt);
  EXPECT_EQ(moreau::scene::figure_names<Kind>(), names);
}

}  // namespace

// The names the API (server/openapi.json), the command line and the cached figures' files have always
// used, and the lists the error messages give.
TEST(FigureKinds, NamesReadBothWaysAndListAsTheMessagesDo) {
  expect_names_read_both_ways<TrajectoryFigure>({"state", "energy", "step", "phase", "tracking"});
  expect_names_read_both_ways<StudyFigure>({"work", "order"});
  expect_names_read_both_ways<CampaignFigure>({"convergence-cdf", "inputs", "success-map"});
  expect_names_read_both_ways<FigureFormat>({"png", "svg"});
  EXPECT_EQ(figure_name_list<TrajectoryFigure>(), "state, energy, step, phase or tracking");
  EXPECT_EQ(figure_name_list<StudyFigure>(), "work or order");
  EXPECT_EQ(figure_name_list<CampaignFigure>(), "convergence-cdf, inputs or success-map");
  EXPECT_EQ(figure_name_list<FigureFormat>(), "png or svg");
  EXPECT_EQ(default_figure<TrajectoryFigure>(), TrajectoryFigure::kState);
  EXPECT_EQ(default_figure<FigureFormat>(), FigureFormat::kPng);
}

// Each trajectory kind is drawn by render/'s builder of that name (compared as SVG, which needs no GL).
TEST(SceneFigures, EachTrajectoryKindIsDrawnByItsBuilder) {
  TimeSeriesData d = states(2, 6);
  d.h.assign(d.t.size(), 0.1);
  d.energy = {1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125};
  moreau::render::FigureOptions opt;
  opt.title = "t";
  const std::pair<TrajectoryFigure, moreau::render::Figure> expected[] = {
      {TrajectoryFigure::kState, moreau::render::state_figure(d, opt)},
      {TrajectoryFigure::kEnergy, moreau::render::energy_figure(d, opt)},
      {TrajectoryFigure::kStep, moreau::render::step_figure(d, opt)},
      {TrajectoryFigure::kPhase, moreau::render::phase_figure(d, opt)},
  };
  for (const auto& [kind, figure] : expected) {
    SCOPED_TRACE(figure_name(kind));
    const std::string svg = moreau::scene::encode_figure(moreau::scene::trajectory_figure(kind, d, opt), FigureFormat::kSvg);
    EXPECT_EQ(svg, moreau::render::render_svg(figure));
  }
}

// A study's figures say on their y axis which error they plot: the largest Euclidean error of q over the
// common times (study.cc), against h or against run time.
TEST(SceneFigures, StudyFiguresNameTheirErrorOnTheAxis) {
  moreau::scene::StudyResult r;
  r.scene = "toy";
  r.reference = "exact solution";
  r.orders.push_back({});
  for (const double h : {0.1, 0.05, 0.025}) {
    moreau::scene::StudyRow row;
    row.h = h;
    row.status = "completed";
    row.q_max_error = 2.0 * h;
    row.wall_seconds = 1e-4 / h;
    r.rows.push_back(row);
  }
  for (const auto kind : {moreau::scene::StudyFigure::kOrder, moreau::scene::StudyFigure::kWork}) {
    const moreau::render::Figure f = moreau::scene::study_figure(kind, r);
    EXPECT_EQ(f.panels.at(0).y_label, "max over t of ||q(t) - q_ref(t)||");
    // Joined along x: h increasing (errors 0.05 to 0.2), or run time increasing (the largest h first).
    const std::vector<double> along_x =
        kind == moreau::scene::StudyFigure::kOrder ? std::vector<double>{0.05, 0.1, 0.2} : std::vector<double>{0.2, 0.1, 0.05};
    EXPECT_EQ(f.panels.at(0).series.at(0).y, along_x);
  }
}
