// What every time-stepping run does around its step, written once for all the schemes: the fixed time
// grid (FixedTimeGrid) and the run's bookkeeping (RunRecorder): samples handed to the observer every
// output_every steps and at the first and last state, cancellation every RunObserver::kControlInterval
// steps, the range of step sizes, the solver's effort, the energy's rises above round-off, the step
// from which the state rests, failure and cancellation messages, and the wall time of the phase. An
// integrator (abl_integrator.h, moreau_jean_integrator.h, lure_integrator.h, regularized_integrator.h)
// supplies its one-step update and calls the recorder at the same points of its loop; the calls are
// inline and never virtual, and nothing here allocates per step.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>

#include "moreau/core/observer.h"
#include "moreau/core/run_summary.h"

namespace moreau {

// The number of steps the fixed rule takes: t_end - t0 = N h up to round-off, else ceil. Saturates at
// INT64_MAX for counts beyond 9e18 (and for NaN), and is 0 for an empty or reversed interval: converting a
// double at or beyond 2^63 to int64 is undefined behaviour, so the range is checked in double first.
inline std::int64_t fixed_step_count(double t0, double t_end, double h) {
  const double ratio = (t_end - t0) / h;
  if (!(ratio < 9e18)) return std::numeric_limits<std::int64_t>::max();
  if (!(ratio > 0.0)) return 0;
  const double nearest = std::round(ratio);
  if (std::abs(ratio - nearest) <= 1e-9 * std::max(1.0, ratio)) return static_cast<std::int64_t>(nearest);
  return static_cast<std::int64_t>(std::ceil(ratio));
}

// t_k = t0 + k h for k < N and t_N = t_end exactly; every step is h but the last, which lands on t_end
// (it is h itself when t_end - t0 is a whole number of steps up to round-off). Times are computed from k,
// never accumulated, so round-off does not drift over millions of steps.
struct FixedTimeGrid {
  double t0 = 0.0, t_end = 0.0, h = 0.0;
  std::int64_t steps = 0;  // N
  double last_h = 0.0;     // h_{N-1}

  FixedTimeGrid(double t0_, double t_end_, double h_) : t0(t0_), t_end(t_end_), h(h_), steps(fixed_step_count(t0_, t_end_, h_)) {
    const double remainder = (t_end - t0) - static_cast<double>(steps - 1) * h;
    last_h = std::abs(remainder - h) <= 1e-9 * h ? h : remainder;
  }
  double step(std::int64_t k) const { return k + 1 == steps ? last_h : h; }                           // h_k
  double time(std::int64_t k) const { return k == steps ? t_end : t0 + static_cast<double>(k) * h; }  // t_k
};

// The bookkeeping of one run into its RunSummary. q and v are the n positions and velocities the
// observer sees (for a Lur'e system, the state and its discrete derivative).
class RunRecorder {
 public:
  RunRecorder(RunObserver* observer, std::int64_t output_every, int n)
      : observer_(observer), every_(std::max<std::int64_t>(1, output_every)), n_(n) {}

  RunSummary& summary() { return s_; }

  // Step 0: E_0 and whether the initial state already rests.
  void start(double t, double energy, bool at_rest) {
    s_.energy_initial = energy;
    rest_from_ = at_rest ? 0 : -1;
    rest_time_ = t;
    s_.h_min = std::numeric_limits<double>::infinity();
    s_.h_max = 0.0;
  }
  // The sample of the initial state (its h is the nominal step).
  void first_sample(double t, double h_nominal, const double* q, const double* v, double energy) { emit(0, t, h_nominal, q, v, energy); }

  // The one-step solver's effort on this step.
  void solver_step(int iterations, double residual, bool used_fallback) {
    s_.solver.total_iterations += iterations;
    s_.solver.max_iterations = std::max(s_.solver.max_iterations, iterations);
    s_.solver.max_residual = std::max(s_.solver.max_residual, residual);
    s_.solver.fallback_steps += used_fallback;
  }

  // h_k was taken.
  void step_taken(double h_k) {
    s_.h_min = std::min(s_.h_min, h_k);
    s_.h_max = std::max(s_.h_max, h_k);
  }

  // Whether the state rests at step k (time t): the first step of the final run of resting steps is the
  // run's convergence step (Theorem 4.3's finite time).
  void rest(bool at_rest, std::int64_t k, double t) {
    if (!at_rest) {
      rest_from_ = -1;
    } else if (rest_from_ < 0) {
      rest_from_ = k;
      rest_time_ = t;
    }
  }

  // E_{k+1} - E_k above the scheme's round-off allowance counts as a rise (Theorem 4.2: none under its
  // assumptions).
  void energy_step(double energy_before, double energy_after, double allowance) {
    const double rise = energy_after - energy_before;
    if (rise > allowance) {
      ++s_.energy_increases;
      s_.energy_max_increase = std::max(s_.energy_max_increase, rise);
    }
  }

  // The end of step k: its sample if k is a multiple of output_every, and every kControlInterval steps
  // the observer's chance to cancel. False: the run is cancelled (finish it, then call cancelled()).
  bool after_step(std::int64_t k, double t, double h_k, const double* q, const double* v, double energy) {
    if (k % every_ == 0) {
      emit(k, t, h_k, q, v, energy);
      last_emitted_ = k;
    }
    return !(observer_ && k % RunObserver::kControlInterval == 0 && !observer_->keep_going(k, t));
  }

  // The last state's sample, unless after_step gave it already.
  void last_sample(std::int64_t k, double t, double h_k, const double* q, const double* v, double energy) {
    if (last_emitted_ != k) emit(k, t, h_k, q, v, energy);
  }

  // The summary of a run that ended at step k (completed or cancelled): the final state, energy, rest
  // and convergence steps. Converged means at rest for at least RunSummary::kMinRestSteps steps to the
  // end and, by the integrator's own test, at an equilibrium of its scheme (rest_is_equilibrium).
  void finish(std::int64_t k, double t, const double* q, const double* v, double energy, bool rest_is_equilibrium = true) {
    s_.steps = k;
    s_.t_final = t;
    s_.q_final.assign(q, q + n_);
    s_.v_final.assign(v, v + n_);
    s_.energy_final = energy;
    s_.energy_nonincreasing = s_.energy_increases == 0;
    if (rest_from_ >= 0) {
      s_.rest_step = rest_from_;
      s_.rest_time = rest_time_;
      if (k - rest_from_ >= RunSummary::kMinRestSteps && rest_is_equilibrium) {
        s_.converged_step = rest_from_;
        s_.converged_time = rest_time_;
      }
    }
    if (k == 0) s_.h_min = s_.h_max = 0.0;
  }
  std::int64_t rest_from() const { return rest_from_; }
  double rest_time() const { return rest_time_; }

  // A run cancelled at step k (after finish()).
  RunSummary cancelled(std::int64_t k) {
    s_.status = RunStatus::kCancelled;
    s_.message = "cancelled at step " + std::to_string(k);
    return close();
  }

  // A run that failed at step k: the last state the observer saw as good, never a non-finite one
  // (v may be nullptr: not reported), and why, prefixed with where.
  RunSummary fail(std::int64_t k, double t, const double* q, const double* v, const std::string& why) {
    s_.steps = k;
    s_.t_final = t;
    if (finite(q)) s_.q_final.assign(q, q + n_);
    if (v && finite(v)) s_.v_final.assign(v, v + n_);
    s_.energy_nonincreasing = s_.energy_increases == 0;
    s_.status = RunStatus::kFailed;
    char where[96];
    std::snprintf(where, sizeof where, "step %lld (t = %.17g): ", static_cast<long long>(k), t);
    s_.message = where + why;
    return close();
  }

  // The summary, with the wall time of the "integrate" phase.
  RunSummary close() {
    s_.add_phase("integrate", std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    return s_;
  }

 private:
  void emit(std::int64_t k, double t, double h, const double* q, const double* v, double energy) {
    if (observer_) observer_->on_sample(Sample{k, t, h, n_, q, v, energy});
  }
  bool finite(const double* x) const {
    for (int i = 0; i < n_; ++i)
      if (!std::isfinite(x[i])) return false;
    return true;
  }

  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  RunObserver* observer_;
  std::int64_t every_;
  int n_;
  RunSummary s_;
  std::int64_t rest_from_ = -1;
  double rest_time_ = 0.0;
  std::int64_t last_emitted_ = 0;
};

}  // namespace moreau
