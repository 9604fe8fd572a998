// The per-step checks of core/step_conditions.h against an independent computation: Eigen's
// SelfAdjointEigenSolver for lambda_min(M) and JacobiSVD for ||C||_2, on random symmetric positive
// definite, indefinite and nearly singular M and random C, at n = 1, 2 (closed forms), 3, 4 (fixed size)
// and 7 (dynamic). For n <= 2 the checker must equal the reference; for n > 2 it may use bounds, so its
// lambda_min is a lower bound with the same sign, and its ratio an upper bound that is exact above 1.
// The comparison at n = 3 and 4 is compiled in step_conditions_fixed_sizes_test.cc; the comparison itself
// is in step_conditions_support.h.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>

#include <Eigen/Dense>

#include "moreau/core/step_conditions.h"
#include "step_conditions_support.h"

namespace moreau {
namespace {

TEST(StepConditions, AgreeWithEigenSolvers) {
  std::mt19937 rng(20161124);
  CompareWithEigen<1>(1, rng);
  CompareWithEigen<2>(2, rng);
  CompareWithEigen<3>(3, rng);
  CompareWithEigen<4>(4, rng);
  CompareWithEigen<Eigen::Dynamic>(7, rng);
}

// Along a smooth path M(t) = R(t) diag(d(t)) R(t)^T, C(t) = c(t) C0 (n = 7, M far from diagonally
// dominant, so Gershgorin's bound cannot decide, and h large enough that the bound ||C||_1 ||C||_inf
// cannot either), as M(Q^k) and C(Q^k, V^k) move in a run with (4.2) holding at some steps and failing at
// others: each recorded lambda_min is at most the true one, each ratio is what its label says (exact, an
// upper bound <= 1, a lower bound > 1, and then within 0.1%), the run's smallest recorded lambda_min is
// within the 0.1% of the Cholesky certificate of the true smallest one, and eigenvalues are computed at
// few steps.
TEST(StepConditions, CholeskyCertificatesAlongASmoothPath) {
  const int n = 7;
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd A(n, n), B(n, n), C0(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      A(i, j) = normal(rng);
      B(i, j) = normal(rng);
      C0(i, j) = normal(rng);
    }
  C0 /= Eigen::JacobiSVD<Eigen::MatrixXd>(C0).singularValues()(0);  // ||C0||_2 = 1
  const Eigen::MatrixXd S = B - B.transpose();
  const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(A).householderQ();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
  StepConditionChecker<Eigen::Dynamic> checker(n);
  MassDefinitenessTrack track;
  double true_min = 1e300;
  int gershgorin_failed = 0, norm_bound_failed = 0, violations = 0, bounded_violations = 0;
  const int steps = 2000;
  const double h = 0.12;  // r_k = 2 h ||C||_2 / lambda_min(M) from about 0.1 to 1.4
  for (int k = 0; k < steps; ++k) {
    const double t = 1e-3 * k;
    Eigen::VectorXd d(n);
    for (int i = 0; i < n; ++i) d(i) = 0.5 + i + 0.3 * std::sin(3.0 * t + i);         // lambda_min between 0.2 and 0.8
    const Eigen::MatrixXd R = Q * (I - 0.05 * t * S).inverse() * (I + 0.05 * t * S);  // Cayley: a rotation
    Eigen::MatrixXd M = R * d.asDiagonal() * R.transpose();
    M = 0.5 * (M + M.transpose()).eval();
    const Eigen::MatrixXd C = (1.0 + 0.5 * std::sin(2.0 * t)) * C0;
    const double lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues()(0);
    const double ratio = 2.0 * h * Eigen::JacobiSVD<Eigen::MatrixXd>(C).singularValues()(0) / lambda;
    double gersh = 1e300;
    for (int i = 0; i < n; ++i) gersh = std::min(gersh, M(i, i) - (M.row(i).cwiseAbs().sum() - std::abs(M(i, i))));
    gershgorin_failed += gersh <= 0.0;
    const double c2_bound = C.cwiseAbs().colwise().sum().maxCoeff() * C.cwiseAbs().rowwise().sum().maxCoeff();
    norm_bound_failed += 4.0 * h * h * c2_bound > lambda * lambda;
    true_min = std::min(true_min, lambda);

    const StepCheck c = checker.check(M, C, h, 0.0);
    ASSERT_LE(c.lambda_min_m, lambda * (1.0 + 1e-12)) << "step " << k;
    ASSERT_GT(c.lambda_min_m, 0.0);
    ExpectRatioAsLabelled(c, ratio, k);
    if (ratio > 1.0 + 1e-9) {
      ++violations;
      bounded_violations += c.ratio_kind == BoundKind::kLowerBound;
      EXPECT_GT(c.ratio(), (1.0 - 1e-3) * ratio) << "step " << k << ": the Rayleigh quotients' bound must stay tight";
    }
    if (c.exact) {
      EXPECT_NEAR(c.lambda_min_m, lambda, 1e-12 * lambda);
    }
    track.record(c.lambda_min_m, c.exact, k, t);
  }
  EXPECT_EQ(gershgorin_failed, steps) << "the path must exercise the Cholesky certificate of M";
  EXPECT_GT(norm_bound_failed, steps / 4) << "the path must exercise the Cholesky certificate of C";
  EXPECT_GT(violations, steps / 10);
  EXPECT_GT(bounded_violations, violations / 2) << "the path must exercise the Rayleigh quotients' bounds";
  EXPECT_LE(track.lambda_min, true_min * (1.0 + 1e-12));
  EXPECT_GE(track.lambda_min, (1.0 - 1e-3) * true_min * (1.0 - 1e-12));
  EXPECT_LE(checker.eigenvalue_computations(), steps / 100);
  EXPECT_GE(checker.eigenvalue_computations(), 2);
}

// A run records r_k through StepConditionTrack::ceiling: below the largest ratio recorded so far the checker
// gives only a bound (n = 2) and the track only counts the step. Along a path whose ratio rises, falls and
// crosses 1 several times, the records must be those of plain bookkeeping of every step's exact ratio (the
// largest, its step, the violations and the first of them), bit for bit, at n = 1, 2 and 7.
template <int N>
void CeilingRecordsWhatEveryStepWouldRecord(int n) {
  std::mt19937 rng(41 + n);
  std::normal_distribution<double> normal;
  Eigen::MatrixXd A(n, n), C0(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      A(i, j) = normal(rng);
      C0(i, j) = normal(rng);
    }
  const Eigen::MatrixXd M0 = A * A.transpose() / n + Eigen::MatrixXd::Identity(n, n);
  const double lambda0 = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M0).eigenvalues()(0);
  StepConditionChecker<N> exact(n), checker(n);
  StepConditionTrack track;
  double worst_num = 0.0, worst_den = 1.0;
  std::int64_t worst_step = -1, first_violation = -1, violations = 0, bounded = 0;
  const int steps = 4000;
  const double h = 0.05 / Eigen::JacobiSVD<Eigen::MatrixXd>(C0).singularValues()(0);
  for (int k = 0; k < steps; ++k) {
    const double t = 1e-3 * k;
    Mat<N> M = M0 * (1.0 + 0.3 * std::sin(5.0 * t));
    M(0, 0) += 0.2 * std::cos(7.0 * t);
    // r_k = 0.15 |sin 4t| (1 + 3t) lambda0 / lambda_min(M): it oscillates with a growing amplitude, so
    // new largest ratios come now and then, and violations from about t = 2.
    const Mat<N> C = C0 * (1.5 * lambda0 * std::abs(std::sin(4.0 * t)) * (1.0 + 3.0 * t));
    const StepCheck e = exact.check(M, C, h, 0.0);
    const StepCheck c = checker.check(M, C, h, track.ceiling());
    bounded += c.ratio_kind == BoundKind::kUpperBound && n <= 2;
    if (e.ratio_sq_num * worst_den > worst_num * e.ratio_sq_den) {
      worst_num = e.ratio_sq_num;
      worst_den = e.ratio_sq_den;
      worst_step = k;
    }
    if (e.ratio_sq_num > e.ratio_sq_den * (1.0 + StepConditionTrack::kRoundoff) * (1.0 + StepConditionTrack::kRoundoff)) {
      if (violations++ == 0) first_violation = k;
    }
    track.record_squared(c.ratio_sq_num, c.ratio_sq_den, c.ratio_kind, k, t);
  }
  EXPECT_EQ(track.checked, steps);
  EXPECT_EQ(track.worst_ratio(), std::sqrt(worst_num / worst_den)) << "n = " << n;
  EXPECT_EQ(track.worst_step, worst_step) << "n = " << n;
  EXPECT_EQ(track.violations, violations) << "n = " << n;
  EXPECT_EQ(track.first_violation_step, first_violation) << "n = " << n;
  EXPECT_GT(violations, steps / 20) << "the path must cross (4.2)";
  EXPECT_LT(violations, steps / 2);
  if (n == 2) {
    EXPECT_GT(bounded, steps / 2) << "the n = 2 closed form of ||C||_2 must be skipped on most steps";
  }
}

TEST(StepConditions, CeilingRecordsWhatEveryStepWouldRecord) {
  CeilingRecordsWhatEveryStepWouldRecord<1>(1);
  CeilingRecordsWhatEveryStepWouldRecord<2>(2);
  CeilingRecordsWhatEveryStepWouldRecord<Eigen::Dynamic>(7);
}

TEST(StepConditions, TrackCountsViolationsFromTheFirst) {
  StepConditionTrack t;
  EXPECT_EQ(t.verdict(), Verdict::kNotChecked);
  // r^2 as num / den.
  t.record_squared(0.25, 1.0, BoundKind::kExact, 0, 0.0);
  const double r = 1.0 + StepConditionTrack::kRoundoff / 2;  // the rule's own equality, up to round-off
  t.record_squared(r * r * 4.0, 4.0, BoundKind::kExact, 1, 0.1);
  EXPECT_EQ(t.verdict(), Verdict::kHolds);
  t.record_squared(9.0, 1.0, BoundKind::kExact, 2, 0.2);
  t.record_squared(16.0, 4.0, BoundKind::kExact, 3, 0.3);
  EXPECT_EQ(t.verdict(), Verdict::kFails);
  EXPECT_EQ(t.violations, 2);
  EXPECT_EQ(t.first_violation_step, 2);
  EXPECT_DOUBLE_EQ(t.worst_ratio(), 3.0);
  EXPECT_EQ(t.worst_time, 0.2);
  EXPECT_EQ(t.checked, 4);
}

}  // namespace
}  // namespace moreau
