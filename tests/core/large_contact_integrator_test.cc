// The large-contact Moreau-Jean path (large_contact_integrator.h) and its LCP solver (sparse_lcp.h),
// against independent references: the enumeration of every complementary set for small LCPs, the statics
// of a resting stack (each contact carries the weight above it), the closed forms of Newton's cradle.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>
#include <vector>

#include "moreau/core/large_contact_integrator.h"
#include "moreau/core/sparse_lcp.h"

namespace moreau {
namespace {

// The unique solution of w = D z + q, 0 <= z perp w >= 0 (D positive definite) by trying all 2^m
// complementary sets with a dense LDL^T: the oracle, independent of the pivoting rules.
Eigen::VectorXd enumerate_lcp(const Eigen::MatrixXd& D, const Eigen::VectorXd& q) {
  const int m = static_cast<int>(q.size());
  const double scale = q.cwiseAbs().maxCoeff() + 1e-300;
  for (int set = 0; set < (1 << m); ++set) {
    std::vector<int> F;
    for (int i = 0; i < m; ++i)
      if (set & (1 << i)) F.push_back(i);
    Eigen::VectorXd z = Eigen::VectorXd::Zero(m);
    if (!F.empty()) {
      Eigen::MatrixXd dff(F.size(), F.size());
      Eigen::VectorXd rhs(F.size());
      for (std::size_t a = 0; a < F.size(); ++a) {
        rhs(a) = -q(F[a]);
        for (std::size_t b = 0; b < F.size(); ++b) dff(a, b) = D(F[a], F[b]);
      }
      const Eigen::VectorXd zf = dff.ldlt().solve(rhs);
      for (std::size_t a = 0; a < F.size(); ++a) z(F[a]) = zf(a);
    }
    const Eigen::VectorXd w = D * z + q;
    if (z.minCoeff() >= -1e-12 * scale && w.minCoeff() >= -1e-12 * scale) return z;
  }
  ADD_FAILURE() << "no complementary set solves the LCP";
  return Eigen::VectorXd::Zero(m);
}

TEST(SparseLcp, AgreesWithEnumerationOnEveryRandomProblemUpToTenRows) {
  std::mt19937 rng(20261129);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_int_distribution<int> coin(0, 1);
  int problems = 0, murty = 0;
  for (int m = 1; m <= 10; ++m) {
    for (int trial = 0; trial < 300; ++trial) {
      // D = A A^T + delta I: positive definite, dense or (every other trial) banded; some trials nearly
      // singular (delta 1e-6) so that the block phase stalls and Murty's rule has to finish.
      Eigen::MatrixXd A(m, m);
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < m; ++j) A(i, j) = (trial % 2 == 0 || std::abs(i - j) <= 1) ? normal(rng) : 0.0;
      const double delta = trial % 7 == 0 ? 1e-6 : 0.1;
      const Eigen::MatrixXd D = A * A.transpose() + delta * Eigen::MatrixXd::Identity(m, m);
      Eigen::VectorXd q(m);
      for (int i = 0; i < m; ++i) q(i) = trial % 5 == 0 && coin(rng) ? 0.0 : normal(rng);  // ties: q_i = 0
      const Eigen::VectorXd expected = enumerate_lcp(D, q);

      // The default rules (Gauss-Seidel guesses, then the block phase), Murty's rule alone, the classic block
      // phase (all infeasible rows flip) without retries or guesses, and the default block phase without guesses.
      for (int mode = 0; mode < 4; ++mode) {
        SparseLcpSolver solver;
        solver.options.least_index_only = mode == 1;
        solver.options.block_retries = mode == 2 ? 0 : 3;
        if (mode == 2) solver.options.removal_fraction = 0.0;  // the classic block rule: every infeasible row flips
        if (mode >= 2) solver.options.guess_sweeps = 0;
        solver.set_matrix(D.sparseView());
        std::vector<int> rows(m);
        for (int i = 0; i < m; ++i) rows[i] = i;
        std::vector<char> in_F(m);
        for (int i = 0; i < m; ++i) in_F[i] = static_cast<char>(coin(rng));  // an arbitrary warm start
        Eigen::VectorXd z(m), w(m);
        SparseLcpStats st;
        ASSERT_TRUE(solver.solve(rows, q, z, w, in_F, st)) << "m = " << m << ", trial " << trial << ", mode " << mode;
        murty += st.murty_pivots > 0;
        const double scale = expected.cwiseAbs().maxCoeff() + q.cwiseAbs().maxCoeff();
        EXPECT_LE((z - expected).cwiseAbs().maxCoeff(), 1e-8 * scale) << "m = " << m << ", trial " << trial << ", mode " << mode;
        // The answer is a complementary set's exact solution: w == 0.0 on F, z == 0.0 off it.
        for (int i = 0; i < m; ++i) {
          if (in_F[i])
            EXPECT_EQ(w(i), 0.0);
          else
            EXPECT_EQ(z(i), 0.0);
        }
        EXPECT_LE(st.passes, SparseLcpSolver::pass_budget(m));
      }
      ++problems;
    }
  }
  EXPECT_EQ(problems, 3000);
  EXPECT_GT(murty, 0) << "no problem reached Murty's rule: the fallback went untested";
}

TEST(SparseLcp, SolvesOnASubsetOfRowsAndLeavesTheOthersAlone) {
  // A 5 x 5 tridiagonal D; the problem on rows {1, 3, 4}: the oracle on the 3 x 3 principal submatrix.
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(5, 5);
  for (int i = 0; i < 5; ++i) {
    D(i, i) = 2.0;
    if (i + 1 < 5) D(i, i + 1) = D(i + 1, i) = -1.0;
  }
  Eigen::VectorXd q(5);
  q << 7.0, -1.0, 7.0, -2.0, 0.5;
  const std::vector<int> rows{1, 3, 4};
  Eigen::MatrixXd Dsub(3, 3);
  Eigen::VectorXd qsub(3);
  for (int a = 0; a < 3; ++a) {
    qsub(a) = q(rows[a]);
    for (int b = 0; b < 3; ++b) Dsub(a, b) = D(rows[a], rows[b]);
  }
  const Eigen::VectorXd expected = enumerate_lcp(Dsub, qsub);
  SparseLcpSolver solver;
  solver.set_matrix(D.sparseView());
  Eigen::VectorXd z = Eigen::VectorXd::Constant(5, 99.0), w = Eigen::VectorXd::Constant(5, 99.0);
  std::vector<char> in_F(5, 0);
  SparseLcpStats st;
  ASSERT_TRUE(solver.solve(rows, q, z, w, in_F, st));
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(z(rows[a]), expected(a), 1e-14);
  EXPECT_EQ(z(0), 99.0);
  EXPECT_EQ(z(2), 99.0);
}

TEST(SparseLcp, RefusesDependentRows) {
  // D = a a^T: rank one, both rows closed at the solution of the regular problem.
  Eigen::MatrixXd D(2, 2);
  D << 1.0, 1.0, 1.0, 1.0;
  Eigen::VectorXd q(2);
  q << -1.0, -1.0;
  SparseLcpSolver solver;
  solver.set_matrix(D.sparseView());
  std::vector<int> rows{0, 1};
  std::vector<char> in_F{1, 1};
  Eigen::VectorXd z(2), w(2);
  SparseLcpStats st;
  EXPECT_FALSE(solver.solve(rows, q, z, w, in_F, st));
  EXPECT_TRUE(st.singular);
}

// N balls of radius r on a vertical line above a floor: coordinates y_i (heights of the centres), gaps
// y_1 - r (the floor) and y_{i+1} - y_i - 2r, gravity.
LargeContactSystem stack(int n, const std::vector<double>& masses, double r, double g) {
  LargeContactSystem s;
  s.mass.resize(n);
  s.force.resize(n);
  for (int i = 0; i < n; ++i) {
    s.mass(i) = masses[static_cast<std::size_t>(i) % masses.size()];
    s.force(i) = s.mass(i) * g;
  }
  std::vector<Eigen::Triplet<double>> t;
  s.offsets.resize(n);
  t.emplace_back(0, 0, 1.0);
  s.offsets(0) = -r;
  for (int i = 1; i < n; ++i) {
    t.emplace_back(i, i, 1.0);
    t.emplace_back(i, i - 1, -1.0);
    s.offsets(i) = -2.0 * r;
  }
  s.gradients.resize(n, n);
  s.gradients.setFromTriplets(t.begin(), t.end());
  s.restitution.assign(static_cast<std::size_t>(n), 0.5);
  return s;
}

// Records that every sample's velocity is 0.0 exactly.
struct RestWatcher : RunObserver {
  std::int64_t samples = 0, moving = 0;
  void on_sample(const Sample& s) override {
    ++samples;
    for (int j = 0; j < s.n; ++j)
      if (s.v[j] != 0.0) {
        ++moving;
        break;
      }
  }
};

TEST(LargeContactIntegrator, AStackRestsExactlyWithEachContactCarryingTheWeightAboveIt) {
  // r a power of two: the centres r (1 + 2i) and so the gaps are exact, every contact touching with gap
  // 0.0 (with r = 0.05 some gaps are 3e-17 and the ball above falls that far in a real, tiny impact).
  const double r = 0.0625, g = 9.81, h = 1e-3;
  for (int n : {1, 2, 8, 64, 1024}) {
    const std::vector<double> masses{1.0, 0.3, 2.5};
    const LargeContactSystem sys = stack(n, masses, r, g);
    ASSERT_EQ(sys.validate(), "");
    MoreauJeanSettings settings;
    settings.t_end = 0.1;
    settings.h = h;
    LargeContactIntegrator integrator(sys, settings);
    Eigen::VectorXd q0(n), v0 = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) q0(i) = r + 2.0 * r * i;  // every contact touching
    RestWatcher watch;
    ContactDiagnostics diag;
    const RunSummary s = integrator.run(q0, v0, &watch, &diag);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    EXPECT_EQ(s.steps, 100);
    EXPECT_EQ(watch.moving, 0) << "n = " << n << ": a velocity was not 0.0 exactly";
    EXPECT_EQ(s.rest_step, 0);
    EXPECT_EQ(s.converged_step, 0);
    for (int i = 0; i < n; ++i) ASSERT_EQ(s.q_final[static_cast<std::size_t>(i)], q0(i)) << "n = " << n << ", ball " << i;
    // Contact i (the floor for i = 0) carries the weight of balls i..n-1 over the step: h g sum m_j.
    double above = 0.0;
    for (int i = n - 1; i >= 0; --i) {
      above += sys.mass(i) * g;
      EXPECT_NEAR(integrator.impulses()(i), h * above, 1e-12 * h * above) << "n = " << n << ", contact " << i;
    }
    EXPECT_EQ(diag.impact_count, 0);
    EXPECT_LE(s.solver.max_residual, 1e-12);
  }
}

// A granular column written by hand (no expressions): N balls (x_i, y_i) of mass 1 and radius r in a tube
// of width 3r, the floor under the first ball, both walls for each ball, |p_{i+1} - p_i| - 2r between
// neighbours, contacts ball by ball (left_i, right_i, c_i), and their gradients in closed form.
class ColumnGaps final : public SparseVectorFunction {
 public:
  ColumnGaps(int n, double r) : n_(n), r_(r) {}
  std::vector<double> make_scratch() const override { return {}; }
  void evaluate(const double* q, double* gap, double* gradient, double* /*scratch*/) const override {
    int c = 0, k = 0;
    gap[c++] = q[1] - r_;  // the floor: y_1 - r
    gradient[k++] = 1.0;
    for (int i = 0; i < n_; ++i) {
      const double x = q[2 * i];
      gap[c++] = x - r_;  // left wall
      gradient[k++] = 1.0;
      gap[c++] = 3 * r_ - r_ - x;  // right wall
      gradient[k++] = -1.0;
      if (i + 1 < n_) {
        const double dx = q[2 * i + 2] - x, dy = q[2 * i + 3] - q[2 * i + 1], d = std::hypot(dx, dy);
        gap[c++] = d - 2 * r_;
        for (double g : {-dx / d, -dy / d, dx / d, dy / d}) gradient[k++] = g;  // (x_i, y_i, x_{i+1}, y_{i+1})
      }
    }
  }

 private:
  int n_;
  double r_;
};

LargeContactSystem column(int n, double r, double g, double e) {
  LargeContactSystem s;
  s.mass = Eigen::VectorXd::Ones(2 * n);
  s.force = Eigen::VectorXd::Zero(2 * n);
  for (int i = 0; i < n; ++i) s.force(2 * i + 1) = g;
  std::vector<Eigen::Triplet<double>> t;
  int c = 0;
  t.emplace_back(c++, 1, 1.0);
  for (int i = 0; i < n; ++i) {
    t.emplace_back(c++, 2 * i, 1.0);
    t.emplace_back(c++, 2 * i, 1.0);
    if (i + 1 < n) {
      for (int j = 2 * i; j < 2 * i + 4; ++j) t.emplace_back(c, j, 1.0);
      ++c;
    }
  }
  s.gradients.resize(c, 2 * n);
  s.gradients.setFromTriplets(t.begin(), t.end());
  s.gradients.makeCompressed();
  s.offsets = Eigen::VectorXd::Zero(c);
  s.restitution.assign(static_cast<std::size_t>(c), e);
  s.nonlinear_gaps = std::make_shared<ColumnGaps>(n, r);
  return s;
}

TEST(LargeContactIntegrator, AColumnAtRestCarriesTheStaticsOfTheZigzag) {
  // The zigzag at rest: ball i against the left wall (i even) or the right one, its neighbour sqrt(3) r
  // above. Statics (closed form): contact c_i, along the line of centres at 60 degrees from horizontal,
  // carries the weight of the balls above it, N_i sin 60 = (N - 1 - i) m g; each ball's wall carries the
  // horizontal parts of its two contacts, (N_{i-1} + N_i) cos 60; the floor all the weight. Impulses are
  // these forces times h, and the velocity stays 0.0 (2N closed contacts on 2N coordinates).
  const double r = 0.0625, g = 9.81, h = 1e-3;
  for (int n : {2, 3, 50, 1000}) {
    const LargeContactSystem sys = column(n, r, g, 0.5);
    ASSERT_EQ(sys.validate(), "");
    MoreauJeanSettings settings;
    settings.t_end = 0.02;
    settings.h = h;
    LargeContactIntegrator integrator(sys, settings);
    Eigen::VectorXd q0(2 * n), v0 = Eigen::VectorXd::Zero(2 * n);
    for (int i = 0; i < n; ++i) {
      q0(2 * i) = i % 2 == 0 ? r : 2 * r;
      q0(2 * i + 1) = r + i * std::sqrt(3.0) * r;
    }
    RestWatcher watch;
    const RunSummary s = integrator.run(q0, v0, &watch);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    EXPECT_EQ(watch.moving, 0) << "n = " << n << ": a velocity was not 0.0 exactly";
    EXPECT_EQ(s.rest_step, 0);
    const Eigen::VectorXd& P = integrator.impulses();
    std::vector<double> pair(static_cast<std::size_t>(n), 0.0);  // N_i h; pair[n - 1] = 0 (no ball above)
    for (int i = 0; i + 1 < n; ++i) pair[static_cast<std::size_t>(i)] = h * (n - 1 - i) * g / (std::sqrt(3.0) / 2);
    const double tol = 1e-11 * h * n * g;
    int c = 0;
    EXPECT_NEAR(P(c++), h * n * g, tol) << "n = " << n << ": the floor";
    for (int i = 0; i < n; ++i) {
      const double wall = 0.5 * ((i > 0 ? pair[static_cast<std::size_t>(i - 1)] : 0.0) + pair[static_cast<std::size_t>(i)]);
      EXPECT_NEAR(P(c++), i % 2 == 0 ? wall : 0.0, tol) << "n = " << n << ", left wall of ball " << i;
      EXPECT_NEAR(P(c++), i % 2 == 0 ? 0.0 : wall, tol) << "n = " << n << ", right wall of ball " << i;
      if (i + 1 < n) EXPECT_NEAR(P(c++), pair[static_cast<std::size_t>(i)], tol) << "n = " << n << ", contact " << i;
    }
  }
}

// N balls on a horizontal line (no gravity), gaps x_{i+1} - x_i - d >= 0 between neighbours, masses 1.
LargeContactSystem cradle(int n, double d, double e) {
  LargeContactSystem s;
  s.mass = Eigen::VectorXd::Ones(n);
  s.force = Eigen::VectorXd::Zero(n);
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i + 1 < n; ++i) {
    t.emplace_back(i, i + 1, 1.0);
    t.emplace_back(i, i, -1.0);
  }
  s.gradients.resize(n - 1, n);
  s.gradients.setFromTriplets(t.begin(), t.end());
  s.offsets = Eigen::VectorXd::Constant(n - 1, -d);
  s.restitution.assign(static_cast<std::size_t>(n - 1), e);
  return s;
}

TEST(LargeContactIntegrator, AGappedCradleWithElasticImpactsEndsWithTheLastBallMoving) {
  // Balls 1 cm apart, the first at v0 = 1: impacts one at a time, each passing the velocity on (Newton,
  // e = 1, equal masses: the closed form of a two-body impact). After the wave: (0, ..., 0, v0) exactly.
  const double d = 0.1, spacing = 0.01, v0 = 1.0, h = 1e-3;
  for (int n : {2, 3, 16, 128, 1024}) {
    const LargeContactSystem sys = cradle(n, d, 1.0);
    MoreauJeanSettings settings;
    settings.h = h;
    settings.t_end = (n - 1) * spacing / v0 + 0.05;  // the wave's travel time, then 50 steps more
    settings.max_recorded_impacts = 0;
    LargeContactIntegrator integrator(sys, settings);
    Eigen::VectorXd q0(n), vinit = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i) q0(i) = i * (d + spacing);
    vinit(0) = v0;
    ContactDiagnostics diag;
    const RunSummary s = integrator.run(q0, vinit, nullptr, &diag);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    for (int i = 0; i + 1 < n; ++i) ASSERT_EQ(s.v_final[static_cast<std::size_t>(i)], 0.0) << "n = " << n << ", ball " << i;
    EXPECT_EQ(s.v_final[static_cast<std::size_t>(n - 1)], v0) << "n = " << n;
    EXPECT_EQ(diag.impact_count, n - 1) << "n = " << n;
    EXPECT_GE(diag.smallest_gap, -h * v0) << "n = " << n;  // at most one step of travel into a contact
  }
}

TEST(LargeContactIntegrator, ATouchingCradleGivesMoreausSimultaneousImpactAndItsEnergyCheckCoversEveryContact) {
  // Three touching balls, the first at v0 = 1, e = 1: Moreau's law on both contacts at once,
  // D = [[2, -1], [-1, 2]], q = (-2 v0, 0): P = (4/3, 2/3) v0, V+ = (-1/3, 2/3, 2/3) v0; momentum and
  // kinetic energy conserved. (Not the sequential textbook answer (0, 0, v0).)
  const double d = 0.1, v0 = 1.0, h = 1e-3;
  const LargeContactSystem sys = cradle(3, d, 1.0);
  MoreauJeanSettings settings;
  settings.h = h;
  settings.t_end = h;  // the impact step alone
  LargeContactIntegrator integrator(sys, settings);
  Eigen::VectorXd q0(3), vinit = Eigen::VectorXd::Zero(3);
  q0 << 0.0, d, 2.0 * d;
  vinit(0) = v0;
  ContactDiagnostics diag;
  const RunSummary s = integrator.run(q0, vinit, nullptr, &diag);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  EXPECT_NEAR(s.v_final[0], -v0 / 3.0, 1e-15);
  EXPECT_NEAR(s.v_final[1], 2.0 * v0 / 3.0, 1e-15);
  EXPECT_NEAR(s.v_final[2], 2.0 * v0 / 3.0, 1e-15);
  EXPECT_NEAR(integrator.impulses()(0), 4.0 * v0 / 3.0, 1e-15);
  EXPECT_NEAR(integrator.impulses()(1), 2.0 * v0 / 3.0, 1e-15);
  ASSERT_EQ(diag.impacts.size(), 1u);  // contact 0 approaches; contact 1 is closed and carries impulse
  const ImpactEvent& ev = diag.impacts[0];
  EXPECT_EQ(ev.simultaneous, 1);
  EXPECT_EQ(ev.closed_carrying, 1);
  ASSERT_TRUE(ev.reference_evaluated);
  EXPECT_NEAR(ev.reference_impulse, 4.0 * v0 / 3.0, 1e-15);
  EXPECT_NEAR(ev.eq9_change, 0.0, 1e-15);  // e = 1: no loss
  EXPECT_NEAR(ev.kinetic_change, 0.0, 1e-15);
  EXPECT_LE(diag.max_eq9_mismatch, 1e-15);
}

TEST(LargeContactIntegrator, ATouchingCradleWithRestitutionOneHalfMatchesEq9OverEveryContact) {
  // e = 0.5 on a touching cradle of 5: the step passes impulse through the closed contacts; eq. (9)'s
  // reference solves the impact law on all of them, so the step and the reference agree (no smooth
  // force here: exactly, up to round-off) and the loss is 1/2 (1 - e) P_1 U-_1 < 0. (d a power of two:
  // the gaps are 0.0 exactly.)
  const double d = 0.125, v0 = 1.0, h = 1e-3;
  const LargeContactSystem sys = cradle(5, d, 0.5);
  MoreauJeanSettings settings;
  settings.h = h;
  settings.t_end = h;
  LargeContactIntegrator integrator(sys, settings);
  Eigen::VectorXd q0(5), vinit = Eigen::VectorXd::Zero(5);
  for (int i = 0; i < 5; ++i) q0(i) = i * d;
  vinit(0) = v0;
  ContactDiagnostics diag;
  const RunSummary s = integrator.run(q0, vinit, nullptr, &diag);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  ASSERT_EQ(diag.impacts.size(), 1u);
  const ImpactEvent& ev = diag.impacts[0];
  EXPECT_EQ(ev.closed_carrying, 3);
  EXPECT_LT(ev.eq9_change, 0.0);
  EXPECT_NEAR(ev.eq9_change, 0.5 * (1.0 - 0.5) * ev.impulse * ev.pre, 1e-15);
  EXPECT_LE(diag.max_eq9_mismatch, 1e-14);
  double momentum = 0.0;
  for (double v : s.v_final) momentum += v;
  EXPECT_NEAR(momentum, v0, 1e-15);
}

TEST(LargeContactIntegrator, ValidationNamesTheProblemAndTheLimit) {
  LargeContactSystem s = stack(3, {1.0}, 0.05, 9.81);
  EXPECT_EQ(s.validate(), "");
  s.mass(1) = 0.0;
  EXPECT_EQ(s.validate(), "mass 1 is not a finite positive number");
  s = stack(3, {1.0}, 0.05, 9.81);
  s.restitution[2] = 1.5;
  EXPECT_EQ(s.validate(), "the restitution of contact 2 is outside [0, 1]");
  s = stack(kMaxLargeContactDof + 1, {1.0}, 0.05, 9.81);
  EXPECT_NE(s.validate().find("more than 10000 coordinates"), std::string::npos) << s.validate();
  MoreauJeanSettings settings;
  settings.h = 1e-3;
  settings.t_end = 1e-2;
  LargeContactIntegrator integrator(s, settings);
  const RunSummary r = integrator.run(Eigen::VectorXd::Zero(s.dof()), Eigen::VectorXd::Zero(s.dof()));
  EXPECT_EQ(r.status, RunStatus::kFailed);
  EXPECT_NE(r.message.find("more than 10000 coordinates"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace moreau
