#include "moreau/core/run_summary.h"

#include <string>

#include "moreau/platform/number_text.h"

namespace moreau {

const char* to_string(RunStatus status) {
  switch (status) {
    case RunStatus::kCompleted: return "completed";
    case RunStatus::kFailed: return "failed";
    case RunStatus::kCancelled: return "cancelled";
  }
  return "unknown";
}

double RunSummary::wall_seconds() const {
  double total = 0.0;
  for (const auto& [name, seconds] : phase_seconds) total += seconds;
  return total;
}

void RunSummary::add_phase(const std::string& name, double seconds) {
  for (auto& [existing, s] : phase_seconds) {
    if (existing == name) {
      s += seconds;
      return;
    }
  }
  phase_seconds.emplace_back(name, seconds);
}

std::string RunSummary::BriefReport() const {
  using platform::significant;
  std::string conv = "not at rest";
  if (converged_step) {
    conv = "v == 0 from step " + std::to_string(*converged_step) + " (t = " + significant(converged_time.value_or(0.0), 6) + ")";
  } else if (below_normal_step) {
    conv = "below the smallest normal number from step " + std::to_string(*below_normal_step) + " (not a rest)";
  }
  std::string line = std::string(to_string(status)) + ": " + std::to_string(steps) + " steps to t = " + significant(t_final, 6) + ", " +
                     conv + ", energy " + (energy_nonincreasing ? "non-increasing" : "not monotone") + " (" +
                     significant(energy_initial, 6) + " -> " + significant(energy_final, 6) + "), solver max " +
                     std::to_string(solver.max_iterations) + " iterations, residual " + significant(solver.max_residual, 3) + ", " +
                     platform::fixed(wall_seconds(), 3) + " s";
  if (!message.empty()) line += ": " + message;
  return line;
}

}  // namespace moreau
