// The one-step inclusion (6.5) P y + x in -d phi(y), continued from one_step_solver_test.cc (split in two
// translation units by the sizes the solver is instantiated at): the fixed size n = 2, whose own scalar
// route must give the dynamic-size general path's results bit for bit, a plain linear solve, warm start
// and the norm term (zero ball, residual); random problems at n = 2 and at dynamic n = 6 against an
// independent brute-force search over sign patterns (one_step_solver_support.h); and the dense
// dynamic-size paths on ill-conditioned problems: principal pivoting, against the brute force and up to
// 64 coordinates against the inclusion's residual computed from its definition, and the shared
// factorisation, against the same solver factorising each pattern's own matrix.
#include "moreau/core/one_step_solver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>

#include "one_step_solver_support.h"

namespace moreau {
namespace {

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

TEST(OneStepSolver, RandomNonsymmetricDynamic6) { RandomProblems<Eigen::Dynamic>(6, 200, 3); }

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
