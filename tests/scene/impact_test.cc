// Lagrangian systems with unilateral constraints and impacts (section 4 of Brogliato 2003) on the
// moreau-jean scheme: the bouncing ball against its closed forms (the discrete first impact, impact
// times, the Zeno accumulation time t_inf = t1 (1+e)/(1-e)), the energy balance of every step and eq. (9)
// at every impact, Example 1 (eq. 17), the controller and a contact in one coupled one-step problem, the
// drift of a curved constraint and the position correction, the report, and the errors bad scenes get.
// The moreau-jean scheme on systems without constraints is tested in impact_unconstrained_test.cc.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "impact_support.h"

namespace moreau::scene {
namespace {

constexpr double kG = 9.81;

json Ball(double e, double h) {
  json doc = Scene(e == 0.0 ? "bouncing-ball-e0.json" : (e == 0.5 ? "bouncing-ball-e0.5.json" : "bouncing-ball-e0.8.json"));
  doc["integrator"]["h"] = h;
  return doc;
}

// Exact impact times of the ball dropped from y0 at rest: t1 = sqrt(2 y0/g), v1 = g t1,
// t_{k+1} = t_k + 2 e^k v1 / g; accumulation at t_inf = t1 (1 + e)/(1 - e).
std::vector<double> ImpactTimes(double y0, double e, int count) {
  std::vector<double> t;
  const double t1 = std::sqrt(2.0 * y0 / kG), v1 = kG * t1;
  t.push_back(t1);
  for (int k = 1; k < count; ++k) t.push_back(t.back() + 2.0 * std::pow(e, k) * v1 / kG);
  return t;
}

// The discrete first impact. Falling from y0 at rest, V^j = -g h j and Q^j = y0 - g h^2 j (j+1)/2; the step
// from Q^j is predicted active when Q^j + h V_free <= 0 with V_free = -g h (j+1), i.e. when
// J (J+1) >= 2 y0 / (g h^2) with J = j + 1. So the first impact is at t = J h for the least such J, with
// U- = -g h (J - 1) and U+ = -e U-; and |J h - t1| <= h.
TEST(Impact, FirstImpactOfTheBallIsTheDiscreteClosedForm) {
  for (double e : {0.0, 0.5, 0.8}) {
    for (double h : {1e-3, 1e-4}) {
      const ContactRun r = RunContacts(Ball(e, h));
      ASSERT_FALSE(r.diag.impacts.empty());
      const double y0 = 1.0;
      const double bound = 2.0 * y0 / (kG * h * h);
      double J = std::floor(std::sqrt(bound));
      while (J * (J + 1.0) < bound) J += 1.0;
      while ((J - 1.0) * J >= bound) J -= 1.0;
      const ImpactEvent& first = r.diag.impacts.front();
      EXPECT_EQ(first.step, static_cast<std::int64_t>(J)) << "e = " << e << ", h = " << h;
      EXPECT_NEAR(first.t, J * h, 1e-12);
      EXPECT_NEAR(first.pre, -kG * h * (J - 1.0), 1e-11);
      EXPECT_NEAR(first.post, -e * first.pre, 1e-11);
      EXPECT_LE(std::abs(first.t - std::sqrt(2.0 * y0 / kG)), h);
    }
  }
}

// Impact times converge to the closed form at first order: a tenfold smaller step divides the error of
// each of the first four impacts by at least 5. Envelope: each discrete flight is short by at most 3h
// (the free steps trail the parabola by g h t/2, the impact is predicted up to one step early, the impact
// step itself does not move the ball), and its rebound speed lacks at most d = e (d_prev + 2 g h), i.e.
// d <= 2 g h e/(1-e), costing 2 d/g more: the k-th impact is off by at most (k-1)(3 + 4e/(1-e)) h.
TEST(Impact, ImpactTimesConvergeToTheClosedForm) {
  for (double e : {0.5, 0.8}) {
    const std::vector<double> exact = ImpactTimes(1.0, e, 4);
    const ContactRun coarse = RunContacts(Ball(e, 1e-3));
    const ContactRun fine = RunContacts(Ball(e, 1e-4));
    ASSERT_GE(coarse.diag.impacts.size(), 4u);
    ASSERT_GE(fine.diag.impacts.size(), 4u);
    for (int k = 1; k < 4; ++k) {
      const double ec = std::abs(coarse.diag.impacts[k].t - exact[k]);
      const double ef = std::abs(fine.diag.impacts[k].t - exact[k]);
      EXPECT_LE(ef, ec / 5.0 + 1e-4) << "e = " << e << ", impact " << k + 1 << ": " << ec << " then " << ef;
      EXPECT_LE(ec, k * (3.0 + 4.0 * e / (1.0 - e)) * 1e-3) << "e = " << e << ", impact " << k + 1;
    }
  }
}

// Zeno: infinitely many impacts before t_inf. The run passes through the accumulation and rests:
// V == 0.0 exactly from some step to the end, the rest time converges to t_inf, the ball never moves
// faster than sqrt(2 g y0) (W is non-increasing), and at rest 0 <= y <= g h^2 (the contact is predicted
// active from y only if y - g h^2 <= 0).
TEST(Impact, ZenoAccumulationIsPassedAndTheBallRests) {
  for (double e : {0.5, 0.8}) {
    const double t_inf = std::sqrt(2.0 / kG) * (1.0 + e) / (1.0 - e);
    std::vector<double> errors;
    for (double h : {1e-3, 1e-4}) {
      json doc = Ball(e, h);
      const ContactRun r = RunContacts(doc);
      ASSERT_GE(r.diag.rest_step, 0) << "e = " << e << ", h = " << h;
      EXPECT_LT(r.diag.rest_time, r.scene.settings.t_end);
      EXPECT_GE(r.diag.impact_count, 5);
      EXPECT_GE(r.diag.settle_step[0], 0);
      EXPECT_EQ(r.diag.settle_step[0], r.diag.rest_step);
      errors.push_back(std::abs(r.diag.rest_time - t_inf));
      const double y_rest = r.rec.q[static_cast<std::size_t>(r.diag.rest_step)];
      for (std::size_t k = 0; k < r.rec.t.size(); ++k) {
        ASSERT_LE(std::abs(r.rec.v[k]), std::sqrt(2.0 * kG * 1.0) * (1.0 + 1e-12));
        ASSERT_GE(r.rec.q[k], 0.0);
        if (static_cast<std::int64_t>(k) >= r.diag.rest_step) {
          ASSERT_EQ(r.rec.v[k], 0.0);
          ASSERT_EQ(r.rec.q[k], y_rest);
        }
      }
      EXPECT_LE(y_rest, kG * h * h);
      EXPECT_TRUE(r.diag.lagrange_dirichlet.nonincreasing);
    }
    EXPECT_LE(errors[1], errors[0] / 4.0) << "e = " << e << ": rest time error " << errors[0] << " then " << errors[1];
  }
}

// The energy balance of every step, for the ball (m = 1, U = g y, theta = 1, mdi update):
//  - a free step (V+ = V - g h, Q+ = Q + h V+):      W+ - W = -g^2 h^2 / 2;
//  - an impact (U- < 0, U+ = -e U-, Q+ = Q):         W+ - W = -(1 - e^2) U-^2 / 2   (eq. 9);
//  - a closing step (U- >= 0 or e = 0, V+ = 0):      W+ - W = -V^2 / 2;
// so W is non-increasing at every step, impacts included (Lemma 3).
TEST(Impact, EnergyBalanceOfEveryStepAndEquationNine) {
  for (double e : {0.0, 0.5, 0.8}) {
    const ContactRun r = RunContacts(Ball(e, 1e-3));
    const double h = 1e-3;
    std::set<std::int64_t> impact_steps;
    for (const ImpactEvent& ev : r.diag.impacts) {
      impact_steps.insert(ev.step);
      const double loss = -0.5 * (1.0 - e * e) * ev.pre * ev.pre;
      EXPECT_NEAR(ev.kinetic_change, loss, 1e-12 * (1.0 + std::abs(loss)));
      EXPECT_NEAR(ev.eq9_change, loss, 1e-12 * (1.0 + std::abs(loss)));
      EXPECT_NEAR(ev.impulse, (1.0 + e) * -ev.pre + kG * h, 1e-12 * (1.0 + ev.impulse));
      // Moreau's impact law alone, solved apart: no gravity impulse in it.
      ASSERT_TRUE(ev.reference_evaluated);
      EXPECT_NEAR(ev.reference_impulse, (1.0 + e) * -ev.pre, 1e-12 * (1.0 + ev.impulse));
    }
    EXPECT_LE(r.diag.max_eq9_mismatch, 1e-12);
    auto W = [&](std::size_t k) { return 0.5 * r.rec.v[k] * r.rec.v[k] + kG * r.rec.q[k]; };
    int free_steps = 0, closing = 0;
    for (std::size_t k = 0; k + 1 < r.rec.t.size(); ++k) {
      const double dW = W(k + 1) - W(k);
      const double tol = 1e-12;
      const double vk = r.rec.v[k], vn = r.rec.v[k + 1];
      if (impact_steps.count(static_cast<std::int64_t>(k + 1))) {
        ASSERT_NEAR(dW, -0.5 * (1.0 - e * e) * vk * vk, tol) << "impact step " << k + 1;
      } else if (std::abs(vn - (vk - kG * h)) <= 1e-12) {
        ASSERT_NEAR(dW, -0.5 * kG * kG * h * h, tol) << "free step " << k + 1;
        ++free_steps;
      } else {
        ASSERT_EQ(vn, 0.0) << "step " << k + 1 << " is neither free nor an impact nor closing";
        ASSERT_NEAR(dW, -0.5 * vk * vk, tol) << "closing step " << k + 1;
        ++closing;
      }
      ASSERT_LE(dW, 1e-13);
    }
    EXPECT_GT(free_steps, 0);
    EXPECT_GT(closing, 0);  // the rest steps (and the landing that ends the discrete Zeno phase)
    EXPECT_TRUE(r.diag.lagrange_dirichlet.nonincreasing) << "e = " << e;
    EXPECT_GE(r.diag.smallest_gap, 0.0);  // a linear gap is never crossed: free steps are predicted exactly
  }
}

// The textbook update Q+ = Q + h V+ ("standard"): at an impact the rebound already moves the ball up, so
// W+ - W = -(1 - e^2) U-^2 / 2 + e g h |U-|, which is positive once |U-| < 2 e g h / (1 - e^2): the report
// shows W rising at the slow impacts of the Zeno phase.
// A bar of mass m and inertia I falling flat onto two supports at its ends, q = (y, th), gaps
// y -/+ (L/2) sin th, restitutions e1 != e2: both contacts impact in the same step. Moreau's impact law for
// the pair is the 2x2 LCP U+ = U- + S P with the Delassus matrix S = H M^{-1} H^T; with both contacts
// active, S P = -(1 + e) o U-, solved here with Eigen from H and M, independently of the integrator. Its
// energy change is 1/2 sum_i (1 - e_i) P_i U-_i, and with e1 = e2 it is eq. (9),
// -1/2 (1-e)/(1+e) |V+ - V-|_M^2. The scheme's own step differs from the law by the gravity impulse
// over h, which the contacts absorb: its dT equals the law's up to round-off for this bar at th = 0.
TEST(Impact, SimultaneousImpactsOfABarOnTwoSupportsFollowMoreausLaw) {
  for (const auto& [e1, e2] : std::vector<std::pair<double, double>>{{0.5, 0.5}, {0.8, 0.2}}) {
    const double m = 2.0, I = 0.5, L = 1.0;
    json doc = {{"parameters", {{"m", m}, {"I", I}, {"L", L}, {"g", kG}}},
                {"system",
                 {{"type", "lagrangian"},
                  {"coordinates", {"y", "th"}},
                  {"mass", {{"m", 0}, {0, "I"}}},
                  {"potential", "m*g*y"},
                  {"constraints",
                   {{{"name", "left"}, {"gap", "y - L/2*sin(th)"}, {"restitution", e1}},
                    {{"name", "right"}, {"gap", "y + L/2*sin(th)"}, {"restitution", e2}}}}}},
                {"initial", {{"q", {0.05, 0.0}}, {"v", {0.0, 0.0}}}},
                {"integrator", {{"scheme", "moreau-jean"}, {"h", 1e-3}, {"t_end", 0.2}}}};
    const ContactRun r = RunContacts(doc);
    ASSERT_GE(r.diag.impacts.size(), 2u);
    const ImpactEvent& a = r.diag.impacts[0];
    const ImpactEvent& b = r.diag.impacts[1];
    ASSERT_EQ(a.step, b.step) << "both ends hit in the same step";
    EXPECT_EQ(a.simultaneous, 2);
    ASSERT_TRUE(a.reference_evaluated && b.reference_evaluated);
    // The law, from U- (equal at both ends: the bar falls flat) with Eigen.
    Eigen::Matrix2d H;
    H << 1.0, -L / 2, 1.0, L / 2;
    const Eigen::Matrix2d Minv = Eigen::Vector2d(1.0 / m, 1.0 / I).asDiagonal();
    const Eigen::Matrix2d S = H * Minv * H.transpose();
    const Eigen::Vector2d Um(a.pre, b.pre);
    const Eigen::Vector2d P = S.lu().solve(Eigen::Vector2d(-(1.0 + e1) * Um(0), -(1.0 + e2) * Um(1)));
    ASSERT_GT(P.minCoeff(), 0.0) << "both contacts active";
    EXPECT_NEAR(a.reference_impulse, P(0), 1e-12 * P.norm());
    EXPECT_NEAR(b.reference_impulse, P(1), 1e-12 * P.norm());
    const Eigen::Vector2d dV = Minv * H.transpose() * P;
    const Eigen::Vector2d Vm = Eigen::Vector2d(a.pre, 0.0);  // y' = U-, th' = 0
    const Eigen::Matrix2d M = Eigen::Vector2d(m, I).asDiagonal();
    const double dT_law = 0.5 * (Vm + dV).dot(M * (Vm + dV)) - 0.5 * Vm.dot(M * Vm);
    EXPECT_NEAR(a.eq9_change, dT_law, 1e-12 * std::abs(dT_law));
    EXPECT_NEAR(a.eq9_change, 0.5 * ((1.0 - e1) * P(0) * Um(0) + (1.0 - e2) * P(1) * Um(1)), 1e-12 * std::abs(dT_law));
    if (e1 == e2) {
      EXPECT_NEAR(a.eq9_change, -0.5 * (1.0 - e1) / (1.0 + e1) * dV.dot(M * dV), 1e-12 * std::abs(dT_law));
    }
    // Different restitutions set the bar spinning: th' = (L/2)(P2 - P1)/I.
    if (e1 != e2) {
      EXPECT_GT(std::abs(dV(1)), 0.1);
    }
    // The step's dT, from its own velocities. (Later impacts, with the bar tilted or one end resting,
    // differ from the law by what the step adds over h.)
    EXPECT_NEAR(a.kinetic_change, dT_law, 1e-9 * std::abs(dT_law));
    EXPECT_NEAR(b.kinetic_change, dT_law, 1e-9 * std::abs(dT_law));  // one step, one change: both events carry it
  }
}

TEST(Impact, StandardPositionUpdateRaisesWAtSlowImpacts) {
  const double e = 0.8, h = 1e-3;
  json doc = Ball(e, h);
  doc["integrator"]["position_update"] = "standard";
  const ContactRun r = RunContacts(doc);
  EXPECT_FALSE(r.diag.lagrange_dirichlet.nonincreasing);
  EXPECT_GT(r.diag.lagrange_dirichlet.increases, 0);
  auto W = [&](std::size_t k) { return 0.5 * r.rec.v[k] * r.rec.v[k] + kG * r.rec.q[k]; };
  int rising = 0;
  for (const ImpactEvent& ev : r.diag.impacts) {
    const auto k = static_cast<std::size_t>(ev.step);
    const double predicted = -0.5 * (1.0 - e * e) * ev.pre * ev.pre + e * kG * h * std::abs(ev.pre);
    EXPECT_NEAR(W(k) - W(k - 1), predicted, 1e-12) << "impact at step " << ev.step;
    rising += predicted > 0.0;
  }
  EXPECT_GT(rising, 0);
}

// Example 1, eq. (17): x is a damped oscillator (independent of the impacts in y), y a bouncing mass.
// x(t) = e^{-z t} (x0 cos(w t) + z x0/w sin(w t)), z = f/(2m), w = sqrt(c/m - z^2). The damper is implicit
// and the spring explicit: W = m x'^2/2 + c x^2/2 + m y'^2/2 + m g y (eq. 18) is non-increasing when
// f >= h c/2 (the quadratic form of the step's energy change is then negative semi-definite).
TEST(Impact, Example1DampedOscillatorAndBouncingMass) {
  std::vector<double> errors;
  for (double h : {1e-3, 1e-4}) {
    json doc = Scene("example1-eq17.json");
    doc["integrator"]["h"] = h;
    doc["integrator"]["t_end"] = 5;
    const ContactRun r = RunContacts(doc);
    const double m = 1.0, f = 0.4, c = 4.0, x0 = 1.0, y0 = 0.5, e = 0.5;
    const double z = f / (2.0 * m), w = std::sqrt(c / m - z * z);
    double err = 0.0;
    for (std::size_t k = 0; k < r.rec.t.size(); ++k) {
      const double t = r.rec.t[k];
      const double x = std::exp(-z * t) * (x0 * std::cos(w * t) + z * x0 / w * std::sin(w * t));
      err = std::max(err, std::abs(r.rec.q[2 * k] - x));
      ASSERT_GE(r.rec.q[2 * k + 1], 0.0);
    }
    errors.push_back(err);
    EXPECT_TRUE(r.diag.lagrange_dirichlet.nonincreasing) << "h = " << h;
    EXPECT_TRUE(r.diag.potential_known);
    // y: the first impact as for the ball (from y0 = 0.5), and the contact closes near t_inf.
    const double bound = 2.0 * y0 / (kG * h * h);
    double J = std::floor(std::sqrt(bound));
    while (J * (J + 1.0) < bound) J += 1.0;
    while ((J - 1.0) * J >= bound) J -= 1.0;
    ASSERT_FALSE(r.diag.impacts.empty());
    EXPECT_EQ(r.diag.impacts.front().step, static_cast<std::int64_t>(J));
    const double t_inf = std::sqrt(2.0 * y0 / kG) * (1.0 + e) / (1.0 - e);
    ASSERT_GE(r.diag.settle_step[0], 0);
    EXPECT_NEAR(r.diag.settle_time[0], t_inf, 0.01);
    EXPECT_LT(r.diag.rest_step, 0);  // x still oscillates: the system as a whole is not at rest
  }
  EXPECT_GT(std::log10(errors[0] / errors[1]), 0.9);  // first order in x
}

// The impacts in y do not disturb x: the same oscillator without the mass in y gives the same x.
TEST(Impact, Example1XIsIndependentOfTheImpacts) {
  json doc = Scene("example1-eq17.json");
  doc["integrator"]["t_end"] = 3;
  const ContactRun both = RunContacts(doc);
  json osc = Scene("example1-eq17.json");
  osc["integrator"]["t_end"] = 3;
  osc["system"]["coordinates"] = {"x"};
  osc["system"]["mass"] = {{"m"}};
  osc["system"]["potential"] = "c*x^2/2";
  osc["system"]["controller"] = {{{"type", "quadratic"}, {"weights", {"f"}}}};
  osc["system"].erase("constraints");
  osc["system"].erase("coriolis");
  osc["initial"] = {{"q", {"x0"}}, {"v", {0}}};
  osc["integrator"]["scheme"] = "moreau-jean";
  const ContactRun alone = RunContacts(osc);
  ASSERT_EQ(alone.rec.t.size(), both.rec.t.size());
  for (std::size_t k = 0; k < alone.rec.t.size(); ++k) {
    ASSERT_NEAR(both.rec.q[2 * k], alone.rec.q[k], 1e-14);
    ASSERT_NEAR(both.rec.v[2 * k], alone.rec.v[k], 1e-14);
  }
}

// The controller and a contact in one coupled one-step problem: a block on the ramp y = x/2 (gap
// y - x/2 >= 0, e = 0) under gravity, braked by Phi = a |x'| (a horizontal dry-friction brake). Along the
// ramp s = (2, 1)/sqrt(5): m s'' = -(m g + 2 a)/sqrt(5) while s' > 0, so from s'(0) = s0 it stops at
// t* = sqrt(5) m s0/(m g + 2 a), and stays (the brake holds it: m g/2 <= a). Discretely the speed drops by
// exactly h (m g + 2 a)/(sqrt(5) m) per step, so V == 0.0 from step K = ceil(t*/h), t_K - t* in [0, h).
TEST(Impact, ControllerAndContactInOneProblemStopTheBlockExactly) {
  const double m = 1.0, a = 10.0, s0 = 1.0, h = 1e-3;
  const double r5 = std::sqrt(5.0);
  json doc = {{"name", "ramp"},
              {"parameters", {{"m", m}, {"g", kG}, {"a", a}}},
              {"system",
               {{"type", "lagrangian"},
                {"coordinates", {"x", "y"}},
                {"mass", {{"m", 0}, {0, "m"}}},
                {"potential", "m*g*y"},
                {"controller", {{{"type", "abs"}, {"gains", {"a", 0}}}}},
                {"constraints", {{{"name", "ramp"}, {"gap", "y - x/2"}, {"restitution", 0}}}}}},
              {"initial", {{"q", {0, 0}}, {"v", {2.0 * s0 / r5, s0 / r5}}}},
              {"integrator", {{"scheme", "moreau-jean"}, {"h", h}, {"t_end", 0.5}}}};
  const ContactRun r = RunContacts(doc);
  const double dec = (m * kG + 2.0 * a) / (r5 * m);
  const double t_star = r5 * m * s0 / (m * kG + 2.0 * a);
  ASSERT_GE(r.diag.rest_step, 0);
  EXPECT_EQ(r.diag.rest_step, static_cast<std::int64_t>(std::ceil(t_star / h)));
  EXPECT_GE(r.diag.rest_time, t_star);
  EXPECT_LT(r.diag.rest_time - t_star, h);
  for (std::int64_t k = 1; k < r.diag.rest_step; ++k) {
    const double speed = s0 - static_cast<double>(k) * h * dec;
    EXPECT_NEAR(r.rec.v[2 * k], 2.0 * speed / r5, 1e-12) << "k = " << k;
    EXPECT_NEAR(r.rec.v[2 * k + 1], speed / r5, 1e-12) << "k = " << k;
  }
  EXPECT_EQ(r.summary.v_final[0], 0.0);
  EXPECT_EQ(r.summary.v_final[1], 0.0);
  EXPECT_GE(r.diag.smallest_gap, -1e-15);
  EXPECT_EQ(r.summary.solver.fallback_steps, 0);
  EXPECT_EQ(r.diag.impact_count, 0);  // sliding contact, no impact
}

// A contact and an abs term on the same coordinate (a ball on a floor, with Coulomb friction on its own
// height: the 1-DOF form of a joint limit with joint friction), which the Moreau-Jean step solves as one
// row whose graph is the sum of the two laws (merge_rows). Against the closed form of the continuous
// motion: falling with acceleration g - a/m, rising with g + a/m, Newton's law U+ = -e U- at each impact;
// then the ball rests exactly on the floor. (The 7-joint arm of Urdf.JointLimitWithCoulombFriction... is
// the case the unmerged rows could not solve.)
TEST(Impact, CoulombFrictionOnTheContactCoordinateFollowsTheClosedFormAndRestsExactly) {
  const double m = 1.0, a = 2.0, e = 0.5, y0 = 1.0, h = 1e-4;
  json doc = {{"name", "ball-with-friction"},
              {"parameters", {{"m", m}, {"g", kG}, {"a", a}}},
              {"system",
               {{"type", "lagrangian"},
                {"coordinates", {"y"}},
                {"mass", {{"m"}}},
                {"potential", "m*g*y"},
                {"controller", {{{"type", "abs"}, {"gains", {"a"}}}}},
                {"constraints", {{{"name", "floor"}, {"gap", "y"}, {"restitution", e}}}}}},
              {"initial", {{"q", {y0}}, {"v", {0}}}},
              {"integrator", {{"scheme", "moreau-jean"}, {"h", h}, {"t_end", 3.0}}}};
  const ContactRun r = RunContacts(doc);
  const double down = kG - a / m, up = kG + a / m;
  const double t1 = std::sqrt(2.0 * y0 / down), u1 = -std::sqrt(2.0 * y0 * down);
  const double rise = e * -u1 / up, apex = (e * u1) * (e * u1) / (2.0 * up);
  const double t2 = t1 + rise + std::sqrt(2.0 * apex / down), u2 = -std::sqrt(2.0 * apex * down);
  ASSERT_GE(r.diag.impacts.size(), 2u);
  EXPECT_NEAR(r.diag.impacts[0].t, t1, 2 * h);
  EXPECT_NEAR(r.diag.impacts[0].pre, u1, 2 * h * up);
  EXPECT_NEAR(r.diag.impacts[1].t, t2, 4 * h);
  EXPECT_NEAR(r.diag.impacts[1].pre, u2, 4 * h * up);
  for (const ImpactEvent& ev : r.diag.impacts) {
    EXPECT_EQ(ev.post, -e * ev.pre) << "Newton's law at t = " << ev.t;  // the merged row's wall is -e U- itself
    EXPECT_GT(ev.impulse, 0.0);
  }
  // At rest on the floor: gravity m g exceeds friction a, so the floor carries the rest, and the ball
  // stays, v == 0.0 exactly, with the contact closed.
  ASSERT_GE(r.diag.rest_step, 0);
  EXPECT_EQ(r.summary.v_final[0], 0.0);
  EXPECT_GE(r.diag.settle_step[0], 0) << "the floor carries an impulse at rest (m g > a)";
  EXPECT_GE(r.diag.smallest_gap, -h * h * kG);
  EXPECT_EQ(r.summary.solver.fallback_steps, 0);
}

// A curved constraint (inside the unit disc, gap 1 - x^2 - y^2): a closed contact keeps U = 0 but the
// position moves along the tangent, so each step changes the gap by exactly -h^2 |V+|^2 (grad h = -2 q,
// q . V+ = 0) and the drift accumulates below 0. With position_correction = projection the gap is
// brought back to 0 after every step, and the report counts the corrections and the energy they add.
TEST(Impact, CurvedConstraintDriftsAndTheProjectionCorrectsIt) {
  const double h = 1e-3;
  json doc = {{"name", "bowl"},
              {"parameters", {{"g", kG}}},
              {"system",
               {{"type", "lagrangian"},
                {"coordinates", {"x", "y"}},
                {"mass", {{1, 0}, {0, 1}}},
                {"potential", "g*y"},
                {"constraints", {{{"name", "bowl"}, {"gap", "1 - x^2 - y^2"}, {"restitution", 0}}}}}},
              {"initial", {{"q", {0, -1}}, {"v", {1.5, 0}}}},
              {"integrator", {{"scheme", "moreau-jean"}, {"h", h}, {"t_end", 2}}}};
  const ContactRun drift = RunContacts(doc);
  EXPECT_LT(drift.diag.smallest_gap, -1e-4);
  EXPECT_EQ(drift.diag.corrected_steps, 0);
  int closed_steps = 0;
  for (std::size_t k = 10; k + 1 < drift.rec.t.size(); ++k) {
    auto gap = [&](std::size_t j) {
      return 1.0 - drift.rec.q[2 * j] * drift.rec.q[2 * j] - drift.rec.q[2 * j + 1] * drift.rec.q[2 * j + 1];
    };
    const double vx = drift.rec.v[2 * (k + 1)], vy = drift.rec.v[2 * (k + 1) + 1];
    const double qx = drift.rec.q[2 * k], qy = drift.rec.q[2 * k + 1];
    if (std::abs(qx * vx + qy * vy) > 1e-12) continue;  // not a closed-contact step
    EXPECT_NEAR(gap(k + 1) - gap(k), -h * h * (vx * vx + vy * vy), 1e-13);
    ++closed_steps;
  }
  EXPECT_GT(closed_steps, 1000);

  doc["integrator"]["position_correction"] = "projection";
  const ContactRun proj = RunContacts(doc);
  // The projection stops once h >= -64 eps (1 + |q| |grad h|) (the round-off of h itself; |q| <= 1, |grad h| <= 2).
  EXPECT_GE(proj.diag.smallest_gap, -64.0 * std::numeric_limits<double>::epsilon() * 3.0);
  EXPECT_GT(proj.diag.corrected_steps, 1000);
  EXPECT_GT(proj.diag.largest_violation, 0.0);
  // One step's drift h^2 |V|^2, with |V|^2 <= 1.5^2 + 2 g (the height gained by the corrections, < 1).
  EXPECT_LE(proj.diag.largest_violation, h * h * (1.5 * 1.5 + 2.0 * kG));
  EXPECT_TRUE(std::isfinite(proj.diag.correction_energy));
  const Simulation sim = Simulation::from_json(doc);
  const RunSummary s = sim.run(nullptr);
  const json rep = sim.report_json(s);
  EXPECT_EQ(rep["contacts"]["position_correction"]["mode"], "projection");
  EXPECT_GT(rep["contacts"]["position_correction"]["corrected_steps"].get<std::int64_t>(), 1000);
  EXPECT_NE(sim.report_text(s).find("projected onto h >= 0"), std::string::npos);
}

// Simulation: the same entry point for constrained scenes; the report carries the impacts.
TEST(Impact, SimulationReportsImpactsRestGapAndLemma3) {
  const Simulation sim = Simulation::from_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/bouncing-ball-e0.5.json");
  EXPECT_EQ(sim.system_type(), "lagrangian");
  EXPECT_EQ(sim.scheme(), scene::Scheme::kMoreauJean);
  EXPECT_EQ(sim.position_names(), std::vector<std::string>{"y"});
  const RunSummary s = sim.run(nullptr);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  const json rep = sim.report_json(s);
  EXPECT_EQ(rep["scheme"], "moreau-jean");
  EXPECT_EQ(rep["constraints"][0]["name"], "ground");
  EXPECT_GE(rep["contacts"]["impact_count"].get<int>(), 5);
  EXPECT_EQ(rep["contacts"]["impacts"][0]["constraint"], "ground");
  EXPECT_FALSE(rep["contacts"]["rest_time"].is_null());
  EXPECT_GE(rep["contacts"]["smallest_gap"]["value"].get<double>(), 0.0);
  EXPECT_TRUE(rep["lagrange_dirichlet"]["nonincreasing"].get<bool>());
  const std::string text = sim.report_text(s);
  for (const char* part : {"impacts", "rest", "smallest gap", "Lemma 3", "non-increasing including impacts", "eq. (9)"})
    EXPECT_NE(text.find(part), std::string::npos) << part << "\n" << text;
  // Explicit diagnostics for callers that run one Simulation from several threads.
  RunDiagnostics d;
  const RunSummary s2 = sim.run(nullptr, &d);
  ASSERT_NE(d.contacts(), nullptr);
  EXPECT_EQ(d.contacts()->impact_count, rep["contacts"]["impact_count"].get<std::int64_t>());
  EXPECT_EQ(sim.report_json(s2, d)["contacts"]["impact_count"], rep["contacts"]["impact_count"]);
}

// ---- bad scenes -----------------------------------------------------------------------------------------
struct BadContact {
  std::string name;
  std::function<void(json&)> mutate;
  std::string pointer;
  std::string reason_part;
};

class BadContactScene : public ::testing::TestWithParam<BadContact> {};

TEST_P(BadContactScene, ErrorNamesTheField) {
  json doc = Scene("example1-eq17.json");
  GetParam().mutate(doc);
  try {
    load_scene(doc);
    FAIL() << "accepted a bad scene";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), GetParam().pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(GetParam().reason_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Impact, BadContactScene,
    ::testing::Values(
        BadContact{"AblWithConstraints", [](json& d) { d["integrator"]["scheme"] = "abl"; }, "/integrator/scheme",
                   "cannot integrate unilateral constraints"},
        BadContact{"RestitutionAboveOne", [](json& d) { d["system"]["constraints"][0]["restitution"] = 1.5; },
                   "/system/constraints/0/restitution", "[0, 1]"},
        BadContact{"NegativeRestitution", [](json& d) { d["system"]["constraints"][0]["restitution"] = "-e"; },
                   "/system/constraints/0/restitution", "[0, 1]"},
        BadContact{"GapWithVelocity", [](json& d) { d["system"]["constraints"][0]["gap"] = "y + y_dot"; }, "/system/constraints/0/gap",
                   "cannot appear"},
        BadContact{"GapUnknownName", [](json& d) { d["system"]["constraints"][0]["gap"] = "z"; }, "/system/constraints/0/gap",
                   "unknown name 'z'"},
        BadContact{"ConstantGap", [](json& d) { d["system"]["constraints"][0]["gap"] = "2*e"; }, "/system/constraints/0/gap", "constant"},
        BadContact{"MissingGap", [](json& d) { d["system"]["constraints"][0].erase("gap"); }, "/system/constraints/0", "missing 'gap'"},
        BadContact{"UnknownConstraintField", [](json& d) { d["system"]["constraints"][0]["friction"] = 0.3; },
                   "/system/constraints/0/friction", "unknown field"},
        BadContact{"ConstraintsNotArray", [](json& d) { d["system"]["constraints"] = "y"; }, "/system/constraints", "expected an array"},
        BadContact{"DuplicateName",
                   [](json& d) {
                     d["system"]["constraints"].push_back({{"name", "floor"}, {"gap", "y + 1"}});
                   },
                   "/system/constraints/1/name", "duplicate"},
        BadContact{"InitialViolates", [](json& d) { d["initial"]["q"][1] = -0.1; }, "/initial/q", "violates constraint 'floor'"},
        BadContact{"NormController",
                   [](json& d) {
                     d["system"]["controller"].push_back({{"type", "norm"}, {"gain", 1}});
                   },
                   "/system/controller/1/type", "not supported by the moreau-jean"},
        BadContact{"TheoremRule", [](json& d) { d["integrator"]["step_rule"] = "theorem-4.1"; }, "/integrator/step_rule", "fixed step"},
        BadContact{"K1", [](json& d) { d["integrator"]["k1"] = 1; }, "/integrator/k1", "abl"},
        BadContact{"Theta", [](json& d) { d["integrator"]["theta"] = 0.5; }, "/integrator/theta", "implicit-euler"},
        BadContact{"BadCorrection", [](json& d) { d["integrator"]["position_correction"] = "baumgarte"; },
                   "/integrator/position_correction", "projection"},
        BadContact{"BadUpdate", [](json& d) { d["integrator"]["position_update"] = "midpoint"; }, "/integrator/position_update", "mdi"},
        BadContact{"LureScheme", [](json& d) { d["integrator"]["scheme"] = "implicit-euler"; }, "/integrator/scheme", "lure systems"}),
    [](const auto& info) { return info.param.name; });

// The correction options belong to moreau-jean: an abl scene with them is refused.
TEST(Impact, ContactOptionsNeedMoreauJean) {
  json doc = Scene("damped-relay.json");
  doc["integrator"]["position_correction"] = "projection";
  try {
    load_scene(doc);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/integrator/position_correction");
  }
}

}  // namespace
}  // namespace moreau::scene
