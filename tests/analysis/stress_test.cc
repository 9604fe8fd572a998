// The stress suite as a test: every case runs without NaN or Inf, completes, and meets what the theory
// promises for it (non-increasing energy, finite-step rest, or the absence of rest).
#include "moreau/analysis/stress.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <string>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "moreau/core/models/manipulator.h"

namespace moreau::scene {

// Test names and failure messages show the case's name, not its bytes.
void PrintTo(const StressCase& c, std::ostream* os) { *os << c.name; }

namespace {

class Stress : public ::testing::TestWithParam<StressCase> {};

TEST_P(Stress, MeetsItsExpectations) {
  const StressOutcome o = run_stress_case(GetParam());
  EXPECT_TRUE(o.finite);
  EXPECT_TRUE(o.failures.empty()) << format_outcome(o);
}

INSTANTIATE_TEST_SUITE_P(Suite, Stress, ::testing::ValuesIn(stress_cases()), [](const auto& info) {
  std::string name = info.param.name;
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
});

// The one-coordinate cases (m x'' + c x' + a Sign(x') = f) against their discrete closed form, computed
// here without the library's solver: a step of (0.2) is the scalar inclusion
// (m/h + c) V' - p in -a Sign(V') with p = m V/h + f, whose solution is V' = 0 when |p| <= a and
// V' = (p - a sign p) / (m/h + c) otherwise; then Q' = Q + h V. The run must take the same steps, come to
// rest at the same step (within one, for a |p| within round-off of a) and end at the same state.
TEST(Stress, OneCoordinateCasesFollowTheirDiscreteClosedForm) {
  int checked = 0;
  for (const auto& c : stress_cases()) {
    const nlohmann::json& sc = c.scene;
    // Robot cases name a URDF instead of coordinates; at() and contains() never read past a missing key.
    const nlohmann::json& system = sc.at("system");
    if (!system.contains("coordinates") || system.at("coordinates").size() != 1) continue;
    if (!sc.contains("parameters") || !sc.at("parameters").contains("f")) continue;
    const double m = sc["parameters"]["m"], cc = sc["parameters"]["c"], a = sc["parameters"]["a"], f = sc["parameters"]["f"];
    const double h = sc["integrator"]["h"], t_end = sc["integrator"]["t_end"];
    if (t_end / h > 2e7) continue;  // the 1e8-step case: its expectations are checked by Suite/Stress
    const StressOutcome o = run_stress_case(c);
    ASSERT_EQ(o.summary.status, RunStatus::kCompleted) << c.name;
    double q = sc["initial"]["q"][0], v = sc["initial"]["v"][0], t = 0.0;
    std::int64_t k = 0, rest_from = -1;
    for (; k < o.summary.steps; ++k) {
      const double hk = std::min(h, t_end - t);
      const double p = m * v / hk + f;
      const double v_next = std::abs(p) <= a ? 0.0 : (p - a * (p > 0 ? 1.0 : -1.0)) / (m / hk + cc);
      q += hk * v;
      v = v_next;
      t = (k + 1 == o.summary.steps) ? t_end : t + hk;
      if (v == 0.0 && rest_from < 0) rest_from = k + 1;
      if (v != 0.0) rest_from = -1;
    }
    EXPECT_NEAR(o.summary.t_final, t_end, 1e-9 * t_end) << c.name;
    EXPECT_NEAR(o.summary.q_final[0], q, 1e-9 * (1.0 + std::abs(q))) << c.name;
    EXPECT_NEAR(o.summary.v_final[0], v, 1e-9 * (1.0 + std::abs(v))) << c.name;
    EXPECT_EQ(o.summary.v_final[0] == 0.0, v == 0.0) << c.name;
    if (rest_from >= 0) {
      ASSERT_TRUE(o.summary.rest_step.has_value()) << c.name;
      EXPECT_LE(std::abs(*o.summary.rest_step - rest_from), 1) << c.name;
    } else {
      EXPECT_FALSE(o.summary.rest_step.has_value()) << c.name;
    }
    ++checked;
  }
  EXPECT_GE(checked, 4);  // tiny mass, huge mass, tiny step, the two perturbations
}

// The manipulator at |v0| ~ 100 with a scene step of 0.1 under the Theorem 4.2 rule: every step it takes
// is shorter than 0.1, and each satisfies Theorem 4.1's (4.2), r_k <= 1 (the run's own per-step check,
// itself checked against eigenvalue solvers in step_conditions_test.cc), which the scene's h = 0.1 breaks
// at the start (r_0 = 2 h ||C||_2 / lambda_min(M) computed here from the paper's closed forms).
TEST(Stress, TheTheorem42RuleShrinksTheStep) {
  bool found = false;
  for (const auto& c : stress_cases()) {
    if (c.name != "theorem-4.2-rule-shrinks-h") continue;
    found = true;
    const StressOutcome o = run_stress_case(c);
    EXPECT_LT(o.summary.h_max, 0.1);
    EXPECT_GT(o.summary.theorem41.checked, 0);
    EXPECT_EQ(o.summary.theorem41.violations, 0);
  }
  EXPECT_TRUE(found) << "no stress case theorem-4.2-rule-shrinks-h";
  // At the case's initial state (q = (3, -1), v = (60, 80), g = 0.9), h = 0.1 would break (4.2).
  moreau::models::ManipulatorParameters p;
  p.gravity_m_s2 = 0.9;
  const moreau::models::Manipulator model(p);
  moreau::LagrangianTerms<2> terms;
  model.evaluate(0.0, moreau::Vec<2>(3.0, -1.0), moreau::Vec<2>(60.0, 80.0), terms);
  const double lambda_min = Eigen::SelfAdjointEigenSolver<moreau::Mat<2>>(terms.M).eigenvalues()(0);
  const double c_norm = Eigen::JacobiSVD<moreau::Mat<2>>(terms.C).singularValues()(0);
  EXPECT_GT(2.0 * 0.1 * c_norm / lambda_min, 1.0);
}

// The robot cases' premises, from the runs' own per-step checks of (4.2): the fixed step does leave
// Theorem 4.1 (at its first step, where the arm moves fastest), and at five or ten times the speed the
// Theorem 4.1 rule keeps every step inside it by shrinking h_k far below the scene's 1e-3.
TEST(Stress, RobotCasesAreWhereTheySayTheyAre) {
  const std::map<std::string, std::size_t> joints = {
      {"robot-iiwa-fixed-step", 7}, {"robot-iiwa-10x-speed", 7}, {"robot-puma560-fixed-step", 6}, {"robot-puma560-5x-speed", 6}};
  std::size_t checked = 0;
  for (const auto& c : stress_cases()) {
    if (!joints.count(c.name)) continue;
    const StressOutcome o = run_stress_case(c);
    ASSERT_EQ(o.summary.status, RunStatus::kCompleted) << c.name << ": " << o.summary.message;
    ASSERT_EQ(o.summary.q_final.size(), joints.at(c.name)) << c.name;
    const StepConditionTrack& r = o.summary.theorem41;
    EXPECT_EQ(r.checked, o.summary.steps) << c.name;
    if (c.scene["integrator"]["step_rule"] == "fixed") {
      EXPECT_GT(r.violations, 0) << c.name;
      EXPECT_EQ(r.first_violation_step, 0) << c.name;
      EXPECT_EQ(o.summary.h_min, 1e-3) << c.name;
    } else {
      EXPECT_EQ(r.violations, 0) << c.name;
      EXPECT_LT(o.summary.h_min, 1e-4) << c.name;
    }
    ++checked;
  }
  EXPECT_EQ(checked, joints.size());
}

}  // namespace
}  // namespace moreau::scene
