// What a run reports: status, finite-step convergence (Theorem 4.3), the energy sequence (Theorem 4.2),
// the equilibrium check, solver effort and wall time by phase. Plain data; formatting lives in the
// client, except the one-line BriefReport.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace moreau {

enum class RunStatus { kCompleted, kFailed, kCancelled };
const char* to_string(RunStatus status);

struct SolverEffort {
  int max_iterations = 0;     // most pattern solves (or sweeps) in one step
  double max_residual = 0.0;  // largest accepted dist(-(P y + x), d phi(y)) over the run
  std::int64_t total_iterations = 0;
  std::int64_t fallback_steps = 0;  // steps that needed the exhaustive or forward-backward fallback
  std::int64_t rest_steps = 0;      // steps solved by the y = 0 closed form (velocity exactly at rest)
};

struct EquilibriumCheck {
  bool evaluated = false;
  // dist(-F(t, Q, 0) - grad V(Q), dPhi(0)) at the final state: 0 when Q is an equilibrium of (0.2).
  double residual = 0.0;
  // Whether -F(t, Q, 0) - grad V(Q) lies in int dPhi(0), the finite-convergence condition of Thm 4.3.
  bool interior = false;
};

struct RunSummary {
  RunStatus status = RunStatus::kCompleted;
  std::string message;  // why a run failed or was cancelled; empty when completed

  std::int64_t steps = 0;
  double t_final = 0.0;
  // The first step N with V^k == 0.0 exactly for every k >= N up to the last step, if any.
  std::optional<std::int64_t> converged_step;
  std::optional<double> converged_time;
  std::vector<double> q_final, v_final;

  // E_k = 1/2 <M(Q^k) V^k, V^k>.
  double energy_initial = 0.0;
  double energy_final = 0.0;
  bool energy_nonincreasing = true;
  double energy_max_increase = 0.0;   // largest E_{k+1} - E_k above the round-off allowance
  std::int64_t energy_increases = 0;  // steps where E rose above the allowance

  double h_min = 0.0;
  double h_max = 0.0;

  EquilibriumCheck equilibrium;
  SolverEffort solver;

  // Wall time by phase, in the order they ran ("parse", "compile", "integrate", "write", ...).
  std::vector<std::pair<std::string, double>> phase_seconds;
  double wall_seconds() const;
  void add_phase(const std::string& name, double seconds);

  // One line, for logs: status, steps, t_final, convergence, energy, solver effort, time.
  std::string BriefReport() const;
};

}  // namespace moreau
