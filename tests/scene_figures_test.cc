// analysis/figures: the bridge from a scene's results to render/'s series, labelled for the kind of system.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "moreau/analysis/figures.h"
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
}
