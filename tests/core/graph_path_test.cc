// The fallback of the graph inclusion solver (graph_inclusion_solver.h, step 3): piecewise-linear path
// following, against the enumeration of every piece pattern (the small-m oracle, solve_by_enumeration)
// on random problems of m <= 10 with P-matrices D (positive definite symmetric part, not symmetric),
// graphs of every named kind (up to five pieces) and random q; then degenerate problems (q at a
// breakpoint, components that tie all the way, integer data); sizes beyond the enumeration's limit
// (m = 12, 16, 32), checked against the definition of (GE) directly; a positive semidefinite D; and
// ill-conditioned P-matrices (condition number 1e8).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "moreau/core/graph_inclusion_solver.h"
#include "moreau/core/maximal_monotone_graph.h"

namespace moreau {
namespace {

using Solver = GraphInclusionSolver<Eigen::Dynamic>;

const std::vector<MonotoneGraph>& Pool() {
  static const std::vector<MonotoneGraph> pool = {MonotoneGraph::relay(1.0),           MonotoneGraph::complementarity(),
                                                  MonotoneGraph::saturation(2.0, 1.0), MonotoneGraph::dead_zone(0.3, 1.5),
                                                  MonotoneGraph::mos(0.2, 1.0, 3.0),   MonotoneGraph::adhesive(0.5, 2.0),
                                                  MonotoneGraph::coulomb(0.5, 1.0),    MonotoneGraph::zero(),
                                                  MonotoneGraph::relay(0.25),          MonotoneGraph::adhesive(1.0, 0.0)};
  return pool;
}

// D = S + K with S symmetric positive definite (smallest eigenvalue >= 0.2 / m ... 0.2) and K skew.
Eigen::MatrixXd RandomPMatrix(int m, std::mt19937& rng) {
  std::normal_distribution<double> N(0.0, 1.0);
  const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
  const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
  return R * R.transpose() / m + 0.2 * Eigen::MatrixXd::Identity(m, m) + 0.5 * (K - K.transpose());
}

// max_i of |u + D w - q|_i and dist((u_i, w_i), G_i), computed from the definition.
double Residual(const Eigen::MatrixXd& D, const Eigen::VectorXd& q, const std::vector<const MonotoneGraph*>& g, const Eigen::VectorXd& u,
                const Eigen::VectorXd& w) {
  double r = (u + D * w - q).cwiseAbs().maxCoeff();
  for (int i = 0; i < static_cast<int>(q.size()); ++i) r = std::max(r, g[i]->distance(u(i), w(i)));
  return r;
}

double Scale(const Eigen::MatrixXd& D, const Eigen::VectorXd& q, const Eigen::VectorXd& u, const Eigen::VectorXd& w) {
  return 1.0 + q.cwiseAbs().maxCoeff() + D.cwiseAbs().rowwise().sum().maxCoeff() * w.cwiseAbs().maxCoeff() + u.cwiseAbs().maxCoeff();
}

// One problem: the path alone (kPathOnly), the default route and the oracle agree to 1e-12 of the
// problem's scale. Returns the default route's route.
GraphSolveRoute Agree(const Eigen::MatrixXd& D, const Eigen::VectorXd& q, const std::vector<const MonotoneGraph*>& g, int seed) {
  const int m = static_cast<int>(q.size());
  Solver oracle, path, solver;
  oracle.configure(m);
  path.configure(m);
  solver.configure(m);
  path.set_fallback(Solver::Fallback::kPathOnly);
  Eigen::VectorXd ue(m), we(m), up(m), wp(m), u(m), w(m);
  GraphSolveStats so, sp, st;
  EXPECT_TRUE(oracle.solve_by_enumeration(D, q, g.data(), ue, we, so)) << "seed " << seed;
  EXPECT_TRUE(path.solve(D, q, g.data(), up, wp, sp)) << "seed " << seed << " m " << m << " residual " << sp.residual;
  EXPECT_TRUE(sp.route == GraphSolveRoute::kPath || sp.route == GraphSolveRoute::kDecoupled)
      << "seed " << seed << ": the path did not finish (route " << static_cast<int>(sp.route) << ", " << sp.iterations << " solves)\nD =\n"
      << D << "\nq = " << q.transpose();
  EXPECT_TRUE(solver.solve(D, q, g.data(), u, w, st)) << "seed " << seed;
  EXPECT_TRUE(st.route != GraphSolveRoute::kEnumeration && st.route != GraphSolveRoute::kForwardBackward) << "seed " << seed;
  const double tol = 1e-12 * Scale(D, q, ue, we);
  EXPECT_LE((up - ue).cwiseAbs().maxCoeff(), tol) << "seed " << seed << " m " << m;
  EXPECT_LE((wp - we).cwiseAbs().maxCoeff(), tol) << "seed " << seed << " m " << m;
  EXPECT_LE((u - ue).cwiseAbs().maxCoeff(), tol) << "seed " << seed << " m " << m;
  EXPECT_LE((w - we).cwiseAbs().maxCoeff(), tol) << "seed " << seed << " m " << m;
  EXPECT_LE(Residual(D, q, g, up, wp), 1e-13 * Scale(D, q, up, wp)) << "seed " << seed;
  return st.route;
}

// 10,000 random problems, m from 1 to 10, graphs drawn from the pool with at most 3^10 patterns in all.
TEST(GraphInclusionPath, AgreesWithEnumerationOnRandomProblems) {
  int from_path = 0;
  for (int seed = 0; seed < 10000; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    const int m = 1 + seed % 10;
    const Eigen::MatrixXd D = RandomPMatrix(m, rng);
    std::normal_distribution<double> N(0.0, 1.0);
    const Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
    std::vector<const MonotoneGraph*> g(m);
    long patterns = 1;
    for (int i = 0; i < m; ++i) {
      do g[i] = &Pool()[rng() % Pool().size()];
      while (patterns * g[i]->num_pieces() > Solver::kMaxEnumeration / std::max(1L, static_cast<long>(std::pow(3, m - 1 - i))));
      patterns *= g[i]->num_pieces();
    }
    from_path += Agree(D, q, g, seed) == GraphSolveRoute::kPath;
    if (HasFailure()) return;
  }
  std::printf("active-set iteration fell back to the path on %d of 10000 problems\n", from_path);
}

// Degenerate problems: q_i exactly at a breakpoint of the decoupled resolvent (u_i + D_ii w_i at a
// vertex), components identical in every respect (D = c I + b 1 1^T, equal graphs and q: they tie at
// every pivot), integer D and q, and q = 0.
TEST(GraphInclusionPath, AgreesWithEnumerationOnDegenerateProblems) {
  int count = 0;
  for (int seed = 0; seed < 600; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed) + 100000u);
    const int m = 2 + seed % 7;
    const int kind = (seed / 7) % 4;
    Eigen::MatrixXd D;
    Eigen::VectorXd q(m);
    std::vector<const MonotoneGraph*> g(m);
    const MonotoneGraph& graph = Pool()[(seed / 28) % 7];  // the first seven: at most 5 pieces
    for (int i = 0; i < m; ++i) g[i] = &graph;
    if (m > 6 && graph.num_pieces() > 3) continue;  // keep the oracle within 3^10 patterns
    if (kind == 0) {                                // q at a vertex of the decoupled resolvent
      D = RandomPMatrix(m, rng);
      for (int i = 0; i < m; ++i) {
        const int k = static_cast<int>(rng() % graph.u().size());
        q(i) = graph.u()[k] + D(i, i) * graph.w()[k];
      }
    } else if (kind == 1) {  // identical components
      const double b = (seed % 3 == 0) ? -0.5 / m : 1.0;
      D = Eigen::MatrixXd::Identity(m, m) + b * Eigen::MatrixXd::Ones(m, m);
      q.setConstant(seed % 2 ? 3.0 : -1.5);
    } else if (kind == 2) {  // small integers (P-matrix: diagonally dominant)
      std::uniform_int_distribution<int> I(-2, 2);
      D = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return static_cast<double>(I(rng)); });
      for (int i = 0; i < m; ++i) D(i, i) = 1.0 + D.row(i).cwiseAbs().sum();
      q = Eigen::VectorXd::NullaryExpr(m, [&] { return static_cast<double>(I(rng)); });
    } else {  // q = 0
      D = RandomPMatrix(m, rng);
      q.setZero();
    }
    Agree(D, q, g, seed);
    ++count;
    if (HasFailure()) return;
  }
  EXPECT_GT(count, 400);
  std::printf("%d degenerate problems\n", count);
}

// Beyond the enumeration's 3^10 patterns: m = 12, 16, 32 relay and mixed rows, the path alone and the
// default route, each answer checked against (GE)'s definition to round-off, and the default route never
// reaching enumeration or forward-backward.
// Solves (D, q, g) with the path alone and with the default route, each answer accepted and satisfying (GE)
// to 1e-13 of its scale from the definition; `check` then sees each route's statistics.
template <typename Check>
void SolveWithEachFallback(const Eigen::MatrixXd& D, const Eigen::VectorXd& q, const std::vector<const MonotoneGraph*>& g,
                           const std::string& label, Check check) {
  const int m = static_cast<int>(q.size());
  for (Solver::Fallback f : {Solver::Fallback::kPathOnly, Solver::Fallback::kPath}) {
    Solver solver;
    solver.configure(m);
    solver.set_fallback(f);
    Eigen::VectorXd u(m), w(m);
    GraphSolveStats st;
    ASSERT_TRUE(solver.solve(D, q, g.data(), u, w, st)) << label << " residual " << st.residual;
    EXPECT_LE(Residual(D, q, g, u, w), 1e-13 * Scale(D, q, u, w)) << label;
    check(f, st);
  }
}

TEST(GraphInclusionPath, SolvesBeyondTheEnumerationLimit) {
  for (int m : {12, 16, 32}) {
    int fell_back = 0, max_pivots = 0;
    for (int seed = 0; seed < 200; ++seed) {
      std::mt19937 rng(static_cast<unsigned>(seed * 7 + m));
      const Eigen::MatrixXd D = RandomPMatrix(m, rng);
      std::normal_distribution<double> N(0.0, 1.0);
      const Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
      std::vector<const MonotoneGraph*> g(m);
      for (int i = 0; i < m; ++i) g[i] = seed % 2 ? &Pool()[0] : &Pool()[rng() % Pool().size()];
      SolveWithEachFallback(D, q, g, std::string("m ").append(std::to_string(m)).append(" seed ").append(std::to_string(seed)),
                            [&](Solver::Fallback f, const GraphSolveStats& st) {
                              EXPECT_TRUE(st.route == GraphSolveRoute::kPath || st.route == GraphSolveRoute::kActiveSet)
                                  << "m " << m << " seed " << seed;
                              if (f == Solver::Fallback::kPath) fell_back += st.used_fallback;
                              if (f == Solver::Fallback::kPathOnly) max_pivots = std::max(max_pivots, st.iterations);
                            });
    }
    std::printf("m = %d: %d of 200 problems needed the fallback; path alone: at most %d pattern solves\n", m, fell_back, max_pivots);
  }
}

// D only positive semidefinite: four frictionless contacts on a planar rigid body (three velocities), D =
// H M^{-1} H^T of rank 3, the contact law the corner law, q = H v for a random approaching velocity v
// (feasible: a solution exists). The path may stop at a singular pattern; whatever route answers, an
// accepted answer satisfies (GE) to round-off, checked from its definition, and every problem is solved.
TEST(GraphInclusionPath, PositiveSemidefiniteDIsSolvedAndVerified) {
  const int m = 4;
  const MonotoneGraph corner = MonotoneGraph::complementarity();
  std::vector<const MonotoneGraph*> g(m, &corner);
  int by_route[5] = {0, 0, 0, 0, 0};
  for (int seed = 0; seed < 500; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed) + 7000u);
    std::normal_distribution<double> N(0.0, 1.0);
    Eigen::MatrixXd H(m, 3);
    for (int i = 0; i < m; ++i) {  // normal (0, 1) at the corner (x_i, -0.5): rows [0, 1, x_i]
      const double x = (seed % 2) ? -1.0 + 2.0 * i / (m - 1) : N(rng);
      H.row(i) << 0.0, 1.0, x;
    }
    const Eigen::Vector3d Minv(1.0, 1.0, 3.0);
    const Eigen::MatrixXd D = H * Minv.asDiagonal() * H.transpose();
    const Eigen::VectorXd q = H * Eigen::Vector3d(N(rng), N(rng), N(rng));
    SolveWithEachFallback(D, q, g, std::string("seed ").append(std::to_string(seed)), [&](Solver::Fallback f, const GraphSolveStats& st) {
      if (f == Solver::Fallback::kPathOnly) ++by_route[static_cast<int>(st.route)];
    });
  }
  std::printf("path alone on positive semidefinite D: decoupled %d, path %d, enumeration %d, forward-backward %d\n", by_route[0],
              by_route[2], by_route[3], by_route[4]);
}

// Ill-conditioned P-matrices: symmetric part Q diag(1 ... 1e-8) Q^T (condition number 1e8) plus a skew
// part, every graph kind including walls on both sides (mos without slope), m from 2 to 8: the path alone
// finishes every problem and agrees with the oracle.
TEST(GraphInclusionPath, IllConditionedProblems) {
  const MonotoneGraph walls = MonotoneGraph::mos(0.0, 1.0, 0.0);
  for (int seed = 0; seed < 2000; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed) * 31u + 5u);
    std::normal_distribution<double> N(0.0, 1.0);
    const int m = 2 + seed % 7;
    const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd Q = Eigen::HouseholderQR<Eigen::MatrixXd>(R).householderQ();
    Eigen::VectorXd ev(m);
    for (int i = 0; i < m; ++i) ev(i) = std::pow(1e8, -static_cast<double>(i) / (m - 1));
    const Eigen::MatrixXd D = Q * ev.asDiagonal() * Q.transpose() + (seed % 3) * 0.3 * (K - K.transpose());
    const Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
    std::vector<const MonotoneGraph*> g(m);
    for (int i = 0; i < m; ++i) {
      const std::size_t k = rng() % (Pool().size() + 1);
      g[i] = k < Pool().size() ? &Pool()[k] : &walls;
    }
    Agree(D, q, g, seed);
    if (HasFailure()) return;
  }
}

}  // namespace
}  // namespace moreau
