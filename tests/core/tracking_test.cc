// Tracking control and its sampled-data laws (core/include/moreau/core/tracking.h) against closed forms:
// the continuous closed loop's reaching-time bounds and exponential decay on the surface, the implicit
// law's finite-step reaching on the nominal model, its O(T_s) band and exact steady state under a constant
// disturbance, the explicit law's chattering amplitude and rate, the boundary layer's discrete pole, the
// one-step problem's closed forms (separable gains, norm term), the Lyapunov decrease of ABL's Theorem 4.2
// carried over to sigma, and the chattering index on hand-made sequences. Every plant here is integrated
// by the test itself (exact or RK4 sub-steps under a zero-order hold), never by the code under test.
#include "moreau/core/tracking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "moreau/core/models/manipulator.h"

namespace moreau {
namespace {

// ---------------------------------------------------------------------------------------------------
// One degree of freedom: m q'' = u + d(t), a reference q_d with its derivatives, and the test's own
// integrator: N sub-steps of h = T_s / N per period with u held, d at each sub-step's midpoint,
//   q += h v + h^2 (u + d) / (2 m),  v += h (u + d) / m,
// exact for constant d (then the plant is integrated exactly) and second order otherwise.

struct Scalar {
  std::function<double(double)> q, v, a;  // q_d, q_d', q_d''
};

Scalar Ramp(double q0, double c) {
  return {[=](double t) { return q0 + c * t; }, [=](double) { return c; }, [](double) { return 0.0; }};
}
Scalar Sine(double amp, double w) {
  return {[=](double t) { return amp * std::sin(w * t); }, [=](double t) { return amp * w * std::cos(w * t); },
          [=](double t) { return -amp * w * w * std::sin(w * t); }};
}

struct Plant1 {
  double m = 1.0;                                                // the true mass
  std::function<double(double)> d = [](double) { return 0.0; };  // the disturbance
};

struct Setup1 {
  Plant1 plant;
  double m_nominal = 1.0;  // the controller's model
  double lambda = 1.0;
  double alpha = 1.0;  // a_1
  double w = 0.0;      // quadratic weight
  double period = 1e-3;
  double layer = 0.0;
  int substeps = 4;
  double t_end = 1.0;
  double q0 = 0.0, v0 = 0.0;
  Scalar ref;
  SampledTrackingLaw law = SampledTrackingLaw::kImplicit;
};

// Per sample k (t_k = k T_s): the test's own e_k and sigma_k from the state, and the controller's output.
struct Trace1 {
  std::vector<double> t, e, sigma, u, selection, predicted;
  std::vector<bool> on_surface, in_layer;
  // sup |sigma(t)| over the sub-steps of each period (the state at every sub-step end).
  std::vector<double> sup_sigma;
};

TrackingGains<1> Gains1(const Setup1& s) {
  TrackingGains<1> g;
  g.lambda = Vec<1>(s.lambda);
  g.phi.weights = Vec<1>(s.w);
  g.phi.gains = Vec<1>(s.alpha);
  g.phi.norm_gain = 0.0;
  g.period = s.period;
  g.boundary_layer = s.layer;
  return g;
}

Trace1 Simulate1(const Setup1& s) {
  const TrackingGains<1> gains = Gains1(s);
  EXPECT_EQ(gains.problem(s.law), "");
  SampledTrackingController<1> ctrl(gains, s.law);
  TrackingStep<1> out;
  out.resize(1);
  LagrangianTerms<1> nominal;
  nominal.resize(1);
  nominal.M(0, 0) = s.m_nominal;
  ReferencePoint<1> now, next;
  now.resize(1);
  next.resize(1);
  Trace1 tr;
  double q = s.q0, v = s.v0;
  const long steps = std::lround(s.t_end / s.period);
  const double h = s.period / s.substeps, m = s.plant.m;
  auto sigma_of = [&](double t, double qq, double vv) { return (vv - s.ref.v(t)) + s.lambda * (qq - s.ref.q(t)); };
  for (long k = 0; k < steps; ++k) {
    const double t = k * s.period;
    now.q(0) = s.ref.q(t), now.v(0) = s.ref.v(t), now.a(0) = s.ref.a(t);
    const double tn = (k + 1) * s.period;
    next.q(0) = s.ref.q(tn), next.v(0) = s.ref.v(tn), next.a(0) = s.ref.a(tn);
    EXPECT_TRUE(ctrl.step(Vec<1>(q), Vec<1>(v), now, next, nominal, out));
    tr.t.push_back(t);
    tr.e.push_back(q - s.ref.q(t));
    tr.sigma.push_back(sigma_of(t, q, v));
    tr.u.push_back(out.u(0));
    tr.selection.push_back(out.selection(0));
    tr.predicted.push_back(out.sigma_predicted(0));
    tr.on_surface.push_back(out.on_surface);
    tr.in_layer.push_back(out.in_boundary_layer);
    const double u = out.u(0);
    double sup = 0.0;
    for (int j = 0; j < s.substeps; ++j) {
      const double ts = t + j * h;
      const double f = (u + s.plant.d(ts + 0.5 * h)) / m;
      q += h * v + 0.5 * h * h * f;
      v += h * f;
      sup = std::max(sup, std::abs(sigma_of(ts + h, q, v)));
    }
    tr.sup_sigma.push_back(sup);
  }
  return tr;
}

// The first sample whose implicit prediction was on the surface, or -1.
long FirstOnSurface(const Trace1& tr) {
  for (std::size_t k = 0; k < tr.on_surface.size(); ++k)
    if (tr.on_surface[k]) return static_cast<long>(k);
  return -1;
}
// The first sample with |sigma_k| <= band, or -1.
long FirstWithin(const Trace1& tr, double band) {
  for (std::size_t k = 0; k < tr.sigma.size(); ++k)
    if (std::abs(tr.sigma[k]) <= band) return static_cast<long>(k);
  return -1;
}

std::vector<double> From(const std::vector<double>& x, long k) { return std::vector<double>(x.begin() + k, x.end()); }

// ---------------------------------------------------------------------------------------------------

TEST(TrackingErrors, DefinitionsOnHandValues) {
  ReferencePoint<2> r;
  r.q = Vec<2>(1.0, -2.0);
  r.v = Vec<2>(0.5, 0.25);
  r.a = Vec<2>(-1.0, 3.0);
  TrackingErrors<2> err;
  err.resize(2);
  tracking_errors(Vec<2>(1.5, -1.0), Vec<2>(0.0, 1.25), r, Vec<2>(2.0, 4.0), err);
  // e = (0.5, 1), e' = (-0.5, 1), sigma = e' + Lambda e = (0.5, 5), v_r = q_d' - Lambda e = (-0.5, -3.75),
  // a_r = q_d'' - Lambda e' = (0, -1).
  EXPECT_EQ(err.e, Vec<2>(0.5, 1.0));
  EXPECT_EQ(err.e_dot, Vec<2>(-0.5, 1.0));
  EXPECT_EQ(err.sigma, Vec<2>(0.5, 5.0));
  EXPECT_EQ(err.v_r, Vec<2>(-0.5, -3.75));
  EXPECT_EQ(err.a_r, Vec<2>(0.0, -1.0));
  // sigma = q' - v_r.
  EXPECT_EQ(err.sigma, Vec<2>(0.0, 1.25) - err.v_r);

  LagrangianTerms<2> nominal;
  nominal.M << 2.0, 1.0, 1.0, 3.0;
  nominal.C << 0.0, 1.0, -1.0, 0.0;
  nominal.g = Vec<2>(0.5, -0.5);
  Vec<2> model;
  continuous_model_part(nominal, err, model);
  // M a_r = (-1, -3), C v_r = (-3.75, 0.5), + g.
  EXPECT_EQ(model, Vec<2>(-1.0 - 3.75 + 0.5, -3.0 + 0.5 - 0.5));
}

TEST(TrackingErrors, TabulatedReferenceIsExactForACubic) {
  // q_d = t^3 - 2 t: the Hermite interpolants of (q, v) and of (v, a) and the linear one of a are exact.
  const double t0 = -0.3, dt = 0.1;
  const int m = 12;
  Eigen::Matrix<double, 1, Eigen::Dynamic> q(1, m), v(1, m), a(1, m);
  for (int j = 0; j < m; ++j) {
    const double t = t0 + j * dt;
    q(0, j) = t * t * t - 2.0 * t;
    v(0, j) = 3.0 * t * t - 2.0;
    a(0, j) = 6.0 * t;
  }
  TabulatedReference<1> ref(t0, dt, q, v, a);
  ASSERT_TRUE(ref.valid());
  ReferencePoint<1> r;
  r.resize(1);
  for (const double t : {-0.3, 0.0, 0.37, 0.51, 0.8}) {
    ASSERT_TRUE(ref.at(t, r)) << t;
    EXPECT_NEAR(r.q(0), t * t * t - 2.0 * t, 1e-14) << t;
    EXPECT_NEAR(r.v(0), 3.0 * t * t - 2.0, 1e-14) << t;
    EXPECT_NEAR(r.a(0), 6.0 * t, 1e-14) << t;
  }
  EXPECT_FALSE(ref.at(-0.31, r));
  EXPECT_FALSE(ref.at(0.81, r));

  CallableReference<1, std::function<void(double, ReferencePoint<1>&)>> f([](double t, ReferencePoint<1>& out) {
    out.q(0) = t;
    out.v(0) = 1.0;
    out.a(0) = 0.0;
  });
  ASSERT_TRUE(f.at(2.5, r));
  EXPECT_EQ(r.q(0), 2.5);
}

TEST(TrackingErrors, GainsAreValidated) {
  TrackingGains<1> g;
  g.lambda = Vec<1>(1.0);
  g.phi = Controller<1>::zero(1);
  g.period = 1e-3;
  EXPECT_EQ(g.problem(SampledTrackingLaw::kImplicit), "");
  EXPECT_NE(g.problem(SampledTrackingLaw::kSaturated), "");  // no layer width
  g.lambda = Vec<1>(0.0);
  EXPECT_NE(g.problem(SampledTrackingLaw::kExplicit), "");
  g.lambda = Vec<1>(1.0);
  g.period = 0.0;
  EXPECT_NE(g.problem(SampledTrackingLaw::kImplicit), "");
}

// ---------------------------------------------------------------------------------------------------
// The continuous closed loop, m sigma' = -a sgn(sigma) + d, |d| <= D < a, seen through a fine T_s: sigma
// reaches 0 at t_r with m |sigma(0)| / (a + D) <= t_r <= m |sigma(0)| / (a - D).

Setup1 ReachingSetup(SampledTrackingLaw law, double period) {
  Setup1 s;
  s.plant.m = 2.0;
  s.m_nominal = 2.0;
  const double D = 1.0;
  s.plant.d = [D](double t) { return D * std::sin(3.0 * t + 0.3); };
  s.lambda = 4.0;
  s.alpha = 3.0;
  s.period = period;
  s.t_end = 4.0;
  s.ref = Sine(0.5, 2.0);
  // e(0) = 0.2, e'(0) = 1.2: sigma(0) = 1.2 + 4 * 0.2 = 2.
  s.q0 = s.ref.q(0.0) + 0.2;
  s.v0 = s.ref.v(0.0) + 1.2;
  s.law = law;
  return s;
}

TEST(TrackingContinuous, ReachingTimeWithinTheBounds) {
  const double m = 2.0, sigma0 = 2.0, a = 3.0, D = 1.0, Ts = 1e-5;
  const double upper = m * sigma0 / (a - D), lower = m * sigma0 / (a + D);  // 2 s and 1 s
  for (const auto law : {SampledTrackingLaw::kImplicit, SampledTrackingLaw::kExplicit}) {
    const Trace1 tr = Simulate1(ReachingSetup(law, Ts));
    EXPECT_DOUBLE_EQ(tr.sigma[0], sigma0);
    // Reached: within the explicit law's chattering band (a + D) T_s / m of 0.
    const long k = FirstWithin(tr, (a + D) * Ts / m);
    ASSERT_GE(k, 0) << sampled_tracking_law_name(law);
    const double tr_measured = tr.t[k];
    EXPECT_LE(tr_measured, upper * (1.0 + 1e-3) + Ts) << sampled_tracking_law_name(law);
    EXPECT_GE(tr_measured, lower * (1.0 - 1e-3)) << sampled_tracking_law_name(law);
    if (law == SampledTrackingLaw::kImplicit) {
      // The solver's first prediction on the surface is the sample before (|sigma_k| <= a T_s / m).
      EXPECT_NEAR(static_cast<double>(FirstOnSurface(tr)), static_cast<double>(k), 1.0);
    }
  }
}

TEST(TrackingContinuous, ReachingTimeWithAQuadraticTermIsTheClosedForm) {
  // d = 0, Phi = w/2 s^2 + a |s|: m s' = -w s - a, so t_r = (m / w) ln(1 + w |s(0)| / a) exactly.
  Setup1 s = ReachingSetup(SampledTrackingLaw::kImplicit, 1e-5);
  s.plant.d = [](double) { return 0.0; };
  s.w = 1.5;
  const double m = 2.0, sigma0 = 2.0, a = 3.0, w = 1.5;
  const double expected = (m / w) * std::log(1.0 + w * sigma0 / a);
  const Trace1 tr = Simulate1(s);
  const long k = FirstOnSurface(tr);
  ASSERT_GE(k, 0);
  // On the surface at the sample after k; the step's O(T_s^2) hold terms add O(T_s) over the reach.
  EXPECT_NEAR(tr.t[k] + s.period, expected, 2e-3 * expected);
}

TEST(TrackingContinuous, ReachingBoundWithAMassMismatch) {
  // Controller mass 1.8, plant 2: m sigma' = -a sgn(sigma) + d + (m^ - m) a_r, so D becomes
  // D + |m^ - m| sup |a_r| (a_r = q_d'' - Lambda e' from the test's own state).
  Setup1 s = ReachingSetup(SampledTrackingLaw::kImplicit, 1e-5);
  s.m_nominal = 1.8;
  s.alpha = 6.0;
  const Trace1 tr = Simulate1(s);
  const long k = FirstOnSurface(tr);
  ASSERT_GE(k, 0);
  double sup_ar = 0.0;
  for (long j = 0; j <= k; ++j) {
    const double t = tr.t[j];
    const double e_dot = tr.sigma[j] - s.lambda * tr.e[j];
    sup_ar = std::max(sup_ar, std::abs(s.ref.a(t) - s.lambda * e_dot));
  }
  const double D_eff = 1.0 + 0.2 * sup_ar;
  ASSERT_LT(D_eff, s.alpha);
  EXPECT_LE(tr.t[k], 2.0 * 2.0 / (s.alpha - D_eff) * (1.0 + 1e-3) + s.period);
}

TEST(TrackingContinuous, ErrorDecaysAsExpMinusLambdaTAfterReaching) {
  // On the surface e' = -Lambda e + sigma, so |e(t) - e(t_r) exp(-Lambda (t - t_r))| <= sup |sigma| / Lambda.
  const Setup1 s = ReachingSetup(SampledTrackingLaw::kImplicit, 1e-4);
  const Trace1 tr = Simulate1(s);
  const long k = FirstOnSurface(tr) + 1;
  ASSERT_GT(k, 0);
  double delta = 0.0;
  for (std::size_t j = k; j < tr.sup_sigma.size(); ++j) delta = std::max({delta, tr.sup_sigma[j], std::abs(tr.sigma[j])});
  // delta is O(T_s): the band of the implicit law (TrackingImplicit below), with the hold's excursion.
  EXPECT_LT(delta, 4.0 * (1.0 + 3.0) * s.period / 2.0);
  const double er = tr.e[k];
  ASSERT_GT(std::abs(er), 0.03);  // a visible decay
  ASSERT_LT(tr.t[k], 2.5);
  for (std::size_t j = k; j < tr.e.size(); j += (j + 100 < tr.e.size() ? 100 : 1)) {
    const double expected = er * std::exp(-s.lambda * (tr.t[j] - tr.t[k]));
    EXPECT_LE(std::abs(tr.e[j] - expected), 1.01 * delta / s.lambda + 1e-12) << tr.t[j];
  }
}

// ---------------------------------------------------------------------------------------------------
// The implicit law.

TEST(TrackingImplicit, FiniteStepReachingOnTheNominalModel) {
  // Plant = the nominal Euler model, m (v_{k+1} - v_k) / T_s = u_k, q_{k+1} = q_k + T_s v_k, d = 0. The
  // one-step problem is then the plant's own step: sigma_{k+1} = sigma_k - a T_s sgn(sigma_k) / m while
  // |sigma_k| > a T_s / m, then exactly 0.0, from step k* = ceil(m |sigma_0| / (a T_s)) - 1 on.
  const double m = 1.0, a = 2.0, Ts = 0.01, lambda = 3.0;
  const Scalar ref = Ramp(0.5, 0.2);
  TrackingGains<1> g;
  g.lambda = Vec<1>(lambda);
  g.phi = Controller<1>::zero(1);
  g.phi.gains = Vec<1>(a);
  g.period = Ts;
  SampledTrackingController<1> ctrl(g, SampledTrackingLaw::kImplicit);
  TrackingStep<1> out;
  out.resize(1);
  LagrangianTerms<1> nominal;
  nominal.resize(1);
  nominal.M(0, 0) = m;
  ReferencePoint<1> now, next;
  now.resize(1);
  next.resize(1);
  double q = 0.5 + 0.01, v = 0.2 + 0.2737;  // sigma_0 = 0.2737 + 3 * 0.01 = 0.3037
  const double sigma0 = 0.3037;
  const long k_star = static_cast<long>(std::ceil(m * sigma0 / (a * Ts))) - 1;  // 15.185 -> 15
  ASSERT_EQ(k_star, 15);
  for (long k = 0; k < 60; ++k) {
    const double t = k * Ts, tn = (k + 1) * Ts;
    now.q(0) = ref.q(t), now.v(0) = ref.v(t), now.a(0) = 0.0;
    next.q(0) = ref.q(tn), next.v(0) = ref.v(tn), next.a(0) = 0.0;
    ASSERT_TRUE(ctrl.step(Vec<1>(q), Vec<1>(v), now, next, nominal, out));
    EXPECT_TRUE(out.condition_holds());
    if (k < k_star) {
      EXPECT_FALSE(out.on_surface) << k;
      EXPECT_NEAR(out.sigma_predicted(0), sigma0 - (k + 1) * a * Ts / m, 1e-12) << k;
      EXPECT_NEAR(out.selection(0), a, 1e-12) << k;  // a Sgn(sigma_{k+1}) with sigma_{k+1} > 0
    } else {
      EXPECT_TRUE(out.on_surface) << k;
      EXPECT_EQ(out.sigma_predicted(0), 0.0) << k;  // exactly, from the solver's closed form
      EXPECT_EQ(out.pattern(0), 0) << k;
      EXPECT_LE(std::abs(out.selection(0)), a) << k;  // in a [-1, 1] = dPhi(0)
    }
    // The plant's step, then sigma_{k+1} from the state: the prediction, to round-off.
    const double v_next = v + Ts * out.u(0) / m;
    q += Ts * v;
    v = v_next;
    const double sigma_next = (v - ref.v(tn)) + lambda * (q - ref.q(tn));
    EXPECT_NEAR(sigma_next, out.sigma_predicted(0), 1e-12) << k;
  }
}

TEST(TrackingImplicit, SlidingBandIsOrderTsUnderABoundedDisturbance) {
  // After reaching, sigma(t_{k+1}) = sigma_{k+1}^pred + (1/m) int d + (Lambda/m) int (t_{k+1} - s)(u_k + d) ds
  // (docs/tracking.md), so on the surface |sigma(t_{k+1})| <= T_s D / m + Lambda T_s^2 (|u_k| + D) / (2 m).
  double band[2];
  for (int r = 0; r < 2; ++r) {
    const double Ts = r == 0 ? 2e-3 : 1e-3;
    const Setup1 s = ReachingSetup(SampledTrackingLaw::kImplicit, Ts);
    const double m = 2.0, D = 1.0;
    const Trace1 tr = Simulate1(s);
    const long k0 = FirstOnSurface(tr);
    ASSERT_GE(k0, 0);
    band[r] = 0.0;
    int checked = 0;
    for (std::size_t k = k0; k + 1 < tr.sigma.size(); ++k) {
      if (!tr.on_surface[k]) continue;
      ++checked;
      const double bound = Ts * D / m + s.lambda * Ts * Ts * (std::abs(tr.u[k]) + D) / (2.0 * m);
      EXPECT_LE(std::abs(tr.sigma[k + 1]), bound * (1.0 + 1e-9) + 1e-15) << k;
      band[r] = std::max(band[r], std::abs(tr.sigma[k + 1]));
    }
    // Once on the surface it stays: every later prediction is on it (|sigma_k| <= a T_s / m needs only D < a).
    EXPECT_EQ(checked, static_cast<int>(tr.sigma.size()) - 1 - k0);
  }
  // Order one in T_s.
  EXPECT_GT(band[0] / band[1], 1.8);
  EXPECT_LT(band[0] / band[1], 2.2);
}

// The constant-disturbance configuration shared by the implicit, explicit and saturated laws: m = 1,
// a = 2, Lambda = 5, T_s = 1 ms, d = D0 = -0.6, a ramp q_d = 0.5 + 0.2 t, sigma(0) = 1.
Setup1 ConstantDisturbance(SampledTrackingLaw law, double layer = 0.0) {
  Setup1 s;
  s.plant.m = 1.0;
  s.m_nominal = 1.0;
  s.plant.d = [](double) { return -0.6; };
  s.lambda = 5.0;
  s.alpha = 2.0;
  s.period = 1e-3;
  s.layer = layer;
  s.t_end = 6.0;
  s.ref = Ramp(0.5, 0.2);
  s.q0 = 0.5;
  s.v0 = 1.2;
  s.law = law;
  return s;
}

TEST(TrackingImplicit, ConstantDisturbanceExactSteadyStateAndNoChattering) {
  // On the surface with constant d = D0 the fixed point is q'' = 0, u = -D0, sigma = D0 T_s / m and
  // e = D0 T_s / (m Lambda) (docs/tracking.md): a constant offset of order T_s, and no switching.
  const double m = 1.0, D0 = -0.6, Ts = 1e-3, lambda = 5.0;
  const Trace1 tr = Simulate1(ConstantDisturbance(SampledTrackingLaw::kImplicit));
  const long k0 = FirstOnSurface(tr);
  ASSERT_GE(k0, 0);
  // Reaching: m sigma' = -a + D0 = -2.6 from sigma(0) = 1.
  EXPECT_NEAR(tr.t[k0], 1.0 / 2.6, 0.01);
  const long last = static_cast<long>(tr.u.size()) - 1;
  EXPECT_NEAR(tr.sigma[last], D0 * Ts / m, 1e-12);
  EXPECT_NEAR(tr.u[last], -D0, 1e-9);
  EXPECT_NEAR(tr.e[last], D0 * Ts / (m * lambda), 1e-12);
  EXPECT_NEAR(tr.selection[last], D0, 1e-9);  // xi = m sigma_k / T_s, a linear feedback of size |D0|
  // Chattering index 0 from the first sample on the surface on.
  const ChatteringIndex c = chattering_index(From(tr.u, k0 + 1), Ts);
  EXPECT_EQ(c.sign_changes, 0);
  EXPECT_EQ(c.per_second, 0.0);
  // u settles without oscillating: its total variation is its net change, but for the first samples'
  // O(Lambda T_s) correction.
  EXPECT_LE(c.total_variation, std::abs(tr.u[last] - tr.u[k0 + 1]) + 0.05);
  // Every prediction from k0 on is on the surface, with sigma_{k+1}^pred exactly 0.0.
  for (std::size_t k = k0; k < tr.u.size(); ++k) {
    ASSERT_TRUE(tr.on_surface[k]) << k;
    ASSERT_EQ(tr.predicted[k], 0.0) << k;
  }
}

TEST(TrackingExplicit, ChattersWithAmplitudeOfOrderAlphaTsOverM) {
  // Explicit: sigma_{k+1} ~ sigma_k + T_s (D0 - a sgn(sigma_k)) / m: steps of -A = -(a + |D0|) T_s / m
  // from sigma >= 0 and +B = (a - |D0|) T_s / m from sigma < 0 (D0 < 0). The orbit stays in [-B, A), so
  // peak-to-peak sigma is in [A, A + B] = [(a + |D0|), 2 a] T_s / m; runs of one sign last at most
  // ceil(A/B) and ceil(B/A) samples, so u changes sign at least 2 / ((ceil(A/B) + ceil(B/A)) T_s) times a
  // second, and at most once a sample.
  const double m = 1.0, a = 2.0, D0 = 0.6, Ts = 1e-3;
  const Trace1 tr = Simulate1(ConstantDisturbance(SampledTrackingLaw::kExplicit));
  const double A = (a + D0) * Ts / m, B = (a - D0) * Ts / m;
  const long k0 = FirstWithin(tr, A);
  ASSERT_GE(k0, 0);
  EXPECT_NEAR(tr.t[k0], 1.0 / 2.6, 0.01);
  const long from = static_cast<long>(tr.u.size()) - 2000;  // the last 2 s
  ASSERT_GT(from, k0);
  const ChatteringIndex cu = chattering_index(From(tr.u, from), Ts);
  const double min_rate = 2.0 / ((std::ceil(A / B) + std::ceil(B / A)) * Ts);  // 667 per second
  EXPECT_GE(cu.per_second, 0.95 * min_rate);
  EXPECT_LE(cu.per_second, 1.0 / Ts);
  // u switches between about +a and -a.
  EXPECT_GT(cu.peak_to_peak, 2.0 * a * 0.95);
  const ChatteringIndex cs = chattering_index(From(tr.sigma, from), Ts);
  EXPECT_GE(cs.peak_to_peak, 0.95 * A);
  EXPECT_LE(cs.peak_to_peak, 1.05 * (A + B));
  EXPECT_EQ(cs.sign_changes, cu.sign_changes);  // u = -a sgn(sigma_k) + O(Lambda T_s)

  // The implicit law in the same configuration: no sign change, and a total variation far below.
  const Trace1 im = Simulate1(ConstantDisturbance(SampledTrackingLaw::kImplicit));
  const ChatteringIndex ci = chattering_index(From(im.u, from), Ts);
  EXPECT_EQ(ci.sign_changes, 0);
  EXPECT_LT(ci.total_variation * 1e4, cu.total_variation);
  EXPECT_LT(chattering_index(From(im.sigma, from), Ts).peak_to_peak, 1e-12);
}

TEST(TrackingSaturated, BoundaryLayerPoleDecidesBetweenSmoothAndChattering) {
  // Inside the layer u = -m Lambda e' - a sigma / phi: the discrete pole is 1 - a T_s / (m phi). With
  // phi = 4 a T_s / m (pole 3/4) sigma settles at phi D0 / a, where u = -D0, without switching; with
  // phi = a T_s / (4 m) (pole -3) the layer is unstable and u chatters like the explicit law.
  const double m = 1.0, a = 2.0, D0 = -0.6, Ts = 1e-3;
  const double thick = 4.0 * a * Ts / m, thin = a * Ts / (4.0 * m);
  const Trace1 smooth = Simulate1(ConstantDisturbance(SampledTrackingLaw::kSaturated, thick));
  const long from = static_cast<long>(smooth.u.size()) - 2000;
  const ChatteringIndex cs = chattering_index(From(smooth.u, from), Ts);
  EXPECT_EQ(cs.sign_changes, 0);
  EXPECT_NEAR(smooth.sigma.back(), thick * D0 / a, 1e-9);
  EXPECT_NEAR(smooth.u.back(), -D0, 1e-6);
  EXPECT_TRUE(smooth.in_layer.back());

  const Trace1 chatter = Simulate1(ConstantDisturbance(SampledTrackingLaw::kSaturated, thin));
  const ChatteringIndex cc = chattering_index(From(chatter.u, from), Ts);
  EXPECT_GT(cc.per_second, 0.5 / Ts);
  EXPECT_GT(cc.total_variation, 1e3 * cs.total_variation);
}

// ---------------------------------------------------------------------------------------------------
// The one-step problem's closed forms with n = 2, M^ = m I, C^ = 0, g^ = 0.

// Gains for two coordinates: Lambda = lambda I, Phi = 1/2 sum w_i s_i^2 + sum a_i |s_i| + a_norm ||s||.
TrackingGains<2> Gains2(double lambda, const Vec<2>& w, const Vec<2>& a, double a_norm, double Ts) {
  TrackingGains<2> g;
  g.lambda = Vec<2>(lambda, lambda);
  g.phi.weights = w;
  g.phi.gains = a;
  g.phi.norm_gain = a_norm;
  g.period = Ts;
  return g;
}

// The implicit controller with the nominal model M^ = m I, C^ = 0, g^ = 0, its output and two
// reference points, all sized (q_d = 0 unless a test sets it).
struct Implicit2 {
  Implicit2(const TrackingGains<2>& g, double m) : ctrl(g, SampledTrackingLaw::kImplicit) {
    out.resize(2);
    nominal.resize(2);
    nominal.M = m * Mat<2>::Identity();
    now.resize(2);
    next.resize(2);
  }
  SampledTrackingController<2> ctrl;
  TrackingStep<2> out;
  LagrangianTerms<2> nominal;
  ReferencePoint<2> now, next;
};

TEST(TrackingImplicit, SeparableGainsSoftThresholdPerComponent) {
  // P = (m / T_s + w) I, x = -m sigma_k / T_s: y_i = 0 when m |sigma_i| / T_s <= a_i, else
  // y_i = sign(sigma_i) (m |sigma_i| / T_s - a_i) / (m / T_s + w_i).
  const double m = 2.0, Ts = 0.01;
  Implicit2 c(Gains2(1.0, Vec<2>(0.5, 0.5), Vec<2>(1.0, 4.0), 0.0, Ts), m);
  TrackingStep<2>& out = c.out;
  // q = q_d = 0, v = sigma_k = (0.03, -0.015): m |sigma| / T_s = (6, 3) against a = (1, 4).
  const Vec<2> sigma(0.03, -0.015);
  ASSERT_TRUE(c.ctrl.step(Vec<2>::Zero(), sigma, c.now, c.next, c.nominal, out));
  const double p = m / Ts + 0.5;
  EXPECT_FALSE(out.on_surface);
  EXPECT_NEAR(out.sigma_predicted(0), (6.0 - 1.0) / p, 1e-15);
  EXPECT_EQ(out.sigma_predicted(1), 0.0);  // at rest: exactly
  EXPECT_EQ(out.pattern(1), 0);
  EXPECT_EQ(out.pattern(0), 1);
  // xi = W y + A Sgn(y): (0.5 y_0 + 1, multiplier of the resting component = m sigma_1 / T_s = -3).
  EXPECT_NEAR(out.selection(0), 0.5 * out.sigma_predicted(0) + 1.0, 1e-13);
  EXPECT_NEAR(out.selection(1), -3.0, 1e-13);
  // Model part: v_r,k = 0 (e = 0), e_{k+1} = T_s v_k, v_r,k+1 = -T_s v_k: M^ (v_r,k+1 - v_r,k) / T_s = -m v_k.
  EXPECT_NEAR(out.u_model(0), -m * sigma(0), 1e-15);
  EXPECT_NEAR(out.u_model(1), -m * sigma(1), 1e-15);
  EXPECT_EQ(out.u, out.u_model - out.selection);
}

TEST(TrackingImplicit, DynamicSizeGivesTheFixedSizeResult) {
  // The same sample with N = Eigen::Dynamic (robot arms beyond the fixed sizes) and N = 3, a full M^ and
  // a nonzero C^ (the semismooth Newton path of the solver).
  Mat<3> M;
  M << 2.0, 0.3, 0.1, 0.3, 1.5, -0.2, 0.1, -0.2, 1.0;
  Mat<3> C;
  C << 0.0, 0.4, -0.1, -0.3, 0.0, 0.2, 0.1, -0.2, 0.0;
  const Vec<3> g_vec(0.1, -0.2, 0.3), q(0.1, 0.2, -0.1), v(0.5, -0.4, 0.02);
  TrackingGains<3> g3;
  g3.lambda = Vec<3>(1.0, 2.0, 3.0);
  g3.phi.weights = Vec<3>(0.5, 0.0, 1.0);
  g3.phi.gains = Vec<3>(1.0, 2.0, 40.0);
  g3.period = 0.01;
  TrackingGains<Eigen::Dynamic> gd;
  gd.lambda = g3.lambda;
  gd.phi.weights = g3.phi.weights;
  gd.phi.gains = g3.phi.gains;
  gd.period = g3.period;
  SampledTrackingController<3> c3(g3, SampledTrackingLaw::kImplicit);
  SampledTrackingController<Eigen::Dynamic> cd(gd, SampledTrackingLaw::kImplicit);
  LagrangianTerms<3> n3{M, C, g_vec};
  LagrangianTerms<Eigen::Dynamic> nd{M, C, g_vec};
  ReferencePoint<3> r3, r3n;
  ReferencePoint<Eigen::Dynamic> rd, rdn;
  r3.resize(3);
  r3n.resize(3);
  rd.resize(3);
  rdn.resize(3);
  r3n.q = Vec<3>(0.01, 0.0, -0.01);
  rdn.q = r3n.q;
  TrackingStep<3> o3;
  TrackingStep<Eigen::Dynamic> od;
  o3.resize(3);
  od.resize(3);
  ASSERT_TRUE(c3.step(q, v, r3, r3n, n3, o3));
  ASSERT_TRUE(cd.step(Eigen::VectorXd(q), Eigen::VectorXd(v), rd, rdn, nd, od));
  EXPECT_NEAR((Eigen::VectorXd(o3.u) - od.u).norm(), 0.0, 1e-12);
  EXPECT_NEAR((Eigen::VectorXd(o3.sigma_predicted) - od.sigma_predicted).norm(), 0.0, 1e-14);
  EXPECT_EQ(o3.on_surface, od.on_surface);
  // The third component rests (a_3 = 40 is large): exactly 0.0, in both.
  EXPECT_EQ(o3.sigma_predicted(2), 0.0);
  EXPECT_EQ(od.sigma_predicted(2), 0.0);
  EXPECT_EQ(o3.pattern(2), 0);
  EXPECT_NE(o3.sigma_predicted(0), 0.0);
  // The inclusion itself: xi - W y in A Sgn(y), componentwise.
  const Vec<3> w = o3.selection - g3.phi.weights.cwiseProduct(o3.sigma_predicted);
  for (int i = 0; i < 3; ++i) {
    if (o3.sigma_predicted(i) == 0.0)
      EXPECT_LE(std::abs(w(i)), g3.phi.gains(i) * (1.0 + 1e-12)) << i;
    else
      EXPECT_NEAR(w(i), g3.phi.gains(i) * (o3.sigma_predicted(i) > 0.0 ? 1.0 : -1.0), 1e-12) << i;
  }
}

TEST(TrackingImplicit, NormTermShrinksTheBall) {
  // phi = a_n ||.||: y = 0 when ||x|| = m ||sigma_k|| / T_s <= a_n, else y = (sigma_k / ||sigma_k||)
  // (m ||sigma_k|| / T_s - a_n) / (m / T_s + w).
  const double m = 1.0, Ts = 0.01, an = 3.0, w = 0.5;
  Implicit2 c(Gains2(2.0, Vec<2>(w, w), Vec<2>::Zero(), an, Ts), m);
  TrackingStep<2>& out = c.out;

  const Vec<2> inside(0.012, -0.016);  // ||.|| = 0.02: m ||sigma|| / T_s = 2 <= 3
  ASSERT_TRUE(c.ctrl.step(Vec<2>::Zero(), inside, c.now, c.next, c.nominal, out));
  EXPECT_TRUE(out.on_surface);
  EXPECT_EQ(out.sigma_predicted, Vec<2>::Zero());
  EXPECT_NEAR((out.selection - m * inside / Ts).norm(), 0.0, 1e-13);  // xi = M^ sigma_k / T_s, in a_n B

  const Vec<2> outside(0.06, 0.08);  // ||.|| = 0.1: 10 > 3
  ASSERT_TRUE(c.ctrl.step(Vec<2>::Zero(), outside, c.now, c.next, c.nominal, out));
  EXPECT_FALSE(out.on_surface);
  const Vec<2> expected = (outside / 0.1) * ((10.0 - an) / (m / Ts + w));
  EXPECT_NEAR((out.sigma_predicted - expected).norm(), 0.0, 1e-13);
  // xi = w y + a_n y / ||y||.
  const Vec<2> xi = w * expected + an * expected / expected.norm();
  EXPECT_NEAR((out.selection - xi).norm(), 0.0, 1e-12);
}

// ---------------------------------------------------------------------------------------------------
// Two degrees of freedom: the manipulator of ABL section 6 as plant and nominal model.

struct Manip {
  models::Manipulator model;
  LagrangianTerms<2> terms;
  Manip() { terms.resize(2); }
  void at(double t, const Vec<2>& q, const Vec<2>& v) { model.evaluate(t, q, v, terms); }
};

void ManipReference(double t, ReferencePoint<2>& r) {
  r.q = Vec<2>(0.3 * std::sin(t), 0.5 * std::cos(1.5 * t));
  r.v = Vec<2>(0.3 * std::cos(t), -0.75 * std::sin(1.5 * t));
  r.a = Vec<2>(-0.3 * std::sin(t), -1.125 * std::cos(1.5 * t));
}

TEST(TrackingImplicit, NominalManipulatorLoopIsSchemeZeroTwoInSigma) {
  // Plant = the nominal Euler model M(q_k)(v_{k+1} - v_k)/T_s + C(q_k, v_k) v_{k+1} + g(q_k) = u_k,
  // q_{k+1} = q_k + T_s v_k. Then: sigma_{k+1} from the state is the prediction; on_surface means
  // exactly 0.0; and E_k = 1/2 sigma_k^T M(q_k) sigma_k decreases as in ABL's Theorem 4.2, (4.12)-(4.13),
  // with grad V + F = 0: E_{k+1} - E_k <= -T_s alpha ||sigma_{k+1}|| whenever ||eps_k||_2 <= 2 eta
  // (eps_k of (4.9) at V^k = v_k, eta = min w / 2); and sigma reaches 0 in finitely many steps (Thm 4.3).
  const double Ts = 2e-3;
  SampledTrackingController<2> ctrl(Gains2(3.0, Vec<2>(1.0, 1.0), Vec<2>(2.0, 2.0), 0.0, Ts), SampledTrackingLaw::kImplicit);
  TrackingStep<2> out;
  out.resize(2);
  Manip plant;
  ReferencePoint<2> now, next;
  Vec<2> q(0.4, 0.1), v(1.0, -1.5);
  const double eta = 0.5, alpha = 2.0;
  int decreases_checked = 0;
  long first_surface = -1;
  for (long k = 0; k < 2000; ++k) {
    const double t = k * Ts, tn = t + Ts;
    ManipReference(t, now);
    ManipReference(tn, next);
    plant.at(t, q, v);
    ASSERT_TRUE(ctrl.step(q, v, now, next, plant.terms, out)) << k;
    const Vec<2> sigma_k = (v - now.v) + ctrl.gains().lambda.cwiseProduct(q - now.q);
    const double E_k = 0.5 * sigma_k.dot(plant.terms.M * sigma_k);
    const Mat<2> M_k = plant.terms.M, C_k = plant.terms.C;
    // The plant's step.
    const Vec<2> v_next = (M_k / Ts + C_k).lu().solve(out.u - plant.terms.g + M_k * v / Ts);
    const Vec<2> q_next = q + Ts * v;
    const Vec<2> sigma_next = (v_next - next.v) + ctrl.gains().lambda.cwiseProduct(q_next - next.q);
    EXPECT_NEAR((sigma_next - out.sigma_predicted).norm(), 0.0, 1e-11) << k;
    if (out.on_surface) {
      EXPECT_EQ(out.sigma_predicted(0), 0.0);
      EXPECT_EQ(out.sigma_predicted(1), 0.0);
      if (first_surface < 0) first_surface = k;
    } else {
      EXPECT_GT(out.sigma_predicted.norm(), 0.0);
    }
    Mat<2> M_next;
    plant.model.mass(q_next, M_next);
    const Mat<2> eps = (M_next - M_k) / Ts - C_k - C_k.transpose();
    const double eps_norm = Eigen::JacobiSVD<Mat<2>>(eps).singularValues()(0);
    const double E_next = 0.5 * sigma_next.dot(M_next * sigma_next);
    if (eps_norm <= 2.0 * eta) {
      ++decreases_checked;
      EXPECT_LE(E_next - E_k, -Ts * alpha * sigma_next.norm() + 1e-14 * (1.0 + E_k)) << k;
    }
    q = q_next;
    v = v_next;
  }
  EXPECT_GT(decreases_checked, 1900);
  ASSERT_GE(first_surface, 0);
  EXPECT_LT(first_surface * Ts, 3.0);
}

TEST(TrackingImplicit, ManipulatorBandUnderZeroOrderHoldIsOrderTs) {
  // The true (continuous) manipulator under a zero-order hold with a disturbance, integrated by RK4 with
  // 8 sub-steps a period: after reaching, max |sigma_k| is O(T_s): it halves with T_s.
  auto d = [](double t) { return Vec<2>(0.5 * std::sin(t), 0.3 * std::cos(2.0 * t)); };
  double band[2];
  for (int r = 0; r < 2; ++r) {
    const double Ts = r == 0 ? 4e-3 : 2e-3;
    SampledTrackingController<2> ctrl(Gains2(3.0, Vec<2>::Zero(), Vec<2>(3.0, 3.0), 0.0, Ts), SampledTrackingLaw::kImplicit);
    TrackingStep<2> out;
    out.resize(2);
    Manip plant;
    ReferencePoint<2> now, next;
    Vec<2> q(0.4, 0.1), v(1.0, -1.5);
    auto accel = [&](double t, const Vec<2>& qq, const Vec<2>& vv, const Vec<2>& u) {
      plant.at(t, qq, vv);
      return Vec<2>(plant.terms.M.lu().solve(u + d(t) - plant.terms.C * vv - plant.terms.g));
    };
    const long steps = std::lround(4.0 / Ts);
    band[r] = 0.0;
    long reached = -1;
    for (long k = 0; k < steps; ++k) {
      const double t = k * Ts;
      ManipReference(t, now);
      ManipReference(t + Ts, next);
      const Vec<2> sigma_k = (v - now.v) + ctrl.gains().lambda.cwiseProduct(q - now.q);
      if (reached >= 0 && t > 2.5) band[r] = std::max(band[r], sigma_k.cwiseAbs().maxCoeff());
      plant.at(t, q, v);
      ASSERT_TRUE(ctrl.step(q, v, now, next, plant.terms, out));
      EXPECT_TRUE(out.condition_holds());
      if (out.on_surface && reached < 0) reached = k;
      const Vec<2> u = out.u;
      const double h = Ts / 8.0;
      for (int j = 0; j < 8; ++j) {
        const double s = t + j * h;
        const Vec<2> k1v = accel(s, q, v, u), k1q = v;
        const Vec<2> k2v = accel(s + h / 2, q + h / 2 * k1q, v + h / 2 * k1v, u), k2q = v + h / 2 * k1v;
        const Vec<2> k3v = accel(s + h / 2, q + h / 2 * k2q, v + h / 2 * k2v, u), k3q = v + h / 2 * k2v;
        const Vec<2> k4v = accel(s + h, q + h * k3q, v + h * k3v, u), k4q = v + h * k3v;
        q += h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
        v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
      }
    }
    ASSERT_GE(reached, 0);
    ASSERT_LT(reached * Ts, 2.5);
  }
  EXPECT_GT(band[0] / band[1], 1.6);
  EXPECT_LT(band[0] / band[1], 2.5);
}

// ---------------------------------------------------------------------------------------------------

TEST(TrackingChattering, IndexOnHandMadeSequences) {
  const std::vector<double> alternating{1.0, -1.0, 1.0, -1.0};
  ChatteringIndex c = chattering_index(alternating, 0.5);
  EXPECT_EQ(c.sign_changes, 3);
  EXPECT_DOUBLE_EQ(c.per_second, 3.0 / (4 * 0.5));
  EXPECT_DOUBLE_EQ(c.total_variation, 6.0);
  EXPECT_DOUBLE_EQ(c.peak_to_peak, 2.0);

  // Zeros neither break nor make a change: signs + . . + - . - +  ->  2 changes.
  const std::vector<double> with_zeros{1.0, 0.0, 0.0, 2.0, -3.0, 0.0, -1.0, 4.0};
  c = chattering_index(with_zeros, 0.5);
  EXPECT_EQ(c.sign_changes, 2);
  EXPECT_DOUBLE_EQ(c.per_second, 2.0 / (8 * 0.5));
  EXPECT_DOUBLE_EQ(c.total_variation, 1.0 + 0.0 + 2.0 + 5.0 + 3.0 + 1.0 + 5.0);
  EXPECT_DOUBLE_EQ(c.peak_to_peak, 7.0);

  const std::vector<double> monotone{-3.0, -2.0, -1.5, -1.0};
  c = chattering_index(monotone, 1e-3);
  EXPECT_EQ(c.sign_changes, 0);
  EXPECT_DOUBLE_EQ(c.total_variation, 2.0);

  EXPECT_EQ(chattering_index(std::vector<double>{0.0, 0.0}, 1.0).sign_changes, 0);
  EXPECT_EQ(chattering_index(std::vector<double>{}, 1.0).sign_changes, 0);
  EXPECT_EQ(sign_changes(std::vector<double>{-1.0, 0.0, 1.0}), 1);
}

}  // namespace
}  // namespace moreau
