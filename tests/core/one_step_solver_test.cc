// The one-step inclusion (6.5) P y + x in -d phi(y): closed forms, random problems checked against an
// independent brute-force search over sign patterns, exact zeros, and the norm term.
#include "moreau/core/one_step_solver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cmath>
#include <random>

namespace moreau {
namespace {

// Independent reference for phi = sum a_i |y_i| (no norm term): try every sign pattern, solve its
// linear system with a different factorisation (full-pivot LU on the reduced system), keep the one
// satisfying the inclusion. Unique by Theorem 4.1, so the first hit is the answer.
Eigen::VectorXd BruteForce(const Eigen::MatrixXd& P, const Eigen::VectorXd& x, const Eigen::VectorXd& a) {
  const int n = static_cast<int>(x.size());
  int total = 1;
  for (int i = 0; i < n; ++i) total *= 3;
  for (int code = 0; code < total; ++code) {
    std::vector<int> s(n), free;
    int c = code;
    for (int i = 0; i < n; ++i) {
      s[i] = c % 3 - 1;
      c /= 3;
      if (s[i] != 0) free.push_back(i);
    }
    Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
    if (!free.empty()) {
      const int m = static_cast<int>(free.size());
      Eigen::MatrixXd A(m, m);
      Eigen::VectorXd b(m);
      for (int r = 0; r < m; ++r) {
        b(r) = -(x(free[r]) + a(free[r]) * s[free[r]]);
        for (int cc = 0; cc < m; ++cc) A(r, cc) = P(free[r], free[cc]);
      }
      Eigen::VectorXd yf = A.fullPivLu().solve(b);
      for (int r = 0; r < m; ++r) y(free[r]) = yf(r);
    }
    bool ok = true;
    const Eigen::VectorXd w = -(P * y + x);
    for (int i = 0; i < n && ok; ++i) {
      if (s[i] != 0)
        ok = y(i) * s[i] >= 0.0;
      else
        ok = std::abs(w(i)) <= a(i) * (1 + 1e-12);
    }
    if (ok) return y;
  }
  ADD_FAILURE() << "brute force found no pattern";
  return Eigen::VectorXd::Zero(n);
}

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

TEST(OneStepSolver, NoNonsmoothTermIsALinearSolve) {
  OneStepSolver<2> solver;
  solver.configure(Vec<2>::Zero(), 0.0);
  Mat<2> P;
  P << 3, 1, -1, 2;
  const Vec<2> x(1.0, -2.0);
  Vec<2> y;
  OneStepStats st;
  ASSERT_TRUE(solver.solve(P, x, y, st));
  EXPECT_LT((P * y + x).norm(), 1e-15);
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

template <int N>
void RandomProblems(int n, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  OneStepSolver<N> solver;
  Vec<N> a(n);
  for (int i = 0; i < n; ++i) a(i) = unif(rng);
  solver.configure(a, 0.0);
  int zeros = 0;
  for (int trial = 0; trial < count; ++trial) {
    // P = S + K with S symmetric positive definite and K skew: the structure of M/h + C + W.
    Eigen::MatrixXd G(n, n), K(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        G(i, j) = gauss(rng);
        K(i, j) = gauss(rng);
      }
    Mat<N> P = G * G.transpose() + 0.5 * Eigen::MatrixXd::Identity(n, n) + 0.8 * (K - K.transpose());
    Vec<N> x(n);
    for (int i = 0; i < n; ++i) x(i) = 2.0 * gauss(rng);
    Vec<N> y(n);
    OneStepStats st;
    ASSERT_TRUE(solver.solve(P, x, y, st)) << "trial " << trial << " residual " << st.residual;
    const Eigen::VectorXd ref = BruteForce(P, x, a);
    for (int i = 0; i < n; ++i) {
      if (ref(i) == 0.0) {
        EXPECT_EQ(y(i), 0.0) << "component " << i << " of trial " << trial << " must be exactly zero";
        ++zeros;
      } else {
        EXPECT_NEAR(y(i), ref(i), 1e-12 * (1.0 + std::abs(ref(i))));
      }
    }
    EXPECT_LE(st.residual, st.tolerance);
  }
  EXPECT_GT(zeros, 0) << "the random problems should exercise sticking components";
}

// The fixed-size n = 2 solver takes its own scalar route (solve_pattern2, solve2); the dynamic-size solver
// at n = 2 takes the general one (A_ with pinned rows and columns of the identity, Eigen's PartialPivLU).
// Reference: that general path. Same problems in the same order (so the same warm-start patterns), one
// of the gains 0 on some problems (a component with no relay is never pinned): the same y, residual,
// tolerance and iteration count, bit for bit.
TEST(OneStepSolver, TwoCoordinatesTakeTheGeneralPathsArithmetic) {
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  int pinned = 0, moving = 0;
  for (const Vec<2>& a : {Vec<2>(0.7, 1.3), Vec<2>(0.0, 1.0), Vec<2>(2.0, 0.0)}) {
    OneStepSolver<2> fixed;
    OneStepSolver<Eigen::Dynamic> dynamic;
    fixed.configure(a, 0.0);
    dynamic.configure(Eigen::VectorXd(a), 0.0);
    for (int trial = 0; trial < 2000; ++trial) {
      Mat<2> P;
      const double k = 0.8 * gauss(rng);
      P << 2.0 + std::abs(gauss(rng)), 0.3 * gauss(rng) + k, 0.0, 2.0 + std::abs(gauss(rng));
      P(1, 0) = P(0, 1) - 2.0 * k;  // symmetric part plus a skew part, as M/h + C + W
      const Vec<2> x(2.0 * gauss(rng), 2.0 * gauss(rng));
      Vec<2> y;
      Eigen::VectorXd yd(2);
      OneStepStats st, sd;
      ASSERT_TRUE(fixed.solve(P, x, y, st)) << trial;
      ASSERT_TRUE(dynamic.solve(Eigen::MatrixXd(P), Eigen::VectorXd(x), yd, sd)) << trial;
      for (int i = 0; i < 2; ++i) {
        ASSERT_EQ(std::bit_cast<std::uint64_t>(y(i)), std::bit_cast<std::uint64_t>(yd(i))) << "trial " << trial << " y(" << i << ")";
        (y(i) == 0.0 ? pinned : moving) += a(i) > 0.0;
      }
      ASSERT_EQ(std::bit_cast<std::uint64_t>(st.residual), std::bit_cast<std::uint64_t>(sd.residual)) << trial;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(st.tolerance), std::bit_cast<std::uint64_t>(sd.tolerance)) << trial;
      ASSERT_EQ(st.iterations, sd.iterations) << trial;
    }
  }
  EXPECT_GT(pinned, 1000) << "the problems should pin components (one pinned: the pinned-row route)";
  EXPECT_GT(moving, 1000);
}

TEST(OneStepSolver, RandomNonsymmetric2) { RandomProblems<2>(2, 400, 1); }
TEST(OneStepSolver, RandomNonsymmetric3) { RandomProblems<3>(3, 300, 2); }
TEST(OneStepSolver, RandomNonsymmetricDynamic6) { RandomProblems<Eigen::Dynamic>(6, 200, 3); }

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

// dist(-(P y + x), d phi(y)) for phi = sum a_i |y_i| + a_norm ||y||, computed here from its definition.
double InclusionResidual(const Eigen::MatrixXd& P, const Eigen::VectorXd& x, const Eigen::VectorXd& a, double a_norm,
                         const Eigen::VectorXd& y) {
  Eigen::VectorXd w = -(P * y + x);
  const double ny = y.norm();
  if (ny == 0.0) {
    const Eigen::VectorXd clipped = w.cwiseMax(-a).cwiseMin(a);
    return std::max(0.0, (w - clipped).norm() - a_norm);
  }
  if (a_norm > 0.0) w -= (a_norm / ny) * y;
  double sum = 0.0;
  for (int i = 0; i < y.size(); ++i) {
    const double d = y(i) > 0.0 ? w(i) - a(i) : (y(i) < 0.0 ? w(i) + a(i) : std::max(0.0, std::abs(w(i)) - a(i)));
    sum += d * d;
  }
  return std::sqrt(sum);
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

TEST(OneStepSolver, WarmStartNeedsOneSolve) {
  OneStepSolver<2> solver;
  solver.configure(Vec<2>(1.0, 1.0), 0.0);
  Mat<2> P;
  P << 10, 2, -2, 10;
  Vec<2> y;
  OneStepStats st;
  ASSERT_TRUE(solver.solve(P, Vec<2>(-30.0, 25.0), y, st));
  ASSERT_TRUE(solver.solve(P, Vec<2>(-29.0, 24.0), y, st));
  EXPECT_EQ(st.iterations, 1);
}

TEST(OneStepSolver, NormTermZeroBallAndResidual) {
  OneStepSolver<2> solver;
  solver.configure(Vec<2>::Zero(), 1.5);  // phi = 1.5 ||y||
  Mat<2> P;
  P << 2, 0.5, -0.5, 3;
  Vec<2> y;
  OneStepStats st;
  // ||x|| <= 1.5: y = 0.
  ASSERT_TRUE(solver.solve(P, Vec<2>(1.0, -1.0), y, st));
  EXPECT_EQ(y.norm(), 0.0);
  // Outside the ball: y != 0 and P y + x + 1.5 y/||y|| = 0.
  ASSERT_TRUE(solver.solve(P, Vec<2>(4.0, -3.0), y, st));
  ASSERT_GT(y.norm(), 0.0);
  EXPECT_LT((P * y + Vec<2>(4.0, -3.0) + 1.5 * y / y.norm()).norm(), 1e-13);
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

}  // namespace
}  // namespace moreau

namespace moreau {
namespace {

// Ill-conditioned problems, where the active-set iteration may cycle and principal pivoting takes over:
// P = M/h + C + W with M = G D G^T spanning six decades (the mass matrix of a long chain) and C skew.
Eigen::MatrixXd IllConditionedP(int n, std::mt19937& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::MatrixXd G(n, n), K(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      G(i, j) = gauss(rng);
      K(i, j) = gauss(rng);
    }
  Eigen::VectorXd d(n);
  for (int i = 0; i < n; ++i) d(i) = std::pow(10.0, -6.0 * i / std::max(1, n - 1));
  const Eigen::MatrixXd M = G * d.asDiagonal() * G.transpose();
  const double lmin = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues()(0);
  // Skew part kept below the symmetric part's smallest eigenvalue: P is a P-matrix (Theorem 4.1's case).
  const Eigen::MatrixXd S = K - K.transpose();
  const double s = 0.9 * lmin / std::max(S.norm(), 1e-300);
  return M / 1e-3 + (s / 1e-3) * S + 1e-3 * Eigen::MatrixXd::Identity(n, n);
}

TEST(OneStepSolver, PrincipalPivotingMatchesBruteForceWhenTheActiveSetIterationCycles) {
  std::mt19937 rng(21);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  const int n = 8;
  OneStepSolver<Eigen::Dynamic> solver;
  Eigen::VectorXd a(n);
  for (int i = 0; i < n; ++i) a(i) = unif(rng);
  solver.configure(a, 0.0);
  int pivoted = 0;
  for (int trial = 0; trial < 150; ++trial) {
    const Eigen::MatrixXd P = IllConditionedP(n, rng);
    Eigen::VectorXd x(n), y(n);
    for (int i = 0; i < n; ++i) x(i) = 3.0 * gauss(rng);
    OneStepStats st;
    ASSERT_TRUE(solver.solve(P, x, y, st)) << "trial " << trial << " residual " << st.residual;
    pivoted += st.used_fallback;
    const Eigen::VectorXd ref = BruteForce(P, x, a);
    for (int i = 0; i < n; ++i) {
      if (ref(i) == 0.0)
        EXPECT_EQ(y(i), 0.0) << "component " << i << " of trial " << trial;
      else
        EXPECT_NEAR(y(i), ref(i), 1e-8 * (1.0 + ref.cwiseAbs().maxCoeff())) << "component " << i << " of trial " << trial;
    }
  }
  EXPECT_GT(pivoted, 0) << "no trial reached principal pivoting: the test does not exercise it";
}

TEST(OneStepSolver, PrincipalPivotingSolvesSixtyFourCoordinatesExactly) {
  std::mt19937 rng(22);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  for (int n : {16, 32, 64}) {
    OneStepSolver<Eigen::Dynamic> solver;
    Eigen::VectorXd a(n);
    for (int i = 0; i < n; ++i) a(i) = unif(rng);
    solver.configure(a, 0.0);
    int pivoted = 0, resting = 0;
    for (int trial = 0; trial < 20; ++trial) {
      const Eigen::MatrixXd P = IllConditionedP(n, rng);
      Eigen::VectorXd x(n), y(n);
      for (int i = 0; i < n; ++i) x(i) = 3.0 * gauss(rng);
      OneStepStats st;
      ASSERT_TRUE(solver.solve(P, x, y, st)) << "n = " << n << ", trial " << trial << ", residual " << st.residual;
      pivoted += st.used_fallback;
      // The inclusion, from its definition: a unique solution (P is a P-matrix), so a zero residual
      // identifies it.
      const double scale = x.cwiseAbs().maxCoeff() + P.cwiseAbs().rowwise().sum().maxCoeff() * y.cwiseAbs().maxCoeff() + a.maxCoeff();
      EXPECT_LE(InclusionResidual(P, x, a, 0.0, y), 1e-12 * scale) << "n = " << n << ", trial " << trial;
      for (int i = 0; i < n; ++i) resting += y(i) == 0.0;
    }
    EXPECT_GT(pivoted, 0) << "n = " << n << ": no trial reached principal pivoting";
    EXPECT_GT(resting, 0) << "n = " << n << ": no component rests, exactness is not exercised";
  }
}

// Dense P of 16 to 128 coordinates with separable phi: the patterns of a step share one LU, that of the
// step's first pattern's P_FF, which later patterns update by a Schur complement of the components that
// changed state. Against the same solver factorising each pattern's own n x n matrix (the independent
// reference): the same resting components, exactly 0.0, and the same y to the problems' conditioning;
// every step finished without falling back to the direct solves, and the updates were used.
TEST(OneStepSolver, SharedFactorisationGivesTheDirectSolvesSolution) {
  std::mt19937 rng(23);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  for (int n : {16, 33, 64, 128}) {
    OneStepSolver<Eigen::Dynamic> shared, direct;
    Eigen::VectorXd a(n);
    for (int i = 0; i < n; ++i) a(i) = unif(rng);
    shared.configure(a, 0.0);
    direct.configure(a, 0.0);
    direct.use_direct_solves();
    ASSERT_TRUE(shared.shares_factorisation()) << "n = " << n;
    ASSERT_FALSE(direct.shares_factorisation());
    int resting = 0, moving = 0, pivoted = 0;
    for (int trial = 0; trial < 12; ++trial) {
      const Eigen::MatrixXd P = IllConditionedP(n, rng);
      Eigen::VectorXd x(n), y(n), y_direct(n);
      // Scales that leave some components resting and some moving, trial by trial.
      const double scale = 0.5 + 0.5 * trial;
      for (int i = 0; i < n; ++i) x(i) = scale * gauss(rng);
      OneStepStats st, st_direct;
      ASSERT_TRUE(shared.solve(P, x, y, st)) << "n = " << n << ", trial " << trial << ", residual " << st.residual;
      ASSERT_TRUE(direct.solve(P, x, y_direct, st_direct)) << "n = " << n << ", trial " << trial;
      pivoted += st.used_fallback;
      for (int i = 0; i < n; ++i) {
        ASSERT_EQ(y(i) == 0.0, y_direct(i) == 0.0) << "n = " << n << ", trial " << trial << ", component " << i;
        resting += y(i) == 0.0;
        moving += y(i) != 0.0;
      }
      EXPECT_LE((y - y_direct).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + y_direct.cwiseAbs().maxCoeff())) << "n = " << n << ", trial " << trial;
      const double tol = x.cwiseAbs().maxCoeff() + P.cwiseAbs().rowwise().sum().maxCoeff() * y.cwiseAbs().maxCoeff() + a.maxCoeff();
      EXPECT_LE(InclusionResidual(P, x, a, 0.0, y), 1e-12 * tol) << "n = " << n << ", trial " << trial;
    }
    EXPECT_EQ(shared.direct_retries(), 0) << "n = " << n;
    // A pattern re-solved directly (its shared solution missed the round-off tolerance) is a safety net,
    // not the path: if most steps needed it, the shared factorisation would cost more than it saves.
    EXPECT_LT(shared.direct_resolves(), 12 / 2) << "n = " << n << ": more than half the 12 trials needed a direct re-solve";
    EXPECT_GT(resting, n) << "n = " << n << ": too few resting components";
    EXPECT_GT(moving, n) << "n = " << n << ": too few moving components";
    EXPECT_GT(shared.schur_updates(), 12) << "n = " << n << ": the steps' later patterns were not solved by updates";
    EXPECT_GT(pivoted, 0) << "n = " << n << ": no trial reached principal pivoting";
  }
  // Outside 16..128 (or with a norm term) each pattern has its own factorisation.
  OneStepSolver<Eigen::Dynamic> small, large, with_norm;
  small.configure(Eigen::VectorXd::Ones(15), 0.0);
  large.configure(Eigen::VectorXd::Ones(129), 0.0);
  with_norm.configure(Eigen::VectorXd::Ones(32), 0.5);
  EXPECT_FALSE(small.shares_factorisation());
  EXPECT_FALSE(large.shares_factorisation());
  EXPECT_FALSE(with_norm.shares_factorisation());
}

}  // namespace
}  // namespace moreau
