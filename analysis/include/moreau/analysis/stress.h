// The stress suite: stiff and extreme scenes for the ABL scheme, each with what the theory of Adly,
// Brogliato and Le (2016) promises for it (or that it lies outside the theory), run and checked.
// `moreau stress` prints one line per case; tests/analysis/stress_test.cc asserts every expectation.
// The cases are documented in docs/stress.md.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/core/run_summary.h"

namespace moreau::scene {

struct StressCase {
  std::string name;
  std::string what;  // one line: the extreme this case exercises
  nlohmann::json scene;
  bool expect_completed = true;
  std::optional<bool> expect_energy_nonincreasing;  // set where Theorem 4.2 (or constant M) promises it
  std::optional<bool> expect_converged;             // set where Theorem 4.3 promises it (or rules it out)
  bool within_theory = true;
  std::string theory;  // which result applies, or why none does
};

struct StressOutcome {
  const StressCase* c = nullptr;
  RunSummary summary;
  bool finite = true;                 // no NaN or Inf anywhere in the final state or the energy
  std::vector<std::string> failures;  // unmet expectations; empty = pass
  double seconds = 0.0;
};

std::vector<StressCase> stress_cases();
StressOutcome run_stress_case(const StressCase& c);
std::string format_outcome(const StressOutcome& o);

}  // namespace moreau::scene
