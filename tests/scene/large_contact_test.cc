// Scenes on the large-contact path (issue 53): beyond the dense limits, compiled from the scene format
// with a diagonal mass, and within them chosen by structure. Checked against the dense Moreau-Jean step
// (an independent implementation of the same scheme), the statics of a resting stack and the closed form
// of Newton's cradle; and every requirement of the path refused with the field named.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "moreau/scene/report.h"
#include "moreau/scene/scene.h"
#include "support/contact_scenes.h"

namespace moreau::scene {
namespace {

using nlohmann::json;
using test_support::cradle_scene;

json stack_scene(int n, double drop, double t_end) { return test_support::stack_scene(n, drop, t_end, 0.5, true); }

LagrangianScene on_dense_step(LagrangianScene sc) {
  auto c = std::make_shared<CompiledLagrangian>(*sc.compiled);
  c->large_contacts = nullptr;
  sc.compiled = c;
  return sc;
}

struct Trajectory : RunObserver {
  std::vector<std::vector<double>> q, v;
  void on_sample(const Sample& s) override {
    q.emplace_back(s.q, s.q + s.n);
    v.emplace_back(s.v, s.v + s.n);
  }
};

// The scene run on the large-contact path and on the dense step, sampled at every step, and the largest
// differences of their positions and velocities over the run.
struct BothSteps {
  RunSummary large, dense;
  ContactDiagnostics large_contacts, dense_contacts;
  double dq = 0.0, dv = 0.0;
  std::size_t samples = 0;
};

BothSteps RunOnBothSteps(const LagrangianScene& sc) {
  EXPECT_TRUE(uses_large_contact_path(sc));
  const LagrangianScene dense = on_dense_step(sc);
  EXPECT_FALSE(uses_large_contact_path(dense));
  Trajectory a, b;
  BothSteps r;
  r.large = run_scene(sc, &a, &r.large_contacts);
  r.dense = run_scene(dense, &b, &r.dense_contacts);
  EXPECT_EQ(r.large.status, RunStatus::kCompleted) << r.large.message;
  EXPECT_EQ(r.dense.status, RunStatus::kCompleted) << r.dense.message;
  EXPECT_EQ(a.q.size(), b.q.size());
  r.samples = std::min(a.q.size(), b.q.size());
  for (std::size_t k = 0; k < r.samples; ++k)
    for (std::size_t j = 0; j < a.q[k].size(); ++j) {
      r.dq = std::max(r.dq, std::abs(a.q[k][j] - b.q[k][j]));
      r.dv = std::max(r.dv, std::abs(a.v[k][j] - b.v[k][j]));
    }
  return r;
}

TEST(LargeContactScene, AgreesWithTheDenseStepWhereBothRun) {
  // A dropped stack of 12 (impacts travelling up and down, contacts opening and closing, rest) and a
  // touching cradle of 9 with e = 0.5: the large-contact path and the dense step, step by step.
  for (const json& doc : {stack_scene(12, 2e-3, 0.3), cradle_scene(9, 0.0, 0.05, 0.5)}) {
    const BothSteps r = RunOnBothSteps(load_scene(doc));
    EXPECT_LE(r.dq, 1e-12) << doc["name"];
    EXPECT_LE(r.dv, 1e-10) << doc["name"];
    EXPECT_EQ(r.large_contacts.impact_count, r.dense_contacts.impact_count) << doc["name"];
    EXPECT_GT(r.large_contacts.impact_count, 0) << doc["name"];  // not a comparison of two resting states
    EXPECT_GT(r.samples, 50u) << doc["name"];
    EXPECT_EQ(r.large.rest_step, r.dense.rest_step) << doc["name"];
    // Both record eq. (9) over every contact carrying impulse: the same reference.
    EXPECT_NEAR(r.large_contacts.max_eq9_mismatch, r.dense_contacts.max_eq9_mismatch, 1e-12) << doc["name"];
  }
}

TEST(LargeContactScene, AGranularColumnAgreesWithTheDenseStep) {
  // Nonlinear gaps between balls (their gradients move with the balls: D formed again at each step with
  // contacts): four balls dropped into a tube land, bounce off each other and the walls and settle. The
  // large-contact path and the dense step (symbolic n x m gradients, GraphInclusionSolver), step by step.
  const LagrangianScene sc = load_scene(test_support::column_scene(4, 2e-3, 0.6));
  ASSERT_FALSE(sc.compiled->large_contacts->linear());
  const BothSteps r = RunOnBothSteps(sc);
  EXPECT_LE(r.dq, 1e-12);
  EXPECT_LE(r.dv, 1e-10);
  EXPECT_EQ(r.large_contacts.impact_count, r.dense_contacts.impact_count);
  EXPECT_GT(r.large_contacts.impact_count, 3);
  ASSERT_TRUE(r.large.rest_step.has_value());  // settled within the run: both rest from the same step, exactly
  EXPECT_EQ(r.large.rest_step, r.dense.rest_step);
  for (double v : r.large.v_final) EXPECT_EQ(v, 0.0);
}

TEST(LargeContactScene, AGranularColumnOfTwoHundredFiftySixSettlesIntoTheZigzagExactly) {
  // 256 balls (512 coordinates, 767 contacts) dropped 1 mm apart: the upper ones land at up to 2 m/s,
  // the column bounces and settles (at t = 1.24 s). At rest every ball touches both neighbours and the
  // wall opposite them: 512 closed contacts on 512 coordinates, square and nonsingular, so the velocity
  // is 0.0 exactly. The positions keep the penetration of the landing steps (a velocity-level scheme
  // without position correction: about h times the impact speed, 3e-3 here; Siconos' column ends with the
  // same order, docs/scaling.md), so the zigzag is checked to that order: each ball against its own wall
  // (the other one is r further), its neighbours about sqrt(3) r above and below.
  const int n = 256;
  const LagrangianScene sc = load_scene(test_support::column_scene(n, 1e-3, 1.5));
  ASSERT_FALSE(sc.compiled->dense);
  ContactDiagnostics c;
  const RunSummary s = run_scene(sc, nullptr, &c);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.rest_step.has_value());
  for (double v : s.v_final) ASSERT_EQ(v, 0.0);
  const double r = test_support::kBallRadius;
  for (int i = 0; i < n; ++i) {
    EXPECT_NEAR(s.q_final[static_cast<std::size_t>(2 * i)], i % 2 == 0 ? r : 2 * r, r / 8) << i;
    if (i + 1 < n)
      EXPECT_NEAR(s.q_final[static_cast<std::size_t>(2 * i + 3)] - s.q_final[static_cast<std::size_t>(2 * i + 1)], std::sqrt(3.0) * r,
                  r / 8)
          << i;
  }
  EXPECT_GT(c.smallest_gap, -0.01);
  EXPECT_GT(c.impact_count, n);
  const json report = report_json(sc, s, &c);
  EXPECT_EQ(report["contacts"]["active_gradient_rank"], 2 * n);
  EXPECT_EQ(report["contacts"]["reactions_unique_at_end"], true);
}

TEST(LargeContactScene, AStackOfAThousandRestsExactly) {
  const LagrangianScene sc = load_scene(stack_scene(1000, 0.0, 0.05));
  ASSERT_FALSE(sc.compiled->dense);
  ContactDiagnostics c;
  const RunSummary s = run_scene(sc, nullptr, &c);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  EXPECT_EQ(s.rest_step, 0);
  for (double v : s.v_final) ASSERT_EQ(v, 0.0);
  EXPECT_EQ(c.impact_count, 0);
  // The report: every contact closed, reactions unique (a square bidiagonal gradient matrix).
  const json report = report_json(sc, s, &c);
  EXPECT_EQ(report["contacts"]["active_gradient_rank"], 1000);
  EXPECT_EQ(report["contacts"]["reactions_unique_at_end"], true);
  const std::string text = report_text(sc, s, &c);
  EXPECT_NE(text.find("(1000 in all; every one in --json)"), std::string::npos) << text.substr(0, 600);
}

TEST(LargeContactScene, AGappedCradleOfAThousandPassesTheVelocityOnExactly) {
  const int n = 1024;
  const LagrangianScene sc = load_scene(cradle_scene(n, 0.01, 0.01 * (n - 1) + 0.05, 1.0));
  ContactDiagnostics c;
  const RunSummary s = run_scene(sc, nullptr, &c);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  for (int i = 0; i + 1 < n; ++i) ASSERT_EQ(s.v_final[static_cast<std::size_t>(i)], 0.0) << i;
  EXPECT_EQ(s.v_final.back(), 1.0);
  EXPECT_EQ(c.impact_count, n - 1);
}

TEST(LargeContactScene, ATouchingCradleReportsItsImpactLawAndChecksEq9OverEveryContact) {
  // The example: touching balls, e = 0.5; the step passes impulse through the closed contacts,
  // and eq. (9)'s reference covers them (a 0.094 mismatch when it covered the approaching contact alone).
  for (bool dense : {false, true}) {
    LagrangianScene sc = load_scene(cradle_scene(5, 0.0, 0.01, 0.5));
    if (dense) sc = on_dense_step(sc);
    ContactDiagnostics c;
    const RunSummary s = run_scene(sc, nullptr, &c);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    ASSERT_GE(c.impacts.size(), 1u);
    EXPECT_EQ(c.impacts[0].closed_carrying, 3) << dense;
    EXPECT_LE(c.max_eq9_mismatch, 1e-12) << dense;
    const json report = report_json(sc, s, &c);
    EXPECT_EQ(report["contacts"]["impacts"][0]["closed_contacts_carrying_impulse"], 3);
    EXPECT_NE(report_text(sc, s, &c).find("passed impulse through closed contacts"), std::string::npos);
  }
}

void ExpectError(const json& doc, const std::string& pointer, const std::string& part) {
  try {
    load_scene(doc);
    ADD_FAILURE() << "accepted; expected an error at " << pointer;
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

TEST(LargeContactScene, RefusesWhatThePathCannotTakeNamingTheField) {
  json doc = stack_scene(100, 0.0, 0.01);
  // A nonlinear gap is taken (the granular column below); one that reads more coordinates than a
  // contact between a few bodies (65 here) is refused before its derivatives are formed.
  std::string wide = "y1^2";
  for (int j = 2; j <= 65; ++j) wide += " + " + test_support::indexed("y", j) + "^2";
  doc["system"]["constraints"][7]["gap"] = wide;
  ExpectError(doc, "/system/constraints/7/gap", "reads 65 coordinates: a gap on the large-contact path reads at most 64");
  doc = stack_scene(100, 0.0, 0.01);
  doc["system"]["constraints"][7]["gap"] = "y8 - y7 - 2*r + 0.01*y8^2";
  doc["integrator"]["position_correction"] = "projection";
  ExpectError(doc, "/integrator/position_correction", "position correction with nonlinear gaps is not taken");
  doc = stack_scene(100, 0.0, 0.01);
  doc["system"]["mass"]["diagonal"][3] = "m + y4^2";
  ExpectError(doc, "/system/mass/diagonal/3", "is not a constant");
  doc = stack_scene(100, 0.0, 0.01);
  doc["system"]["controller"] = json::array({{{"type", "abs"}, {"gains", std::vector<double>(100, 1.0)}}});
  ExpectError(doc, "/system/controller", "large-contact path");
  doc = stack_scene(100, 0.0, 0.01);
  doc["integrator"]["scheme"] = "abl";  // taken at scale (the large ABL path), but not with constraints
  ExpectError(doc, "/integrator/scheme", "cannot integrate unilateral constraints");
  doc = stack_scene(100, 0.0, 0.01);
  doc["system"]["mass"] = json::array();
  for (int i = 0; i < 100; ++i) doc["system"]["mass"].push_back(std::vector<int>(100, 0));
  ExpectError(doc, "/system/coordinates", "with a full mass matrix");
  doc = stack_scene(100, 0.0, 0.01);
  doc["system"]["mass"]["diagonal"][5] = "-m";
  ExpectError(doc, "/system/mass/diagonal/5", "finite positive");
  doc = stack_scene(100, 0.0, 0.01);
  doc["initial"]["q"][50] = 0.0;
  ExpectError(doc, "/initial/q", "violates constraint 'c51'");
  // Contacts that couple densely: 100 constraints each on all of 100 coordinates (a dense Delassus
  // operator, cubic per factorisation) are refused, naming the coupling.
  doc = stack_scene(100, 0.0, 0.01);
  for (int k = 0; k < 100; ++k) {
    std::string gap = "y1 + 100";
    for (int j = 2; j <= 100; ++j) gap += " + " + test_support::indexed("y", j);
    doc["system"]["constraints"][k]["gap"] = gap;
  }
  ExpectError(doc, "/system/constraints", "couple too densely");
  // The limit itself.
  doc = stack_scene(3, 0.0, 0.01);
  json names = json::array();
  for (int i = 0; i < 10001; ++i) names.push_back(test_support::indexed("z", i));
  doc["system"]["coordinates"] = names;
  ExpectError(doc, "/system/coordinates", "more than 10000 degrees of freedom (got 10001)");
}

TEST(LargeContactScene, StudiesOfOtherSchemesAreRefusedBeyondTheDenseLimits) {
  const LagrangianScene sc = load_scene(stack_scene(100, 0.0, 0.01));
  EXPECT_THROW(scene_variant(sc, Scheme::kAbl, 1e-3), std::invalid_argument);
  EXPECT_NO_THROW(scene_variant(sc, Scheme::kMoreauJean, 1e-3));
}

}  // namespace
}  // namespace moreau::scene
