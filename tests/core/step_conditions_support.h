// Shared by step_conditions_test.cc and step_conditions_fixed_sizes_test.cc: what a StepCheck's ratio
// must be given its label, and the comparison of the checker with Eigen's SelfAdjointEigenSolver and
// JacobiSVD on random M and C (StepConditions.AgreeWithEigenSolvers). The comparison at n = 3 and 4 is
// instantiated in step_conditions_fixed_sizes_test.cc only (declared extern below), so that no translation
// unit instantiates the checker at every size; these helpers are therefore in namespace moreau itself, not
// in an unnamed namespace.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Dense>

#include "moreau/core/step_conditions.h"

namespace moreau {

// What StepCheck::ratio_kind promises: exact, an upper bound that proves r_k <= 1, or a lower bound that
// proves r_k > 1.
inline void ExpectRatioAsLabelled(const StepCheck& c, double ratio, int step) {
  switch (c.ratio_kind) {
    case BoundKind::kExact: EXPECT_NEAR(c.ratio(), ratio, 1e-10 * ratio) << "step " << step; break;
    case BoundKind::kUpperBound:
      EXPECT_GE(c.ratio(), ratio * (1.0 - 1e-10)) << "step " << step;
      EXPECT_LE(c.ratio(), 1.0) << "step " << step;
      break;
    case BoundKind::kLowerBound:
      EXPECT_LE(c.ratio(), ratio * (1.0 + 1e-10)) << "step " << step;
      EXPECT_GT(c.ratio(), 1.0) << "step " << step;
      break;
  }
}

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

    const StepCheck c = checker.check(M, C, h, 0.0);  // ceiling 0: every ratio (n <= 2 exactly)
    const double tol = 1e-10 * std::max(1.0, std::abs(lambda));
    if (lambda > tol) {
      ASSERT_GT(c.lambda_min_m, 0.0) << "trial " << trial;
      if (n <= 2) {
        EXPECT_NEAR(c.lambda_min_m, lambda, tol);
        EXPECT_NEAR(c.ratio(), ratio, 1e-10 * ratio);
      } else {
        EXPECT_LE(c.lambda_min_m, lambda + tol);
        ExpectRatioAsLabelled(c, ratio, trial);
      }
      // The verdict of (4.2) agrees with the reference whenever the reference is not within round-off of 1.
      if (std::abs(ratio - 1.0) > 1e-9) {
        EXPECT_EQ(c.ratio() > 1.0, ratio > 1.0) << "trial " << trial;
      }
      (ratio > 1.0 ? violations : holds) += 1;
    } else if (lambda < -tol) {
      EXPECT_LE(c.lambda_min_m, 0.0) << "trial " << trial;
      EXPECT_NEAR(c.lambda_min_m, lambda, tol) << "an indefinite M must be reported with its exact lambda_min";
      bool exact = false;
      EXPECT_LE(checker.lambda_min(M, exact), 0.0);
      EXPECT_TRUE(exact) << "an indefinite M must be reported with its exact lambda_min";
      ++indefinite;
    }
  }
  // The random draws cover all three outcomes.
  EXPECT_GT(violations, 50);
  EXPECT_GT(holds, 50);
  EXPECT_GT(indefinite, 50);
}

extern template void CompareWithEigen<3>(int n, std::mt19937& rng);
extern template void CompareWithEigen<4>(int n, std::mt19937& rng);

}  // namespace moreau
