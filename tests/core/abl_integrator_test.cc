// The scheme (0.2) against closed-form solutions, the discrete scheme's own exact sequences, and the
// theorems of Adly, Brogliato and Le (2016): finite-step convergence (Thm 4.3), non-increasing energy
// (Thm 4.2), the step rules (Thms 4.1, 4.2), and the measured order (Thm 5.2, Remark 5.1).
#include "moreau/core/abl_integrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "moreau/core/models/manipulator.h"
#include "moreau/core/models/oscillator1.h"

namespace moreau {
namespace {

constexpr double kPi = 3.14159265358979323846;

using models::Oscillator1;

// Records every sample.
struct Recorder : RunObserver {
  std::vector<double> t, h, q, v, e;
  void on_sample(const Sample& s) override {
    t.push_back(s.t);
    h.push_back(s.h);
    for (int i = 0; i < s.n; ++i) {
      q.push_back(s.q[i]);
      v.push_back(s.v[i]);
    }
    e.push_back(s.kinetic_energy);
  }
};

AblSettings Fixed(double h, double t_end) {
  AblSettings s;
  s.h = h;
  s.t_end = t_end;
  return s;
}

// Damped relay m v' = -c v - a Sign(v): v(t) = (v0 + a/c) e^{-ct/m} - a/c until it stops at
// t* = (m/c) ln(1 + c v0 / a); q(t) = q0 + (m/c)(v0 + a/c)(1 - e^{-ct/m}) - (a/c) t.
struct DampedRelayExact {
  double m, c, a, q0, v0;
  double stop_time() const { return m / c * std::log(1.0 + c * v0 / a); }
  double v(double t) const { return t >= stop_time() ? 0.0 : (v0 + a / c) * std::exp(-c * t / m) - a / c; }
  double q(double t) const {
    const double ts = std::min(t, stop_time());
    return q0 + m / c * (v0 + a / c) * (1.0 - std::exp(-c * ts / m)) - a / c * ts;
  }
};

TEST(AblIntegrator, DampedRelayStopsInFiniteStepsAtTheExactTime) {
  const DampedRelayExact exact{2.0, 0.5, 1.0, 0.0, 3.0};
  for (double h : {1e-2, 1e-3, 1e-4}) {
    Oscillator1 model(exact.m, 0.0, 0.0, exact.c, exact.a);
    Recorder rec;
    AblIntegrator<Oscillator1> integrator(model, Fixed(h, 8.0));
    const RunSummary s = integrator.run(Vec<1>(exact.q0), Vec<1>(exact.v0), &rec);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    ASSERT_TRUE(s.converged_step.has_value());
    // Bit-exact rest from step N on.
    for (std::size_t k = static_cast<std::size_t>(*s.converged_step); k < rec.v.size(); ++k) ASSERT_EQ(rec.v[k], 0.0);
    ASSERT_NE(rec.v[*s.converged_step - 1], 0.0);
    // The discrete stop time is within a step (plus the O(h) drift of the discrete velocity) of t*.
    EXPECT_NEAR(*s.converged_time, exact.stop_time(), 3.0 * h) << "h = " << h;
    EXPECT_NEAR(s.q_final[0], exact.q(8.0), 3.0 * h);
    EXPECT_TRUE(s.energy_nonincreasing);
    EXPECT_EQ(s.equilibrium.residual, 0.0);
    EXPECT_TRUE(s.equilibrium.interior);
  }
}

// An Oscillator1 that counts its evaluations and declares its terms constant or not, as told.
struct CountingOscillator : Oscillator1 {
  bool declared_constant = false;
  int evaluations = 0;
  CountingOscillator(bool constant) : Oscillator1(2.0, 0.0, 0.0, 0.5, 1.0), declared_constant(constant) {}
  bool constant_terms() const { return declared_constant; }
  void evaluate(double t, const Vec<1>& q, const Vec<1>& v, LagrangianTerms<1>& out) {
    ++evaluations;
    Oscillator1::evaluate(t, q, v, out);
  }
};

// A model whose M, C and g never change is evaluated at the start (and for the final equilibrium
// check) only. Reference: the same model evaluated at every step: the same samples, bit for bit.
TEST(AblIntegrator, ConstantTermsAreEvaluatedOnceWithTheSameResults) {
  CountingOscillator varying(false), constant(true);
  Recorder rec_varying, rec_constant;
  AblIntegrator<CountingOscillator> a(varying, Fixed(1e-3, 8.0)), b(constant, Fixed(1e-3, 8.0));
  const RunSummary s_varying = a.run(Vec<1>(0.0), Vec<1>(3.0), &rec_varying);
  const RunSummary s_constant = b.run(Vec<1>(0.0), Vec<1>(3.0), &rec_constant);
  ASSERT_EQ(s_varying.status, RunStatus::kCompleted) << s_varying.message;
  ASSERT_EQ(s_constant.status, RunStatus::kCompleted) << s_constant.message;
  EXPECT_EQ(varying.evaluations, 8000 + 2);  // the initial state, each step's new state, the final check
  EXPECT_EQ(constant.evaluations, 2);
  EXPECT_EQ(rec_constant.q, rec_varying.q);
  EXPECT_EQ(rec_constant.v, rec_varying.v);
  EXPECT_EQ(rec_constant.e, rec_varying.e);
  EXPECT_EQ(s_constant.converged_step, s_varying.converged_step);
  EXPECT_EQ(s_constant.theorem41.checked, s_varying.theorem41.checked);
}

// The discrete sequence of the forced relay m v' = f - a Sign(v) (F = -f), |f| < a, is known exactly:
// V^k = v0 - k h (a - f)/m until it would cross zero, then 0.0 forever; Q^k = q(t_k) + (a - f) h t_k / (2m)
// with q the exact solution, because the position update uses V^k (explicit in position).
TEST(AblIntegrator, ForcedRelayThatSticksFollowsItsDiscreteClosedForm) {
  const double m = 1.5, a = 2.0, f = 0.5, v0 = 1.2, q0 = -0.3, h = 1e-3;
  Oscillator1 model(m, 0.0, -f, 0.0, a);
  Recorder rec;
  AblIntegrator<Oscillator1> integrator(model, Fixed(h, 3.0));
  const RunSummary s = integrator.run(Vec<1>(q0), Vec<1>(v0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  const double decel = (a - f) / m;
  const double t_stop = v0 / decel;  // exact stop time
  ASSERT_EQ(rec.t.size(), 3001u);
  for (std::size_t k = 0; k < rec.t.size(); ++k) {
    const double t = rec.t[k];
    if (t < t_stop - h) {
      EXPECT_NEAR(rec.v[k], v0 - t * decel, 1e-12) << k;
      const double q_exact = q0 + v0 * t - 0.5 * decel * t * t;
      EXPECT_NEAR(rec.q[k], q_exact + 0.5 * decel * h * t, 1e-11) << k;
    } else if (t > t_stop + h) {
      EXPECT_EQ(rec.v[k], 0.0) << k;
    }
  }
  EXPECT_NEAR(*s.converged_time, t_stop, h);
  // At rest the residual force f lies strictly inside [-a, a]: Theorem 4.3's interior condition.
  EXPECT_TRUE(s.equilibrium.interior);
}

// Coulomb oscillator m q'' + k q in -a Sign(q') from rest at p0: each half period pi/w the turning point
// shrinks by 2a/k towards the origin; motion stops at the first turning point with |p| <= a/k.
// The scheme's own first-order error, derived here: within a half period the motion is a spring about the
// centre c = a/k sign, and one step of (0.2) (V' = V - h w^2 (Q - c), Q' = Q + h V) multiplies
// 1/2 V^2 + 1/2 w^2 (Q - c)^2 by exactly 1 + h^2 w^2, so over the pi/(w h) steps of a half period the
// amplitude A_j = |p_j| - a/k grows by (1 + h^2 w^2)^{pi/(2 w h)} = 1 + (pi w / 2) h + O(h^2). The rest
// point is therefore off by (pi w / 2) h sum_j A_j + O(h^2), away from the origin.
TEST(AblIntegrator, CoulombOscillatorRestsWhereTheClosedFormSays) {
  const double m = 1.0, k = 4.0, a = 1.0, p0 = 2.1;
  const double w = std::sqrt(k / m);
  double p = p0, amplitude_sum = 0.0;
  int half_periods = 0;
  while (std::abs(p) > a / k) {
    amplitude_sum += std::abs(p) - a / k;
    p = -(p - 2.0 * a / k * (p > 0 ? 1.0 : -1.0));
    ++half_periods;
  }
  const double t_rest = half_periods * kPi / w;
  for (double h : {1e-3, 1e-4}) {
    Oscillator1 model(m, k, 0.0, 0.0, a);
    AblIntegrator<Oscillator1> integrator(model, Fixed(h, t_rest + 2.0));
    const RunSummary s = integrator.run(Vec<1>(p0), Vec<1>(0.0));
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    ASSERT_TRUE(s.converged_step.has_value());
    EXPECT_EQ(s.v_final[0], 0.0);
    const double drift = kPi * w / 2.0 * h * amplitude_sum * (p > 0 ? 1.0 : -1.0);  // 13.8 h here
    EXPECT_NEAR(s.q_final[0], p + drift, 0.05 * std::abs(drift)) << "h = " << h;
    EXPECT_NEAR(*s.converged_time, t_rest, 2.0 * h) << "h = " << h;
    EXPECT_EQ(s.equilibrium.residual, 0.0);
  }
}

// Remark 5.1: order 1 for constant M. Errors of the damped relay at t = 1 (before the stop) for h and h/10.
TEST(AblIntegrator, OrderOneForConstantMass) {
  const DampedRelayExact exact{2.0, 0.5, 1.0, 0.0, 3.0};
  std::vector<double> errors;
  const std::vector<double> hs = {1e-2, 1e-3, 1e-4};
  for (double h : hs) {
    Oscillator1 model(exact.m, 0.0, 0.0, exact.c, exact.a);
    AblIntegrator<Oscillator1> integrator(model, Fixed(h, 1.0));
    const RunSummary s = integrator.run(Vec<1>(exact.q0), Vec<1>(exact.v0));
    errors.push_back(std::hypot(s.q_final[0] - exact.q(1.0), s.v_final[0] - exact.v(1.0)));
  }
  for (std::size_t i = 1; i < hs.size(); ++i) {
    const double order = std::log(errors[i - 1] / errors[i]) / std::log(hs[i - 1] / hs[i]);
    EXPECT_NEAR(order, 1.0, 0.05) << "between h = " << hs[i - 1] << " and " << hs[i];
  }
}

TEST(AblIntegrator, ManipulatorReachesRestInFiniteStepsAndStaysThere) {
  models::Manipulator model;
  Recorder rec;
  AblIntegrator<models::Manipulator> integrator(model, Fixed(1e-3, 10.0));
  const RunSummary s = integrator.run(Vec<2>(3.0, -1.0), Vec<2>(-1.0, 1.0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.converged_step.has_value());
  EXPECT_LT(*s.converged_step, s.steps);
  for (std::size_t k = static_cast<std::size_t>(*s.converged_step); k < rec.t.size(); ++k) {
    ASSERT_EQ(rec.v[2 * k], 0.0);
    ASSERT_EQ(rec.v[2 * k + 1], 0.0);
    // Q is frozen one step after V is zero.
    if (k > static_cast<std::size_t>(*s.converged_step)) {
      ASSERT_EQ(rec.q[2 * k], rec.q[2 * k - 2]);
      ASSERT_EQ(rec.q[2 * k + 1], rec.q[2 * k - 1]);
    }
  }
  // Theorem 4.3: Q* is an equilibrium, -grad V(Q*) in int dPhi(0) = (-1, 1)^2.
  EXPECT_EQ(s.equilibrium.residual, 0.0);
  EXPECT_TRUE(s.equilibrium.interior);
  const double th2 = s.q_final[1];
  EXPECT_LT(std::abs(0.5 * 1.0 * 9.81 * std::sin(th2)), 1.0);
}

// Theorem 4.2 needs Assumption 4.1: ||grad V|| <= (alpha - beta)/2 = 1/2 with alpha = 1, F = 0, so
// b m2 g <= 1/2; then E_k is non-increasing and the steps are non-increasing.
TEST(AblIntegrator, Theorem42RuleKeepsEnergyNonIncreasing) {
  models::ManipulatorParameters p;
  p.gravity_m_s2 = 0.9;  // b m2 g = 0.45
  models::Manipulator model(p);
  Recorder rec;
  AblSettings settings = Fixed(0.05, 10.0);
  settings.step_rule = StepRule::kTheorem42;
  AblIntegrator<models::Manipulator> integrator(model, settings);
  const RunSummary s = integrator.run(Vec<2>(3.0, -1.0), Vec<2>(-4.0, 6.0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  EXPECT_TRUE(s.energy_nonincreasing) << "max increase " << s.energy_max_increase;
  for (std::size_t k = 1; k < rec.e.size(); ++k) ASSERT_LE(rec.e[k], rec.e[k - 1] * (1 + 1e-14) + 1e-300) << k;
  for (std::size_t k = 2; k + 1 < rec.h.size(); ++k) ASSERT_LE(rec.h[k], rec.h[k - 1]) << k;
  EXPECT_LT(s.h_min, 0.05) << "the rule must have shortened the step at this speed";
  ASSERT_TRUE(s.converged_step.has_value());
}

// Theorem 4.1's rule with given constants: h_k <= k1 / (2 k3 ||V^k||).
TEST(AblIntegrator, Theorem41RuleBoundsTheStep) {
  models::Manipulator model;
  Recorder rec;
  AblSettings settings = Fixed(0.1, 3.0);
  settings.step_rule = StepRule::kTheorem41;
  settings.k1 = 0.05;  // lambda_min(M) >= 0.05 for these parameters
  settings.k3 = 0.5;   // ||C(q, v)|| = m2 b |sin th2| |th2'| <= 0.5 ||v||
  AblIntegrator<models::Manipulator> integrator(model, settings);
  const RunSummary s = integrator.run(Vec<2>(0.0, 0.0), Vec<2>(3.0, 4.0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  for (std::size_t k = 1; k + 1 < rec.t.size(); ++k) {
    const double vn = std::hypot(rec.v[2 * (k - 1)], rec.v[2 * (k - 1) + 1]);
    const double bound = vn > 0 ? std::min(0.1, 0.05 / (2 * 0.5 * vn)) : 0.1;
    ASSERT_LE(rec.h[k], bound * (1 + 1e-15)) << k;
  }
  EXPECT_LT(s.h_min, 0.1);
}

TEST(AblIntegrator, Theorem42WithoutQuadraticTermIsAClearFailure) {
  models::ManipulatorParameters p;
  Controller<2> phi;
  phi.weights = Vec<2>::Zero();
  phi.gains = Vec<2>(1.0, 1.0);
  models::Manipulator model(p, phi);
  AblSettings settings = Fixed(0.01, 1.0);
  settings.step_rule = StepRule::kTheorem42;
  AblIntegrator<models::Manipulator> integrator(model, settings);
  const RunSummary s = integrator.run(Vec<2>(0.0, 1.0), Vec<2>(1.0, 2.0));
  EXPECT_EQ(s.status, RunStatus::kFailed);
  EXPECT_NE(s.message.find("eta"), std::string::npos) << s.message;
}

struct CancelAfterFirstCheck : RunObserver {
  void on_sample(const Sample&) override {}
  bool keep_going(std::int64_t, double) override { return false; }
};

TEST(AblIntegrator, ObserverCanCancel) {
  models::Manipulator model;
  AblIntegrator<models::Manipulator> integrator(model, Fixed(1e-4, 10.0));
  CancelAfterFirstCheck cancel;
  const RunSummary s = integrator.run(Vec<2>(3.0, -1.0), Vec<2>(-1.0, 1.0), &cancel);
  EXPECT_EQ(s.status, RunStatus::kCancelled);
  EXPECT_EQ(s.steps, RunObserver::kControlInterval);
}

}  // namespace
}  // namespace moreau

namespace moreau {
namespace {
// The explicit peer chatters: on the damped relay its velocity never rests at 0.0 but keeps changing
// sign with an amplitude of order h a / m, where the implicit scheme is exactly 0.0.
TEST(AblIntegrator, ExplicitPeerChattersWhereTheImplicitSchemeRests) {
  Oscillator1 model(2.0, 0.0, 0.0, 0.5, 1.0);
  AblSettings settings = Fixed(1e-2, 6.0);
  settings.velocity_update = VelocityUpdate::kExplicit;
  AblIntegrator<Oscillator1> integrator(model, settings);
  Recorder rec;
  const RunSummary s = integrator.run(Vec<1>(0.0), Vec<1>(3.0), &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted);
  int sign_changes = 0;
  double amplitude = 0.0;
  for (std::size_t k = 1; k < rec.v.size(); ++k) {
    if (rec.t[k] < 4.0) continue;  // after the exact stop time t* = 3.665
    if (rec.v[k] * rec.v[k - 1] < 0.0) ++sign_changes;
    amplitude = std::max(amplitude, std::abs(rec.v[k]));
  }
  EXPECT_GT(sign_changes, 100);
  EXPECT_GT(amplitude, 0.0);
  EXPECT_LE(amplitude, 1e-2 * 1.0 / 2.0 * 1.01);  // |V| <= h a / m after the first overshoot
  EXPECT_FALSE(s.converged_step.has_value());
}
}  // namespace
}  // namespace moreau
