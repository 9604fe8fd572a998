// The integrator's hot loop allocates nothing: the number of heap allocations of a run does not depend
// on its number of steps (fixed-size and dynamic-size models, with and without a decimated observer).
// This is its own test binary because it replaces the global operator new and the C allocator (malloc,
// calloc, ...: Eigen's dynamic-size temporaries come from there, not from operator new).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

#include "moreau/scene/scene.h"
#include "support/allocation_counter.h"
#include "support/chain_scene.h"

namespace moreau::scene {
namespace {

struct Decimated : RunObserver {
  long samples = 0;
  void on_sample(const Sample&) override { ++samples; }
};

long AllocationsOfRun(const nlohmann::json& doc, double t_end, RunObserver* observer) {
  nlohmann::json d = doc;
  d["integrator"]["t_end"] = t_end;
  const LagrangianScene sc = load_scene(d);
  const long before = moreau::testing::allocations();
  const RunSummary s = run_scene(sc, observer);
  EXPECT_EQ(s.status, RunStatus::kCompleted) << s.message;
  return moreau::testing::allocations() - before;
}

// Five coupled coordinates with a configuration-dependent M and a potential: beyond the fixed-size
// dispatch, so Eigen::Dynamic code runs. (The manipulator's file for the rest: controller, integrator.)
nlohmann::json five_coordinates() {
  nlohmann::json doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json");
  doc["system"]["coordinates"] = {"y1", "y2", "y3", "y4", "y5"};
  nlohmann::json mass = nlohmann::json::array();
  for (int i = 0; i < 5; ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int j = 0; j < 5; ++j) row.push_back(i == j ? "3 + cos(y1)" : (std::abs(i - j) == 1 ? "0.5*cos(y2 - y3)" : "0"));
    mass.push_back(row);
  }
  doc["system"]["mass"] = mass;
  doc["system"]["potential"] = "sin(y1) + 0.1*y5^2";
  return doc;
}

TEST(Allocation, FixedSizeRunDoesNotAllocatePerStep) {
  const auto doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json");
  Decimated obs;
  const long short_run = AllocationsOfRun(doc, 0.5, &obs);
  const long long_run = AllocationsOfRun(doc, 5.0, &obs);
  EXPECT_GT(short_run, 0) << "the counter must see the run's own allocations (its summary)";
  EXPECT_EQ(short_run, long_run);
}

TEST(Allocation, UrdfRobotRunDoesNotAllocatePerStep) {
  // Seven joints from URDF (rigid_body.h computes M, C and G every step), with joint friction.
  const auto doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-coulomb-rest.json");
  Decimated obs;
  const long short_run = AllocationsOfRun(doc, 0.1, &obs);
  const long long_run = AllocationsOfRun(doc, 1.0, &obs);
  EXPECT_GT(short_run, 0);
  EXPECT_EQ(short_run, long_run);
}

TEST(Allocation, DynamicSizeRunDoesNotAllocatePerStep) {
  nlohmann::json doc = five_coordinates();
  doc["system"]["controller"] = {{{"type", "quadratic"}, {"weights", {1, 1, 1, 1, 1}}}, {{"type", "abs"}, {"gains", {1, 1, 1, 1, 1}}}};
  doc["initial"] = {{"q", {0.1, 0.2, 0.3, 0.4, 0.5}}, {"v", {1, -2, 3, -1, 2}}};
  // Every step rule: the adaptive ones compute lambda_min(M), ||C||_2 and (Theorem 4.2) eps_k each step.
  for (const char* rule : {"fixed", "theorem-4.1", "theorem-4.2"}) {
    SCOPED_TRACE(rule);
    doc["integrator"]["step_rule"] = rule;
    Decimated obs;
    const long short_run = AllocationsOfRun(doc, 0.2, &obs);
    const long long_run = AllocationsOfRun(doc, 2.0, &obs);
    EXPECT_GT(short_run, 0) << "the counter must see the run's own allocations (its summary)";
    EXPECT_EQ(short_run, long_run);
  }
}

// Tracking runs (tracking_integrator.h): the 7-joint arm's 1 kHz implicit controller (fixed size), and a
// five-coordinate scene (dynamic size) under every law, with measurement noise on the sampled ones.
TEST(Allocation, TrackingRunsDoNotAllocatePerStep) {
  {
    const auto doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-tracking.json");
    Decimated obs;
    const long short_run = AllocationsOfRun(doc, 0.01, &obs);
    const long long_run = AllocationsOfRun(doc, 0.1, &obs);
    EXPECT_GT(short_run, 0);
    EXPECT_EQ(short_run, long_run);
  }
  nlohmann::json doc = five_coordinates();
  doc["system"].erase("controller");
  doc["system"]["force"] = {"0.3*sin(t)", "0", "0", "0.2*cos(2*t)", "0"};
  doc["system"]["tracking"] = {{"reference", {"sin(t)", "0.5*t", "0", "cos(t)", "0.1*t^2"}},
                               {"lambda", {2, 2, 2, 2, 2}},
                               {"controller",
                                {{{"type", "quadratic"}, {"weights", {1, 1, 1, 1, 1}}},
                                 {{"type", "abs"}, {"gains", {2, 2, 2, 2, 2}}},
                                 {{"type", "norm"}, {"gain", 1}}}}};
  doc["initial"] = {{"q", {0.1, 0.2, 0.3, 0.4, 0.5}}, {"v", {1, -2, 3, -1, 2}}};
  doc["integrator"] = {{"h", 1e-3}, {"t_end", 1.0}};
  for (const char* law : {"continuous", "implicit", "explicit", "saturated"}) {
    SCOPED_TRACE(law);
    doc["system"]["tracking"]["law"] = law;
    if (std::string(law) != "continuous") {
      doc["system"]["tracking"]["period"] = 1e-2;
      doc["system"]["tracking"]["measurement"] = {{"noise", 1e-5}, {"quantum", 1e-6}};
    }
    if (std::string(law) == "saturated") doc["system"]["tracking"]["boundary_layer"] = 0.05;
    Decimated obs;
    const long short_run = AllocationsOfRun(doc, 0.2, &obs);
    const long long_run = AllocationsOfRun(doc, 2.0, &obs);
    EXPECT_GT(short_run, 0);
    EXPECT_EQ(short_run, long_run);
  }
}

TEST(Allocation, LongChainRunDoesNotAllocatePerStep) {
  // 32 links from URDF (scripts/make-chain-urdf.py), bent and moving under gravity with the controller on
  // every joint: dense P of dynamic size, whose patterns share one LU per step (one_step_solver.h).
  const nlohmann::json doc = moreau::test_support::chain_scene(32, 0.0);
  ASSERT_FALSE(doc["system"]["urdf"]["text"].get<std::string>().empty());
  Decimated obs;
  const long short_run = AllocationsOfRun(doc, 0.005, &obs);
  const long long_run = AllocationsOfRun(doc, 0.05, &obs);
  EXPECT_GT(short_run, 0);
  EXPECT_EQ(short_run, long_run);
}

}  // namespace
}  // namespace moreau::scene
