// Lur'e systems with maximal monotone feedback, eq. (4) of Brogliato (2003), integrated by the
// theta-method: finite-time convergence of the first-order relay system (bit-exact zero), the saturation
// and dead-zone decays and the LCS (6) against closed forms derived below (for the continuous system and
// for the discrete recursion itself), the storage function W of Lemma 2, the absolute stability checks
// (Lemmas 1-2), the trajectory columns, and the errors bad scenes get.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "moreau/core/absolute_stability.h"
#include "moreau/core/lure_integrator.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {
namespace {

using nlohmann::json;

json Scene(const std::string& name) { return read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + name); }

struct Recorder : RunObserver {
  std::vector<double> t, x, v, e;
  int n = 0;
  void on_sample(const Sample& s) override {
    n = s.n;
    t.push_back(s.t);
    x.insert(x.end(), s.q, s.q + s.n);
    v.insert(v.end(), s.v, s.v + s.n);
    e.push_back(s.kinetic_energy);
  }
};

struct LureRun {
  LureScene scene;
  RunSummary summary;
  LureDiagnostics diag;
  Recorder rec;
};

LureRun RunLure(json doc) {
  LureRun r{load_lure_scene(doc), {}, {}, {}};
  r.summary = run_lure_scene(r.scene, &r.rec, &r.diag);
  EXPECT_EQ(r.summary.status, RunStatus::kCompleted) << r.summary.message;
  return r;
}

// ---- x' = -x - Sign(x) --------------------------------------------------------------------------------
// Continuous: x(t) = (x0 + 1) e^{-t} - 1 until t* = ln(1 + x0), then 0.
// Discrete (theta = 1): while x_k > h, x_{k+1} = (x_k - h)/(1 + h), i.e. x_k + 1 = (x0 + 1)(1 + h)^{-k};
// the step from x_k <= h lands on y = 0 (the vertical piece), so x_K = 0.0 exactly at
// K = ceil(ln(1 + x0) / ln(1 + h)), and stays 0.0. K h - t* = h (K - t*/ln(1+h)) + t* (h/ln(1+h) - 1)
// lies in [0, h + t* h/2 + O(h^2)) < 2h. Before t*: 0 <= x_k - x(t_k) = (x0 + 1)((1+h)^{-k} - e^{-kh})
// <= (x0 + 1) t e^{-t} h/2 (1 + O(h)) <= (x0 + 1) h / (2e) (1 + O(h)).
TEST(Lure, RelayReachesZeroBitExactlyAtTheDiscreteTimeOfLnOnePlusX0) {
  for (double h : {1e-2, 1e-3, 1e-4}) {
    json doc = Scene("lure-relay.json");
    doc["integrator"]["h"] = h;
    const LureRun r = RunLure(doc);
    const double x0 = r.scene.x0[0];
    const double t_star = std::log(1.0 + x0);
    ASSERT_TRUE(r.summary.converged_step.has_value()) << "h = " << h;
    const auto K = static_cast<std::int64_t>(std::ceil(t_star / std::log1p(h)));
    EXPECT_EQ(*r.summary.converged_step, K) << "h = " << h;
    const double t_rest = *r.summary.converged_time;
    EXPECT_GE(t_rest, t_star);
    EXPECT_LT(t_rest - t_star, 2.0 * h);
    EXPECT_NEAR(t_rest, *r.scene.exact_rest_time, 2.0 * h);
    for (std::size_t k = 0; k < r.rec.t.size(); ++k) {
      const double xk = r.rec.x[k];
      if (static_cast<std::int64_t>(k) >= K) {
        ASSERT_EQ(xk, 0.0) << "k = " << k;  // bit-exact rest, not round-off
        ASSERT_EQ(r.rec.v[k], k == static_cast<std::size_t>(K) ? -r.rec.x[k - 1] / h : 0.0);
        continue;
      }
      // The discrete recursion, to round-off.
      const double discrete = (x0 + 1.0) * std::pow(1.0 + h, -static_cast<double>(k)) - 1.0;
      EXPECT_NEAR(xk, discrete, 1e-12 * (x0 + 1.0)) << "k = " << k;
      // The continuous solution, within the derived first-order bound.
      const double t = r.rec.t[k];
      if (t <= t_star) {
        const double exact = (x0 + 1.0) * std::exp(-t) - 1.0;
        EXPECT_GE(xk - exact, -1e-12);
        EXPECT_LE(xk - exact, (x0 + 1.0) * h / (2.0 * std::exp(1.0)) * (1.0 + 2.0 * h) + 1e-12) << "t = " << t;
      } else {
        EXPECT_LE(xk, h);  // the last steps before the discrete rest
      }
    }
    // Lemma 2 with P = 1: W = x^2/2 non-increasing, and it ends at 0.
    EXPECT_TRUE(r.diag.storage.evaluated);
    EXPECT_TRUE(r.diag.storage.nonincreasing);
    EXPECT_EQ(r.diag.storage.final, 0.0);
    EXPECT_EQ(r.diag.output_rest_step[0], K);
  }
}

// ---- x' = -x - sat(x), sat slope k = 2, limit L = 1 -----------------------------------------------------
// Continuous: x = (x0 + 1) e^{-t} - 1 while x >= L/k, until t1 = ln((x0 + 1)/(L/k + 1)); then
// x = (L/k) e^{-(1+k)(t - t1)}.
// Discrete: x_{k+1} = (x_k - h)/(1 + h) while the result stays >= L/k, i.e. for k < k1 = the number of
// j >= 1 with (x0 + 1)(1+h)^{-j} - 1 >= L/k; after that x_{k+1} = x_k / (1 + (1+k) h) (implicit Euler of
// x' = -(1+k) x).
TEST(Lure, SaturationDecayMatchesTheDiscreteRecursionAndTheClosedForm) {
  std::vector<double> errors;
  const std::vector<double> hs = {1e-2, 1e-3, 1e-4};
  for (double h : hs) {
    json doc = Scene("lure-saturation.json");
    doc["integrator"]["h"] = h;
    const LureRun r = RunLure(doc);
    const double x0 = r.scene.x0[0], k = 2.0, L = 1.0;
    const double t1 = std::log((x0 + 1.0) / (L / k + 1.0));
    const auto k1 = static_cast<std::int64_t>(std::floor(std::log((x0 + 1.0) / (L / k + 1.0)) / std::log1p(h)));
    double max_err = 0.0;
    for (std::size_t j = 0; j < r.rec.t.size(); ++j) {
      const auto jj = static_cast<std::int64_t>(j);
      const double discrete = jj <= k1 ? (x0 + 1.0) * std::pow(1.0 + h, -static_cast<double>(jj)) - 1.0
                                       : ((x0 + 1.0) * std::pow(1.0 + h, -static_cast<double>(k1)) - 1.0) *
                                             std::pow(1.0 + (1.0 + k) * h, -static_cast<double>(jj - k1));
      ASSERT_NEAR(r.rec.x[j], discrete, 1e-12 * (x0 + 1.0)) << "h = " << h << ", step " << j;
      const double t = r.rec.t[j];
      const double exact = t <= t1 ? (x0 + 1.0) * std::exp(-t) - 1.0 : L / k * std::exp(-(1.0 + k) * (t - t1));
      max_err = std::max(max_err, std::abs(r.rec.x[j] - exact));
      // The scene's own exact solution (an expression in t) is the same closed form.
      double slot = t, out = 0.0;
      std::vector<double> scratch(r.scene.exact_tape->scratch_size());
      r.scene.exact_tape->eval(&slot, &out, scratch.data());
      ASSERT_NEAR(out, exact, 1e-12);
    }
    errors.push_back(max_err);
    EXPECT_TRUE(r.diag.storage.nonincreasing);
  }
  // First order: each tenfold smaller step divides the error by about ten.
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double order = std::log10(errors[i - 1] / errors[i]);
    EXPECT_GT(order, 0.9) << "h = " << hs[i];
    EXPECT_LT(order, 1.1) << "h = " << hs[i];
  }
}

// ---- x' = -a x - dz(x), dead zone of half-width d and slope k (a = 1/2, d = 1/2, k = 2) ----------------
// Continuous: x = xe + (x0 - xe) e^{-(a+k) t}, xe = k d/(a+k), until x = d at t1 = ln((x0-xe)/(d-xe))/(a+k);
// then x = d e^{-a (t - t1)}. Discrete: x_{k+1} - xe = (x_k - xe)/(1 + (a+k) h) while the result stays >= d
// (k1 steps), then x_{k+1} = x_k / (1 + a h).
TEST(Lure, DeadZoneDecayMatchesTheDiscreteRecursionAndTheClosedForm) {
  std::vector<double> errors;
  for (double h : {1e-2, 1e-3, 1e-4}) {
    json doc = Scene("lure-dead-zone.json");
    doc["integrator"]["h"] = h;
    const LureRun r = RunLure(doc);
    const double a = 0.5, d = 0.5, k = 2.0, x0 = r.scene.x0[0];
    const double xe = k * d / (a + k);
    const double t1 = std::log((x0 - xe) / (d - xe)) / (a + k);
    const auto k1 = static_cast<std::int64_t>(std::floor(std::log((x0 - xe) / (d - xe)) / std::log1p((a + k) * h)));
    double max_err = 0.0;
    for (std::size_t j = 0; j < r.rec.t.size(); ++j) {
      const auto jj = static_cast<std::int64_t>(j);
      const double phase1 = xe + (x0 - xe) * std::pow(1.0 + (a + k) * h, -static_cast<double>(std::min(jj, k1)));
      const double discrete = jj <= k1 ? phase1 : phase1 * std::pow(1.0 + a * h, -static_cast<double>(jj - k1));
      ASSERT_NEAR(r.rec.x[j], discrete, 1e-12 * x0) << "h = " << h << ", step " << j;
      const double t = r.rec.t[j];
      const double exact = t <= t1 ? xe + (x0 - xe) * std::exp(-(a + k) * t) : d * std::exp(-a * (t - t1));
      max_err = std::max(max_err, std::abs(r.rec.x[j] - exact));
    }
    errors.push_back(max_err);
    EXPECT_TRUE(r.diag.storage.nonincreasing);
    EXPECT_EQ(r.diag.y_l_final[0], 0.0);  // inside the dead zone the feedback is exactly 0
  }
  for (std::size_t i = 1; i < errors.size(); ++i) {
    const double order = std::log10(errors[i - 1] / errors[i]);
    EXPECT_GT(order, 0.9);
    EXPECT_LT(order, 1.1);
  }
}

// theta = 1/2 is second order where the feedback is locally constant (the multiplier is implicit, the
// linear part theta-weighted): the saturation's first phase, x' = -x - 1, for t <= 0.9 < t1 = ln(8/3).
TEST(Lure, ThetaOneHalfIsSecondOrderWhereTheFeedbackIsConstant) {
  std::vector<double> errors;
  for (double h : {1e-2, 1e-3}) {
    json doc = Scene("lure-saturation.json");
    doc["integrator"]["h"] = h;
    doc["integrator"]["theta"] = 0.5;
    doc["integrator"]["t_end"] = 0.9;
    const LureRun r = RunLure(doc);
    const double x0 = 3.0;
    errors.push_back(std::abs(r.summary.q_final[0] - ((x0 + 1.0) * std::exp(-0.9) - 1.0)));
  }
  EXPECT_GT(std::log10(errors[0] / errors[1]), 1.9);
}

// ---- the LCS (6) ----------------------------------------------------------------------------------------
// A = [[0, 1], [-2, -3]] (eigenvalues -1, -2), x0 = (1, -0.4) = 1.6 (1, -1) - 0.6 (1, -2). Free motion:
// y = x1 + 2 x2 = -1.6 e^{-t} + 1.8 e^{-2t}, which reaches 0 at tc = ln(9/8); then y == 0 with
// lambda = -CAx/CB = 3/2 |x2| >= 0, x1 = -2 x2 and x2' = -x2/2, x2(tc) = -1.6 (8/9) + 1.2 (8/9)^2.
// Discrete on the constraint: x1+ = x1 + h x2+ and x1+ = -2 x2+ give x2+ = x2 / (1 + h/2).
TEST(Lure, LinearComplementaritySystemStaysOnTheConstraintWithTheClosedFormDecay) {
  std::vector<double> errors;
  for (double h : {1e-3, 1e-4}) {
    json doc = Scene("lure-lcs.json");
    doc["integrator"]["h"] = h;
    const LureRun r = RunLure(doc);
    const double tc = std::log(9.0 / 8.0);
    ASSERT_GE(r.diag.output_rest_step[0], 0);
    const double t_contact = r.diag.output_rest_time[0];
    EXPECT_GE(t_contact, tc - 1e-12);
    EXPECT_LE(t_contact, tc + 2.0 * h);
    const double x2c = -1.6 * (8.0 / 9.0) + 1.2 * (8.0 / 9.0) * (8.0 / 9.0);
    const auto kc = static_cast<std::size_t>(r.diag.output_rest_step[0]);
    double max_err = 0.0;
    for (std::size_t k = kc; k < r.rec.t.size(); ++k) {
      const double x1 = r.rec.x[2 * k], x2 = r.rec.x[2 * k + 1];
      EXPECT_LE(std::abs(x1 + 2.0 * x2), 1e-15) << "y = C x stays 0 (k = " << k << ")";
      if (k > kc) {
        EXPECT_NEAR(x2, r.rec.x[2 * (k - 1) + 1] / (1.0 + h / 2.0), 1e-15);
      }
      max_err = std::max(max_err, std::abs(x2 - x2c * std::exp(-(r.rec.t[k] - tc) / 2.0)));
    }
    errors.push_back(max_err);
    EXPECT_LE(r.diag.y_l_final[0], 0.0);  // y_L = -lambda, lambda >= 0
    EXPECT_TRUE(r.scene.p_check.all());
    EXPECT_TRUE(r.diag.storage.nonincreasing);
  }
  EXPECT_GT(std::log10(errors[0] / errors[1]), 0.9);  // first order
}

// ---- two-state relay: Lemma 2 and the trajectory columns ------------------------------------------------
TEST(Lure, TwoStateRelaySlidesExactlyOnYZeroAndItsStorageFunctionDecreases) {
  const LureRun r = RunLure(Scene("lure-relay-2state.json"));
  EXPECT_EQ(r.scene.spr.spr, Verdict::kHolds);
  ASSERT_TRUE(r.scene.spr.storage_found()) << r.scene.spr.storage_method;
  EXPECT_EQ(r.scene.storage_source, "found");
  EXPECT_TRUE(r.diag.storage.nonincreasing);
  EXPECT_LT(r.diag.storage.final, 1e-3 * r.diag.storage.initial);
  // y reaches 0 in finite time and stays exactly 0 (sliding).
  ASSERT_GE(r.diag.output_rest_step[0], 0);
  EXPECT_LT(r.diag.output_rest_time[0], 1.0);
  EXPECT_EQ(r.diag.y_final[0], 0.0);
  // Velocities are the discrete derivative; row 0 is A x0 - B w0 with w0 = Sign(y0) = 1 (y0 = 1).
  const int n = 2;
  const double h = r.scene.settings.h;
  EXPECT_EQ(r.rec.v[0], 0.0);         // (A x0)_1 = x2 = 0
  EXPECT_EQ(r.rec.v[1], -2.0 - 1.0);  // (A x0)_2 - 1 = -2 - 1
  for (std::size_t k = 1; k < r.rec.t.size(); k += 37)
    for (int i = 0; i < n; ++i) EXPECT_NEAR(r.rec.v[n * k + i], (r.rec.x[n * k + i] - r.rec.x[n * (k - 1) + i]) / h, 1e-9) << "k = " << k;
  // The sample's energy is W_k.
  const Eigen::MatrixXd& P = *r.scene.storage;
  for (std::size_t k = 0; k < r.rec.t.size(); k += 101) {
    const Eigen::Vector2d x(r.rec.x[2 * k], r.rec.x[2 * k + 1]);
    EXPECT_NEAR(r.rec.e[k], 0.5 * x.dot(P * x), 1e-12 * (1.0 + r.rec.e[k]));
  }
}

// A generic graph with a wall, a vertical jump and rays: the run stays in the domain and W decreases.
TEST(Lure, GenericGraphRunStaysInTheDomain) {
  const LureRun r = RunLure(Scene("lure-graph.json"));
  for (std::size_t k = 0; k < r.rec.t.size(); ++k) {
    const double y = r.rec.x[2 * k] + 2.0 * r.rec.x[2 * k + 1];
    ASSERT_GE(y, -1.0 - 1e-14) << "k = " << k;
  }
  EXPECT_TRUE(r.diag.storage.nonincreasing);
  EXPECT_EQ(r.diag.y_final[0], 0.0);
}

// ---- the absolute stability checks ------------------------------------------------------------------------
TEST(AbsoluteStability, StorageMatrixConditionsAreCheckedOneByOne) {
  Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2), P(2, 2);
  A << 0, 1, -2, -3;
  B << 0, 1;
  C << 1, 2;
  P << 7, 1, 1, 2;  // PA + A^T P = diag(-4, -10), B^T P = C
  StorageMatrixCheck c = check_storage_matrix(A, B, C, P);
  EXPECT_TRUE(c.all());
  EXPECT_DOUBLE_EQ(c.max_eigenvalue_pa, -4.0);
  P << 1, 0, 0, 1;  // B^T P = (0, 1) != C; PA + A^T P = [[0, -1], [-1, -6]] not negative definite
  c = check_storage_matrix(A, B, C, P);
  EXPECT_TRUE(c.symmetric && c.positive_definite);
  EXPECT_FALSE(c.output_matches);
  EXPECT_FALSE(c.dissipative);
  P << 0.5, 1, 1, 2;  // det 0: not positive definite
  EXPECT_FALSE(check_storage_matrix(A, B, C, P).positive_definite);
  P << 7, 1, 1.5, 2;
  EXPECT_FALSE(check_storage_matrix(A, B, C, P).symmetric);
}

TEST(AbsoluteStability, StrictPositiveRealnessTest) {
  auto test = [](std::initializer_list<double> a, std::initializer_list<double> b, std::initializer_list<double> c) {
    const int n = static_cast<int>(std::sqrt(static_cast<double>(a.size())));
    Eigen::MatrixXd A(n, n), B(n, 1), C(1, n);
    int i = 0;
    for (double v : a) A(i / n, i % n) = v, ++i;
    i = 0;
    for (double v : b) B(i++, 0) = v;
    i = 0;
    for (double v : c) C(0, i++) = v;
    return test_strict_positive_realness(A, B, C);
  };
  // 1/(s + 1): SPR, P = 1.
  PositiveRealnessTest t = test({-1}, {1}, {1});
  EXPECT_EQ(t.spr, Verdict::kHolds);
  ASSERT_TRUE(t.storage_found());
  EXPECT_NEAR(t.P(0, 0), 1.0, 1e-12);
  // (2s + 1)/(s^2 + 3s + 2): SPR; Re G(jw) = (2 + 5 w^2)/|.|^2 > 0.
  t = test({0, 1, -2, -3}, {0, 1}, {1, 2});
  EXPECT_EQ(t.spr, Verdict::kHolds);
  EXPECT_TRUE(t.storage_found());
  // 1/(s^2 + s + 1): relative degree 2, CB = 0: not SPR.
  t = test({0, 1, -1, -1}, {0, 1}, {1, 0});
  EXPECT_NE(t.cb, Verdict::kHolds);
  EXPECT_NE(t.spr, Verdict::kHolds);
  // (s - 1)/(s + 1)^2: G(0) = -1 < 0, not positive real.
  t = test({0, 1, -1, -2}, {0, 1}, {-1, 1});
  EXPECT_EQ(t.frequency, Verdict::kFails);
  EXPECT_EQ(t.spr, Verdict::kFails);
  EXPECT_FALSE(t.storage_found());
  // 1/(s - 1): A not Hurwitz.
  t = test({1}, {1}, {1});
  EXPECT_EQ(t.hurwitz, Verdict::kFails);
  EXPECT_EQ(t.spr, Verdict::kFails);
  // 1/s: positive real but not strictly (A = 0).
  t = test({0}, {1}, {1});
  EXPECT_NE(t.spr, Verdict::kHolds);
}

// A scene whose P fails a condition still runs; the report says which condition fails.
TEST(AbsoluteStability, ReportSaysWhichConditionFails) {
  json doc = Scene("lure-lcs.json");
  doc["system"]["P"] = {{1, 0}, {0, 1}};
  const Simulation sim = Simulation::from_json(doc);
  const RunSummary s = sim.run(nullptr);
  const json rep = sim.report_json(s);
  const json& st = rep["absolute_stability"];
  EXPECT_EQ(st["P"], "given");
  EXPECT_EQ(st["P_symmetric"]["verdict"], "holds");
  EXPECT_EQ(st["P_positive_definite"]["verdict"], "holds");
  EXPECT_EQ(st["BtP_equals_C"]["verdict"], "fails");
  EXPECT_EQ(st["lemma_hypotheses"], "fails");
  EXPECT_NE(sim.report_text(s).find("B^T P = C fails"), std::string::npos);
}

// The counterexample as a scene: G(s) = 1/(s+1) + 0.01/(s^2 + 2e-4 s + 100) is not SPR (Re G(jw)
// < 0 just above w = 10); the report says so with a witness, and Lemmas 1-2 fail (not relied on: the run
// itself completes).
TEST(AbsoluteStability, ReportGivesAWitnessForANarrowDipAndLemmasFail) {
  json doc = Scene("lure-relay-2state.json");
  doc["system"]["A"] = {{-1, 0, 0}, {0, 0, 1}, {0, -100, -2e-4}};
  doc["system"]["B"] = {{1}, {0}, {1}};
  doc["system"]["C"] = {{1, 0.01, 0}};
  doc["initial"]["x"] = {1, 0, 0};
  doc["integrator"]["t_end"] = 0.1;
  const Simulation sim = Simulation::from_json(doc);
  const RunSummary s = sim.run(nullptr);
  const json rep = sim.report_json(s);
  const json& st = rep["absolute_stability"];
  EXPECT_EQ(st["strictly_positive_real"], "fails");
  EXPECT_EQ(st["frequency_condition"]["verdict"], "fails");
  const double w = st["frequency_condition"]["witness"]["omega"].get<double>();
  EXPECT_GT(w, 10.0);
  EXPECT_LT(w, 10.06);
  EXPECT_EQ(st["lemma_hypotheses"], "fails");
  ASSERT_EQ(rep["guarantees"].size(), 2u);
  EXPECT_EQ(rep["guarantees"][0]["result"], "Lemma 1");
  EXPECT_EQ(rep["guarantees"][0]["verdict"], "fails");
  EXPECT_EQ(rep["guarantees"][1]["verdict"], "fails");
  EXPECT_EQ(sim.guarantees(s).relied_on_failure(), "");  // not relied on: --strict does not fail the run
  const std::string text = sim.report_text(s);
  EXPECT_NE(text.find("strictly positive real: fails (G(jw) + G(jw)^H is not positive definite at w = 10.0"), std::string::npos) << text;
  EXPECT_EQ(text.find("strictly positive real: holds"), std::string::npos);
}

// A badly scaled minimal SPR realisation, G(s) = 1/(s + 1) + 0.5 s/(s^2 + s + 1e14) (Re G(jw) = 1/(1 + w^2)
// + 0.5 w^2 / ((1e14 - w^2)^2 + w^2) > 0; exact Kalman determinants far from 0: see
// absolute_stability_exact_test.cc). The report used to say "minimal (PBH): fails (margin 1e-21)" and so
// "Lemma 1 fails"; it now says that the exact tests decided, and which.
TEST(AbsoluteStability, ReportDecidesABadlyScaledRealisationExactly) {
  json doc = Scene("lure-relay-2state.json");
  doc["system"]["A"] = {{-1, 0, 0}, {0, 0, 1}, {0, -1e14, -1}};
  doc["system"]["B"] = {{1}, {0}, {1}};
  doc["system"]["C"] = {{1, 0, 0.5}};
  doc["initial"]["x"] = {1, 0, 0};
  doc["integrator"]["t_end"] = 0.01;
  const Simulation sim = Simulation::from_json(doc);
  const RunSummary s = sim.run(nullptr);
  const json rep = sim.report_json(s);
  const json& st = rep["absolute_stability"];
  EXPECT_EQ(st["minimal"]["verdict"], "holds");
  EXPECT_EQ(st["minimal"]["exact"], true);
  EXPECT_EQ(st["minimal"]["controllability_rank"], 3);
  EXPECT_EQ(st["A_hurwitz"]["verdict"], "holds");
  EXPECT_EQ(st["high_frequency_condition"]["verdict"], "holds");
  EXPECT_EQ(st["frequency_condition"]["decided_by"], "Sturm (exact)");
  EXPECT_EQ(st["strictly_positive_real"], "holds");
  EXPECT_EQ(rep["guarantees"][0]["verdict"], "holds");
  EXPECT_EQ(rep["guarantees"][1]["verdict"], "holds");
  const std::string text = sim.report_text(s);
  EXPECT_NE(text.find("minimal: holds (Kalman rank test, exact"), std::string::npos) << text;
  EXPECT_NE(text.find("A Hurwitz holds (Routh's test on det(sI - A), exact"), std::string::npos) << text;
  EXPECT_NE(text.find("(decided by Sturm (exact))"), std::string::npos) << text;
  EXPECT_EQ(text.find("fails"), std::string::npos) << text;
}

// ---- Simulation: the columns and the report -----------------------------------------------------------
TEST(Lure, SimulationNamesTheColumnsAndReports) {
  const Simulation sim = Simulation::from_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/lure-relay-2state.json");
  EXPECT_EQ(sim.system_type(), "lure");
  EXPECT_EQ(sim.scheme(), scene::Scheme::kImplicitEuler);
  EXPECT_EQ(sim.lagrangian(), nullptr);
  ASSERT_NE(sim.lure(), nullptr);
  EXPECT_EQ(sim.position_names(), (std::vector<std::string>{"x1", "x2"}));
  EXPECT_EQ(sim.velocity_names(), (std::vector<std::string>{"x1_dot", "x2_dot"}));
  EXPECT_EQ(sim.dof(), 2);
  EXPECT_EQ(sim.planned_steps(), 10000);
  const RunSummary s = sim.run(nullptr);
  const json rep = sim.report_json(s);
  EXPECT_EQ(rep["system"], "lure");
  EXPECT_EQ(rep["absolute_stability"]["strictly_positive_real"], "holds");
  EXPECT_TRUE(rep["storage_function"]["nonincreasing"].get<bool>());
  EXPECT_EQ(rep["final"]["y"][0], 0.0);
  const std::string text = sim.report_text(s);
  EXPECT_NE(text.find("strictly positive real: holds"), std::string::npos) << text;
  EXPECT_NE(text.find("how: frequency domain"), std::string::npos) << text;
}

// ---- bad scenes ---------------------------------------------------------------------------------------
struct BadLure {
  std::string name;
  std::function<void(json&)> mutate;
  std::string pointer;
  std::string reason_part;
};

class BadLureScene : public ::testing::TestWithParam<BadLure> {};

TEST_P(BadLureScene, ErrorNamesTheField) {
  json doc = Scene("lure-graph.json");
  GetParam().mutate(doc);
  try {
    Simulation::from_json(doc);
    FAIL() << "accepted a bad scene";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), GetParam().pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(GetParam().reason_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Lure, BadLureScene,
    ::testing::Values(
        BadLure{"NonMonotoneW",
                [](json& d) {
                  d["system"]["feedback"][0]["vertices"][2] = {0, -1};
                },
                "/system/feedback/0/vertices/2/1", "not monotone"},
        BadLure{"NonMonotoneU",
                [](json& d) {
                  d["system"]["feedback"][0]["vertices"][3] = {-0.5, 2};
                },
                "/system/feedback/0/vertices/3/0", "not monotone"},
        BadLure{"NegativeSlope", [](json& d) { d["system"]["feedback"][0]["right"] = -1; }, "/system/feedback/0/right", ">= 0"},
        BadLure{"BadEnd", [](json& d) { d["system"]["feedback"][0]["left"] = "floor"; }, "/system/feedback/0/left", "wall"},
        BadLure{"RepeatedVertex",
                [](json& d) {
                  d["system"]["feedback"][0]["vertices"][1] = {-1, -2};
                },
                "/system/feedback/0/vertices/1", "repeats"},
        BadLure{"VertexShape", [](json& d) { d["system"]["feedback"][0]["vertices"][1] = {1}; }, "/system/feedback/0/vertices/1", "[u, w]"},
        BadLure{"UnknownFeedback",
                [](json& d) {
                  d["system"]["feedback"][0] = {{"type", "hysteresis"}};
                },
                "/system/feedback/0/type", "unknown feedback type"},
        BadLure{"NegativeRelayGain",
                [](json& d) {
                  d["system"]["feedback"][0] = {{"type", "relay"}, {"gain", -1}};
                },
                "/system/feedback/0/gain", ">= 0"},
        BadLure{"ZeroSaturationSlope",
                [](json& d) {
                  d["system"]["feedback"][0] = {{"type", "saturation"}, {"slope", 0}, {"limit", 1}};
                },
                "/system/feedback/0/slope", "> 0"},
        BadLure{"MosLimitBelowThreshold",
                [](json& d) {
                  d["system"]["feedback"][0] = {{"type", "mos"}, {"threshold", 1}, {"limit", 0.5}, {"slope", 1}};
                },
                "/system/feedback/0/limit", "threshold"},
        BadLure{"MissingGain",
                [](json& d) {
                  d["system"]["feedback"][0] = {{"type", "relay"}};
                },
                "/system/feedback/0", "missing 'gain'"},
        BadLure{"UnknownGraphField", [](json& d) { d["system"]["feedback"][0]["slope"] = 1; }, "/system/feedback/0/slope", "unknown field"},
        BadLure{"FeedbackCount",
                [](json& d) {
                  d["system"]["feedback"].push_back({{"type", "relay"}, {"gain", 1}});
                },
                "/system/feedback", "expected 1 graphs"},
        BadLure{"CShape",
                [](json& d) {
                  d["system"]["C"] = {{1, 2, 3}};
                },
                "/system/C/0", "expected 2 entries"},
        BadLure{"BRows", [](json& d) { d["system"]["B"] = {{1}}; }, "/system/B", "expected 2 rows"},
        BadLure{"ANotSquare",
                [](json& d) {
                  d["system"]["A"] = {{0, 1, 0}, {-2, -3, 0}};
                },
                "/system/A/0", "square"},
        BadLure{"MissingA", [](json& d) { d["system"].erase("A"); }, "/system", "missing required field 'A'"},
        BadLure{"PShape", [](json& d) { d["system"]["P"] = {{1}}; }, "/system/P", "expected 2 rows"},
        BadLure{"ThetaTooSmall", [](json& d) { d["integrator"]["theta"] = 0.3; }, "/integrator/theta", "[1/2, 1]"},
        BadLure{"LagrangianScheme", [](json& d) { d["integrator"]["scheme"] = "abl"; }, "/integrator/scheme", "lagrangian systems"},
        BadLure{"UnknownScheme", [](json& d) { d["integrator"]["scheme"] = "rk4"; }, "/integrator/scheme", "unknown scheme"},
        BadLure{"AdaptiveRule", [](json& d) { d["integrator"]["step_rule"] = "theorem-4.1"; }, "/integrator/step_rule", "fixed step"},
        BadLure{"OutsideDomain",
                [](json& d) {
                  d["initial"]["x"] = {-3, 0};
                },
                "/initial/x", "outside the domain"},
        BadLure{"InitialSize", [](json& d) { d["initial"]["x"] = {1}; }, "/initial/x", "expected 2 entries"},
        BadLure{"LagrangianField", [](json& d) { d["system"]["mass"] = {{1}}; }, "/system/mass", "unknown field"},
        BadLure{"BadStateName",
                [](json& d) {
                  d["system"]["states"] = {"x", "1y"};
                },
                "/system/states/1", "expected a name"},
        // State names are the trajectory's column names (t, h, <states>, <states>_dot, energy): none may
        // be one of its own columns or another state's rate, whatever the order.
        BadLure{"StateNamedAsTheStepColumn",
                [](json& d) {
                  d["system"]["states"] = {"h", "y"};
                },
                "/system/states/0", "the trajectory has its own column 'h'"},
        BadLure{"StateNamedAsTheEnergyColumn", [](json& d) { d["system"]["states"] = {"x", "energy"}; }, "/system/states/1",
                "the trajectory has its own column 'energy'"},
        BadLure{"StateNamedAsTheTimeColumn", [](json& d) { d["system"]["states"] = {"t", "y"}; }, "/system/states/0",
                "the trajectory has its own column 't'"},
        BadLure{"StateNamedAsAnotherStatesRate", [](json& d) { d["system"]["states"] = {"x", "x_dot"}; }, "/system/states/1",
                "'x_dot' is the name of the velocity of state 'x'"},
        BadLure{"StateNamedAsTheRateOfALaterState", [](json& d) { d["system"]["states"] = {"y_dot", "y"}; }, "/system/states/0",
                "'y_dot' is the name of the velocity of state 'y'"},
        BadLure{"DuplicateStateName", [](json& d) { d["system"]["states"] = {"x", "x"}; }, "/system/states/1", "duplicate name 'x'"},
        // Every slope of a graph must be a finite number: near the largest double the rise and the run of a
        // segment overflow (2e308 / 2e308 = inf / inf = NaN), on a short steep segment the slope does.
        BadLure{"GraphSlopeOverflowsNearTheLargestDouble",
                [](json& d) { d["system"]["feedback"][0]["vertices"] = {{-1e308, -1e308}, {1e308, 1e308}}; },
                "/system/feedback/0/vertices/1", "overflows"},
        BadLure{"GraphSlopeOverflowsOnAShortSteepSegment",
                [](json& d) { d["system"]["feedback"][0]["vertices"] = {{-1e-300, -1e300}, {1e-300, 1e300}}; },
                "/system/feedback/0/vertices/1", "overflows"},
        BadLure{"SaturationBreakpointOverflows",
                [](json& d) { d["system"]["feedback"][0] = {{"type", "saturation"}, {"slope", 1e-300}, {"limit", 1e300}}; },
                "/system/feedback/0/slope", "overflows"},
        BadLure{"MosTopOverflows", [](json& d) { d["system"]["feedback"][0] = {{"type", "mos"}, {"limit", 1e300}, {"slope", 1e300}}; },
                "/system/feedback/0/slope", "overflows"},
        BadLure{"AdhesiveBreakpointOverflows",
                [](json& d) { d["system"]["feedback"][0] = {{"type", "adhesive"}, {"force", 1e300}, {"stiffness", 1e-300}}; },
                "/system/feedback/0/stiffness", "overflows"},
        BadLure{"StepLongerThanTheInterval", [](json& d) { d["integrator"]["h"] = 1e9; }, "/integrator/h", "longer than the interval"},
        BadLure{"StepCountOverflows", [](json& d) { d["integrator"]["h"] = 1e-300; }, "/integrator/h", "steps, more than the limit"}),
    [](const auto& info) { return info.param.name; });

// The complementarity law (Figure 3c) needs y0 >= 0: the LCS scene with y0 < 0 is refused at /initial/x.
TEST(Lure, ComplementarityNeedsAnAdmissibleInitialOutput) {
  json doc = Scene("lure-lcs.json");
  doc["initial"]["x"] = {1, -0.6};  // y0 = -0.2
  try {
    load_lure_scene(doc);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/initial/x");
    EXPECT_NE(std::string(e.what()).find("Lemma 1"), std::string::npos);
  }
}

}  // namespace
}  // namespace moreau::scene
