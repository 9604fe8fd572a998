#include "moreau/core/run_summary.h"

#include <cstdio>

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
  char buf[512];
  char conv[96];
  if (converged_step) {
    std::snprintf(conv, sizeof conv, "v == 0 from step %lld (t = %.6g)", static_cast<long long>(*converged_step),
                  converged_time.value_or(0.0));
  } else if (below_normal_step) {
    std::snprintf(conv, sizeof conv, "below the smallest normal number from step %lld (not a rest)",
                  static_cast<long long>(*below_normal_step));
  } else {
    std::snprintf(conv, sizeof conv, "not at rest");
  }
  std::snprintf(buf, sizeof buf,
                "%s: %lld steps to t = %.6g, %s, energy %s (%.6g -> %.6g), solver max %d iterations, "
                "residual %.2e, %.3f s",
                to_string(status), static_cast<long long>(steps), t_final, conv, energy_nonincreasing ? "non-increasing" : "not monotone",
                energy_initial, energy_final, solver.max_iterations, solver.max_residual, wall_seconds());
  std::string line = buf;
  if (!message.empty()) line += ": " + message;
  return line;
}

}  // namespace moreau
