// The scheme (0.2) at scale (large_abl_integrator.h) and its one-step solver (sparse_one_step_solver.h),
// against independent references: the enumeration of every sign pattern of (6.5) (BruteForce), the dense scheme
// (abl_integrator.h with its own dense solver) step by step on a nonlinear chain, and the damped relay's
// exact discrete sequence.
#include "moreau/core/large_abl_integrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "moreau/core/abl_integrator.h"
#include "one_step_solver_support.h"

namespace moreau {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;

// A random sparse symmetric positive definite P of bandwidth b: B B^T + d I with B banded.
SparseMatrix RandomBandedSpd(int n, int b, double shift, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(n, n);
  const int half = std::max(0, b / 2);
  for (int i = 0; i < n; ++i)
    for (int j = std::max(0, i - half); j <= i; ++j) B(i, j) = u(rng);
  Eigen::MatrixXd P = B * B.transpose();
  P.diagonal().array() += shift;
  return P.sparseView();
}

// Gains a_i in [0, 2), a fraction of them 0 (components nothing holds), and x_i in [-3, 3).
void RandomGainsAndData(int n, double zero_gains, std::mt19937& rng, Eigen::VectorXd& a, Eigen::VectorXd& x) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  a.resize(n);
  x.resize(n);
  for (int i = 0; i < n; ++i) {
    a(i) = u(rng) < zero_gains ? 0.0 : 2.0 * u(rng);
    x(i) = 6.0 * (u(rng) - 0.5);
  }
}

TEST(SparseOneStepSolver, AgreesWithEnumerationOnEveryRandomProblemUpToSevenComponents) {
  std::mt19937 rng(20261130);
  int solved = 0, resting = 0, moving = 0;
  for (int trial = 0; trial < 1500; ++trial) {
    const int n = 1 + trial % 7;
    const int band = trial % 3 == 0 ? 1 : (trial % 3 == 1 ? 2 : n);
    const SparseMatrix P = RandomBandedSpd(n, 2 * band, trial % 5 == 0 ? 1e-3 : 0.5, rng);
    Eigen::VectorXd a, x;
    RandomGainsAndData(n, 0.15, rng, a, x);
    // The independent reference: every sign pattern's equations solved densely (one_step_solver_support.h).
    const Eigen::VectorXd expected = BruteForce(Eigen::MatrixXd(P), x, a);
    SparseOneStepSolver solver;
    solver.configure(P, a);
    // Twice: from the cold start, then warm from the first answer's pattern (which must give it at once).
    for (int round = 0; round < 2; ++round) {
      Eigen::VectorXd y;
      OneStepStats st;
      ASSERT_TRUE(solver.solve(x, y, st)) << "trial " << trial << " round " << round;
      EXPECT_LE(st.residual, st.tolerance);
      for (int i = 0; i < n; ++i) {
        EXPECT_NEAR(y(i), expected(i), 1e-9 * (1.0 + expected.cwiseAbs().maxCoeff())) << "trial " << trial << " component " << i;
        // A component the enumeration finds strictly held (its multiplier inside (-a_i, a_i) by a margin)
        // is exactly 0.0.
        const double w = -(Eigen::MatrixXd(P) * expected + x)(i);
        if (expected(i) == 0.0 && std::abs(w) < a(i) - 1e-6) {
          EXPECT_EQ(y(i), 0.0) << "trial " << trial;
          resting += round == 0;
        } else {
          moving += round == 0;
        }
      }
      if (round == 1) EXPECT_LE(st.iterations, 1) << "a warm start from the answer's own pattern takes one pass";
    }
    ++solved;
  }
  EXPECT_EQ(solved, 1500);
  EXPECT_GT(resting, 500);  // both kinds of component are exercised
  EXPECT_GT(moving, 500);
}

// Beyond a band of 8 (P coupling every component: 10 of them) P_FF is factorised by Eigen's sparse
// LDL^T with a minimum-degree order instead of the band's own: the same answers.
TEST(SparseOneStepSolver, AgreesWithEnumerationBeyondTheBand) {
  std::mt19937 rng(531);
  for (int trial = 0; trial < 12; ++trial) {
    const int n = 10;
    const SparseMatrix P = RandomBandedSpd(n, 2 * n, 0.3, rng);
    Eigen::VectorXd a, x;
    RandomGainsAndData(n, 0.1, rng, a, x);
    const Eigen::VectorXd expected = BruteForce(Eigen::MatrixXd(P), x, a);
    SparseOneStepSolver solver;
    solver.configure(P, a);
    ASSERT_FALSE(solver.banded_factor());
    Eigen::VectorXd y;
    OneStepStats st;
    ASSERT_TRUE(solver.solve(x, y, st)) << "trial " << trial;
    for (int i = 0; i < n; ++i) EXPECT_NEAR(y(i), expected(i), 1e-9 * (1.0 + expected.cwiseAbs().maxCoeff())) << "trial " << trial;
  }
}

TEST(SparseOneStepSolver, ZeroByTheClosedFormOfLemma61) {
  std::mt19937 rng(7);
  const SparseMatrix P = RandomBandedSpd(50, 2, 1.0, rng);
  const Eigen::VectorXd a = Eigen::VectorXd::Constant(50, 1.0);
  const Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(50, -1.0, 1.0);  // |x_i| <= a_i: -x in d phi(0)
  SparseOneStepSolver solver;
  solver.configure(P, a);
  Eigen::VectorXd y;
  OneStepStats st;
  ASSERT_TRUE(solver.solve(x, y, st));
  EXPECT_TRUE(st.zero_by_closed_form);
  EXPECT_EQ(st.iterations, 0);
  EXPECT_EQ(y.cwiseAbs().maxCoeff(), 0.0);
}

// A nonlinear chain: consistent finite-element mass tridiag(1, 4, 1) m/6 (2 on the free end), springs k
// between neighbours and to the wall, and a pendulum term c0 (1 - cos q_i) at every node (a
// Frenkel-Kontorova chain), with viscous and Coulomb friction at every node.
struct Chain {
  int n = 0;
  double m6 = 0.0, k = 0.0, c0 = 0.0;
  double grad(const double* q, int i) const {
    const double left = i > 0 ? q[i - 1] : 0.0;
    double g = k * (q[i] - left) + c0 * std::sin(q[i]);
    if (i + 1 < n) g -= k * (q[i + 1] - q[i]);
    return g;
  }
  double mass(int i, int j) const {
    if (i == j) return (i == n - 1 ? 2.0 : 4.0) * m6;
    return std::abs(i - j) == 1 ? m6 : 0.0;
  }
};

class ChainGradient final : public SparseVectorFunction {
 public:
  explicit ChainGradient(Chain c) : c_(c) {}
  std::vector<double> make_scratch() const override { return {}; }
  void evaluate(const double* q, double* value, double*, double*) const override {
    for (int i = 0; i < c_.n; ++i) value[i] = c_.grad(q, i);
  }

 private:
  Chain c_;
};

// The dense scheme's model of the same chain (abl_integrator.h, dense M and LU, its own solver).
struct DenseChain {
  static constexpr int kDof = Eigen::Dynamic;
  Chain c;
  Controller<Eigen::Dynamic> phi;
  int dof() const { return c.n; }
  const Controller<Eigen::Dynamic>& controller() const { return phi; }
  bool constant_mass() const { return true; }
  bool constant_terms() const { return false; }
  void mass(const Eigen::VectorXd&, Eigen::MatrixXd& M) const {
    M.setZero(c.n, c.n);
    for (int i = 0; i < c.n; ++i)
      for (int j = std::max(0, i - 1); j <= std::min(c.n - 1, i + 1); ++j) M(i, j) = c.mass(i, j);
  }
  void evaluate(double, const Eigen::VectorXd& q, const Eigen::VectorXd&, LagrangianTerms<Eigen::Dynamic>& out) const {
    mass(q, out.M);
    out.C.setZero(c.n, c.n);
    for (int i = 0; i < c.n; ++i) out.g(i) = c.grad(q.data(), i);
  }
};

struct Recorder : RunObserver {
  std::vector<double> t, q, v;
  void on_sample(const Sample& s) override {
    t.push_back(s.t);
    q.insert(q.end(), s.q, s.q + s.n);
    v.insert(v.end(), s.v, s.v + s.n);
  }
};

LargeAblSystem ChainSystem(const Chain& c, double w, double a) {
  LargeAblSystem sys;
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < c.n; ++i)
    for (int j = std::max(0, i - 1); j <= std::min(c.n - 1, i + 1); ++j) t.emplace_back(i, j, c.mass(i, j));
  sys.mass.resize(c.n, c.n);
  sys.mass.setFromTriplets(t.begin(), t.end());
  sys.phi = Controller<Eigen::Dynamic>::zero(c.n);
  sys.phi.weights.setConstant(w);
  sys.phi.gains.setConstant(a);
  sys.force.setZero(c.n);
  sys.gradient = std::make_shared<ChainGradient>(c);
  return sys;
}

TEST(LargeAblIntegrator, MatchesTheDenseSchemeStepByStepOnANonlinearChainAndRestsExactly) {
  for (int n : {3, 24, 40}) {
    const Chain c{n, 1.0 / (6.0 * n), 1.0 * n, 0.5};
    const LargeAblSystem sys = ChainSystem(c, 0.15, 0.05 * 9.81 / n);
    AblSettings settings;
    settings.h = 1e-3;
    settings.t_end = 4.0;
    Eigen::VectorXd q0 = Eigen::VectorXd::Zero(n), v0(n);
    for (int i = 0; i < n; ++i) v0(i) = std::sin(3.14159265358979 * (i + 1) / (2.0 * n));
    Recorder large_rec, dense_rec;
    LargeAblIntegrator large(sys, settings.grid());
    const RunSummary ls = large.run(q0, v0, &large_rec);
    DenseChain model{c, sys.phi};
    AblSettings dense_settings = settings;
    dense_settings.bandwidth = 1;
    AblIntegrator<DenseChain> dense(model, dense_settings);
    const RunSummary ds = dense.run(q0, v0, &dense_rec);
    ASSERT_EQ(ls.status, RunStatus::kCompleted) << ls.message;
    ASSERT_EQ(ds.status, RunStatus::kCompleted) << ds.message;
    ASSERT_EQ(large_rec.t.size(), dense_rec.t.size());
    double dq = 0.0, dv = 0.0;
    for (std::size_t i = 0; i < large_rec.q.size(); ++i) {
      dq = std::max(dq, std::abs(large_rec.q[i] - dense_rec.q[i]));
      dv = std::max(dv, std::abs(large_rec.v[i] - dense_rec.v[i]));
    }
    EXPECT_LE(dq, 1e-12) << "n = " << n;
    EXPECT_LE(dv, 1e-10) << "n = " << n;
    // Finite-step convergence (Theorem 4.3): both rest, exactly, from the same step.
    ASSERT_TRUE(ls.rest_step.has_value()) << "n = " << n;
    ASSERT_TRUE(ds.rest_step.has_value());
    EXPECT_EQ(*ls.rest_step, *ds.rest_step) << "n = " << n;
    for (double v : ls.v_final) EXPECT_EQ(v, 0.0);
    EXPECT_EQ(ls.equilibrium.residual, 0.0);
    EXPECT_GT(ls.solver.rest_steps, 0);
    EXPECT_EQ(ls.mass.checked, ls.steps);  // the per-step checks at every step
    EXPECT_GT(ls.mass.lambda_min, 0.0);
    EXPECT_LE(ls.mass.lambda_min, 2.0 * c.m6 * (1.0 + 1e-12));  // below lambda_min (<= the smallest diagonal minus...)
  }
}

// n independent damped relays m v' = -c v - a Sgn(v) (diagonal M): the scheme's exact discrete sequence
// V^{k+1} = (m V^k / h - a) / (m / h + c) while that is positive, then 0.0 for ever (Lemma 6.1).
TEST(LargeAblIntegrator, DampedRelaysFollowTheirExactDiscreteSequence) {
  const int n = 1000;
  const double m = 2.0, c = 0.7, a = 1.3, h = 1e-3;
  LargeAblSystem sys;
  sys.mass.resize(n, n);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) t.emplace_back(i, i, m);
  sys.mass.setFromTriplets(t.begin(), t.end());
  sys.phi = Controller<Eigen::Dynamic>::zero(n);
  sys.phi.weights.setConstant(c);
  sys.phi.gains.setConstant(a);
  sys.force.setZero(n);
  TimeGrid grid;
  grid.h = h;
  grid.t_end = 3.0;
  Eigen::VectorXd v0(n);
  for (int i = 0; i < n; ++i) v0(i) = (i % 2 ? -1.0 : 1.0) * (0.1 + 2.0 * i / n);
  Recorder rec;
  LargeAblIntegrator integrator(sys, grid);
  const RunSummary s = integrator.run(Eigen::VectorXd::Zero(n), v0, &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  Eigen::VectorXd v = v0;
  for (std::size_t k = 0; k < rec.t.size(); ++k) {
    for (int i = 0; i < n; ++i) {
      const double got = rec.v[k * n + static_cast<std::size_t>(i)];
      // The two evaluate the recurrence in different orders; its factor (m/h) / (m/h + c) = 0.99965 is near
      // 1, so their roundings add up over the steps: a few ulps per step.
      ASSERT_NEAR(got, v(i), 4e-16 * static_cast<double>(k + 1) * std::abs(v0(i))) << "step " << k << " relay " << i;
      if (v(i) == 0.0) ASSERT_EQ(got, 0.0);
    }
    for (int i = 0; i < n; ++i) {
      const double sgn = v(i) > 0.0 ? 1.0 : -1.0;
      const double next = (m * std::abs(v(i)) / h - a) / (m / h + c);
      v(i) = v(i) == 0.0 || next <= 0.0 ? 0.0 : sgn * next;
    }
  }
  for (double x : s.v_final) EXPECT_EQ(x, 0.0);
}

TEST(LargeAblIntegrator, RefusesWhatItDoesNotTake) {
  const Chain c{8, 1.0 / 48.0, 8.0, 0.0};
  LargeAblSystem sys = ChainSystem(c, 0.1, 0.1);
  sys.phi.norm_gain = 1.0;
  EXPECT_NE(sys.validate().find("norm term"), std::string::npos);
  sys.phi.norm_gain = 0.0;
  sys.mass.coeffRef(0, 1) = 1.0;  // not symmetric
  EXPECT_NE(sys.validate().find("not symmetric"), std::string::npos);
  sys = ChainSystem(c, 0.1, 0.1);
  sys.mass.coeffRef(3, 3) = -1.0;  // indefinite
  EXPECT_EQ(sys.validate(), "");
  EXPECT_LE(certified_lambda_min(sys.mass), 0.0);
  TimeGrid grid;
  LargeAblIntegrator integrator(sys, grid);
  const RunSummary s = integrator.run(Eigen::VectorXd::Zero(8), Eigen::VectorXd::Zero(8));
  EXPECT_EQ(s.status, RunStatus::kFailed);
  EXPECT_NE(s.message.find("not positive definite"), std::string::npos) << s.message;
}

TEST(CertifiedLambdaMin, IsAPositiveLowerBoundWithinAPerMilleOfTheEigenvalue) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 5 + 7 * trial;
    SparseMatrix M = RandomBandedSpd(n, 4, 1e-2, rng);  // not diagonally dominant: Gershgorin does not decide
    const double exact = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Eigen::MatrixXd(M)).eigenvalues()(0);
    const double bound = certified_lambda_min(M);
    ASSERT_GT(bound, 0.0);
    EXPECT_LE(bound, exact * (1.0 + 1e-12));
    EXPECT_GE(bound, 0.25 * exact) << "n = " << n;  // halvings from (1 - 1e-3) x^T M x
  }
}

}  // namespace
}  // namespace moreau
