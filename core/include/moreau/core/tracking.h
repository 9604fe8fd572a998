// Tracking control of a fully actuated Lagrangian system
//
//   M(q) q'' + C(q, q') q' + g(q) = u + d(t)                                              (plant)
//
// by a set-valued (sliding-mode) passivity-based controller, and its sampled-data (digital) versions: the
// controller sees (q_k, v_k) = (q(t_k), q'(t_k)) at t_k = t_0 + k T_s and holds u_k over [t_k, t_k + T_s)
// (zero-order hold). References: Miranda-Villatoro, Brogliato and Castanos, "Multivalued robust tracking
// control of Lagrange systems: continuous and discrete-time algorithms", IEEE TAC 62(9), 2017 (MBC); Adly,
// Brogliato and Le, "Implicit Euler time-discretization of a class of Lagrangian systems with set-valued
// robust controller", J. Convex Anal. 23(1), 2016 (ABL, whose equation numbers are cited as (0.2), (4.2),
// (6.5)); Acary and Brogliato, "Implicit Euler numerical scheme and chattering-free implementation of
// sliding mode systems", Systems & Control Letters 59, 2010 (AB). docs/tracking.md has the derivations.
//
// Tracking variables (Slotine and Li's passivity-based construction, the one MBC builds on), with
// Lambda = diag(lambda), lambda_i > 0:
//
//   e = q - q_d,   e' = q' - q_d',   sigma = e' + Lambda e,
//   v_r = q_d' - Lambda e  (so sigma = q' - v_r),   a_r = q_d'' - Lambda e'  (= v_r').
//
// Continuous controller: u = M^(q) a_r + C^(q, q') v_r + g^(q) - xi,  xi in dPhi(sigma), with M^, C^, g^
// the nominal model the controller knows and Phi the potential of controller.h (quadratic w_i, weighted
// |.| with gains a_i, norm term a_norm). With an exact model the closed loop is
//
//   M(q) sigma' + C(q, q') sigma + dPhi(sigma) ∋ d(t),
//
// which is (0.1) of ABL with the velocity replaced by sigma, grad V = 0 and F = -d. Model mismatch adds
// (M - M^) a_r + (C - C^) v_r + (g - g^) to d. For |d| <= D < alpha (alpha = Controller::alpha()) sigma
// reaches 0 in finite time, t_r <= max_q lambda_max(M) ||sigma(0)|| / (alpha - D), and on sigma = 0,
// e' = -Lambda e: each e_i decays as exp(-lambda_i t).
//
// Sampled-data laws (SampledTrackingLaw), all from the sample (t_k, q_k, v_k) and the nominal model's
// M^_k = M^(q_k), C^_k = C^(q_k, v_k), g^_k (LagrangianTerms: g holds grad V^ plus any known force):
//
//  - kImplicit (the implicit discretisation of MBC and AB, written here as the scheme (0.2) of ABL applied
//    to the nominal closed loop). With (0.2)'s explicit position update, the predicted
//        e_{k+1} = q_k + T_s v_k - q_d(t_{k+1}),  v_{r,k+1} = q_d'(t_{k+1}) - Lambda e_{k+1}
//    are known at t_k. The control is the nominal Euler model's input that brings the velocity to
//    v_{k+1} = v_{r,k+1} + sigma_{k+1}:
//        u_k = M^_k (v_{r,k+1} - v_{r,k}) / T_s + C^_k v_{r,k+1} + g^_k - xi_k,
//    where sigma_{k+1} and xi_k in dPhi(sigma_{k+1}) solve the one-step problem
//        M^_k (sigma_{k+1} - sigma_k) / T_s + C^_k sigma_{k+1} + dPhi(sigma_{k+1}) ∋ 0,
//    that is (6.5) of ABL, P y + x in -d phi(y), with y = sigma_{k+1}, P = M^_k / T_s + C^_k + W (the
//    quadratic part as in (6.4)), x = -M^_k sigma_k / T_s and phi = A |.| + a_norm ||.||; it is solved by
//    OneStepSolver, exactly. Then xi_k = M^_k (sigma_k - sigma_{k+1}) / T_s - C^_k sigma_{k+1}. On the
//    nominal model the closed loop in sigma is (0.2) with grad V + F = 0, so ABL's Theorem 4.1 gives a
//    unique sigma_{k+1} when 2 T_s ||C^_k||_2 <= lambda_min(M^_k) ((4.2) with V^k = v_k; reported as
//    TrackingStep::condition), and sigma_{k+1} = 0 exactly when -x = M^_k sigma_k / T_s lies in
//    d phi(0) = A [-1, 1]^n + a_norm B: the solver's closed form (OneStepStats::zero_by_closed_form),
//    reported as on_surface. The selection is then xi_k = M^_k sigma_k / T_s: a linear feedback of size
//    O(sup |d|), not a switch, which is why the implicit law does not chatter. On the true plant with a
//    disturbance, sigma(t_{k+1}) is the prediction plus what d and the hold did over the period: O(T_s)
//    (for the 1-DOF plant the exact expression is in docs/tracking.md and tested).
//  - kExplicit: the continuous law evaluated at the sample, u_k = M^_k a_r(t_k) + C^_k v_r(t_k) + g^_k - xi_k,
//    xi_k = W sigma_k + A sgn(sigma_k) + a_norm sigma_k / ||sigma_k||, with sgn(0) = 0 and the last term 0
//    at sigma_k = 0: the element of least norm of dPhi(sigma_k). The switch is decided on the sample:
//    sigma chatters around 0 with an amplitude of order alpha T_s / m.
//  - kSaturated: the boundary-layer fix of the explicit law, sgn(s) replaced by sat(s / phi) and
//    sigma / ||sigma|| by sigma / max(||sigma||, phi), phi = boundary_layer > 0. Inside the layer the law
//    is linear, with discrete pole 1 - a T_s / (m phi) for a 1-DOF plant of mass m: no chattering for
//    phi >= a T_s / m, unstable inside the layer (so it chatters like the explicit law) for
//    phi < a T_s / (2 m).
//
// Deviations, extensions and what is not taken from MBC: Lambda is diagonal; the quadratic part W of Phi
// plays the role of a linear gain K sigma; the continuous-time bounds above and the O(T_s) expression are
// derived in docs/tracking.md, not quoted. docs/tracking.md lists what was checked against which source.
//
// No allocation per step: every buffer is sized in the constructor (dynamic sizes) and the caller sizes
// its TrackingStep once (TrackingStep::resize).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "moreau/core/controller.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/core/step_conditions.h"
#include "moreau/core/types.h"

namespace moreau {

// The desired trajectory at one instant: q_d(t), q_d'(t), q_d''(t).
template <int N>
struct ReferencePoint {
  Vec<N> q, v, a;
  void resize(int n) {
    q.setZero(n);
    v.setZero(n);
    a.setZero(n);
  }
};

// A reference from a callable f(double t, ReferencePoint<N>& out), which fills q_d, q_d', q_d'' at t (out
// sized by the caller once).
template <int N, class F>
class CallableReference {
 public:
  explicit CallableReference(F f) : f_(std::move(f)) {}
  bool at(double t, ReferencePoint<N>& out) const {
    f_(t, out);
    return true;
  }

 private:
  F f_;
};

// A reference from arrays: column j of q, v, a holds q_d, q_d', q_d'' at t_0 + j dt. At a sample time (t
// within 1e-9 dt of t_0 + j dt) the columns themselves; between samples, q_d by the cubic Hermite
// interpolant of (q, v) at the two ends, q_d' by that of (v, a), and q_d'' linearly (so the three are
// consistent only at the samples, and exact for a cubic q_d). Outside [t_0, t_0 + (m - 1) dt]: false.
template <int N>
class TabulatedReference {
 public:
  using Columns = Eigen::Matrix<double, N, Eigen::Dynamic>;
  TabulatedReference(double t0, double dt, Columns q, Columns v, Columns a)
      : t0_(t0), dt_(dt), q_(std::move(q)), v_(std::move(v)), a_(std::move(a)) {}

  int samples() const { return static_cast<int>(q_.cols()); }
  bool valid() const {
    return dt_ > 0.0 && std::isfinite(t0_) && std::isfinite(dt_) && samples() >= 1 && v_.cols() == q_.cols() && a_.cols() == q_.cols() &&
           v_.rows() == q_.rows() && a_.rows() == q_.rows();
  }

  bool at(double t, ReferencePoint<N>& out) const {
    const double s = (t - t0_) / dt_;
    const double last = samples() - 1;
    if (!(s >= -1e-9 && s <= last + 1e-9)) return false;
    const double j = std::round(s);
    if (std::abs(s - j) <= 1e-9) {
      const auto c = static_cast<Eigen::Index>(j);
      out.q = q_.col(c);
      out.v = v_.col(c);
      out.a = a_.col(c);
      return true;
    }
    const auto c = static_cast<Eigen::Index>(std::floor(s));
    const double r = s - static_cast<double>(c);
    // Cubic Hermite basis on [0, 1], derivatives scaled by dt.
    const double h00 = (1.0 + 2.0 * r) * (1.0 - r) * (1.0 - r), h10 = r * (1.0 - r) * (1.0 - r);
    const double h01 = r * r * (3.0 - 2.0 * r), h11 = r * r * (r - 1.0);
    out.q = h00 * q_.col(c) + (h10 * dt_) * v_.col(c) + h01 * q_.col(c + 1) + (h11 * dt_) * v_.col(c + 1);
    out.v = h00 * v_.col(c) + (h10 * dt_) * a_.col(c) + h01 * v_.col(c + 1) + (h11 * dt_) * a_.col(c + 1);
    out.a = (1.0 - r) * a_.col(c) + r * a_.col(c + 1);
    return true;
  }

 private:
  double t0_, dt_;
  Columns q_, v_, a_;
};

// The tracking variables at one instant (see the top of this file).
template <int N>
struct TrackingErrors {
  Vec<N> e, e_dot, sigma, v_r, a_r;
  void resize(int n) {
    e.setZero(n);
    e_dot.setZero(n);
    sigma.setZero(n);
    v_r.setZero(n);
    a_r.setZero(n);
  }
};

// e = q - q_d, e' = v - q_d', sigma = e' + Lambda e, v_r = q_d' - Lambda e, a_r = q_d'' - Lambda e'.
template <int N>
void tracking_errors(const Vec<N>& q, const Vec<N>& v, const ReferencePoint<N>& r, const Vec<N>& lambda, TrackingErrors<N>& out) {
  out.e = q - r.q;
  out.e_dot = v - r.v;
  out.sigma = out.e_dot + lambda.cwiseProduct(out.e);
  out.v_r = r.v - lambda.cwiseProduct(out.e);
  out.a_r = r.a - lambda.cwiseProduct(out.e_dot);
}

// The continuous controller's model-based part, M^ a_r + C^ v_r + g^ (u = this - xi, xi in dPhi(sigma)).
template <int N>
void continuous_model_part(const LagrangianTerms<N>& nominal, const TrackingErrors<N>& err, Vec<N>& out) {
  out.noalias() = nominal.M * err.a_r;
  out.noalias() += nominal.C * err.v_r;
  out += nominal.g;
}

// The element of least norm of dPhi(sigma) = W sigma + A Sgn(sigma) + a_norm d||sigma||: W sigma +
// A sgn(sigma) + a_norm sigma / ||sigma||, with sgn(0) = 0 and the norm term 0 at sigma = 0.
template <int N>
void least_norm_selection(const Controller<N>& phi, const Vec<N>& sigma, Vec<N>& out) {
  for (Eigen::Index i = 0; i < sigma.size(); ++i) {
    const double s = sigma(i);
    out(i) = phi.weights(i) * s + (s > 0.0 ? phi.gains(i) : (s < 0.0 ? -phi.gains(i) : 0.0));
  }
  if (phi.norm_gain > 0.0) {
    const double ns = sigma.norm();
    if (ns > 0.0) out += (phi.norm_gain / ns) * sigma;
  }
}

// The boundary-layer law of width phi_width > 0: W sigma + A sat(sigma / phi) + a_norm sigma / max(||sigma||,
// phi). Returns whether sigma is inside the layer (every |sigma_i| <= phi and, with a norm term,
// ||sigma|| <= phi), where the law is linear in sigma.
template <int N>
bool boundary_layer_selection(const Controller<N>& phi, double phi_width, const Vec<N>& sigma, Vec<N>& out) {
  bool inside = true;
  for (Eigen::Index i = 0; i < sigma.size(); ++i) {
    const double r = sigma(i) / phi_width;
    const double sat = r > 1.0 ? 1.0 : (r < -1.0 ? -1.0 : r);
    if (std::abs(r) > 1.0 && phi.gains(i) > 0.0) inside = false;
    out(i) = phi.weights(i) * sigma(i) + phi.gains(i) * sat;
  }
  if (phi.norm_gain > 0.0) {
    const double ns = sigma.norm();
    if (ns > phi_width) inside = false;
    out += (phi.norm_gain / std::max(ns, phi_width)) * sigma;
  }
  return inside;
}

enum class SampledTrackingLaw { kImplicit, kExplicit, kSaturated };

inline const char* sampled_tracking_law_name(SampledTrackingLaw law) {
  switch (law) {
    case SampledTrackingLaw::kImplicit: return "implicit";
    case SampledTrackingLaw::kExplicit: return "explicit";
    case SampledTrackingLaw::kSaturated: return "saturated";
  }
  return "unknown";
}

// What the sampled-data controllers are given, once.
template <int N>
struct TrackingGains {
  Vec<N> lambda;                // Lambda = diag(lambda), lambda_i > 0
  Controller<N> phi;            // Phi on sigma: quadratic weights w_i, gains a_i, a_norm
  double period = 0.0;          // T_s > 0
  double boundary_layer = 0.0;  // phi > 0, kSaturated only

  // Empty when the gains can be used with law; otherwise what is wrong.
  std::string problem(SampledTrackingLaw law) const {
    const auto n = lambda.size();
    if (phi.weights.size() != n || phi.gains.size() != n) return "lambda, the weights and the gains must have one entry per coordinate";
    if (!(lambda.array() > 0.0).all() || !lambda.allFinite()) return "every lambda_i must be finite and > 0";
    if (!(phi.weights.array() >= 0.0).all() || !phi.weights.allFinite()) return "every weight w_i must be finite and >= 0";
    if (!(phi.gains.array() >= 0.0).all() || !phi.gains.allFinite()) return "every gain a_i must be finite and >= 0";
    if (!(phi.norm_gain >= 0.0) || !std::isfinite(phi.norm_gain)) return "the norm gain must be finite and >= 0";
    if (!(period > 0.0) || !std::isfinite(period)) return "the sampling period T_s must be finite and > 0";
    if (law == SampledTrackingLaw::kSaturated && (!(boundary_layer > 0.0) || !std::isfinite(boundary_layer)))
      return "the boundary layer width must be finite and > 0";
    return {};
  }
};

// One sample's control and what a report needs about it.
template <int N>
struct TrackingStep {
  using Pattern = typename OneStepSolver<N>::Pattern;
  Vec<N> e, e_dot, sigma;          // e_k, e'_k, sigma_k at the sample
  Vec<N> u_model;                  // the model-based part (implicit: M^_k (v_{r,k+1} - v_{r,k}) / T_s + C^_k v_{r,k+1} + g^_k)
  Vec<N> selection;                // xi_k, the element of dPhi used (implicit: of dPhi(sigma_{k+1}); else at sigma_k)
  Vec<N> u;                        // u_k = u_model - selection, held over [t_k, t_k + T_s)
  Vec<N> sigma_predicted;          // implicit: sigma_{k+1} of the nominal model; other laws: not set
  Pattern pattern;                 // implicit: the solver's sign pattern; 0 where a_i > 0 means sigma_{k+1,i} is exactly 0.0
  bool on_surface = false;         // implicit: sigma_{k+1} == 0 by the solver's closed form (no float comparison)
  bool in_boundary_layer = false;  // saturated: sigma_k inside the layer, where the law is linear
  bool solved = true;              // implicit: the one-step problem was solved (false: u is not usable)
  OneStepStats stats;              // implicit: the solver's statistics
  StepCheck condition;             // implicit: (4.2) at the sample, r_k = 2 T_s ||C^_k||_2 / lambda_min(M^_k)

  // Whether (4.2) held, r_k <= 1, so that Theorem 4.1 of ABL covers the step (implicit law only).
  bool condition_holds() const {
    return condition.lambda_min_m > 0.0 && condition.ratio_kind != BoundKind::kLowerBound &&
           condition.ratio_sq_num <= condition.ratio_sq_den;
  }

  void resize(int n) {
    e.setZero(n);
    e_dot.setZero(n);
    sigma.setZero(n);
    u_model.setZero(n);
    selection.setZero(n);
    u.setZero(n);
    sigma_predicted.setZero(n);
    pattern.setZero(n);
  }
};

template <int N>
class SampledTrackingController {
 public:
  // gains must have no problem (TrackingGains::problem) for law.
  SampledTrackingController(const TrackingGains<N>& gains, SampledTrackingLaw law)
      : gains_(gains), law_(law), checker_(static_cast<int>(gains.lambda.size())) {
    const int n = size();
    err_.resize(n);
    next_e_.setZero(n);
    next_v_r_.setZero(n);
    tmp_.setZero(n);
    x_.setZero(n);
    y_.setZero(n);
    P_.setZero(n, n);
    if (law_ == SampledTrackingLaw::kImplicit) solver_.configure(gains_.phi.gains, gains_.phi.norm_gain);
  }

  int size() const { return static_cast<int>(gains_.lambda.size()); }
  SampledTrackingLaw law() const { return law_; }
  const TrackingGains<N>& gains() const { return gains_; }

  // u_k from the sample (q_k, v_k) at t_k, the reference at t_k (now) and at t_k + T_s (next: used by the
  // implicit law only), and the nominal model at the sample. out must be sized (TrackingStep::resize).
  // False when the implicit one-step problem was not solved: out.u must then not be applied.
  bool step(const Vec<N>& q, const Vec<N>& v, const ReferencePoint<N>& now, const ReferencePoint<N>& next,
            const LagrangianTerms<N>& nominal, TrackingStep<N>& out) {
    const double Ts = gains_.period;
    const Vec<N>& lambda = gains_.lambda;
    tracking_errors(q, v, now, lambda, err_);
    out.e = err_.e;
    out.e_dot = err_.e_dot;
    out.sigma = err_.sigma;
    out.on_surface = false;
    out.in_boundary_layer = false;
    out.solved = true;
    switch (law_) {
      case SampledTrackingLaw::kExplicit:
        continuous_model_part(nominal, err_, out.u_model);
        least_norm_selection(gains_.phi, err_.sigma, out.selection);
        break;
      case SampledTrackingLaw::kSaturated:
        continuous_model_part(nominal, err_, out.u_model);
        out.in_boundary_layer = boundary_layer_selection(gains_.phi, gains_.boundary_layer, err_.sigma, out.selection);
        break;
      case SampledTrackingLaw::kImplicit: {
        // The predicted e_{k+1} and v_{r,k+1} ((0.2)'s position update q_{k+1} = q_k + T_s v_k).
        next_e_ = q + Ts * v - next.q;
        next_v_r_ = next.v - lambda.cwiseProduct(next_e_);
        // (6.5): P = M^/T_s + C^ + W, x = -M^ sigma_k / T_s.
        const double inv_ts = 1.0 / Ts;
        P_ = inv_ts * nominal.M + nominal.C;
        P_.diagonal() += gains_.phi.weights;
        x_.noalias() = nominal.M * err_.sigma;
        x_ *= -inv_ts;
        out.condition = checker_.check(nominal.M, nominal.C, Ts, 1.0);
        out.solved = solver_.solve(P_, x_, y_, out.stats);
        out.sigma_predicted = y_;
        out.pattern = solver_.pattern();
        out.on_surface = out.solved && out.stats.zero_by_closed_form;
        // xi_k = M^ (sigma_k - sigma_{k+1}) / T_s - C^ sigma_{k+1}, in dPhi(sigma_{k+1}).
        tmp_ = err_.sigma - y_;
        out.selection.noalias() = nominal.M * tmp_;
        out.selection *= inv_ts;
        out.selection.noalias() -= nominal.C * y_;
        // M^ (v_{r,k+1} - v_{r,k}) / T_s + C^ v_{r,k+1} + g^.
        tmp_ = next_v_r_ - err_.v_r;
        out.u_model.noalias() = nominal.M * tmp_;
        out.u_model *= inv_ts;
        out.u_model.noalias() += nominal.C * next_v_r_;
        out.u_model += nominal.g;
        break;
      }
    }
    out.u = out.u_model - out.selection;
    return out.solved;
  }

 private:
  TrackingGains<N> gains_;
  SampledTrackingLaw law_;
  OneStepSolver<N> solver_;
  StepConditionChecker<N> checker_;
  TrackingErrors<N> err_;
  Vec<N> next_e_, next_v_r_, tmp_, x_, y_;
  Mat<N> P_;
};

// Chattering of a sampled signal u_0, u_1, ... (one coordinate of the control, or of the selection),
// each value held for one period.
struct ChatteringIndex {
  int sign_changes = 0;          // between consecutive nonzero values (a 0.0 neither breaks nor makes one)
  double per_second = 0.0;       // sign_changes / (samples x period)
  double total_variation = 0.0;  // sum_k |u_{k+1} - u_k|
  double peak_to_peak = 0.0;     // max_k u_k - min_k u_k
};

// The number of sign changes: pairs of nonzero values, consecutive once the zeros between them are skipped,
// with opposite signs.
inline int sign_changes(const std::vector<double>& u) {
  int changes = 0, last = 0;
  for (const double x : u) {
    const int s = x > 0.0 ? 1 : (x < 0.0 ? -1 : 0);
    if (s == 0) continue;
    if (last != 0 && s != last) ++changes;
    last = s;
  }
  return changes;
}

inline double total_variation(const std::vector<double>& u) {
  double tv = 0.0;
  for (std::size_t k = 1; k < u.size(); ++k) tv += std::abs(u[k] - u[k - 1]);
  return tv;
}

inline ChatteringIndex chattering_index(const std::vector<double>& u, double period) {
  ChatteringIndex c;
  if (u.empty()) return c;
  c.sign_changes = sign_changes(u);
  c.per_second = c.sign_changes / (static_cast<double>(u.size()) * period);
  c.total_variation = total_variation(u);
  const auto [lo, hi] = std::minmax_element(u.begin(), u.end());
  c.peak_to_peak = *hi - *lo;
  return c;
}

}  // namespace moreau
