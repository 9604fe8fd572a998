// The one-step inclusion (6.5) P y + x in -d phi(y): closed forms (n = 1 and 3), random problems at n = 3
// checked against an independent brute-force search over sign patterns, exact zeros, the norm term with
// the relays, and the banded solves of the dynamic size, against that brute force and against dense LU
// (with the inclusion's residual computed from its definition). The fixed size n = 2 and the dense
// dynamic-size paths (principal pivoting, the shared factorisation) are tested in
// one_step_solver_pivoting_test.cc: two translation units, so that neither instantiates the solver at
// every size. The references are in one_step_solver_support.h.
#include "moreau/core/one_step_solver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "one_step_solver_support.h"

namespace moreau {
namespace {

TEST(OneStepSolver, ScalarClosedForm) {
  OneStepSolver<1> solver;
  solver.configure(Vec<1>(2.0), 0.0);
  OneStepStats st;
  Vec<1> y;
  // |x| <= a: y = 0 exactly.
  ASSERT_TRUE(solver.solve(Mat<1>(4.0), Vec<1>(-1.999), y, st));
  EXPECT_EQ(y(0), 0.0);
  EXPECT_EQ(st.iterations, 0);
  // x = -10: y = (10 - 2) / 4 = 2.
  ASSERT_TRUE(solver.solve(Mat<1>(4.0), Vec<1>(-10.0), y, st));
  EXPECT_DOUBLE_EQ(y(0), 2.0);
  ASSERT_TRUE(solver.solve(Mat<1>(4.0), Vec<1>(10.0), y, st));
  EXPECT_DOUBLE_EQ(y(0), -2.0);
}

TEST(OneStepSolver, RestIsExactlyZero) {
  OneStepSolver<3> solver;
  solver.configure(Vec<3>(1.0, 2.0, 3.0), 0.0);
  Mat<3> P = Mat<3>::Identity() * 100.0;
  P(0, 1) = 5.0;
  Vec<3> y;
  OneStepStats st;
  ASSERT_TRUE(solver.solve(P, Vec<3>(0.5, -1.9, 2.99), y, st));
  EXPECT_EQ(y(0), 0.0);
  EXPECT_EQ(y(1), 0.0);
  EXPECT_EQ(y(2), 0.0);
}

// zero_by_closed_form is set exactly when -x lies in d phi(0) (then y is 0.0), and cleared by the next
// solve that does not take that closed form.
TEST(OneStepSolver, ClosedFormZeroIsReported) {
  OneStepSolver<2> solver;
  solver.configure(Vec<2>(1.0, 2.0), 0.5);
  Mat<2> P;
  P << 10.0, 1.0, -1.0, 10.0;
  Vec<2> y;
  OneStepStats st;
  // d phi(0) is the box [-1, 1] x [-2, 2] plus the ball of radius 0.5: -x = (-1.3, 2.2) is at distance
  // sqrt(0.13) < 0.5 from the box; (-1.3, 2.7) at sqrt(0.58) > 0.5.
  ASSERT_TRUE(solver.solve(P, Vec<2>(1.3, -2.2), y, st));
  EXPECT_TRUE(st.zero_by_closed_form);
  EXPECT_EQ(y(0), 0.0);
  EXPECT_EQ(y(1), 0.0);
  ASSERT_TRUE(solver.solve(P, Vec<2>(1.3, -2.7), y, st));
  EXPECT_FALSE(st.zero_by_closed_form);
  EXPECT_GT(y.norm(), 0.0);
}

TEST(OneStepSolver, RandomNonsymmetric3) { RandomProblems<3>(3, 300, 2); }

// P = S + K with S = G G^T symmetric positive definite and K skew, both zero beyond `band` from the
// diagonal (G lower triangular with `band` sub-diagonals gives S that band): the structure of
// M/h + C + W for a chain.
Eigen::MatrixXd RandomBandedP(int n, int band, std::mt19937& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::MatrixXd G = Eigen::MatrixXd::Zero(n, n), K = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = std::max(0, i - band); j <= i; ++j) G(i, j) = gauss(rng);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j <= std::min(n - 1, i + band); ++j) {
      K(i, j) = 0.8 * gauss(rng);
      K(j, i) = -K(i, j);
    }
  return G * G.transpose() + 0.5 * Eigen::MatrixXd::Identity(n, n) + K;
}

TEST(OneStepSolver, BandedSolvesAreChosenOnlyForNarrowBandsOfDynamicSize) {
  OneStepSolver<Eigen::Dynamic> dynamic;
  dynamic.configure(Eigen::VectorXd::Ones(6), 0.0, 1);
  EXPECT_EQ(dynamic.banded_width(), 1);  // 6 b <= n
  dynamic.configure(Eigen::VectorXd::Ones(5), 0.0, 1);
  EXPECT_EQ(dynamic.banded_width(), -1);  // too wide for n = 5: dense LU is cheaper
  dynamic.configure(Eigen::VectorXd::Ones(64), 0.0, -1);
  EXPECT_EQ(dynamic.banded_width(), -1);  // no promise
  OneStepSolver<3> fixed;
  fixed.configure(Vec<3>::Ones(), 0.0, 0);
  EXPECT_EQ(fixed.banded_width(), -1);  // fixed sizes keep their dense (unrolled) path
}

// Banded solves against the independent brute force (every sign pattern, full-pivot LU on the reduced
// system): the same y, and the same exact zeros.
TEST(OneStepSolver, BandedMatchesBruteForceOnTridiagonalProblems) {
  const int n = 7, band = 1;
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  Eigen::VectorXd a(n);
  for (int i = 0; i < n; ++i) a(i) = unif(rng);
  OneStepSolver<Eigen::Dynamic> solver;
  solver.configure(a, 0.0, band);
  ASSERT_EQ(solver.banded_width(), band);
  int zeros = 0, moving = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const Eigen::MatrixXd P = RandomBandedP(n, band, rng);
    Eigen::VectorXd x(n), y(n);
    for (int i = 0; i < n; ++i) x(i) = 2.0 * gauss(rng);
    OneStepStats st;
    ASSERT_TRUE(solver.solve(P, x, y, st)) << "trial " << trial;
    EXPECT_FALSE(st.used_fallback) << "trial " << trial;
    const Eigen::VectorXd ref = BruteForce(P, x, a);
    for (int i = 0; i < n; ++i) {
      if (ref(i) == 0.0) {
        EXPECT_EQ(y(i), 0.0) << "component " << i << " of trial " << trial;
        ++zeros;
      } else {
        EXPECT_NEAR(y(i), ref(i), 1e-12 * (1.0 + std::abs(ref(i)))) << "component " << i << " of trial " << trial;
        ++moving;
      }
    }
  }
  EXPECT_GT(zeros, 0);
  EXPECT_GT(moving, 0);
}

// At 64 coordinates (too many patterns for the brute force), banded and dense LU on the same problems,
// with and without the norm term of Remark 4.2: the same answers to round-off, each checked against the
// inclusion computed here. The diagonal shift is what M/h adds to P in a step; without it some of these
// random problems make the active-set iteration cycle and the fallback slow, for dense and banded alike.
TEST(OneStepSolver, BandedAgreesWithDenseAtSixtyFourCoordinates) {
  const int n = 64;
  std::mt19937 rng(12);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  for (const int band : {1, 2, 5}) {
    for (const double a_norm : {0.0, 0.7}) {
      Eigen::VectorXd a(n);
      for (int i = 0; i < n; ++i) a(i) = unif(rng);
      OneStepSolver<Eigen::Dynamic> banded, dense;
      banded.configure(a, a_norm, band);
      dense.configure(a, a_norm, -1);
      ASSERT_EQ(banded.banded_width(), band);
      int zeros = 0;
      for (int trial = 0; trial < 40; ++trial) {
        const Eigen::MatrixXd P = RandomBandedP(n, band, rng) + 3.0 * Eigen::MatrixXd::Identity(n, n);
        Eigen::VectorXd x(n), yb(n), yd(n);
        for (int i = 0; i < n; ++i) x(i) = 3.0 * gauss(rng);
        OneStepStats sb, sd;
        ASSERT_TRUE(banded.solve(P, x, yb, sb)) << "band " << band << " trial " << trial;
        ASSERT_TRUE(dense.solve(P, x, yd, sd)) << "band " << band << " trial " << trial;
        EXPECT_FALSE(sb.used_fallback) << "band " << band << " trial " << trial;
        const double scale = 1.0 + yd.cwiseAbs().maxCoeff();
        for (int i = 0; i < n; ++i) {
          EXPECT_EQ(yb(i) == 0.0, yd(i) == 0.0) << "band " << band << " trial " << trial << " component " << i;
          EXPECT_NEAR(yb(i), yd(i), 1e-11 * scale) << "band " << band << " trial " << trial << " component " << i;
          zeros += yb(i) == 0.0;
        }
        EXPECT_LE(InclusionResidual(P, x, a, a_norm, yb), 1e-10 * (1.0 + x.cwiseAbs().maxCoeff()));
      }
      EXPECT_GT(zeros, 0) << "band " << band;
    }
  }
}

// A bandwidth promise that P breaks is never used silently: whatever the solver returns satisfies (6.5)
// with the whole P, because acceptance always uses the whole P.
TEST(OneStepSolver, ABrokenBandwidthPromiseIsCaughtByTheResidual) {
  const int n = 12;
  std::mt19937 rng(13);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::VectorXd a = Eigen::VectorXd::Constant(n, 0.3);
  OneStepSolver<Eigen::Dynamic> solver;
  solver.configure(a, 0.0, 1);  // promised 1, given 3
  int caught = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::MatrixXd P = RandomBandedP(n, 3, rng);
    Eigen::VectorXd x(n), y(n);
    for (int i = 0; i < n; ++i) x(i) = 3.0 * gauss(rng);
    OneStepStats st;
    const bool solved = solver.solve(P, x, y, st);
    if (!solved || st.used_fallback) ++caught;
    if (solved) {
      EXPECT_LE(InclusionResidual(P, x, a, 0.0, y), 1e-10 * (1.0 + x.cwiseAbs().maxCoeff())) << "trial " << trial;
    }
  }
  EXPECT_GT(caught, 30) << "the banded solves of a wider P should fail their check";
}

TEST(OneStepSolver, NormAndAbsTogether) {
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  OneStepSolver<3> solver;
  solver.configure(Vec<3>(0.5, 0.0, 1.0), 0.7);
  for (int trial = 0; trial < 200; ++trial) {
    Mat<3> G = Mat<3>::NullaryExpr([&] { return gauss(rng); });
    Mat<3> K = Mat<3>::NullaryExpr([&] { return gauss(rng); });
    Mat<3> P = G * G.transpose() + Mat<3>::Identity() + (K - K.transpose());
    Vec<3> x = Vec<3>::NullaryExpr([&] { return 3.0 * gauss(rng); });
    Vec<3> y;
    OneStepStats st;
    ASSERT_TRUE(solver.solve(P, x, y, st)) << trial;
    EXPECT_LE(solver.residual(P, x, y), 1e-12 * (1 + x.norm()));
  }
}

// The norm term's fallback (the search over the radius t = ||y||, each trial a separable problem solved
// by pivoting) on random problems: against the independent enumeration of every pattern with its radius
// equation for n <= 6, and for n up to 10 and at 40 against the inclusion's residual computed from its
// definition (the solution being unique, a y that satisfies (6.5) to round-off is it). Some gains are 0
// (components free of the l1 term), P nonsymmetric (a skew part, as C and W add), nearly singular in
// some trials.
TEST(OneStepSolver, NormTermSearchOverTheRadiusAgreesWithEnumeration) {
  std::mt19937 rng(20261129);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  int compared = 0, zeros = 0, checked = 0;
  for (const int n : {1, 2, 3, 4, 5, 6, 7, 8, 10, 40}) {
    for (int trial = 0; trial < (n <= 6 ? 60 : 30); ++trial) {
      Eigen::VectorXd a(n);
      for (int i = 0; i < n; ++i) a(i) = trial % 4 == 0 && i % 3 == 0 ? 0.0 : unif(rng);
      const double a_norm = 0.2 + unif(rng);
      Eigen::MatrixXd G(n, n), K(n, n);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
          G(i, j) = gauss(rng);
          K(i, j) = gauss(rng);
        }
      const double delta = trial % 5 == 0 ? 1e-3 : 0.5;
      const Eigen::MatrixXd P = G * G.transpose() + delta * Eigen::MatrixXd::Identity(n, n) + 0.8 * (K - K.transpose());
      Eigen::VectorXd x(n);
      for (int i = 0; i < n; ++i) x(i) = 3.0 * gauss(rng);
      // y = 0 is solve()'s closed form, outside the search: such problems are drawn again.
      if ((x - x.cwiseMax(-a).cwiseMin(a)).norm() <= a_norm) continue;
      OneStepSolver<Eigen::Dynamic> solver;
      solver.configure(a, a_norm);
      Eigen::VectorXd y(n);
      OneStepStats st;
      ASSERT_TRUE(solver.solve_by_radius(P, x, y, st)) << "n = " << n << ", trial " << trial;
      const double scale = 1.0 + x.cwiseAbs().maxCoeff() + P.cwiseAbs().maxCoeff() * y.cwiseAbs().maxCoeff();
      EXPECT_LE(InclusionResidual(P, x, a, a_norm, y), 1e-12 * scale) << "n = " << n << ", trial " << trial;
      ++checked;
      for (int i = 0; i < n; ++i) zeros += a(i) > 0.0 && y(i) == 0.0;
      if (n <= 6) {
        const Eigen::VectorXd expected = BruteForceWithNorm(P, x, a, a_norm);
        for (int i = 0; i < n; ++i) {
          EXPECT_NEAR(y(i), expected(i), 1e-8 * (1.0 + expected.cwiseAbs().maxCoeff())) << "n = " << n << ", trial " << trial;
          if (a(i) > 0.0 && std::abs(expected(i)) < 1e-10) {
            EXPECT_EQ(y(i), 0.0) << "exact rest, n = " << n << ", trial " << trial;
          }
        }
        ++compared;
      }
      // solve() gives the same answer, by whichever route it takes.
      Eigen::VectorXd y_solve(n);
      OneStepStats st_solve;
      ASSERT_TRUE(solver.solve(P, x, y_solve, st_solve));
      EXPECT_LE((y_solve - y).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + y.cwiseAbs().maxCoeff())) << "n = " << n << ", trial " << trial;
    }
  }
  EXPECT_GT(compared, 250);
  EXPECT_GT(checked, 350);
  EXPECT_GT(zeros, 50) << "components at rest (exactly 0.0) went untested";
}

}  // namespace
}  // namespace moreau
