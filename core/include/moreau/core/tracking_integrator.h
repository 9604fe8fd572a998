// A fully actuated Lagrangian plant tracking a reference q_d(t) under the set-valued passivity-based
// controller of tracking.h, run over the whole interval: the continuous closed loop, or the digital
// controller (sampled at T_s, zero-order hold) with the plant integrated between samples.
//
// The plant: M(q) q'' + C(q, q') q' + g(t, q, q') = u - xi_plant, xi_plant in dPhi_plant(q'), with
// g = grad V + F (F the scene's perturbation, on the left as in ABL (0.1): d = -F) and Phi_plant the
// plant's own set-valued terms (joint friction; none in continuous mode). The controller's model is
// `Nominal` (M^, C^, g^ = grad V^: the controller knows no perturbation), scaled by nominal_scale.
//
// Continuous (settings.sampled empty): the controller u = M^ a_r + C^ v_r + g^ - xi, xi in dPhi(sigma),
// with the closed loop discretised as ABL's (0.2) in sigma. With Q^{k+1} = Q^k + h V^k (explicit in
// position), v_{r,k+1} = q_d'(t_{k+1}) - Lambda (Q^{k+1} - q_d(t_{k+1})) is known at t_k, and with
// a_{r,k} = (v_{r,k+1} - v_{r,k}) / h the plant's step
//   M (V^{k+1} - V^k) / h + C V^{k+1} + g = M^ a_{r,k} + C^ v_{r,k+1} + g^ - xi_k,  xi_k in dPhi(sigma_{k+1}),
// with V^{k+1} = v_{r,k+1} + sigma_{k+1}, is the inclusion (6.5) in y = sigma_{k+1}:
//   P y + x in -d phi(y),  P = M/h + C + W,
//   x = M (v_{r,k+1} - V^k) / h + C v_{r,k+1} + g - (M^ a_{r,k} + C^ v_{r,k+1} + g^).
// With an exact model (M^ = M, C^ = C, g^ = grad V) x = -M sigma_k / h + F: (0.2) for
// M sigma' + C sigma + F in -dPhi(sigma), the closed loop of docs/tracking.md, solved exactly by
// OneStepSolver (sigma_{k+1} == 0.0 when its closed form says so). The control is
// u_k = M^ a_{r,k} + C^ v_{r,k+1} + g^ - xi_k, xi_k = -(M/h + C) y - x.
//
// Sampled (settings.sampled = the law): at t_j = t0 + j T_s the controller reads the measured state
// (quantised to `quantum` and with Gaussian noise of standard deviation `noise`, seeded: both optional),
// computes u_j by SampledTrackingController (tracking.h: implicit, explicit or boundary layer) on the
// nominal model at the measurement, and holds it over [t_j, t_{j+1}). The plant takes T_s / h steps of
// (0.2) with u_j as a constant input: M (V^{k+1} - V^k) / h + C V^{k+1} + g - u_j in -dPhi_plant(V^{k+1}).
//
// Each state's sample carries, per coordinate, q_d, e = q - q_d, sigma (sampled: e' + Lambda e of the true
// state; continuous: the scheme's sigma_{k+1}, whose 0.0 is the solver's) and u, the control applied from t_k (held over the step that
// starts there; the last state repeats the last control): signals() and RunRecorder::signals. The run's TrackingSummary goes into
// RunSummary::tracking; its statistics "after reaching" are kept online, reset at every sample that is
// not on the surface (or outside the band), so a run of any length keeps O(n) memory.
//
// Model requirements: Plant as AblIntegrator's (evaluate, controller(), dof()); Nominal has
// evaluate(t, q, v, LagrangianTerms&); Reference has bool at(double t, ReferencePoint<N>&).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <string>

#include "moreau/core/controller.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/step_conditions.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/core/time_grid.h"
#include "moreau/core/tracking.h"
#include "moreau/core/types.h"

namespace moreau {

template <int N>
struct TrackingSettings : TimeGrid {
  TrackingGains<N> gains;                     // Lambda, Phi on sigma, T_s, boundary layer
  std::optional<SampledTrackingLaw> sampled;  // empty: the continuous closed loop
  double nominal_scale = 1.0;                 // M^, C^, g^ are the nominal model's times this
  double quantum = 0.0;                       // measurement resolution of q and v (0: none)
  double noise = 0.0;                         // standard deviation of the measurement noise (0: none)
  std::uint64_t seed = 1;                     // of the noise
  // The band of reaching for a sampled law, ||sigma_k||_inf <= band; <= 0: 2 max_i (a_i + a_norm) T_s /
  // lambda_min(M^(q_0)), the explicit law's peak-to-peak bound (docs/tracking.md).
  double band = 0.0;
};

template <class Plant, class Nominal, class Reference>
class TrackingIntegrator {
 public:
  static constexpr int N = Plant::kDof;

  TrackingIntegrator(Plant& plant, Nominal& nominal, const Reference& reference, const TrackingSettings<N>& settings)
      : plant_(plant),
        nominal_(nominal),
        reference_(reference),
        settings_(settings),
        grid_(settings.t0, settings.t_end, settings.h),
        checker_(plant.dof()),
        controller_(settings.gains, settings.sampled.value_or(SampledTrackingLaw::kImplicit)),
        noise_(settings.seed) {
    const int n = plant_.dof();
    const Controller<N>& plant_phi = plant_.controller();
    if (settings_.sampled) {
      solver_.configure(plant_phi.gains, plant_phi.norm_gain);
      step_weights_ = plant_phi.weights;
      steps_per_sample_ = std::max<std::int64_t>(1, std::llround(settings_.gains.period / settings_.h));
    } else {
      solver_.configure(settings_.gains.phi.gains, settings_.gains.phi.norm_gain);
      step_weights_ = settings_.gains.phi.weights;
    }
    for (LagrangianTerms<N>* t : {&terms_, &model_}) t->resize(n);
    for (ReferencePoint<N>* r : {&now_, &next_}) r->resize(n);
    err_.resize(n);
    step_out_.resize(n);
    for (Vec<N>* x : {&q_, &v_, &u_, &v_next_, &x_, &y_, &v_r_next_, &model_part_, &q_meas_, &v_meas_, &last_sign_, &last_u_, &sigma_next_,
                      &run_sign_, &run_last_u_})
      x->setZero(n);
    P_.setZero(n, n);
    mass_h_.setZero(n, n);
    sym_.setZero(n, n);
    if constexpr (N == Eigen::Dynamic) llt_ = Eigen::LLT<Mat<N>>(n);
    signals_.assign(static_cast<std::size_t>(kSignalsPerCoordinate * n), 0.0);
  }

  RunSummary run(const Vec<N>& q0, const Vec<N>& v0, RunObserver* observer = nullptr) {
    q_ = q0;
    v_ = v0;
    return SteppingDriver::run(*this, SteppingPlan{settings_.grid(), true}, observer);
  }

  // Columns of a sample's signals, in this order for coordinate i: q_d, e, sigma, u (4 n values).
  static constexpr int kSignalsPerCoordinate = 4;

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = false;
  static constexpr bool kTracksDissipation = false;
  double step_dissipation() const { return 0.0; }
  bool propose_step(double, double, double&, std::string&) { return false; }
  void on_failure() {}

  int dof() const { return plant_.dof(); }
  const double* q() const { return q_.data(); }
  const double* v() const { return v_.data(); }
  int signal_count() const { return static_cast<int>(signals_.size()); }
  const double* signals() const { return signals_.data(); }
  double energy() const { return energy_; }
  // The velocity of a tracking run follows q_d': it is read from the values, never held at 0 by a law.
  RestState rest_state() const { return rest_.state(); }
  double energy_allowance(double e_old, double e_initial) const {
    return 64.0 * std::numeric_limits<double>::epsilon() * std::max(e_old, e_initial);
  }

  bool begin(double t0, StepFailure& f) {
    rest_ = RestTracker{};
    rest_.update(v_);
    summary_ = TrackingSummary{};
    summary_.law = settings_.sampled ? sampled_tracking_law_name(*settings_.sampled) : "continuous";
    summary_.period = settings_.sampled ? settings_.gains.period : settings_.h;
    summary_.steps_per_sample = settings_.sampled ? steps_per_sample_ : 1;
    summary_.alpha = settings_.gains.phi.alpha();
    run_sign_.setZero();
    reset_after_reaching();
    if (settings_.sampled) {
      if (!nominal_at(t0, q_, v_, f, 0)) return false;
      band_ = settings_.band;
      if (!(band_ > 0.0)) {
        const double alpha_max = settings_.gains.phi.gains.size() ? settings_.gains.phi.gains.maxCoeff() : 0.0;
        const double lambda_min = checker_.check(model_.M, model_.C, 1.0, std::numeric_limits<double>::infinity()).lambda_min_m;
        band_ = 2.0 * (alpha_max + settings_.gains.phi.norm_gain) * settings_.gains.period / lambda_min;
      }
      summary_.band = band_;
    }
    return arrive(0, t0, f);
  }

  // Q^{k+1} = Q^k + h V^k, and V^{k+1}: the continuous loop's solution found at arrive(k), or the plant's
  // step (0.2) under the held control.
  bool step(std::int64_t k, double t, double h_k, double /*t_next*/, RunRecorder& rec, StepFailure& f) {
    RunSummary& s = rec.summary();
    s.mass.record(check_.lambda_min_m, check_.exact, k, t);
    if (!(check_.lambda_min_m > 0.0)) return f.at(k, t, q_.data(), v_.data(), not_positive_definite(check_.lambda_min_m, q_.data(), dof()));
    s.theorem41.record_squared(check_.ratio_sq_num, check_.ratio_sq_den, check_.ratio_kind, k, t);
    if (!settings_.sampled) {
      rec.solver_step(stats_.iterations, stats_.residual, stats_.used_fallback);
      s.solver.rest_steps += stats_.zero_by_closed_form;
    } else {
      const double inv_h = 1.0 / h_k;
      P_.noalias() = inv_h * terms_.M + terms_.C;
      P_.diagonal() += step_weights_;
      x_.noalias() = terms_.M * v_;
      x_ = terms_.g - u_ - inv_h * x_;
      OneStepStats st;
      if (!solver_.solve(P_, x_, y_, st))
        return f.at(k, t, q_.data(), v_.data(), "the plant's one-step inclusion (6.5) under the held control was not solved");
      rec.solver_step(st.iterations, st.residual, st.used_fallback);
      v_next_ = y_;
    }
    q_ += h_k * v_;
    v_ = v_next_;
    rest_.update(v_);
    return true;
  }

  // The state k: its terms, its signals, the control from t_k and (continuous) the next velocity.
  bool arrive(std::int64_t k, double t, StepFailure& f) {
    if (!q_.allFinite() || !v_.allFinite()) return f.at(k, t, q_.data(), v_.data(), "the state became non-finite");
    plant_.evaluate(t, q_, v_, terms_);
    if (!terms_.M.allFinite() || !terms_.C.allFinite() || !terms_.g.allFinite())
      return f.at(k, t, q_.data(), v_.data(), "model terms are not finite (an expression left its domain)");
    x_.noalias() = terms_.M * v_;
    energy_ = 0.5 * v_.dot(x_);
    if (!reference_.at(t, now_)) return f.at(k, t, q_.data(), v_.data(), "the reference is not defined at this time");
    tracking_errors(q_, v_, now_, settings_.gains.lambda, err_);
    // The continuous loop's sigma at a state after the first is the scheme's own unknown sigma_{k+1} (V^{k+1}
    // is v_{r,k+1} + sigma_{k+1} by definition); recomputed from V^{k+1} it would carry the round-off of
    // v - q_d' + Lambda e, and an exact 0.0 of the solver would read as 1e-17.
    if (!settings_.sampled && k > 0) err_.sigma = sigma_next_;
    const bool last = k >= grid_.steps;
    const double h_k = last ? settings_.h : grid_.step(k);
    check_ = checker_.check(terms_.M, terms_.C, h_k, std::numeric_limits<double>::infinity());
    bool on_surface;
    if (!settings_.sampled) {
      on_surface = k == 0 ? (err_.sigma.array() == 0.0).all() : stats_.zero_by_closed_form;
      if (!last && !continuous_control(k, t, h_k, f)) return false;
    } else {
      if (k % steps_per_sample_ == 0 && !last && !sample_control(k, t, f)) return false;
      on_surface = err_.sigma.cwiseAbs().maxCoeff() <= band_;
    }
    if (k % summary_.steps_per_sample == 0) {
      if (!last) perturbation(t);
      record_sample(k, t, on_surface, last);
    }
    const int n = dof();
    for (int i = 0; i < n; ++i) {
      double* s = &signals_[static_cast<std::size_t>(kSignalsPerCoordinate * i)];
      s[0] = now_.q(i);
      s[1] = err_.e(i);
      s[2] = err_.sigma(i);
      s[3] = u_(i);
    }
    return true;
  }

  // The continuous loop's step from state k (see the top of this file): y = sigma_{k+1}, V^{k+1}, u_k.
  bool continuous_control(std::int64_t k, double t, double h_k, StepFailure& f) {
    if (!nominal_at(t, q_, v_, f, k)) return false;
    const double t_next = grid_.time(k + 1);
    if (!reference_.at(t_next, next_)) return f.at(k, t, q_.data(), v_.data(), "the reference is not defined at the next step");
    const Vec<N>& lambda = settings_.gains.lambda;
    v_r_next_ = next_.v - lambda.cwiseProduct(q_ + h_k * v_ - next_.q);
    const double inv_h = 1.0 / h_k;
    // M^ a_{r,k} + C^ v_{r,k+1} + g^, a_{r,k} = (v_{r,k+1} - v_{r,k}) / h.
    y_ = v_r_next_ - err_.v_r;
    model_part_.noalias() = model_.M * y_;
    model_part_ *= inv_h;
    model_part_.noalias() += model_.C * v_r_next_;
    model_part_ += model_.g;
    mass_h_.noalias() = inv_h * terms_.M + terms_.C;
    y_ = v_r_next_ - v_;
    x_.noalias() = terms_.M * y_;
    x_ *= inv_h;
    x_.noalias() += terms_.C * v_r_next_;
    x_ += terms_.g - model_part_;
    P_ = mass_h_;
    P_.diagonal() += step_weights_;
    if (!solver_.solve(P_, x_, y_, stats_))
      return f.at(k, t, q_.data(), v_.data(), "the closed loop's one-step inclusion (6.5) in sigma was not solved");
    // u_k = model part - xi_k, xi_k = -(M/h + C) y - x (its quadratic part W y included).
    u_.noalias() = mass_h_ * y_;
    u_ += x_;
    u_ += model_part_;
    v_next_ = v_r_next_ + y_;
    sigma_next_ = y_;
    return true;
  }

  // The digital controller at sample k: the measurement, the nominal model there, u by the law.
  bool sample_control(std::int64_t k, double t, StepFailure& f) {
    measure();
    if (!nominal_at(t, q_meas_, v_meas_, f, k)) return false;
    if (!reference_.at(t + settings_.gains.period, next_))
      return f.at(k, t, q_.data(), v_.data(), "the reference is not defined one sampling period ahead");
    if (!controller_.step(q_meas_, v_meas_, now_, next_, model_, step_out_))
      return f.at(k, t, q_.data(), v_.data(), "the implicit controller's one-step inclusion (6.5) was not solved");
    u_ = step_out_.u;
    if (*settings_.sampled == SampledTrackingLaw::kImplicit) {
      // Strong monotonicity of y -> P y + d phi(y): the symmetric part of P = M^/T_s + C^ + W positive
      // definite (a Cholesky factor exists). (4.2) implies it; it is what uniqueness needs.
      ++summary_.condition_checked;
      summary_.condition42_violations += !step_out_.condition_holds();
      sym_ = (1.0 / settings_.gains.period) * model_.M;
      sym_ += 0.5 * (model_.C + model_.C.transpose());
      sym_.diagonal() += settings_.gains.phi.weights;
      llt_.compute(sym_);
      if (llt_.info() != Eigen::Success) {
        if (summary_.monotone_violations++ == 0) summary_.first_monotone_violation_time = t;
      }
      predicted_on_surface_from_ =
          step_out_.on_surface ? (predicted_on_surface_from_ ? predicted_on_surface_from_ : std::optional<double>(t)) : std::nullopt;
    }
    return true;
  }

  // rho = (M a_r + C v_r + g) - (M^ a_r + C^ v_r + g^) at this sample (plant at the true state, the
  // controller's model where it evaluated it): the closed loop is M sigma' + C sigma + xi = -rho, xi in
  // dPhi(sigma), and reaching needs ||rho|| < alpha (docs/tracking.md). Its largest norm over the samples.
  void perturbation(double t) {
    // Product by product: a difference of matrices would be a temporary (an allocation at dynamic size).
    x_.noalias() = terms_.M * err_.a_r;
    x_.noalias() -= model_.M * err_.a_r;
    x_.noalias() += terms_.C * err_.v_r;
    x_.noalias() -= model_.C * err_.v_r;
    x_ += terms_.g - model_.g;
    const double r = x_.norm();
    if (r > summary_.perturbation_max) {
      summary_.perturbation_max = r;
      summary_.perturbation_max_time = t;
    }
  }

  void measure() {
    q_meas_ = q_;
    v_meas_ = v_;
    if (settings_.noise > 0.0) {
      std::normal_distribution<double> gauss(0.0, settings_.noise);
      for (int i = 0; i < dof(); ++i) {
        q_meas_(i) += gauss(noise_);
        v_meas_(i) += gauss(noise_);
      }
    }
    if (settings_.quantum > 0.0) {
      q_meas_ = (q_meas_ / settings_.quantum).array().round() * settings_.quantum;
      v_meas_ = (v_meas_ / settings_.quantum).array().round() * settings_.quantum;
    }
  }

  bool nominal_at(double t, const Vec<N>& q, const Vec<N>& v, StepFailure& f, std::int64_t k) {
    nominal_.evaluate(t, q, v, model_);
    if (settings_.nominal_scale != 1.0) {
      model_.M *= settings_.nominal_scale;
      model_.C *= settings_.nominal_scale;
      model_.g *= settings_.nominal_scale;
    }
    if (!model_.M.allFinite() || !model_.C.allFinite() || !model_.g.allFinite())
      return f.at(k, t, q_.data(), v_.data(), "the controller's nominal model is not finite here");
    return true;
  }

  // The statistics of a sample: reset when it is not on the surface (or outside the band), so that at
  // the end they cover the samples from the reaching time on.
  // The last state applies no control: its u (the last one, held) is not counted again.
  void record_sample(std::int64_t k, double t, bool on_surface, bool last) {
    TrackingSummary& s = summary_;
    ++s.samples;
    if (!last) {
      s.u_max = std::max(s.u_max, u_.cwiseAbs().maxCoeff());
      s.u_energy += s.period * u_.squaredNorm();
      s.run_sign_changes += count_sign_changes(run_sign_);
      if (s.samples > 1) s.run_total_variation += (u_ - run_last_u_).cwiseAbs().sum();
      run_last_u_ = u_;
    }
    s.error_final = err_.e.cwiseAbs().maxCoeff();
    if (!on_surface) {
      reset_after_reaching();
      s.reached = false;
      return;
    }
    if (!s.reached) {
      s.reached = true;
      s.reaching_time = t;
      s.reaching_step = k;
    }
    ++after_.samples;
    after_.error_max = std::max(after_.error_max, err_.e.cwiseAbs().maxCoeff());
    after_.error_sq += err_.e.squaredNorm();
    after_.sigma_max = std::max(after_.sigma_max, err_.sigma.cwiseAbs().maxCoeff());
    if (last) return;
    after_.sign_changes += count_sign_changes(last_sign_);
    if (after_.samples > 1) after_.total_variation += (u_ - last_u_).cwiseAbs().sum();
    last_u_ = u_;
  }

  // The coordinates of u whose sign differs from the last nonzero sign in `signs` (0: none yet), which
  // this updates: zeros neither break nor make a change.
  int count_sign_changes(Vec<N>& signs) const {
    int changes = 0;
    for (int i = 0; i < dof(); ++i) {
      const double u = u_(i);
      const double sign = u > 0.0 ? 1.0 : (u < 0.0 ? -1.0 : 0.0);
      if (sign == 0.0) continue;
      changes += signs(i) != 0.0 && sign != signs(i);
      signs(i) = sign;
    }
    return changes;
  }

  void reset_after_reaching() {
    after_ = After{};
    last_sign_.setZero();
  }

  void finish(RunRecorder& rec, std::int64_t k, double t) {
    RunSummary& s = rec.summary();
    s.equilibrium.evaluated = false;  // no Theorem 4.3 equilibrium: the state follows q_d
    s.solver.linear_solver = "dense LU with partial pivoting";
    TrackingSummary& tr = summary_;
    if (tr.reached) {
      tr.after_samples = after_.samples;
      tr.error_max = after_.error_max;
      tr.error_rms = std::sqrt(after_.error_sq / (static_cast<double>(after_.samples) * dof()));
      tr.sigma_max = after_.sigma_max;
      tr.sign_changes = after_.sign_changes;
      tr.total_variation = after_.total_variation;
      const double span = static_cast<double>(after_.samples) * tr.period;
      tr.sign_changes_per_second = span > 0.0 ? after_.sign_changes / span : 0.0;
    }
    tr.predicted_on_surface_time = predicted_on_surface_from_;
    s.tracking = tr;
    rec.finish(k, t, q_.data(), v_.data(), energy_, false);
  }

  struct After {
    std::int64_t samples = 0;
    double error_max = 0.0, error_sq = 0.0, sigma_max = 0.0, total_variation = 0.0;
    std::int64_t sign_changes = 0;
  };

  Plant& plant_;
  Nominal& nominal_;
  const Reference& reference_;
  TrackingSettings<N> settings_;
  FixedTimeGrid grid_;
  StepConditionChecker<N> checker_;
  StepCheck check_;
  SampledTrackingController<N> controller_;
  OneStepSolver<N> solver_;
  OneStepStats stats_;
  std::mt19937_64 noise_;
  std::int64_t steps_per_sample_ = 1;
  double band_ = 0.0;
  Vec<N> step_weights_;  // W of the one-step inclusion: the plant's Phi (sampled), or the controller's on sigma (continuous)
  LagrangianTerms<N> terms_, model_;
  ReferencePoint<N> now_, next_;
  TrackingErrors<N> err_;
  TrackingStep<N> step_out_;
  Mat<N> P_, mass_h_;  // P = M/h + C + W, and M/h + C
  Mat<N> sym_;         // the implicit controller's (P + P^T) / 2
  Eigen::LLT<Mat<N>> llt_;
  Vec<N> q_, v_, u_, v_next_, x_, y_, v_r_next_, model_part_, q_meas_, v_meas_, last_sign_, last_u_, sigma_next_, run_sign_, run_last_u_;
  std::vector<double> signals_;
  double energy_ = 0.0;
  RestTracker rest_;
  TrackingSummary summary_;
  After after_;
  std::optional<double> predicted_on_surface_from_;
};

}  // namespace moreau
