// The stress suite as a test: every case runs without NaN or Inf, completes, and meets what the theory
// promises for it (non-increasing energy, finite-step rest, or the absence of rest).
#include "moreau/scene/stress.h"

#include <gtest/gtest.h>

namespace moreau::scene {

// Test names and failure messages show the case's name, not its bytes.
void PrintTo(const StressCase& c, std::ostream* os) { *os << c.name; }

namespace {

class Stress : public ::testing::TestWithParam<StressCase> {};

TEST_P(Stress, MeetsItsExpectations) {
  const StressOutcome o = run_stress_case(GetParam());
  EXPECT_TRUE(o.finite);
  EXPECT_TRUE(o.failures.empty()) << format_outcome(o);
}

INSTANTIATE_TEST_SUITE_P(Suite, Stress, ::testing::ValuesIn(stress_cases()), [](const auto& info) {
  std::string name = info.param.name;
  for (char& ch : name)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return name;
});

TEST(Stress, TheTheorem41RuleShrinksTheStep) {
  for (const auto& c : stress_cases()) {
    if (c.name != "theorem-4.1-shrinks-h") continue;
    const StressOutcome o = run_stress_case(c);
    EXPECT_LT(o.summary.h_max, 0.1);
  }
}

}  // namespace
}  // namespace moreau::scene
