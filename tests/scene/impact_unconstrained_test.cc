// The moreau-jean scheme on systems without constraints (the Impact tests without a contact, apart from
// impact_test.cc because of the integrator instantiated here for a compiled model): a step is the
// inclusion of (0.2) in V^{k+1} with the position moved by the new velocity, against the closed forms of
// the manipulator of section 6 (Adly, Brogliato and Le 2016); one step has the abl scheme's velocity; a
// compiled model whose one-step matrix is not a P-matrix has the steps that the solver of (6.5) declines
// solved through the general rows, checked against the step's inclusion; and the damped relay follows its
// discrete closed form step by step.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "moreau/core/moreau_jean_integrator.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/scene/scene.h"
#include "impact_support.h"

namespace moreau::scene {
namespace {

// The moreau-jean scheme on a system without constraints: every step's (GE) has only the controlled rows,
// which is the inclusion of (0.2) in V^{k+1} (the scheme's header), and the position moves with the new
// velocity. Reference: the paper's closed forms for the manipulator of section 6 (M, C q' and grad V as
// printed in Adly, Brogliato and Le 2016, not the scene's expressions): at every recorded step,
// Q^{k+1} = Q^k + h V^{k+1} exactly, and V^{k+1} satisfies
//   M(Q^k) (V^{k+1} - V^k)/h + C(Q^k, V^k) V^{k+1} + grad V(Q^k) + V^{k+1} in -(Sign(v1), Sign(v2))
// to round-off (componentwise: equal to -sign where v_j != 0, within [-1, 1] where v_j == 0.0).
TEST(Impact, WithoutConstraintsAStepIsTheInclusionOfTheSchemeWithAnImplicitPosition) {
  json doc = Scene("manipulator.json");
  doc["integrator"]["scheme"] = "moreau-jean";
  doc["integrator"]["t_end"] = 2.0;
  const double h = doc["integrator"]["h"];
  const ContactRun r = RunContacts(doc);
  const json& p = doc["parameters"];
  const double m1 = p["m1"], m2 = p["m2"], b = p["b"], I = p["I"], g = p["g"];
  const std::size_t samples = r.rec.t.size();
  ASSERT_EQ(samples, 2001u);
  std::size_t at_rest = 0;
  for (std::size_t k = 0; k + 1 < samples; ++k) {
    const double* q0 = &r.rec.q[2 * k];
    const double* v0 = &r.rec.v[2 * k];
    const double* q1 = &r.rec.q[2 * k + 2];
    const double* v1 = &r.rec.v[2 * k + 2];
    ASSERT_EQ(q1[0], q0[0] + h * v1[0]) << "step " << k;
    ASSERT_EQ(q1[1], q0[1] + h * v1[1]) << "step " << k;
    const double c = std::cos(q0[1]), s = std::sin(q0[1]);
    const double M11 = m1 + m2, M12 = m2 * b * c, M22 = I + m2 * b * b;
    const double dv0 = (v1[0] - v0[0]) / h, dv1 = (v1[1] - v0[1]) / h;
    // r = M dv + C(Q^k, V^k) V^{k+1} + grad V + W V^{k+1}, C = [[0, -m2 b sin(th2) th2'], [0, 0]], W = I.
    const double res[2] = {M11 * dv0 + M12 * dv1 - m2 * b * s * v0[1] * v1[1] + v1[0], M12 * dv0 + M22 * dv1 + m2 * b * g * s + v1[1]};
    // Round-off of r: the terms M V/h are about |M| |V| / h.
    const double tol = 1e-9 * (1.0 + (std::abs(v0[0]) + std::abs(v0[1]) + std::abs(v1[0]) + std::abs(v1[1])) * (M11 + M22) / h);
    for (int j = 0; j < 2; ++j) {
      if (v1[j] != 0.0)
        EXPECT_NEAR(res[j], v1[j] > 0.0 ? -1.0 : 1.0, tol) << "step " << k << ", coordinate " << j;
      else
        EXPECT_LE(std::abs(res[j]), 1.0 + tol) << "step " << k << ", coordinate " << j;
    }
    at_rest += (v1[0] == 0.0 && v1[1] == 0.0);
  }
  // The arm comes to rest exactly and stays (gravity's torque at rest is below the gain 1).
  EXPECT_GT(at_rest, 800u);
  EXPECT_EQ(r.summary.v_final[0], 0.0);
  EXPECT_EQ(r.summary.v_final[1], 0.0);
}

// One step from the same state: moreau-jean's V^{k+1} is that of the abl scheme (0.2) bit for bit, and the
// positions differ only by the update: Q^k + h V^{k+1} against Q^k + h V^k. What this guards is the claim
// the docs make of the two schemes (docs/second-paper.md, docs/siconos-comparison.md) and that a step
// without contacts takes the (6.5) path; it is not an independent check of the velocity: both schemes form
// (6.5) with the same roundings and solve it with the same OneStepSolver. The velocity itself is checked
// against the paper's inclusion by WithoutConstraintsAStepIsTheInclusionOfTheSchemeWithAnImplicitPosition.
TEST(Impact, WithoutConstraintsOneStepHasTheVelocityOfTheAblScheme) {
  const std::vector<std::pair<std::vector<double>, std::vector<double>>> states = {
      {{3.0, -1.0}, {-1.0, 1.0}}, {{0.2, 0.7}, {2.0, -3.0}}, {{-1.0, 2.5}, {1e-3, 0.0}}, {{0.0, 0.3}, {0.0, 0.0}}};
  for (const auto& [q0, v0] : states) {
    json doc = Scene("manipulator.json");
    doc["initial"]["q"] = q0;
    doc["initial"]["v"] = v0;
    const double h = doc["integrator"]["h"];
    doc["integrator"]["t_end"] = h;
    const RunSummary abl = run_scene(load_scene(doc), nullptr);
    doc["integrator"]["scheme"] = "moreau-jean";
    const ContactRun mj = RunContacts(doc);
    ASSERT_EQ(abl.steps, 1);
    ASSERT_EQ(mj.summary.steps, 1);
    for (int j = 0; j < 2; ++j) {
      EXPECT_EQ(mj.summary.v_final[j], abl.v_final[j]) << "q0 = (" << q0[0] << ", " << q0[1] << "), coordinate " << j;
      EXPECT_EQ(abl.q_final[j], q0[j] + h * v0[j]);
      EXPECT_EQ(mj.summary.q_final[j], q0[j] + h * mj.summary.v_final[j]);
    }
  }
}

// A compiled two-coordinate model whose one-step matrix P = M/h + C is not a P-matrix: M = I, C = [[0, k],
// [k, 0]] with k = 30 (a compiled model may give any C; this one is no Christoffel form), g constant,
// phi(v) = |v_1| + |v_2|, h = 0.1, so P = [[10, 30], [30, 10]] has det P < 0 (and (4.2) fails:
// r_k = 2 h ||C||_2 / lambda_min(M) = 6). The sign-pattern solver of (6.5) declines some of its steps, and
// moreau-jean then solves them through the general rows (GraphInclusionSolver). Reference: the step's
// inclusion itself, M (V+ - V) + h C V+ + h g in -h a Sgn(V+), checked coordinate by coordinate at every
// step, and Q+ = Q + h V+; the declined steps are counted by a separate OneStepSolver on the same P and x,
// so the test fails if the general path is never reached.
struct CrossCoupled {
  static constexpr int kDof = 2;
  Mat<2> C = (Mat<2>() << 0.0, 30.0, 30.0, 0.0).finished();
  Vec<2> g = Vec<2>(0.5, -0.3);
  Controller<2> phi = [] {
    Controller<2> c = Controller<2>::zero(2);
    c.gains << 1.0, 1.0;
    return c;
  }();
  int dof() const { return 2; }
  const Controller<2>& controller() const { return phi; }
  bool constant_mass() const { return true; }
  bool constant_terms() const { return true; }
  void mass(const Vec<2>&, Mat<2>& M) const { M.setIdentity(); }
  void evaluate(double, const Vec<2>&, const Vec<2>&, LagrangianTerms<2>& out) const {
    out.M.setIdentity();
    out.C = C;
    out.g = g;
  }
  int num_constraints() const { return 0; }
  double restitution(int) const { return 0.0; }
  template <class Rows>
  void constraints(const Vec<2>&, Eigen::VectorXd&, Rows&) const {}
  bool has_potential() const { return false; }
  double potential(const Vec<2>&) const { return 0.0; }
  double evaluate_with_potential(double t, const Vec<2>& q, const Vec<2>& v, LagrangianTerms<2>& out) const {
    evaluate(t, q, v, out);
    return 0.0;
  }
};

TEST(Impact, StepsThatTheSolverOf65DeclinesSolveTheInclusionThroughTheGeneralRows) {
  CrossCoupled model;
  MoreauJeanSettings settings;
  settings.h = 0.1;
  settings.t_end = 2.0;
  MoreauJeanIntegrator<CrossCoupled> integrator(model, settings);
  Recorder rec;
  const RunSummary s = integrator.run(Vec<2>(0.0, 0.0), Vec<2>(2.0, -1.0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  const std::size_t steps = rec.t.size() - 1;
  ASSERT_EQ(steps, 20u);

  const double h = settings.h, eps = std::numeric_limits<double>::epsilon();
  const Mat<2> P = (1.0 / h) * Mat<2>::Identity() + model.C;
  ASSERT_LT(P.determinant(), 0.0);
  OneStepSolver<2> independent;
  independent.configure(model.phi.gains, 0.0);
  int declined = 0;
  for (std::size_t k = 0; k < steps; ++k) {
    const Vec<2> q0(rec.q[2 * k], rec.q[2 * k + 1]), v0(rec.v[2 * k], rec.v[2 * k + 1]);
    const Vec<2> q1(rec.q[2 * k + 2], rec.q[2 * k + 3]), v1(rec.v[2 * k + 2], rec.v[2 * k + 3]);
    const Vec<2> x = model.g - (1.0 / h) * v0;
    Vec<2> y;
    OneStepStats st;
    declined += !independent.solve(P, x, y, st);
    // (GE) with M = I: r = V+ - V + h C V+ + h g must lie in -h a Sgn(V+).
    const Vec<2> cv = model.C * v1;
    for (int i = 0; i < 2; ++i) {
      const double r = v1(i) - v0(i) + h * cv(i) + h * model.g(i);
      const double a = h * model.phi.gains(i);
      const double tol =
          64.0 * eps *
          (std::abs(v1(i)) + std::abs(v0(i)) + h * model.C.cwiseAbs().row(i).dot(v1.cwiseAbs()) + h * std::abs(model.g(i)) + a);
      if (v1(i) > 0.0) {
        EXPECT_NEAR(r, -a, tol) << "step " << k << ", coordinate " << i;
      } else if (v1(i) < 0.0) {
        EXPECT_NEAR(r, a, tol) << "step " << k << ", coordinate " << i;
      } else {
        EXPECT_LE(std::abs(r), a + tol) << "step " << k << ", coordinate " << i;
      }
      EXPECT_EQ(q1(i), q0(i) + h * v1(i)) << "step " << k;
    }
  }
  EXPECT_GT(declined, 0) << "no step went through the general rows";
}

// The damped relay m x'' = -c x' - a Sign(x') on moreau-jean: the discrete solution written out (the soft
// threshold V^{k+1} = S_a(m V^k / h) / (m/h + c), Q^{k+1} = Q^k + h V^{k+1}), step by step, to round-off,
// with V == 0.0 exactly where the threshold gives 0; it rests exactly from the step the threshold first returns 0.
TEST(Impact, WithoutConstraintsTheDampedRelayIsItsDiscreteClosedForm) {
  json doc = Scene("damped-relay.json");
  doc["integrator"]["scheme"] = "moreau-jean";
  const ContactRun r = RunContacts(doc);
  const double m = doc["parameters"]["m"], c = doc["parameters"]["c"], a = doc["parameters"]["a"];
  const double h = doc["integrator"]["h"];
  double q = doc["parameters"]["q0"], v = doc["parameters"]["v0"];
  // The solver forms m/h as m * (1/h): each step rounds differently from the lines below by a few ulps of
  // v0, and the recurrence contracts by m/h / (m/h + c) = 1 - 2.5e-4 per step, so the differences add up:
  // at most 8 eps v0 per step in V, and h times that sum in Q.
  const double eps = std::numeric_limits<double>::epsilon(), v0 = v;
  double tol_v = 0.0, tol_q = 0.0;
  ASSERT_GT(r.rec.t.size(), 100u);
  for (std::size_t k = 1; k < r.rec.t.size(); ++k) {
    const double p = m * v / h;
    v = std::abs(p) <= a ? 0.0 : (p - (p > 0.0 ? a : -a)) / (m / h + c);
    q += h * v;
    tol_v += 8.0 * eps * v0;
    tol_q += h * tol_v + eps * std::abs(q);
    ASSERT_NEAR(r.rec.v[k], v, tol_v) << "step " << k;
    ASSERT_EQ(r.rec.v[k] == 0.0, v == 0.0) << "step " << k;
    ASSERT_NEAR(r.rec.q[k], q, tol_q) << "step " << k;
  }
  EXPECT_EQ(v, 0.0);
}

}  // namespace
}  // namespace moreau::scene
