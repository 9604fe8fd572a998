// What a run reports: status, finite-step convergence (Theorem 4.3), the energy sequence (Theorem 4.2),
// the equilibrium check, solver effort and wall time by phase. Plain data; formatting lives in the
// client, except the one-line BriefReport.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "moreau/core/verdict.h"

namespace moreau {

enum class RunStatus { kCompleted, kFailed, kCancelled };
const char* to_string(RunStatus status);

struct SolverEffort {
  int max_iterations = 0;     // most pattern solves (or sweeps) in one step
  double max_residual = 0.0;  // largest accepted dist(-(P y + x), d phi(y)) over the run
  std::int64_t total_iterations = 0;
  std::int64_t fallback_steps = 0;  // steps that needed the exhaustive or forward-backward fallback
  std::int64_t rest_steps = 0;      // steps solved by the y = 0 closed form (velocity exactly at rest)
  std::string linear_solver;        // how the step's linear systems were solved (empty: not stated)
};

struct EquilibriumCheck {
  bool evaluated = false;
  // dist(-F(t, Q, 0) - grad V(Q), dPhi(0)) at the final state: 0 when Q is an equilibrium of (0.2).
  double residual = 0.0;
  // Whether -F(t, Q, 0) - grad V(Q) lies in int dPhi(0), the finite-convergence condition of Thm 4.3.
  bool interior = false;
};

// A per-step condition "ratio <= 1": how many steps were checked, how many failed, the first failure and
// the largest ratio (with where it was).
// Whether a recorded value is the quantity itself or a certified bound of it.
enum class BoundKind { kExact, kLowerBound, kUpperBound };

struct StepConditionTrack {
  std::int64_t checked = 0;
  std::int64_t violations = 0;
  std::int64_t first_violation_step = -1;
  double first_violation_time = 0.0;
  std::int64_t worst_step = -1;
  double worst_time = 0.0;

  // A ratio above 1 + kRoundoff fails: the Theorem 4.1 rule sets r_k = 1 up to round-off on purpose.
  static constexpr double kRoundoff = 64.0 * std::numeric_limits<double>::epsilon();

  // r_k^2 = num / den (den > 0), given as a fraction so that the hot loop needs no division and no square
  // root for it; kind says whether it is r_k^2 or a bound of it (an upper bound where (4.2) holds, a
  // lower bound where it certainly fails).
  void record_squared(double num, double den, BoundKind kind, std::int64_t k, double t) {
    ++checked;
    if (num <= ceiling_ * den) return;  // most steps: neither a new largest ratio nor a violation
    if (num * worst_den_ > worst_num_ * den) {
      worst_num_ = num;
      worst_den_ = den;
      worst_kind = kind;
      worst_step = k;
      worst_time = t;
      ceiling_ = std::min(1.0, num / den) * (1.0 - 1e-6);
    }
    if (num > den * ((1.0 + kRoundoff) * (1.0 + kRoundoff))) {
      if (violations == 0) {
        first_violation_step = k;
        first_violation_time = t;
      }
      ++violations;
    }
  }
  // The largest recorded r_k. With no violation, an upper bound on every checked ratio; with violations,
  // the largest r_k or (worst_kind == kLowerBound) a lower bound of the largest.
  BoundKind worst_kind = BoundKind::kExact;
  double worst_ratio() const { return worst_num_ > 0.0 ? std::sqrt(worst_num_ / worst_den_) : 0.0; }
  // Below this r_k^2 a step can move neither the largest ratio nor the violations: the largest recorded
  // r_k^2, capped at 1, less a relative 1e-6 that covers the round-off of this division and of the bounds
  // a checker may give below it (StepConditionChecker::check).
  double ceiling() const { return ceiling_; }
  Verdict verdict() const { return checked == 0 ? Verdict::kNotChecked : (violations > 0 ? Verdict::kFails : Verdict::kHolds); }

 private:
  double worst_num_ = 0.0, worst_den_ = 1.0;
  double ceiling_ = 0.0;
};

// The smallest eigenvalue of M(Q^k) over the run (Assumption 3.1 at the visited states): exact for n <= 2;
// for larger n a certified lower bound wherever a bound already proved definiteness (step_conditions.h),
// and then lambda_min_exact is false.
struct MassDefinitenessTrack {
  std::int64_t checked = 0;
  double lambda_min = std::numeric_limits<double>::infinity();
  bool lambda_min_exact = true;  // false: lambda_min is a lower bound of the smallest eigenvalue seen
  std::int64_t at_step = -1;
  double at_time = 0.0;

  void record(double lambda, bool exact, std::int64_t k, double t) {
    ++checked;
    if (lambda < lambda_min) {
      lambda_min = lambda;
      lambda_min_exact = exact;
      at_step = k;
      at_time = t;
    }
  }
  Verdict verdict() const { return checked == 0 ? Verdict::kNotChecked : (lambda_min > 0.0 ? Verdict::kHolds : Verdict::kFails); }
};

// Assumption 4.1 2)-3) of Adly, Brogliato and Le (2016) at the states a run recorded: the largest
// ||F(t_k, Q^k, V^k)|| and ||grad V(Q^k)|| seen, with where. Filled by the layer that can evaluate F and
// grad V apart (the scene's compiled expressions); samples == 0 when nobody did.
struct ForceBoundTrack {
  std::int64_t samples = 0;
  // Set at the first recorded state where the maxima so far already break the assumption (max ||F|| >=
  // alpha, or max ||grad V|| > (alpha - max ||F||) / 2): a definite failure, since any beta is at least
  // max ||F||. Sampling stops there; the maxima are those up to that state.
  bool failed = false;
  double max_force = 0.0;  // over the samples; a lower bound of the assumption's sup ||F||
  double max_force_time = 0.0;
  double max_gradient = 0.0;  // likewise for ||grad V||
  double max_gradient_time = 0.0;
};

// The total mechanical energy E = 1/2 <M v, v> + V(q) along a run, at the states a run recorded (every
// kStride-th, where the scene layer evaluates V), against the energy balance of (0.1): along a solution
// dE/dt = -<xi, v> - <F, v> with xi in dPhi(v), so E(t) - E(t0) + D(t) = -(work of F) exactly, and = 0 when
// F = 0; what the scheme adds to it is its own energy error. Filled by the layer that can evaluate V
// (the scene's compiled expressions or robot); samples == 0 when nobody did.
struct MechanicalEnergyTrack {
  std::int64_t samples = 0;
  double initial = 0.0;   // E at the first recorded state
  double max_rise = 0.0;  // largest E(t_k) - E(t0) seen (0 when E never rose)
  double max_rise_time = 0.0;
  double max_balance = 0.0;  // largest |E(t_k) - E(t0) + D(t_k)| seen
  double max_balance_time = 0.0;
};

// A tracking run's results (tracking_integrator.h, docs/tracking.md). A "sample" is a controller sample:
// every T_s for a sampled law, every step for the continuous loop. "After reaching" covers the samples
// from the reaching time to the end.
struct TrackingSummary {
  std::string law;                    // "continuous", "implicit", "explicit" or "saturated"
  double period = 0.0;                // T_s (continuous: the step h)
  std::int64_t steps_per_sample = 1;  // T_s / h
  std::int64_t samples = 0;
  // Continuous: sigma == 0.0 exactly at every state from reaching_time to the end, by the one-step
  // solver's closed form. Sampled: ||sigma_k||_inf <= band at every sample from reaching_time on.
  bool reached = false;
  double reaching_time = 0.0;
  std::int64_t reaching_step = -1;
  double band = 0.0;  // sampled laws only
  // Implicit law: the first sample from which every prediction sigma_{k+1} of the nominal model was 0.0 by
  // the solver's closed form, to the end.
  std::optional<double> predicted_on_surface_time;
  // After reaching (when reached): max_k ||e_k||_inf, sqrt(mean_k ||e_k||^2 / n), max_k ||sigma_k||_inf;
  // the sign changes of u (per coordinate between consecutive nonzero values, summed over coordinates),
  // their number per second, and the total variation sum_k ||u_{k+1} - u_k||_1.
  std::int64_t after_samples = 0;
  double error_max = 0.0, error_rms = 0.0, sigma_max = 0.0;
  std::int64_t sign_changes = 0;
  double sign_changes_per_second = 0.0, total_variation = 0.0;
  // Over the run: max_k ||u_k||_inf, sum_k T_s ||u_k||^2 (the integral of ||u||^2 under the hold),
  // ||e||_inf at the last sample, and the sign changes and total variation of u counted as above over
  // every sample (what a run that never reached still shows of its chattering).
  double u_max = 0.0, u_energy = 0.0, error_final = 0.0;
  std::int64_t run_sign_changes = 0;
  double run_total_variation = 0.0;
  // max_k ||rho_k||_2 over the samples, rho = (M a_r + C v_r + g) - (M^ a_r + C^ v_r + g^): the
  // perturbation of the sigma dynamics M sigma' + C sigma + xi = -rho (model error and F), on the states
  // visited; reaching needs it below alpha = min_i a_i + a_norm.
  double perturbation_max = 0.0, perturbation_max_time = 0.0;
  double alpha = 0.0;  // min_i a_i + a_norm of Phi on sigma
  // Implicit law, at every sample: whether the controller's one-step problem P y + x in -d phi(y),
  // P = M^/T_s + C^ + W, is strongly monotone (P + P^T positive definite: then it has exactly one
  // solution), and whether ABL's condition (4.2), 2 T_s ||C^||_2 <= lambda_min(M^), which implies it, held.
  std::int64_t condition_checked = 0, monotone_violations = 0, condition42_violations = 0;
  double first_monotone_violation_time = 0.0;
};

struct RunSummary {
  RunStatus status = RunStatus::kCompleted;
  std::string message;  // why a run failed or was cancelled; empty when completed

  std::int64_t steps = 0;
  double t_final = 0.0;
  // The first step N from which the scheme's state rests (RestState::kAtRest: V^k == 0.0 held there by
  // the set-valued law, as the one-step solver states it) at every k >= N up to the last step, if any: at
  // rest at the end, which by itself proves nothing (V^k can pass through rest at the last step).
  std::optional<std::int64_t> rest_step;
  std::optional<double> rest_time;
  // rest_step, when the rest lasted at least kMinRestSteps steps to the end of the run and the final
  // state is an equilibrium of the scheme (for (0.2): dist(-F(t, Q, 0) - grad V(Q), dPhi(0)) == 0, see
  // `equilibrium`): finite-step convergence as observed on this run. Whether Theorem 4.3 guarantees it
  // is the report's guarantees section, from the theorem's hypotheses.
  std::optional<std::int64_t> converged_step;
  std::optional<double> converged_time;
  static constexpr std::int64_t kMinRestSteps = 10;
  // The first step from which V^k (x^k) stayed below the smallest normal double in magnitude, possibly
  // 0.0, to the end without the law holding it (RestState::kBelowNormal): a decay the floating-point
  // format ended, which is neither a rest nor finite-step convergence.
  std::optional<std::int64_t> below_normal_step;
  std::optional<double> below_normal_time;
  std::vector<double> q_final, v_final;

  // E_k = 1/2 <M(Q^k) V^k, V^k>.
  double energy_initial = 0.0;
  double energy_final = 0.0;
  bool energy_nonincreasing = true;
  double energy_max_increase = 0.0;   // largest E_{k+1} - E_k above the round-off allowance
  std::int64_t energy_increases = 0;  // steps where E rose above the allowance

  // D = sum_k h_k <xi_k, V^{k+1}> with xi_k in dPhi(V^{k+1}) the step's element: the work done against the
  // set-valued controller and friction (dissipation_rate in controller.h), >= 0. Tracked by the scheme (0.2)
  // (dissipation_tracked); the contact scheme's impulses are not separated from it, so it does not.
  double dissipated_work = 0.0;
  bool dissipation_tracked = false;

  double h_min = 0.0;
  double h_max = 0.0;

  EquilibriumCheck equilibrium;
  SolverEffort solver;

  // Checked at every step of the schemes with a mass matrix (step_conditions.h).
  MassDefinitenessTrack mass;               // Assumption 3.1: lambda_min(M(Q^k)) > 0
  StepConditionTrack theorem41;             // (4.2) of Theorem 4.1, for the scheme (0.2) only
  ForceBoundTrack force_bounds;             // Assumption 4.1 2)-3), at the recorded states
  MechanicalEnergyTrack mechanical;         // E = 1/2 <M v, v> + V(q) and its balance, at the recorded states
  std::optional<TrackingSummary> tracking;  // a tracking run's (tracking_integrator.h)

  // Wall time by phase, in the order they ran ("parse", "compile", "integrate", "write", ...).
  std::vector<std::pair<std::string, double>> phase_seconds;
  double wall_seconds() const;
  void add_phase(const std::string& name, double seconds);

  // One line, for logs: status, steps, t_final, convergence, energy, solver effort, time.
  std::string BriefReport() const;
};

}  // namespace moreau
