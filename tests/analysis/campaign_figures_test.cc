// The figures of a robustness campaign (analysis/include/moreau/analysis/campaign_figures.h) from outcomes
// whose figures are known: the CDF's steps at the convergence times, levelling at the fraction that
// converged; the samples that did not succeed drawn apart at t_end; the success map's two groups.
#include "moreau/analysis/campaign_figures.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "moreau/render/render.h"

namespace moreau::scene {
namespace {

using json = nlohmann::json;

CampaignSpec two_input_spec() {
  json scene = {{"system", {{"type", "lagrangian"}, {"mass", {{"m"}}}, {"controller", {{{"type", "abs"}, {"gains", {"a"}}}}}}},
                {"parameters", {{"m", 1.0}, {"a", 1.0}}},
                {"initial", {{"q", {0.0}}, {"v", {1.0}}}},
                {"integrator", {{"h", 0.01}, {"t_end", 4.0}}}};
  json spec = {{"name", "toy"},
               {"scene", scene},
               {"inputs",
                {{{"path", "/parameters/m"}, {"distribution", {{"type", "uniform"}, {"low", 1.0}, {"high", 2.0}}}},
                 {{"path", "/initial/v/0"}, {"distribution", {{"type", "uniform"}, {"low", 0.0}, {"high", 5.0}}}}}},
               {"samples", 4}};
  return CampaignSpec::from_json(spec, "");
}

CampaignOutcome outcome(std::int64_t i, bool success, double t, double m, double v0) {
  CampaignOutcome o;
  o.index = i;
  o.success = o.converged = success;
  o.failure_class = success ? 0 : 1;
  o.converged_time = success ? t : std::nan("");
  o.target_distance = std::nan("");
  o.max_abs_q = 1.0;
  o.inputs = {m, v0};
  return o;
}

TEST(CampaignFigures, CdfInputsAndSuccessMapFromKnownOutcomes) {
  const CampaignSpec spec = two_input_spec();
  // Three of four converge, at t = 3, 1, 2; the fourth (m = 2, v0 = 5) does not.
  const std::vector<CampaignOutcome> outcomes = {outcome(0, true, 3.0, 1.0, 3.0), outcome(1, true, 1.0, 1.5, 1.0),
                                                 outcome(2, true, 2.0, 1.2, 2.0), outcome(3, false, 0.0, 2.0, 5.0)};
  const auto figures = campaign_figures(spec, outcomes, 4.0);
  ASSERT_EQ(figures.size(), 3u);
  EXPECT_EQ(figures[0].first, CampaignFigure::kConvergenceCdf);
  EXPECT_EQ(figures[1].first, CampaignFigure::kInputs);
  EXPECT_EQ(figures[2].first, CampaignFigure::kSuccessMap);

  // The CDF: 0 -> 1/4 at t = 1, -> 2/4 at 2, -> 3/4 at 3, held to t_end = 4 (one sample never converged).
  const render::Series& cdf = figures[0].second.panels.at(0).series.at(0);
  const std::vector<double> x = {1, 1, 2, 2, 3, 3, 4}, y = {0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75};
  EXPECT_EQ(cdf.x, x);
  ASSERT_EQ(cdf.y.size(), y.size());
  for (std::size_t k = 0; k < y.size(); ++k) EXPECT_NEAR(cdf.y[k], y[k], 1e-15) << k;
  EXPECT_THAT(figures[0].second.title, ::testing::HasSubstr("3 of 4 samples succeeded"));

  // One panel per input: the three successes at their convergence times, the failure at t_end.
  const render::Figure& in = figures[1].second;
  ASSERT_EQ(in.panels.size(), 2u);
  // Inputs named in words: the parameter by its name, the initial velocity by its coordinate (q1: the
  // scene names none) and its unit (none given).
  EXPECT_EQ(in.panels[0].x_label, "m");
  EXPECT_EQ(in.panels[1].x_label, "initial q1_dot");
  EXPECT_EQ(in.panels[0].y_label, "t [s]");
  EXPECT_EQ(in.panels[0].series.at(0).color, figures[2].second.panels.at(0).series.at(0).color);  // success: one colour
  EXPECT_EQ(in.panels[0].series.at(0).x, (std::vector<double>{1.0, 1.5, 1.2}));
  EXPECT_EQ(in.panels[0].series.at(0).y, (std::vector<double>{3.0, 1.0, 2.0}));
  EXPECT_EQ(in.panels[0].series.at(1).x, (std::vector<double>{2.0}));
  EXPECT_EQ(in.panels[0].series.at(1).y, (std::vector<double>{4.0}));

  // The success map in the (m, v0) plane.
  const render::Panel& map = figures[2].second.panels.at(0);
  EXPECT_EQ(map.x_label, "m");
  EXPECT_EQ(map.y_label, "initial q1_dot");
  EXPECT_EQ(map.title, "");
  EXPECT_EQ(map.series.at(0).label, "succeeded (3)");
  EXPECT_EQ(map.series.at(1).label, "did not succeed (1)");
  EXPECT_EQ(map.series.at(1).x, (std::vector<double>{2.0}));
  EXPECT_EQ(map.series.at(1).y, (std::vector<double>{5.0}));

  // Each is a figure the renderer accepts (SVG: no OpenGL needed here).
  for (const auto& [kind, f] : figures) EXPECT_THAT(render::render_svg(f), ::testing::HasSubstr("<svg")) << figure_name(kind);
}

// A sample that converged but missed the target is drawn at its convergence time, apart from both the
// successes and the samples that never converged; a map where every sample succeeded says so; the
// scene's coordinate names and units name the axes.
TEST(CampaignFigures, ConvergedOffTheTargetAtItsTimeAndUnitsOnTheAxes) {
  CampaignSpec spec = two_input_spec();
  spec.scene["system"]["coordinates"] = {"x"};
  spec.scene["units"] = {{"x", "m"}, {"t", "ms"}};
  CampaignOutcome missed = outcome(2, true, 2.5, 1.2, 2.0);
  missed.success = false;
  missed.failure_class = 1;
  const auto figures = campaign_figures(spec, {outcome(0, true, 3.0, 1.0, 3.0), outcome(1, false, 0, 1.5, 1.0), missed}, 4.0);
  const render::Figure& in = figures.at(1).second;
  ASSERT_EQ(in.panels.at(0).series.size(), 3u);
  EXPECT_EQ(in.panels[0].series[1].label, "converged off the target: convergence time");
  EXPECT_EQ(in.panels[0].series[1].y, (std::vector<double>{2.5}));
  EXPECT_EQ(in.panels[0].series[2].y, (std::vector<double>{4.0}));  // never converged: at t_end
  EXPECT_EQ(in.panels[1].x_label, "initial x_dot [m/ms]");
  EXPECT_EQ(in.panels[0].y_label, "t [ms]");
  EXPECT_EQ(figures.at(0).second.panels.at(0).x_label, "convergence time t [ms]");
  const auto all = campaign_figures(spec, {outcome(0, true, 3.0, 1.0, 3.0), outcome(1, true, 1.0, 1.5, 1.0)}, 4.0);
  EXPECT_THAT(all.back().second.panels.at(0).title, ::testing::HasSubstr("every sample succeeded"));
}

TEST(CampaignFigures, NothingConvergedLeavesTheCdfOut) {
  const CampaignSpec spec = two_input_spec();
  const auto figures = campaign_figures(spec, {outcome(0, false, 0, 1.0, 1.0), outcome(1, false, 0, 1.5, 2.0)}, 4.0);
  ASSERT_EQ(figures.size(), 2u);
  EXPECT_EQ(figures[0].first, CampaignFigure::kInputs);
  EXPECT_EQ(figures[1].first, CampaignFigure::kSuccessMap);
  EXPECT_EQ(figures[1].second.panels.at(0).series.size(), 1u);
}

}  // namespace
}  // namespace moreau::scene
