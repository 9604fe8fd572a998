// What the schemes of the second paper (Brogliato 2003) report beyond RunSummary: the storage function
// of a Lur'e system (Lemma 2) and, for Lagrangian systems with unilateral constraints, the impacts, the
// rest time, the smallest gap, the position correction and the Lagrange-Dirichlet function W of Lemma 3.
// Plain data, filled by lure_integrator.h and moreau_jean_integrator.h; formatting lives in scene/.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace moreau {

// A scalar sequence W_k that the theory says is non-increasing, watched step by step. A rise above the
// round-off allowance (given by the caller: a few ulps of the terms W is made of) counts as an increase.
struct EnergyTrack {
  bool evaluated = false;
  double initial = 0.0;
  double final = 0.0;
  bool nonincreasing = true;
  std::int64_t increases = 0;
  double max_increase = 0.0;
  std::int64_t first_increase_step = -1;  // the step k+1 at which W first rose, -1 if never
  double first_increase_time = 0.0;

  void start(double w) {
    evaluated = true;
    initial = final = w;
  }
  void step(std::int64_t k, double t, double w_new, double allowance) {
    const double rise = w_new - final;
    if (rise > allowance) {
      if (increases == 0) {
        first_increase_step = k;
        first_increase_time = t;
      }
      ++increases;
      max_increase = std::max(max_increase, rise);
      nonincreasing = false;
    }
    final = w_new;
  }
};

// ---- Lur'e systems (section 3) -------------------------------------------------------------------------
struct LureDiagnostics {
  // W = 1/2 x^T P x (Lemma 2), when a storage matrix P is known (given by the scene or found by the
  // positive-realness test); not evaluated otherwise.
  EnergyTrack storage;
  std::vector<double> y_final;    // y = C x at the last step (the solver's exact value)
  std::vector<double> y_l_final;  // y_L in d phi(y) at the last step
  // Per output component: the first step from which y_i == 0.0 exactly to the end (-1 if none).
  std::vector<std::int64_t> output_rest_step;
  std::vector<double> output_rest_time;
};

// ---- Lagrangian systems with unilateral constraints (section 4) ---------------------------------------
struct ImpactEvent {
  std::int64_t step = 0;  // k+1: the step whose impulse carried the impact
  double t = 0.0;         // t_{k+1}
  int constraint = 0;
  double pre = 0.0;          // U_k = grad h(Q^k)^T V^k < 0, the approaching normal velocity
  double post = 0.0;         // U_{k+1} = grad h(Q^k)^T V^{k+1}
  double impulse = 0.0;      // P_{k+1} >= 0 (the contact percussion over the step)
  double restitution = 0.0;  // e_i, the contact's Newton coefficient the step used (U+ = -e U- when P > 0)
  // The step's kinetic energy change 1/2 <M V^{k+1}, V^{k+1}> - 1/2 <M V^k, V^k> (M = M(Q^k)), against
  // eq. (9): the change Moreau's impact law alone gives from V^k for all the contacts impacting in this
  // step, 1/2 sum_i (1 - e_i) P_i U-_i (= -1/2 (1-e)/(1+e) |V+ - V-|_M^2 for a common e), with P its
  // impulses (reference_impulse: this contact's). Both are per step, the same for simultaneous impacts.
  double kinetic_change = 0.0;
  double eq9_change = 0.0;
  double reference_impulse = 0.0;
  bool reference_evaluated = false;  // false: the contacts carrying impulse have dependent gradients (impulses not unique)
  int simultaneous = 1;              // impacts in the same step
  // Contacts that carried impulse in the same step without approaching: closed contacts the impulse
  // passed through (a touching Newton's cradle, a stack hit from above). With them the step is a
  // simultaneous multiple impact under Moreau's law, and the reference covers them too.
  int closed_carrying = 0;
};

struct ContactDiagnostics {
  int constraints = 0;
  std::int64_t impact_count = 0;
  std::vector<ImpactEvent> impacts;  // the first max_recorded_impacts impacts
  bool impacts_truncated = false;
  double max_eq9_mismatch = 0.0;   // max |kinetic_change - eq9_change| over the impacts with a reference
  std::int64_t active_steps = 0;   // steps with at least one contact in the predicted active set
  std::int64_t impulse_steps = 0;  // steps with at least one positive impulse

  // The first step from which V == 0.0 exactly to the end (the system at rest), if any.
  std::int64_t rest_step = -1;
  double rest_time = 0.0;
  // Per constraint: the first step from which the contact stays closed (an impulse every step, normal
  // velocity exactly 0.0) to the end, if any.
  std::vector<std::int64_t> settle_step;
  std::vector<double> settle_time;

  // The smallest gap min_k min_i h_i(Q^k) over the run (negative: penetration).
  double smallest_gap = std::numeric_limits<double>::infinity();
  double smallest_gap_time = 0.0;
  int smallest_gap_constraint = -1;

  // Position correction (projection of Q^{k+1} onto h >= 0 after the step, when enabled).
  bool correction_enabled = false;
  std::int64_t corrected_steps = 0;
  double max_correction = 0.0;     // largest ||delta q||_M
  double correction_energy = 0.0;  // sum of the potential energy changes it caused
  double largest_violation = 0.0;  // largest -h_i(Q^{k+1}) it removed

  // The Lagrange-Dirichlet function W = 1/2 <M(q) v, v> + U(q) of Lemma 3, eq. (12) on the admissible set.
  EnergyTrack lagrange_dirichlet;
  bool potential_known = false;  // false when the scene gives no potential U (W is then kinetic only)
};

// Counts one impact of a run into `d`: recorded while fewer than `max_recorded` are (impacts_truncated
// after), its eq. (9) difference in max_eq9_mismatch when recorded with a reference, and told to
// `observer` (which may be null). The one bookkeeping of every Moreau-Jean integrator.
template <class Observer>
void count_impact(ContactDiagnostics& d, const ImpactEvent& ev, int max_recorded, Observer* observer) {
  ++d.impact_count;
  const bool recorded = static_cast<int>(d.impacts.size()) < max_recorded;
  if (!recorded) d.impacts_truncated = true;
  if (ev.reference_evaluated && recorded) d.max_eq9_mismatch = std::max(d.max_eq9_mismatch, std::abs(ev.kinetic_change - ev.eq9_change));
  if (observer) observer->on_impact(ev);
  if (recorded) d.impacts.push_back(ev);
}

}  // namespace moreau
