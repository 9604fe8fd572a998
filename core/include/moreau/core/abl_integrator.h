// The implicit Euler scheme of Adly, Brogliato and Le (2016), eq. (0.2), for
//
//   M(q) q'' + C(q, q') q' + grad V(q) + F(t, q, q')  in  -dPhi(q')                       (0.1)
//
// Update rule (implicit in velocity, explicit in position):
//
//   M(Q^k) (V^{k+1} - V^k) / h_k + C(Q^k, V^k) V^{k+1} + grad V(Q^k) + F(t_k, Q^k, V^k)
//                                                                     in -dPhi(V^{k+1})
//   Q^{k+1} = Q^k + h_k V^k
//
// With Phi = 1/2 <W v, v> + phi (controller.h), each step is the inclusion (6.5) P y + x in -d phi(y),
// y = V^{k+1}, P = M/h_k + C + W, x = grad V + F - M V^k / h_k (the paper's (6.4) with F added), solved
// exactly by OneStepSolver.
//
// Step rules: fixed h; Theorem 4.1, h_k = min(h, k1 / (2 k3 ||V^k||)); Theorem 4.2, additionally
// h_k <= h_{k-1} and ||eps_k||_2 <= 2 eta with eps_k of (4.9), eta = min w_i / 2 from Phi's quadratic
// part. k1 and k3 are the constants of Assumptions 3.1 and 3.2 when the caller gives them; otherwise their
// local values at (Q^k, V^k): k1 = lambda_min(M(Q^k)) and k3 = ||C(Q^k, V^k)||_2 / ||V^k||. h_k* of (4.9)
// is found by halving from the Theorem 4.1 value until ||eps_k|| <= 2 eta holds. Every rule shortens the
// last step to land on t_end exactly.
//
// Order: 1/2 in general (Theorem 5.2), 1 for constant M (Remark 5.1). Theorem 4.2: E_k non-increasing
// under Assumption 4.1. Theorem 4.3: V^k == 0 after finitely many steps when
// -F(Q*, 0) - grad V(Q*) lies in int dPhi(0).
//
// Model requirements (a compiled scene or a hand-written C++ functor; templates, so a functor inlines):
//   static constexpr int kDof;                       // N, or Eigen::Dynamic
//   int dof() const;
//   const Controller<kDof>& controller() const;
//   bool constant_mass() const;
//   bool constant_terms() const;                      // M, C and g the same at every (t, q, v): evaluated once
//   void evaluate(double t, const Vec<N>& q, const Vec<N>& v, LagrangianTerms<N>& out);  // M, C, g
//   void mass(const Vec<N>& q, Mat<N>& M);           // M(q) alone, for the Theorem 4.2 rule
#pragma once

#include <chrono>
#include <cstdio>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "moreau/core/controller.h"
#include "moreau/core/observer.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/step_conditions.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/core/time_grid.h"
#include "moreau/core/types.h"
#include "moreau/platform/number_text.h"

namespace moreau {

enum class StepRule { kFixed, kTheorem41, kTheorem42 };

// How V^{k+1} is computed. kImplicit is the scheme (0.2). kExplicit is the peer a user would otherwise
// pick, for studies: everything at (Q^k, V^k) with the single-valued sign (sgn 0 = 0),
//   M(Q^k) (V^{k+1} - V^k)/h_k = -(C V^k + grad V + F + W V^k + A sgn(V^k) + a_norm V^k/||V^k||),
// which chatters around v = 0 instead of resting there (Acary and Brogliato 2010).
enum class VelocityUpdate { kImplicit, kExplicit };

// The grid (h is the fixed step, or the upper bound of the rules of Theorems 4.1 and 4.2) and the
// scheme's own options.
struct AblSettings : TimeGrid {
  StepRule step_rule = StepRule::kFixed;
  VelocityUpdate velocity_update = VelocityUpdate::kImplicit;
  std::optional<double> k1;  // lower bound of M(q) (Assumption 3.1); local value if absent
  std::optional<double> k3;  // bound ||C(u, v)|| <= k3 ||v|| (Assumption 3.2); local value if absent
  // P = M/h + C + W is zero beyond this distance from its diagonal at every state (-1: not known). The
  // scene compiler derives it from which entries of M and C are identically zero; the one-step solver
  // then uses banded LU when the band is narrow (one_step_solver.h).
  int bandwidth = -1;
};

template <class Model>
class AblIntegrator {
 public:
  static constexpr int N = Model::kDof;

  AblIntegrator(Model& model, const AblSettings& settings) : model_(model), settings_(settings), checker_(model.dof()) {
    const int n = model_.dof();
    const Controller<N>& phi = model_.controller();
    weights_ = phi.weights;
    gains_ = phi.gains;
    norm_gain_ = phi.norm_gain;
    eta_ = phi.eta();
    solver_.configure(phi.gains, phi.norm_gain, settings_.bandwidth);
    // Dynamic sizes with a known band read M, C and P within it only (their entries beyond it are
    // identically zero, never written): O(n b) per pass instead of O(n^2). The products M V^k and P y
    // stay whole, the latter so that the acceptance of (6.5) always sees the whole of P.
    band_ = (N == Eigen::Dynamic && settings_.bandwidth >= 0 && settings_.bandwidth < n) ? settings_.bandwidth : -1;
    terms_.resize(n);
    P_.setZero(n, n);
    Mtrial_.setZero(n, n);
    eps_.setZero(n, n);
    x_.setZero(n);
    y_.setZero(n);
    Mv_.setZero(n);
    zero_.setZero(n);
    q_trial_.setZero(n);
    q_.setZero(n);
    v_.setZero(n);
    if constexpr (N == Eigen::Dynamic) mass_lu_ = Eigen::PartialPivLU<Mat<N>>(n);
  }

  // Runs from (Q^0, V^0) at t0 to t_end. Never throws for numerical trouble: a failing step (solver not
  // converged, non-finite state, step rule impossible) ends the run with RunStatus::kFailed and the last
  // good state, which is all the observer has seen.
  RunSummary run(const Vec<N>& q0, const Vec<N>& v0, RunObserver* observer = nullptr) {
    q_ = q0;
    v_ = v0;
    const SteppingPlan plan{settings_.grid(), settings_.step_rule == StepRule::kFixed};
    return SteppingDriver::run(*this, plan, observer);
  }

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = true;
  static constexpr bool kTracksDissipation = true;
  double step_dissipation() const { return step_work_; }
  void on_failure() {}

  // The scheme's part of the stepping loop (stepping_driver.h).
  int dof() const { return model_.dof(); }
  const double* q() const { return q_.data(); }
  const double* v() const { return v_.data(); }
  double energy() const { return energy_; }
  // The scheme (0.2): V^{k+1} rests when the one-step solver took the closed form y = 0 of Lemma 6.1
  // (-x in dPhi(0): the law holds it there), never because the linear solve underflowed to 0.0. The
  // explicit peer has no such statement: its rest is read from the values (RestTracker).
  RestState rest_state() const { return rest_.state(); }
  // Round-off in E_k itself: a few ulps of the run's energy scale.
  double energy_allowance(double e_old, double e_initial) const {
    return 64.0 * std::numeric_limits<double>::epsilon() * std::max(e_old, e_initial);
  }

  bool begin(double t0, StepFailure& f) {
    rest_ = RestTracker{};
    rest_.update(v_);  // the initial state, as given
    terms_vary_ = true;
    if (!evaluate(0, t0, f, "model terms are not finite at the initial state")) return false;
    terms_vary_ = !model_.constant_terms();
    return true;
  }

  // M, C, g at (t_k, Q^k, V^k) (kept from the first step when the model's are constant), and
  // E_k = 1/2 <M V^k, V^k>. arrive() inlines it always for one coordinate: with one runner per size in its
  // own translation unit, GCC stopped inlining it into the step loop there (27 instructions and a call
  // per step on the damped relay from JSON, callgrind); forced for every size, it cost the manipulator
  // 2.4 % more instructions per step, so larger sizes keep GCC's choice.
  bool evaluate(std::int64_t k, double t, StepFailure& f, const char* why) { return evaluate_inlined(k, t, f, why); }
  [[gnu::always_inline]] bool evaluate_inlined(std::int64_t k, double t, StepFailure& f, const char* why) {
    if (terms_vary_) {
      model_.evaluate(t, q_, v_, terms_);
      if (!all_finite(terms_.M, band_) || !all_finite(terms_.C, band_) || !terms_.g.allFinite())
        return f.at(k, t, q_.data(), v_.data(), why);
    }
    if constexpr (N == 2) {
      // The same products and sums as Eigen's M * v, from the entries one by one: a scene's model has
      // just written M's (and C's) entries one by one (its step tape), and Eigen's 16-byte loads of M's
      // columns right after those 8-byte stores wait for them to reach the cache instead of taking their
      // values from the store buffer. Measured on the manipulator from JSON: see README, Performance.
      const double* m = terms_.M.data();
      Mv_(0) = m[0] * v_(0) + m[2] * v_(1);
      Mv_(1) = m[1] * v_(0) + m[3] * v_(1);
    } else {
      Mv_.noalias() = terms_.M * v_;
    }
    energy_ = 0.5 * v_.dot(Mv_);
    return true;
  }

  // One step of (0.2): the inclusion (6.5) for V^{k+1}, then Q^{k+1} = Q^k + h_k V^k.
  bool step(std::int64_t k, double t, double h_k, double /*t_next*/, RunRecorder& rec, StepFailure& f) {
    // Assumption 3.1 and Theorem 4.1's (4.2) at (Q^k, V^k), from the terms already evaluated.
    if (!check_step(rec, h_k, k, t)) return f.at(k, t, q_.data(), v_.data(), failure_);
    RunSummary& s = rec.summary();
    const double inv_h = 1.0 / h_k;
    if (settings_.velocity_update == VelocityUpdate::kImplicit) {
      if constexpr (N == 2) {  // entry by entry, as M V^k in evaluate() and for the same reason
        const double* m = terms_.M.data();
        const double* c = terms_.C.data();
        P_(0, 0) = (inv_h * m[0] + c[0]) + weights_(0);
        P_(1, 0) = inv_h * m[1] + c[1];
        P_(0, 1) = inv_h * m[2] + c[2];
        P_(1, 1) = (inv_h * m[3] + c[3]) + weights_(1);
        x_(0) = terms_.g(0) - inv_h * Mv_(0);
        x_(1) = terms_.g(1) - inv_h * Mv_(1);
      } else {
        if (band_ >= 0) {  // the band only: beyond it P_ keeps the zeros of configure
          for_each_band_segment(P_, band_, [&](Eigen::Index j, Eigen::Index first, Eigen::Index length) {
            P_.col(j).segment(first, length) = inv_h * terms_.M.col(j).segment(first, length) + terms_.C.col(j).segment(first, length);
          });
        } else {
          P_.noalias() = inv_h * terms_.M + terms_.C;  // one pass; the same two roundings per entry as before
        }
        P_.diagonal() += weights_;
        x_ = terms_.g - inv_h * Mv_;
      }
    }
    OneStepStats st;
    if (settings_.velocity_update == VelocityUpdate::kExplicit) {
      explicit_velocity(v_, h_k);
      st.iterations = 1;  // one linear solve with M
    } else {
      if (!solver_.solve(P_, x_, y_, st)) return f.at(k, t, q_.data(), v_.data(), unsolved_step_message(st));
      // The work done against dPhi over the step, h_k <xi, V^{k+1}> with xi = -(P y + x) + W y in dPhi(y):
      // the same for every element of dPhi(y) (dissipation_rate in controller.h), so it needs no multiplier.
      // y = 0 (the closed form of Lemma 6.1, no iteration) takes none. The explicit peer's xi is at V^k,
      // not in dPhi(V^{k+1}): it is not tracked. The driver sums it (step_dissipation()).
      // (From the integrator's own copies of w and a, beside the step's data: read from the model, they cost
      // the manipulator from JSON 7% per step instead of 3.4%, measured A/B.)
      step_work_ = st.iterations != 0 ? h_k * dissipation_rate(weights_, gains_, norm_gain_, y_) : 0.0;
    }
    rec.solver_step(st.iterations, st.residual, st.used_fallback);
    s.solver.rest_steps += (st.iterations == 0);  // the y = 0 closed form of Lemma 6.1

    q_ += h_k * v_;  // Q^{k+1} = Q^k + h_k V^k: explicit in position
    v_ = y_;
    if (settings_.velocity_update == VelocityUpdate::kImplicit)
      rest_.update(v_, st.iterations == 0);
    else
      rest_.update(v_);
    return true;
  }

  bool arrive(std::int64_t k, double t, StepFailure& f) {
    if (!q_.allFinite() || !v_.allFinite()) return f.at(k, t, q_.data(), v_.data(), "the state became non-finite");
    const char* why = "model terms are not finite (an expression left its domain)";
    if constexpr (N == 1) return evaluate_inlined(k, t, f, why);
    return evaluate(k, t, f, why);
  }

  // h_k of Theorems 4.1 and 4.2 (the driver lands it on t_end).
  bool propose_step(double /*t*/, double h_prev, double& h_k, std::string& why) { return adaptive_step(q_, v_, h_prev, h_k, why); }

  // The summary of a run that ended, and Theorem 4.3's equilibrium inclusion at its final position:
  // -F(t, Q, 0) - grad V(Q) in dPhi(0).
  void finish(RunRecorder& rec, std::int64_t k, double t) {
    RunSummary& s = rec.summary();
    model_.evaluate(t, q_, zero_, terms_);
    const Vec<N> z = -terms_.g;
    const Controller<N>& phi = model_.controller();
    s.equilibrium.evaluated = z.allFinite();
    s.equilibrium.residual = phi.distance_to_subdifferential_at_zero(z);
    s.equilibrium.interior = phi.in_interior_of_subdifferential_at_zero(z);
    s.solver.linear_solver = linear_solver_description();
    s.dissipation_tracked = settings_.velocity_update == VelocityUpdate::kImplicit;
    rec.finish(k, t, q_.data(), v_.data(), energy_, s.equilibrium.evaluated && s.equilibrium.residual == 0.0);
  }

  // Why a step's inclusion (6.5) was not accepted: a P whose LU breaks down (singular, or entries not
  // finite) leaves no finite residual or tolerance to quote, and says so instead of printing "nan".
  std::string unsolved_step_message(const OneStepStats& st) const {
    if (!P_.allFinite() || !x_.allFinite())
      return "the one-step inclusion (6.5) has non-finite data: P = M/h + C + W or x = g - M V^k / h is not finite";
    if (!std::isfinite(st.residual) || !std::isfinite(st.tolerance))
      return "the one-step inclusion (6.5) was not solved: P = M/h + C + W is singular to working precision";
    return "the one-step inclusion (6.5) was not solved to round-off (residual " + platform::significant(st.residual, 3) +
           " above the tolerance " + platform::significant(st.tolerance, 3) + ")";
  }

  // For the report: which factorisation solved the step's linear systems.
  std::string linear_solver_description() const {
    if (settings_.velocity_update == VelocityUpdate::kExplicit) return "dense LU with partial pivoting (of M)";
    if (solver_.shares_factorisation()) return "dense LU with partial pivoting, of a step's first pattern, updated for its later patterns";
    if (solver_.banded_width() < 0) return "dense LU with partial pivoting";
    char buf[80];
    std::snprintf(buf, sizeof buf, "banded LU with partial pivoting, bandwidth %d", solver_.banded_width());
    return buf;
  }
  // Records lambda_min(M(Q^k)) and, for the scheme (0.2), r_k of (4.2). False (with failure_ set) when
  // M(Q^k) is not positive definite: the run stops there, naming t and q.
  bool check_step(RunRecorder& rec, double h_k, std::int64_t k, double t) {
    RunSummary& s = rec.summary();
    // The explicit peer records no r_k: an infinite ceiling spares the closed form of ||C||_2.
    const bool records_ratio = settings_.velocity_update == VelocityUpdate::kImplicit;
    const StepCheck c =
        checker_.check(terms_.M, terms_.C, h_k, records_ratio ? s.theorem41.ceiling() : std::numeric_limits<double>::infinity(), band_);
    s.mass.record(c.lambda_min_m, c.exact, k, t);
    if (!(c.lambda_min_m > 0.0)) {
      failure_ = not_positive_definite(c.lambda_min_m, q_.data(), static_cast<int>(q_.size()));
      return false;
    }
    if (records_ratio) s.theorem41.record_squared(c.ratio_sq_num, c.ratio_sq_den, c.ratio_kind, k, t);
    return true;
  }

  // The explicit peer's velocity update (see VelocityUpdate::kExplicit) into y_.
  void explicit_velocity(const Vec<N>& v, double h) {
    const Controller<N>& phi = model_.controller();
    x_.noalias() = terms_.C * v;
    x_ += terms_.g;
    x_ += weights_.cwiseProduct(v);
    for (int i = 0; i < x_.size(); ++i) x_(i) += phi.gains(i) * (v(i) > 0.0 ? 1.0 : (v(i) < 0.0 ? -1.0 : 0.0));
    const double vn = v.norm();
    if (phi.norm_gain > 0.0 && vn > 0.0) x_ += (phi.norm_gain / vn) * v;
    mass_lu_.compute(terms_.M);
    y_.noalias() = mass_lu_.solve(x_);
    y_ = v - h * y_;
  }

  // Smallest eigenvalue of a symmetric matrix, and the spectral norm of any square matrix.
  double min_eigenvalue(const Mat<N>& S) {
    if constexpr (N == 1) {
      return S(0, 0);
    } else if constexpr (N == 2) {
      const double m = 0.5 * (S(0, 0) + S(1, 1));
      const double d = std::hypot(0.5 * (S(0, 0) - S(1, 1)), S(0, 1));
      return m - d;
    } else {
      eig_.compute(S, Eigen::EigenvaluesOnly);
      return eig_.eigenvalues()(0);
    }
  }
  double max_abs_eigenvalue(const Mat<N>& S) {
    if constexpr (N == 1) {
      return std::abs(S(0, 0));
    } else if constexpr (N == 2) {
      const double m = 0.5 * (S(0, 0) + S(1, 1));
      const double d = std::hypot(0.5 * (S(0, 0) - S(1, 1)), S(0, 1));
      return std::max(std::abs(m - d), std::abs(m + d));
    } else {
      eig_.compute(S, Eigen::EigenvaluesOnly);
      return std::max(std::abs(eig_.eigenvalues()(0)), std::abs(eig_.eigenvalues()(eig_.eigenvalues().size() - 1)));
    }
  }

  // h_k of Theorems 4.1 and 4.2 (before landing on t_end). Returns false with a reason when the rule
  // cannot be met.
  bool adaptive_step(const Vec<N>& q, const Vec<N>& v, double h_prev, double& h_k, std::string& why) {
    double h = settings_.h;
    const double vnorm = v.norm();
    if (vnorm > 0.0) {
      const double k1 = settings_.k1 ? *settings_.k1 : min_eigenvalue(terms_.M);
      double k3;
      if (settings_.k3) {
        k3 = *settings_.k3;
      } else {
        eps_.noalias() = terms_.C.transpose() * terms_.C;
        k3 = std::sqrt(max_abs_eigenvalue(eps_)) / vnorm;
      }
      if (!(k1 > 0.0)) {
        why = "Theorem 4.1 rule: k1 = lambda_min(M) is not positive";
        return false;
      }
      if (k3 > 0.0) h = std::min(h, k1 / (2.0 * k3 * vnorm));
    }
    if (settings_.step_rule == StepRule::kTheorem42) {
      h = std::min(h, h_prev);
      if (!model_.constant_mass() || !terms_.C.isZero(0.0)) {
        // h_k* of (4.9): the largest h = h_start / 2^j with ||eps_k(h)||_2 <= 2 eta.
        for (int halvings = 0;; ++halvings) {
          q_trial_ = q + h * v;
          model_.mass(q_trial_, Mtrial_);
          eps_ = (Mtrial_ - terms_.M) / h - terms_.C - terms_.C.transpose();
          if (max_abs_eigenvalue(eps_) <= 2.0 * eta_) break;
          if (halvings == 80 || eta_ == 0.0) {
            why = eta_ == 0.0 ? "Theorem 4.2 rule: ||eps_k|| <= 2 eta needs eta > 0 (a quadratic controller term)"
                              : "Theorem 4.2 rule: no h_k with ||eps_k|| <= 2 eta after 80 halvings";
            return false;
          }
          h *= 0.5;
        }
      }
    }
    h_k = h;
    return true;
  }

  Model& model_;
  AblSettings settings_;
  Vec<N> weights_, gains_;  // Phi's w_i and a_i (controller.h), kept beside the step's own data
  double norm_gain_ = 0.0;
  double eta_ = 0.0;
  OneStepSolver<N> solver_;
  LagrangianTerms<N> terms_;
  bool terms_vary_ = true;  // false: the model's terms are constant, and terms_ holds them
  int band_ = -1;           // M, C and P are zero beyond this distance from the diagonal (-1: read them whole)
  Mat<N> P_, Mtrial_, eps_;
  Vec<N> q_, v_;            // the state (Q^k, V^k)
  double energy_ = 0.0;     // E_k = 1/2 <M(Q^k) V^k, V^k>
  double step_work_ = 0.0;  // h_k <xi, V^{k+1}> of the last step (0 for the explicit peer)
  Vec<N> x_, y_, Mv_, zero_, q_trial_;
  Eigen::SelfAdjointEigenSolver<Mat<N>> eig_;
  Eigen::PartialPivLU<Mat<N>> mass_lu_;
  StepConditionChecker<N> checker_;
  std::string failure_;
  RestTracker rest_;
};

}  // namespace moreau
