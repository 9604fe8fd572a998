// The per-step checks of core/step_conditions.h against an independent computation: Eigen's
// SelfAdjointEigenSolver for lambda_min(M) and JacobiSVD for ||C||_2, on random symmetric positive
// definite, indefinite and nearly singular M and random C, at n = 1, 2 (closed forms), 3, 4 (fixed size)
// and 7 (dynamic). For n <= 2 the checker must equal the reference; for n > 2 it may use bounds, so its
// lambda_min is a lower bound with the same sign, and its ratio an upper bound that is exact above 1.
#include <gtest/gtest.h>

#include <random>

#include <Eigen/Dense>

#include "moreau/core/step_conditions.h"

namespace moreau {
namespace {

template <int N>
void CompareWithEigen(int n, std::mt19937& rng) {
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> shift(-0.5, 2.0), log_h(-6.0, 0.0);
  StepConditionChecker<N> checker(n);
  int violations = 0, holds = 0, indefinite = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    Mat<N> A(n, n), C(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        A(i, j) = normal(rng);
        C(i, j) = normal(rng);
      }
    // M = A A^T / n + s I: positive definite for most s, indefinite for some s < 0.
    Mat<N> M = A * A.transpose() / n;
    M.diagonal().array() += shift(rng) * (trial % 3 == 0 ? 1.0 : 0.2);
    const double h = std::pow(10.0, log_h(rng));

    const double lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(M)).eigenvalues()(0);
    const double c_norm = Eigen::JacobiSVD<Eigen::MatrixXd>(Eigen::MatrixXd(C)).singularValues()(0);
    const double ratio = 2.0 * h * c_norm / lambda;

    const StepCheck c = checker.check(M, C, h);
    const double tol = 1e-10 * std::max(1.0, std::abs(lambda));
    if (lambda > tol) {
      ASSERT_GT(c.lambda_min_m, 0.0) << "trial " << trial;
      if (n <= 2) {
        EXPECT_NEAR(c.lambda_min_m, lambda, tol);
        EXPECT_NEAR(c.ratio(), ratio, 1e-10 * ratio);
      } else {
        EXPECT_LE(c.lambda_min_m, lambda + tol);
        EXPECT_GE(c.ratio(), ratio * (1.0 - 1e-10));
        if (c.ratio() > 1.0) {
          EXPECT_NEAR(c.ratio(), ratio, 1e-10 * ratio) << "a violation must be exact";
        }
      }
      // The verdict of (4.2) agrees with the reference whenever the reference is not within round-off of 1.
      if (std::abs(ratio - 1.0) > 1e-9) {
        EXPECT_EQ(c.ratio() > 1.0, ratio > 1.0) << "trial " << trial;
      }
      (ratio > 1.0 ? violations : holds) += 1;
    } else if (lambda < -tol) {
      EXPECT_LE(c.lambda_min_m, 0.0) << "trial " << trial;
      EXPECT_NEAR(c.lambda_min_m, lambda, tol) << "an indefinite M must be reported with its exact lambda_min";
      EXPECT_EQ(checker.lambda_min(M) <= 0.0, true);
      ++indefinite;
    }
  }
  // The random draws cover all three outcomes.
  EXPECT_GT(violations, 50);
  EXPECT_GT(holds, 50);
  EXPECT_GT(indefinite, 50);
}

TEST(StepConditions, AgreeWithEigenSolvers) {
  std::mt19937 rng(20161124);
  CompareWithEigen<1>(1, rng);
  CompareWithEigen<2>(2, rng);
  CompareWithEigen<3>(3, rng);
  CompareWithEigen<4>(4, rng);
  CompareWithEigen<Eigen::Dynamic>(7, rng);
}

TEST(StepConditions, TrackCountsViolationsFromTheFirst) {
  StepConditionTrack t;
  EXPECT_EQ(t.verdict(), Verdict::kNotChecked);
  // r^2 as num / den.
  t.record_squared(0.25, 1.0, 0, 0.0);
  const double r = 1.0 + StepConditionTrack::kRoundoff / 2;  // the rule's own equality, up to round-off
  t.record_squared(r * r * 4.0, 4.0, 1, 0.1);
  EXPECT_EQ(t.verdict(), Verdict::kHolds);
  t.record_squared(9.0, 1.0, 2, 0.2);
  t.record_squared(16.0, 4.0, 3, 0.3);
  EXPECT_EQ(t.verdict(), Verdict::kFails);
  EXPECT_EQ(t.violations, 2);
  EXPECT_EQ(t.first_violation_step, 2);
  EXPECT_DOUBLE_EQ(t.worst_ratio(), 3.0);
  EXPECT_EQ(t.worst_time, 0.2);
  EXPECT_EQ(t.checked, 4);
}

}  // namespace
}  // namespace moreau
