// lu_solve_in_place (small_lu.h): the small dense solves of the one-step problems. References: Eigen's
// PartialPivLU on the same system (bit for bit up to r = 8, which the header promises, and to round-off
// beyond), and the residual A x - b itself.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <Eigen/Dense>

#include "moreau/core/small_lu.h"

namespace moreau {
namespace {

// Nonsingular systems that need row exchanges: random entries of mixed magnitudes, some of them exactly 0
// (a zero in the corner forces a pivot), and right-hand sides with some zero entries (the substitutions
// skip them).
Eigen::MatrixXd RandomMatrix(int r, std::mt19937& rng) {
  std::normal_distribution<double> N(0.0, 1.0);
  std::uniform_int_distribution<int> exponent(-3, 3), pick(0, 5);
  Eigen::MatrixXd A(r, r);
  for (int j = 0; j < r; ++j)
    for (int i = 0; i < r; ++i) A(i, j) = pick(rng) == 0 ? 0.0 : std::ldexp(N(rng), exponent(rng));
  if (r > 1) A(0, 0) = 0.0;
  if (Eigen::FullPivLU<Eigen::MatrixXd>(A).rank() < r) return RandomMatrix(r, rng);  // zeros made it singular: draw again
  return A;
}

Eigen::VectorXd RandomVector(int r, std::mt19937& rng) {
  std::normal_distribution<double> N(0.0, 1.0);
  std::uniform_int_distribution<int> pick(0, 3);
  Eigen::VectorXd b(r);
  for (int i = 0; i < r; ++i) b(i) = pick(rng) == 0 ? 0.0 : N(rng);
  return b;
}

// The reference: Eigen's PartialPivLU, through a named decomposition (the solve expression of a temporary
// one, assigned to a fixed-size vector, gave NaN under -O3 here).
Eigen::VectorXd EigenSolve(const Eigen::MatrixXd& A, const Eigen::VectorXd& b) {
  const Eigen::PartialPivLU<Eigen::MatrixXd> lu(A);
  Eigen::VectorXd x = lu.solve(b);
  return x;
}

bool SameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(SmallLu, MatchesEigenPartialPivLuBitForBitUpTo8) {
  std::mt19937 rng(7);
  int compared = 0;
  for (int r = 1; r <= 8; ++r) {
    for (int trial = 0; trial < 200; ++trial) {
      const Eigen::MatrixXd A = RandomMatrix(r, rng);
      const Eigen::VectorXd b = RandomVector(r, rng);
      const Eigen::VectorXd expected = EigenSolve(A, b);
      Eigen::MatrixXd work = A;
      Eigen::VectorXd x = b;
      EXPECT_TRUE(lu_solve_in_place(work, x, r));
      for (int i = 0; i < r; ++i) {
        EXPECT_TRUE(SameBits(x(i), expected(i)))
            << "r = " << r << ", trial " << trial << ", x(" << i << ") = " << x(i) << " against Eigen's " << expected(i);
        ++compared;
      }
    }
  }
  EXPECT_EQ(compared, 200 * 36);
}

TEST(SmallLu, SolvesLargerSystemsToRoundOff) {
  std::mt19937 rng(8);
  for (int r : {9, 12, 16, 17, 24, 40}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::MatrixXd A = RandomMatrix(r, rng);
      const Eigen::VectorXd b = RandomVector(r, rng);
      Eigen::MatrixXd work = A;
      Eigen::VectorXd x = b;
      ASSERT_TRUE(lu_solve_in_place(work, x, r));
      const Eigen::VectorXd expected = EigenSolve(A, b);
      // Backward error of partial pivoting: |A x - b| of order eps |A| |x| (growth factors are small here).
      const double scale = A.cwiseAbs().rowwise().sum().maxCoeff() * x.cwiseAbs().maxCoeff() + b.cwiseAbs().maxCoeff();
      EXPECT_LT((A * x - b).cwiseAbs().maxCoeff(), 1e3 * std::numeric_limits<double>::epsilon() * scale) << "r = " << r;
      const double cond = A.norm() * A.inverse().norm();
      EXPECT_LT((x - expected).cwiseAbs().maxCoeff(), 1e3 * cond * std::numeric_limits<double>::epsilon() * expected.cwiseAbs().maxCoeff())
          << "r = " << r << ", trial " << trial;
    }
  }
}

// Only the leading r x r block and the first r entries take part: what lies beyond them (the storage of
// a larger problem) is neither read into the result nor written.
TEST(SmallLu, WorksOnTheLeadingBlockOnly) {
  std::mt19937 rng(9);
  const int r = 3, cap = 7;
  const Eigen::MatrixXd A = RandomMatrix(r, rng);
  const Eigen::VectorXd b = RandomVector(r, rng);
  Eigen::MatrixXd work = Eigen::MatrixXd::Constant(cap, cap, std::numeric_limits<double>::quiet_NaN());
  Eigen::VectorXd x = Eigen::VectorXd::Constant(cap, 1e300);
  work.topLeftCorner(r, r) = A;
  x.head(r) = b;
  ASSERT_TRUE(lu_solve_in_place(work, x, r));
  const Eigen::VectorXd expected = EigenSolve(A, b);
  for (int i = 0; i < r; ++i) EXPECT_TRUE(SameBits(x(i), expected(i)));
  for (int i = r; i < cap; ++i) EXPECT_EQ(x(i), 1e300);
  EXPECT_TRUE(work.rightCols(cap - r).array().isNaN().all());
  EXPECT_TRUE(work.bottomRows(cap - r).array().isNaN().all());
  Eigen::VectorXd none(1);
  EXPECT_TRUE(lu_solve_in_place(work, none, 0));  // r = 0: nothing to do
}

// A zero pivot is reported, and the values are Eigen's: a zero pivot meeting a zero right-hand side gives
// a finite particular solution, otherwise infinities or NaN for the caller to reject.
TEST(SmallLu, ZeroPivotsAreReportedWithEigensValues) {
  Eigen::Matrix3d A;
  A << 1, 2, 3, 2, 4, 6, 1, 0, 1;  // rank 2: row 2 = 2 row 1
  for (const Eigen::Vector3d& b : {Eigen::Vector3d(1, 2, 1), Eigen::Vector3d(1, 3, 1)}) {
    Eigen::Matrix3d work = A;
    Eigen::Vector3d x = b;
    EXPECT_FALSE(lu_solve_in_place(work, x, 3));
    const Eigen::VectorXd expected = EigenSolve(A, b);
    for (int i = 0; i < 3; ++i)
      EXPECT_TRUE(SameBits(x(i), expected(i)) || (std::isnan(x(i)) && std::isnan(expected(i))))
          << "x(" << i << ") = " << x(i) << ", Eigen " << expected(i);
  }
}

}  // namespace
}  // namespace moreau
