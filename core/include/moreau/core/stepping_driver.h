// The loop every time-stepping scheme runs, written once: SteppingDriver owns the time rule (the fixed
// grid FixedTimeGrid, or a scheme's adaptive rule such as Theorems 4.1 and 4.2 of Adly, Brogliato and
// Le (2016), landed on t_end) and the run's bookkeeping (RunRecorder): samples handed to the observer
// every output_every steps (only every sample_stride()-th of those if the observer asks for fewer) and at
// the first and last state, cancellation every
// RunObserver::kControlInterval steps, the range of step sizes, the solver's effort, the energy's rises
// above round-off, the step from which the state rests, failure and cancellation messages, and the wall
// time of the phase. A scheme (abl_integrator.h, moreau_jean_integrator.h, lure_integrator.h) supplies
// only its state and its step; the regularized peer (regularized_integrator.h) takes the grid. A check
// added here applies to every scheme. Everything is a template: no virtual call and no allocation per step.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "moreau/core/observer.h"
#include "moreau/core/types.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/time_grid.h"
#include "moreau/platform/number_text.h"

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

// Whether a scheme's state rests: the velocity V (for a Lur'e system, the state x) held at 0 by the
// set-valued law, decayed below the smallest normal double (2.2e-308) without the law holding it (the
// floating-point format ends the decay: V^k = 3^-k reaches 0.0 by underflow, never mathematically), or
// moving. Finite-step convergence (Theorem 4.3) is claimed only for kAtRest.
enum class RestState { kMoving, kBelowNormal, kAtRest };

// The rest of a scheme's resting values, from its solver's statement when it makes one (`held`: the
// one-step problem's solution is 0 because the law holds it there, e.g. -x in dPhi(0) for (6.5)), else
// from the values: 0.0 exactly is a rest unless the values reached it through the subnormal numbers (an
// underflow; a decay by a factor below 2^-52 in one step, which skips them, is the case this cannot
// tell). One pass over n numbers per step.
class RestTracker {
 public:
  // The common cases first, since this runs at every step: the solver's statement that the law holds the
  // velocity at 0 (a rest), else a largest entry that is a normal number (moving), after one pass.
  template <class Values>
  RestState update(const Values& x, std::optional<bool> held = std::nullopt) {
    if (held && *held) return state_ = RestState::kAtRest;
    double largest = 0.0;
    for (Eigen::Index i = 0; i < x.size(); ++i) largest = std::max(largest, std::abs(x(i)));
    if (largest >= std::numeric_limits<double>::min()) return state_ = RestState::kMoving;
    // Below the smallest normal number (or 0.0): not a rest where the solver could have said so and did
    // not, nor a subnormal; a 0.0 without a solver's statement is a rest unless it was reached through
    // the subnormals.
    if (held || largest != 0.0) return state_ = RestState::kBelowNormal;
    return state_ = state_ == RestState::kBelowNormal ? RestState::kBelowNormal : RestState::kAtRest;
  }
  RestState state() const { return state_; }

 private:
  RestState state_ = RestState::kMoving;
};

// The bookkeeping of one run into its RunSummary. q and v are the n positions and velocities the
// observer sees (for a Lur'e system, the state and its discrete derivative).
class RunRecorder {
 public:
  RunRecorder(RunObserver* observer, std::int64_t output_every, int n)
      : observer_(observer),
        every_(std::max<std::int64_t>(1, output_every)),
        emit_every_(saturating_product(every_, std::max<std::int64_t>(1, observer ? observer->sample_stride() : 1))),
        n_(n) {}

  RunSummary& summary() { return s_; }
  // The scheme's signals (Sample::signals): m values at `values`, which the scheme keeps current.
  void signals(int m, const double* values) {
    m_ = m;
    signals_ = values;
  }

  // Step 0: E_0 and whether the initial state already rests.
  void start(double t, double energy, RestState rest) {
    s_.energy_initial = energy;
    rest_from_ = rest == RestState::kAtRest ? 0 : -1;
    rest_time_ = t;
    below_normal_from_ = rest == RestState::kBelowNormal ? 0 : -1;
    below_normal_time_ = t;
    s_.h_min = std::numeric_limits<double>::infinity();
    s_.h_max = 0.0;
  }
  // The sample of the initial state (its h is the nominal step).
  void first_sample(double t, double h_nominal, const double* q, const double* v, double energy) {
    emit(0, 0, t, h_nominal, q, v, energy, 0.0);
  }

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
  // run's convergence step (Theorem 4.3's finite time). The observer hears of a rest when it reaches
  // RunSummary::kMinRestSteps steps (the window finish() asks for) and again if it ends: a live viewer
  // learns of convergence when it happens, not when the run ends (one comparison per step).
  // A state below the smallest normal number without the law holding it is tracked apart
  // (RunSummary::below_normal_step): it is not a rest.
  void rest(RestState state, std::int64_t k, double t) {
    // Moving, with no rest and no decay below the normal numbers to end: the common case, one branch.
    // (rest_announced_ implies rest_from_ >= 0.)
    if (state == RestState::kMoving && rest_from_ < 0 && below_normal_from_ < 0) return;
    if (state != RestState::kBelowNormal) {
      below_normal_from_ = -1;
    } else if (below_normal_from_ < 0) {
      below_normal_from_ = k;
      below_normal_time_ = t;
    }
    if (state != RestState::kAtRest) {
      if (rest_announced_) {
        rest_announced_ = false;
        if (observer_) observer_->on_rest_ended(rest_from_, k, t);
      }
      rest_from_ = -1;
    } else if (rest_from_ < 0) {
      rest_from_ = k;
      rest_time_ = t;
    } else if (!rest_announced_ && k - rest_from_ == RunSummary::kMinRestSteps) {
      rest_announced_ = true;
      if (observer_) observer_->on_rest_detected(rest_from_, rest_time_, k, t);
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

  // The end of step k: its sample if k is a multiple of output_every (times the observer's
  // sample_stride()), and every kControlInterval steps the observer's chance to cancel. False: the run is
  // cancelled (finish it, then call cancelled()). (Steps arrive in order 1, 2, ...: a countdown replaces
  // k % output_every, an integer division per step.) `dissipated`: D up to step k
  // (RunSummary::dissipated_work), which the sample carries.
  bool after_step(std::int64_t k, double t, double h_k, const double* q, const double* v, double energy, double dissipated) {
    if (--until_sample_ == 0) {
      until_sample_ = emit_every_;
      emit(k, k / every_, t, h_k, q, v, energy, dissipated);
      last_emitted_ = k;
    }
    static_assert((RunObserver::kControlInterval & (RunObserver::kControlInterval - 1)) == 0, "a power of two: a mask, not a division");
    return !(observer_ && (k & (RunObserver::kControlInterval - 1)) == 0 && !observer_->keep_going(k, t));
  }

  // The last state's sample, unless after_step gave it already.
  void last_sample(std::int64_t k, double t, double h_k, const double* q, const double* v, double energy, double dissipated) {
    // ceil(k / output_every), written so that it cannot overflow: a run that records only its first and
    // last states (a study's runs) has output_every = INT64_MAX.
    if (last_emitted_ != k) emit(k, k / every_ + (k % every_ != 0), t, h_k, q, v, energy, dissipated);
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
    if (below_normal_from_ >= 0) {
      s_.below_normal_step = below_normal_from_;
      s_.below_normal_time = below_normal_time_;
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
    s_.message = "step " + std::to_string(k) + " (t = " + platform::shortest(t) + "): " + why;
    return close();
  }

  // The summary, with the wall time of the "integrate" phase.
  RunSummary close() {
    s_.add_phase("integrate", std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    return s_;
  }

 private:
  // a b for a, b >= 1, INT64_MAX when it would overflow.
  static std::int64_t saturating_product(std::int64_t a, std::int64_t b) {
    return a > std::numeric_limits<std::int64_t>::max() / b ? std::numeric_limits<std::int64_t>::max() : a * b;
  }
  void emit(std::int64_t k, std::int64_t index, double t, double h, const double* q, const double* v, double energy, double dissipated) {
    if (observer_) observer_->on_sample(Sample{k, t, h, n_, q, v, energy, dissipated, index, m_, signals_});
  }
  bool finite(const double* x) const {
    for (int i = 0; i < n_; ++i)
      if (!std::isfinite(x[i])) return false;
    return true;
  }

  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  RunObserver* observer_;
  std::int64_t every_;                       // output_every
  std::int64_t emit_every_;                  // output_every times the observer's sample_stride()
  std::int64_t until_sample_ = emit_every_;  // steps until the next multiple of emit_every_
  int n_;
  int m_ = 0;
  const double* signals_ = nullptr;
  RunSummary s_;
  std::int64_t rest_from_ = -1;
  double rest_time_ = 0.0;
  std::int64_t below_normal_from_ = -1;
  double below_normal_time_ = 0.0;
  bool rest_announced_ = false;  // on_rest_detected() was called for the rest from rest_from_
  std::int64_t last_emitted_ = 0;
};

// Where a failed step leaves the run: the step and time to report, the last state the observer may see as
// good (pointers into the scheme; v may be nullptr: not reported) and why.
struct StepFailure {
  std::int64_t k = 0;
  double t = 0.0;
  const double* q = nullptr;
  const double* v = nullptr;
  std::string why;

  // Fills the failure and returns false, so that a scheme's step can end with `return f.at(...)`.
  bool at(std::int64_t k_, double t_, const double* q_, const double* v_, std::string why_) {
    k = k_;
    t = t_;
    q = q_;
    v = v_;
    why = std::move(why_);
    return false;
  }
};

// The time rule and the recording of a run.
// The time rule and the recording of a run: the scheme's grid (h: the fixed step, or the adaptive rule's
// upper bound and the first sample's h) and whether the step is fixed.
struct SteppingPlan {
  TimeGrid grid;
  bool fixed = true;  // false: the scheme proposes each h_k (propose_step)
};

// Runs a scheme from its initial state (set by the scheme before the call) to t_end. The scheme's part
// (private members, with `friend struct SteppingDriver;`):
//
//   int dof() const;
//   const double* q() const;  const double* v() const;    // the state the observer sees
//   double energy() const;  RestState rest_state() const;   // E_k (or W_k), and whether V (x) rests (RestTracker)
//   bool begin(double t0, StepFailure& f);                  // checks and evaluation at the initial state
//   bool step(std::int64_t k, double t_k, double h_k, double t_next, RunRecorder& rec, StepFailure& f);
//       // the one-step problem and the update to step k+1 (may record the solver's effort)
//   bool arrive(std::int64_t k, double t, StepFailure& f);  // checks and evaluation at the new state k
//   double energy_allowance(double e_old, double e_initial) const;  // round-off of E_{k+1} - E_k
//   void finish(RunRecorder& rec, std::int64_t k, double t);        // the summary of an ended run
//   void on_failure();                                      // what else a failed run records
//   static constexpr bool kTracksDissipation;               // whether it has, after each step,
//   double step_dissipation() const;                        // the work done against dPhi in it
//       // (summed by the driver in a local, so that the sum never goes through memory in the hot loop)
//   static constexpr bool kAdaptiveSteps;                   // whether the scheme has an adaptive rule:
//   bool propose_step(double t, double h_prev, double& h_k, std::string& why);  // then h_k from the state
//
// A scheme without an adaptive rule always runs the fixed grid, whatever plan.fixed says.
//
// Failures from begin() and the step count come before the first sample; a failing step ends the run
// with the state its StepFailure names.
struct SteppingDriver {
  // run() for a scheme that writes diagnostics through a pointer member: `slot` points at *diag for the
  // run, or at a local that is dropped when the caller wants none, and is reset afterwards.
  template <class Scheme, class Diagnostics>
  static RunSummary run_with_diagnostics(Scheme& scheme, const SteppingPlan& plan, RunObserver* observer, Diagnostics*& slot,
                                         Diagnostics* diag) {
    Diagnostics local;
    slot = diag ? diag : &local;
    RunSummary summary = run(scheme, plan, observer);
    slot = nullptr;  // it may point at the local above
    return summary;
  }

  template <class Scheme>
  static RunSummary run(Scheme& scheme, const SteppingPlan& plan, RunObserver* observer) {
    RunRecorder rec(observer, plan.grid.output_every, scheme.dof());
    register_signals(scheme, rec, 0);
    StepFailure f;
    if (!scheme.begin(plan.grid.t0, f)) return failed(scheme, rec, f);
    // The grid as TimeGrid defines a valid one (the scene readers refuse a bad one first, by field).
    if (std::string why; !plan.grid.is_valid(&why)) {
      f.at(0, plan.grid.t0, scheme.q(), scheme.v(), "invalid time grid: " + why);
      return failed(scheme, rec, f);
    }
    const bool fixed = plan.fixed || !Scheme::kAdaptiveSteps;
    const FixedTimeGrid grid(plan.grid.t0, plan.grid.t_end, plan.grid.h);
    if (fixed && grid.steps > plan.grid.max_steps) {
      f.at(0, plan.grid.t0, scheme.q(), scheme.v(), "the step count exceeds max_steps");
      return failed(scheme, rec, f);
    }

    std::int64_t k = 0;
    double t = plan.grid.t0;
    double energy = scheme.energy();
    rec.start(t, energy, scheme.rest_state());
    rec.first_sample(t, plan.grid.h, scheme.q(), scheme.v(), energy);
    double h_k = plan.grid.h, h_prev = plan.grid.h;
    double dissipated = 0.0;  // D, RunSummary::dissipated_work
    while (true) {
      if (fixed) {
        if (k >= grid.steps) break;
        h_k = grid.step(k);
      } else if constexpr (Scheme::kAdaptiveSteps) {
        if (t >= plan.grid.t_end) break;
        std::string why;
        if (k >= plan.grid.max_steps)
          why = "max_steps reached before t_end";
        else if (scheme.propose_step(t, h_prev, h_k, why)) {
          // Land on t_end: shorten the last step, or stretch it by at most 1e-9 relative rather than
          // leave a sliver of round-off (t accumulates the h_k).
          const double remaining = plan.grid.t_end - t;
          if (h_k * (1.0 + 1e-9) >= remaining) h_k = remaining;
          if (!(h_k > 0.0) || h_k < 1e-15 * std::max(1.0, std::abs(plan.grid.t_end))) why = "the step size collapsed below 1e-15 t_end";
        }
        if (!why.empty()) {
          f.at(k, t, scheme.q(), scheme.v(), std::move(why));
          return failed(scheme, rec, f);
        }
      }
      const double t_next = fixed ? grid.time(k + 1) : t + h_k;
      if (!scheme.step(k, t, h_k, t_next, rec, f)) return failed(scheme, rec, f);
      if constexpr (Scheme::kTracksDissipation) dissipated += scheme.step_dissipation();
      ++k;
      t = t_next;
      h_prev = h_k;
      rec.step_taken(h_k);
      if (!scheme.arrive(k, t, f)) return failed(scheme, rec, f);
      rec.rest(scheme.rest_state(), k, t);
      const double e_new = scheme.energy();
      rec.energy_step(energy, e_new, scheme.energy_allowance(energy, rec.summary().energy_initial));
      energy = e_new;
      if (!rec.after_step(k, t, h_k, scheme.q(), scheme.v(), energy, dissipated)) {
        rec.summary().dissipated_work = dissipated;
        scheme.finish(rec, k, t);
        return rec.cancelled(k);
      }
    }
    rec.last_sample(k, t, h_k, scheme.q(), scheme.v(), energy, dissipated);
    rec.summary().dissipated_work = dissipated;
    scheme.finish(rec, k, t);
    return rec.close();
  }

 private:
  // A scheme with signals (signal_count(), signals(): a tracking run's) hands them to the recorder; the
  // others have none. (Overloads, not a requires-expression: some runners build as C++17.)
  template <class Scheme>
  static auto register_signals(Scheme& scheme, RunRecorder& rec, int) -> decltype(scheme.signal_count(), void()) {
    rec.signals(scheme.signal_count(), scheme.signals());
  }
  template <class Scheme>
  static void register_signals(Scheme&, RunRecorder&, long) {}

  template <class Scheme>
  static RunSummary failed(Scheme& scheme, RunRecorder& rec, const StepFailure& f) {
    scheme.on_failure();
    return rec.fail(f.k, f.t, f.q, f.v, f.why);
  }
};

}  // namespace moreau
