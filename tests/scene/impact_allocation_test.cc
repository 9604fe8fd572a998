// The second paper's schemes allocate nothing per step: the number of heap allocations of a run does not
// depend on its number of steps (moreau-jean with impacts, a closed contact, the coupled controller and
// the position correction; the Lur'e theta-method, fixed and dynamic sizes). Its own test binary because
// it replaces the global operator new and the C allocator (Eigen's dynamic-size temporaries use malloc).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "moreau/scene/scene.h"
#include "support/allocation_counter.h"

// GCC 12 pairs the replaced operator new with std::free only when it inlines allocations of its own
// (nlohmann::json literals here) and then warns; the pair below is matched by construction.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace moreau::scene {
namespace {

struct Decimated : RunObserver {
  long samples = 0;
  void on_sample(const Sample&) override { ++samples; }
};

nlohmann::json Scene(const std::string& name) { return read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + name); }

long ContactAllocations(nlohmann::json doc, double t_end) {
  doc["integrator"]["t_end"] = t_end;
  doc["output"]["every"] = 100;
  const LagrangianScene sc = load_scene(doc);
  Decimated obs;
  ContactDiagnostics d;
  const long before = moreau::testing::allocations();
  const RunSummary s = run_scene(sc, &obs, &d);
  EXPECT_EQ(s.status, RunStatus::kCompleted) << s.message;
  return moreau::testing::allocations() - before;
}

long LureAllocations(nlohmann::json doc, double t_end) {
  doc["integrator"]["t_end"] = t_end;
  doc["output"]["every"] = 100;
  const LureScene sc = load_lure_scene(doc);
  Decimated obs;
  LureDiagnostics d;
  const long before = moreau::testing::allocations();
  const RunSummary s = run_lure_scene(sc, &obs, &d);
  EXPECT_EQ(s.status, RunStatus::kCompleted) << s.message;
  return moreau::testing::allocations() - before;
}

TEST(Allocation, BouncingBallThroughItsZenoPhase) {
  // 0.5 s: one impact; 3 s: the whole accumulation and the rest.
  EXPECT_EQ(ContactAllocations(Scene("bouncing-ball-e0.8.json"), 0.5), ContactAllocations(Scene("bouncing-ball-e0.8.json"), 6.0));
}

TEST(Allocation, Example1) {
  EXPECT_EQ(ContactAllocations(Scene("example1-eq17.json"), 0.2), ContactAllocations(Scene("example1-eq17.json"), 4.0));
}

TEST(Allocation, ControllerRowsThroughTheGraphSolver) {
  // The paper's manipulator under moreau-jean: no contact, its controller's rows solved every step by the
  // graph solver (dynamic size inside a fixed-size integrator).
  nlohmann::json doc = Scene("manipulator.json");
  doc["integrator"]["scheme"] = "moreau-jean";
  EXPECT_EQ(ContactAllocations(doc, 0.2), ContactAllocations(doc, 3.0));
}

TEST(Allocation, CurvedConstraintWithPositionCorrection) {
  nlohmann::json doc = {{"system",
                         {{"type", "lagrangian"},
                          {"coordinates", {"x", "y"}},
                          {"mass", {{1, 0}, {0, 1}}},
                          {"potential", "9.81*y"},
                          {"controller", {{{"type", "abs"}, {"gains", {0.1, 0.1}}}}},
                          {"constraints", {{{"gap", "1 - x^2 - y^2"}, {"restitution", 0.3}}}}}},
                        {"initial", {{"q", {0, 0}}, {"v", {1.5, 0}}}},
                        {"integrator", {{"scheme", "moreau-jean"}, {"h", 1e-3}, {"t_end", 1}, {"position_correction", "projection"}}}};
  EXPECT_EQ(ContactAllocations(doc, 0.2), ContactAllocations(doc, 3.0));
}

TEST(Allocation, DynamicSizeContacts) {
  // Five coordinates: beyond the fixed-size dispatch; two floors.
  nlohmann::json doc = Scene("example1-eq17.json");
  doc["system"]["coordinates"] = {"p1", "p2", "p3", "p4", "y"};
  doc["system"]["mass"] = {{2, 0, 0, 0, 0}, {0, 2, 0, 0, 0}, {0, 0, 2, 0, 0}, {0, 0, 0, 2, 0}, {0, 0, 0, 0, 1}};
  doc["system"]["potential"] = "p1^2 + p2^2 + p3^2 + p4^2 + 9.81*y + 9.81*p2";
  doc["system"]["controller"] = {{{"type", "abs"}, {"gains", {0.5, 0, 0, 0.5, 0}}}};
  doc["system"]["constraints"] = {{{"gap", "y"}, {"restitution", 0.5}}, {{"gap", "p2 + 1"}, {"restitution", 0}}};
  doc["initial"] = {{"q", {0.1, 0.2, 0.3, 0.4, 0.5}}, {"v", {1, -2, 3, -1, 0}}};
  EXPECT_EQ(ContactAllocations(doc, 0.2), ContactAllocations(doc, 3.0));
}

TEST(Allocation, LureRelayFixedAndDynamicSize) {
  EXPECT_EQ(LureAllocations(Scene("lure-relay-2state.json"), 0.5), LureAllocations(Scene("lure-relay-2state.json"), 5.0));
  EXPECT_EQ(LureAllocations(Scene("lure-lcs.json"), 0.05), LureAllocations(Scene("lure-lcs.json"), 5.0));
  // Five states, two outputs: dynamic sizes.
  nlohmann::json doc = Scene("lure-relay-2state.json");
  doc["system"]["A"] = {{-1, 1, 0, 0, 0}, {-1, -1, 0, 0, 0}, {0, 0, -2, 0, 0}, {0, 0, 0, -1, 1}, {0, 0, 0, -1, -2}};
  doc["system"]["B"] = {{1, 0}, {0, 0}, {0, 1}, {0, 0}, {0, 1}};
  doc["system"]["C"] = {{1, 0, 0, 0, 0}, {0, 0, 1, 0, 1}};
  doc["system"]["feedback"] = {{{"type", "relay"}, {"gain", 1}}, {{"type", "saturation"}, {"slope", 2}, {"limit", 1}}};
  doc["initial"]["x"] = {1, -1, 2, 0.5, 0};
  EXPECT_EQ(LureAllocations(doc, 0.5), LureAllocations(doc, 5.0));
}

}  // namespace
}  // namespace moreau::scene
