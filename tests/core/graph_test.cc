// Maximal monotone graphs (Figure 3 of Brogliato 2003) and the exact solver of the one-step generalized
// equation u + D w = q, w_i in G_i(u_i): monotonicity checks, the named graphs as instances of the
// generic one, exact values of the scalar resolvent, and random problems against an independent
// brute-force search over piece patterns.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "moreau/core/graph_inclusion_solver.h"
#include "moreau/core/maximal_monotone_graph.h"

namespace moreau {
namespace {

using End = MonotoneGraph::End;
constexpr double kInf = std::numeric_limits<double>::infinity();

void ExpectValues(const MonotoneGraph& g, double u, double lo, double hi) {
  double a, b;
  ASSERT_TRUE(g.values(u, a, b)) << "u = " << u << " outside the domain";
  EXPECT_EQ(a, lo) << "u = " << u;
  EXPECT_EQ(b, hi) << "u = " << u;
}

TEST(Graph, NamedGraphsAreInstancesOfTheGenericOne) {
  EXPECT_EQ(MonotoneGraph::relay(2.0), MonotoneGraph({0, 0}, {-2, 2}, End::kSlope, 0, End::kSlope, 0));
  EXPECT_EQ(MonotoneGraph::coulomb(1.0, 3.0), MonotoneGraph({0, 0}, {-1, 1}, End::kSlope, 3, End::kSlope, 3));
  EXPECT_EQ(MonotoneGraph::saturation(2.0, 1.0), MonotoneGraph({-0.5, 0.5}, {-1, 1}, End::kSlope, 0, End::kSlope, 0));
  EXPECT_EQ(MonotoneGraph::dead_zone(0.5, 2.0), MonotoneGraph({-0.5, 0.5}, {0, 0}, End::kSlope, 2, End::kSlope, 2));
  EXPECT_EQ(MonotoneGraph::complementarity(), MonotoneGraph({0}, {0}, End::kWall, 0, End::kSlope, 0));
  EXPECT_EQ(MonotoneGraph::mos(0.5, 1.5, 2.0), MonotoneGraph({-1.5, -0.5, 0.5, 1.5}, {-2, 0, 0, 2}, End::kWall, 0, End::kWall, 0));
  EXPECT_EQ(MonotoneGraph::adhesive(1.0, 4.0), MonotoneGraph({0, 0.25}, {0, 1}, End::kWall, 0, End::kSlope, 0));
  EXPECT_EQ(MonotoneGraph::zero(), MonotoneGraph({0}, {0}, End::kSlope, 0, End::kSlope, 0));
}

TEST(Graph, ValuesOfTheNamedGraphs) {
  const auto relay = MonotoneGraph::relay(2.0);
  ExpectValues(relay, 0.0, -2.0, 2.0);
  ExpectValues(relay, 1e-300, 2.0, 2.0);
  ExpectValues(relay, -5.0, -2.0, -2.0);
  const auto coulomb = MonotoneGraph::coulomb(1.0, 3.0);  // Sign(u) + 3u
  ExpectValues(coulomb, 2.0, 7.0, 7.0);
  ExpectValues(coulomb, -1.0, -4.0, -4.0);
  const auto sat = MonotoneGraph::saturation(2.0, 1.0);  // clamp(2u, -1, 1)
  ExpectValues(sat, 0.25, 0.5, 0.5);
  ExpectValues(sat, 3.0, 1.0, 1.0);
  ExpectValues(sat, -3.0, -1.0, -1.0);
  const auto dz = MonotoneGraph::dead_zone(0.5, 2.0);  // 2 (|u| - 0.5)+ sign u
  ExpectValues(dz, 0.3, 0.0, 0.0);
  ExpectValues(dz, 1.5, 2.0, 2.0);
  ExpectValues(dz, -1.0, -1.0, -1.0);
  const auto corner = MonotoneGraph::complementarity();  // d psi_{R+}
  ExpectValues(corner, 0.0, -kInf, 0.0);
  ExpectValues(corner, 2.0, 0.0, 0.0);
  double lo, hi;
  EXPECT_FALSE(corner.values(-1e-12, lo, hi));
  const auto mos = MonotoneGraph::mos(0.5, 1.5, 2.0);
  ExpectValues(mos, 1.5, 2.0, kInf);
  ExpectValues(mos, -1.5, -kInf, -2.0);
  ExpectValues(mos, 1.0, 1.0, 1.0);
  ExpectValues(mos, 0.0, 0.0, 0.0);
  EXPECT_FALSE(mos.values(1.6, lo, hi));
  const auto adh = MonotoneGraph::adhesive(1.0, 4.0);
  ExpectValues(adh, 0.0, -kInf, 0.0);
  ExpectValues(adh, 0.125, 0.5, 0.5);
  ExpectValues(adh, 7.0, 1.0, 1.0);
  EXPECT_TRUE(relay.contains_origin());
  EXPECT_TRUE(mos.contains_origin());
  EXPECT_FALSE(MonotoneGraph({0, 1}, {1, 2}, End::kSlope, 0, End::kSlope, 0).contains_origin());
}

TEST(Graph, MonotonicityIsChecked) {
  MonotoneGraph::Problem p;
  EXPECT_TRUE(MonotoneGraph::check({0, 0, 1}, {-1, 1, 1}, End::kWall, 0, End::kSlope, 2, &p));
  EXPECT_FALSE(MonotoneGraph::check({0, -1}, {0, 1}, End::kSlope, 0, End::kSlope, 0, &p));
  EXPECT_EQ(p.field, "vertices");
  EXPECT_EQ(p.index, 1);
  EXPECT_EQ(p.coordinate, 0);
  EXPECT_NE(p.reason.find("not monotone"), std::string::npos);
  EXPECT_FALSE(MonotoneGraph::check({0, 1, 2}, {0, 1, 0.5}, End::kSlope, 0, End::kSlope, 0, &p));
  EXPECT_EQ(p.index, 2);
  EXPECT_EQ(p.coordinate, 1);
  EXPECT_FALSE(MonotoneGraph::check({0, 1}, {0, 1}, End::kSlope, -1, End::kSlope, 0, &p));
  EXPECT_EQ(p.field, "left");
  EXPECT_FALSE(MonotoneGraph::check({0, 1}, {0, 1}, End::kSlope, 0, End::kSlope, -0.5, &p));
  EXPECT_EQ(p.field, "right");
  EXPECT_FALSE(MonotoneGraph::check({0, 0}, {1, 1}, End::kSlope, 0, End::kSlope, 0, &p));
  EXPECT_EQ(p.coordinate, -1);
  EXPECT_FALSE(MonotoneGraph::check({}, {}, End::kSlope, 0, End::kSlope, 0, &p));
  EXPECT_FALSE(MonotoneGraph::check({0, kInf}, {0, 1}, End::kSlope, 0, End::kSlope, 0, &p));
}

// Finite vertices can still give a segment whose rise, run or slope overflows a double; the graph would
// carry a NaN or infinite slope (or, when only the run overflows, a slope of 0 instead of a tiny one).
// check() refuses it at the segment's second vertex.
TEST(Graph, SegmentsWhoseSlopeOverflowsAreRefused) {
  struct Case {
    std::vector<double> u, w;
    int index;
  };
  for (const Case& c : std::vector<Case>{{{-1e308, 1e308}, {-1e308, 1e308}, 1},         // run and rise overflow: inf / inf = NaN
                                         {{0, 1e-300}, {0, 1e300}, 1},                  // the slope overflows
                                         {{0, 1e-300, 2e-300}, {0, 1e-300, 1e300}, 2},  // the second segment's slope overflows
                                         {{-1e308, 1e308}, {0, 1}, 1}}) {               // the run overflows: slope 1 / inf = 0
    MonotoneGraph::Problem p;
    EXPECT_FALSE(MonotoneGraph::check(c.u, c.w, End::kSlope, 0, End::kSlope, 0, &p)) << c.u.back() << " " << c.w.back();
    EXPECT_EQ(p.field, "vertices");
    EXPECT_EQ(p.index, c.index);
    EXPECT_EQ(p.coordinate, -1);
    EXPECT_NE(p.reason.find("overflows"), std::string::npos) << p.reason;
  }
  // Large but representable: accepted, and every piece's slope is finite.
  MonotoneGraph::Problem p;
  EXPECT_TRUE(MonotoneGraph::check({-1e307, 1e307}, {-1e307, 1e307}, End::kSlope, 0, End::kSlope, 0, &p)) << p.reason;
  const MonotoneGraph g({-1e307, 1e307}, {-1e307, 1e307}, End::kSlope, 0, End::kSlope, 0);
  ASSERT_EQ(g.u().front(), -1e307) << "fell back to the zero graph";
  for (int j = 0; j < g.num_pieces(); ++j) EXPECT_TRUE(std::isfinite(g.piece(j).slope)) << j;
  // A horizontal segment needs no slope (it is 0), nor does a vertical one: their spans may be huge.
  EXPECT_TRUE(MonotoneGraph::check({-1e308, 1e308}, {1, 1}, End::kSlope, 0, End::kSlope, 0, &p)) << p.reason;
  EXPECT_TRUE(MonotoneGraph::check({0, 0}, {-1e308, 1e308}, End::kSlope, 0, End::kSlope, 0, &p)) << p.reason;
}

// The scalar resolvent u + d w = q: exact on vertical and horizontal pieces.
TEST(Graph, ScalarResolventIsExact) {
  const auto relay = MonotoneGraph::relay(1.0);
  double u, w;
  relay.resolve(0.3, 0.5, u, w);
  EXPECT_EQ(u, 0.0);
  EXPECT_EQ(w, 0.6);
  relay.resolve(2.0, 0.5, u, w);
  EXPECT_EQ(w, 1.0);
  EXPECT_EQ(u, 1.5);
  relay.resolve(-0.5, 0.5, u, w);  // exactly on the vertex (0, -1)
  EXPECT_EQ(u, 0.0);
  EXPECT_EQ(w, -1.0);
  const auto corner = MonotoneGraph::complementarity();
  corner.resolve(-3.0, 2.0, u, w);
  EXPECT_EQ(u, 0.0);
  EXPECT_EQ(w, -1.5);
  corner.resolve(3.0, 2.0, u, w);
  EXPECT_EQ(u, 3.0);
  EXPECT_EQ(w, 0.0);
  const auto sat = MonotoneGraph::saturation(2.0, 1.0);
  sat.resolve(0.4, 1.0, u, w);  // u + 2u = 0.4
  EXPECT_NEAR(u, 0.4 / 3.0, 1e-17);
  EXPECT_DOUBLE_EQ(w, 0.8 / 3.0);
  // Random points on random graphs: on the graph, on the line.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-3.0, 3.0);
  const std::vector<MonotoneGraph> graphs = {relay,
                                             corner,
                                             sat,
                                             MonotoneGraph::dead_zone(0.5, 2.0),
                                             MonotoneGraph::mos(0.5, 1.5, 2.0),
                                             MonotoneGraph::adhesive(1.0, 4.0),
                                             MonotoneGraph::coulomb(0.7, 0.3)};
  for (int trial = 0; trial < 2000; ++trial) {
    const MonotoneGraph& g = graphs[trial % graphs.size()];
    const double q = U(rng), d = std::exp(U(rng));
    const int j = g.resolve(q, d, u, w);
    ASSERT_GE(j, 0);
    EXPECT_LE(std::abs(u + d * w - q), 1e-14 * (1.0 + std::abs(q) + d * std::abs(w)));
    EXPECT_LE(g.distance(u, w), 1e-14 * (1.0 + std::abs(u) + std::abs(w)));
  }
}

// Independent reference: every piece pattern, the 2m x 2m linear system in (u, w) solved by full-pivot
// LU, kept if every point lies on its piece. Unique when D + D^T > 0.
bool BruteForce(const Eigen::MatrixXd& D, const Eigen::VectorXd& q, const std::vector<const MonotoneGraph*>& g, Eigen::VectorXd& u,
                Eigen::VectorXd& w) {
  const int m = static_cast<int>(q.size());
  long total = 1;
  for (int i = 0; i < m; ++i) total *= g[i]->num_pieces();
  for (long code = 0; code < total; ++code) {
    long c = code;
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(2 * m, 2 * m);
    Eigen::VectorXd r = Eigen::VectorXd::Zero(2 * m);
    std::vector<int> p(m);
    for (int i = 0; i < m; ++i) {
      p[i] = static_cast<int>(c % g[i]->num_pieces());
      c /= g[i]->num_pieces();
      K(i, i) = 1.0;  // u_i + (D w)_i = q_i
      K.block(i, m, 1, m) = D.row(i);
      r(i) = q(i);
      const GraphPiece& pc = g[i]->piece(p[i]);
      if (pc.vertical) {
        K(m + i, i) = 1.0;
        r(m + i) = pc.u0;
      } else {
        K(m + i, m + i) = 1.0;
        K(m + i, i) = -pc.slope;
        r(m + i) = pc.w0 - pc.slope * pc.u0;
      }
    }
    Eigen::FullPivLU<Eigen::MatrixXd> lu(K);
    if (lu.rank() < 2 * m) continue;
    const Eigen::VectorXd x = lu.solve(r);
    bool ok = true;
    for (int i = 0; i < m && ok; ++i) {
      const GraphPiece& pc = g[i]->piece(p[i]);
      const double v = pc.vertical ? x(m + i) : x(i);
      ok = v >= pc.lo - 1e-12 && v <= pc.hi + 1e-12;
    }
    if (ok) {
      u = x.head(m);
      w = x.tail(m);
      return true;
    }
  }
  return false;
}

template <int M>
void RandomProblems(int m, int trials, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  const std::vector<MonotoneGraph> pool = {MonotoneGraph::relay(1.0),           MonotoneGraph::complementarity(),
                                           MonotoneGraph::saturation(2.0, 1.0), MonotoneGraph::dead_zone(0.3, 1.5),
                                           MonotoneGraph::mos(0.2, 1.0, 3.0),   MonotoneGraph::adhesive(0.5, 2.0),
                                           MonotoneGraph::coulomb(0.5, 1.0),    MonotoneGraph::zero()};
  GraphInclusionSolver<M> solver;
  solver.configure(m);
  int exact_zero_checks = 0;
  for (int trial = 0; trial < trials; ++trial) {
    Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    Eigen::MatrixXd S = R * R.transpose() + 0.2 * Eigen::MatrixXd::Identity(m, m);
    Eigen::MatrixXd Kk = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd Dd = S + 0.5 * (Kk - Kk.transpose());  // D + D^T > 0, not symmetric
    const Eigen::VectorXd qd = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
    std::vector<const MonotoneGraph*> g(m);
    for (int i = 0; i < m; ++i) g[i] = &pool[(trial * 3 + i * 5 + trial / 7) % pool.size()];
    Eigen::VectorXd ub, wb;
    ASSERT_TRUE(BruteForce(Dd, qd, g, ub, wb)) << "trial " << trial;
    Mat<M> D = Dd;
    Vec<M> q = qd, u(m), w(m);
    GraphSolveStats st;
    ASSERT_TRUE(solver.solve(D, q, g.data(), u, w, st)) << "trial " << trial << " residual " << st.residual;
    for (int i = 0; i < m; ++i) {
      EXPECT_NEAR(u(i), ub(i), 1e-9 * (1.0 + std::abs(ub(i)))) << "trial " << trial << " component " << i;
      EXPECT_NEAR(w(i), wb(i), 1e-9 * (1.0 + std::abs(wb(i)))) << "trial " << trial << " component " << i;
      // A component on a vertical piece at u = 0 is exactly 0.0.
      if (solver.on_vertical_piece(i) && g[i]->piece(solver.pieces()(i)).u0 == 0.0) {
        EXPECT_EQ(u(i), 0.0);
        ++exact_zero_checks;
      }
    }
  }
  EXPECT_GT(exact_zero_checks, 0);  // the pool has vertical pieces at 0: some components must rest
}

TEST(GraphInclusionSolver, RandomProblemsMatchBruteForceFixedSize) { RandomProblems<3>(3, 400, 11); }
TEST(GraphInclusionSolver, RandomProblemsMatchBruteForceDynamicSize) { RandomProblems<Eigen::Dynamic>(5, 200, 12); }
TEST(GraphInclusionSolver, DecoupledProblemsUseTheScalarResolvent) { RandomProblems<1>(1, 300, 13); }

// Components on horizontal pieces are pinned and leave the linear system of a pattern (solve_pattern): a
// problem of m = 21 components (beyond the 16 where a dense LU would block), 17 of them on the zero graph
// (inactive contacts, w = 0) at random places between 4 on graphs of the pool. Reference: the brute force
// on the 4 live components alone with D restricted to them (w = 0 elsewhere does not enter their
// equations), then u = q - D w for the others.
TEST(GraphInclusionSolver, PinnedComponentsLeaveTheSystem) {
  const int m = 21, live = 4;
  std::mt19937 rng(21);
  std::normal_distribution<double> N(0.0, 1.0);
  const std::vector<MonotoneGraph> pool = {MonotoneGraph::relay(1.0), MonotoneGraph::complementarity(), MonotoneGraph::saturation(2.0, 1.0),
                                           MonotoneGraph::coulomb(0.5, 1.0)};
  const MonotoneGraph zero = MonotoneGraph::zero();
  GraphInclusionSolver<Eigen::Dynamic> solver;
  solver.configure(m);
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd D = R * R.transpose() / m + 0.2 * Eigen::MatrixXd::Identity(m, m) + 0.1 * (K - K.transpose());
    const Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
    std::vector<int> order(m);
    for (int i = 0; i < m; ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    std::vector<int> live_at(order.begin(), order.begin() + live);
    std::sort(live_at.begin(), live_at.end());
    std::vector<const MonotoneGraph*> g(m, &zero), g_live(live);
    Eigen::MatrixXd D_live(live, live);
    Eigen::VectorXd q_live(live);
    for (int a = 0; a < live; ++a) {
      g[live_at[a]] = g_live[a] = &pool[(trial + a) % pool.size()];
      q_live(a) = q(live_at[a]);
      for (int b = 0; b < live; ++b) D_live(a, b) = D(live_at[a], live_at[b]);
    }
    Eigen::VectorXd ub, wb;
    ASSERT_TRUE(BruteForce(D_live, q_live, g_live, ub, wb)) << "trial " << trial;
    Eigen::VectorXd w_ref = Eigen::VectorXd::Zero(m);
    for (int a = 0; a < live; ++a) w_ref(live_at[a]) = wb(a);
    const Eigen::VectorXd u_ref = q - D * w_ref;

    Eigen::VectorXd u(m), w(m);
    GraphSolveStats st;
    ASSERT_TRUE(solver.solve(D, q, g.data(), u, w, st)) << "trial " << trial << " residual " << st.residual;
    for (int i = 0; i < m; ++i) {
      EXPECT_NEAR(w(i), w_ref(i), 1e-9 * (1.0 + std::abs(w_ref(i)))) << "trial " << trial << " component " << i;
      EXPECT_NEAR(u(i), u_ref(i), 1e-9 * (1.0 + std::abs(u_ref(i)))) << "trial " << trial << " component " << i;
      if (g[i] == &zero) {
        EXPECT_EQ(w(i), 0.0);  // pinned: exactly
      }
    }
  }
}

// use_leading: a solver configured for 8 components solves problems of 1 to 8 in the leading block of
// 8 x 8 arrays (the Moreau-Jean step's rows for the contacts of I_k only), its size changing from one
// problem to the next as an active set does. Everything outside the block is NaN, so a read there would
// show in the result and a write there would overwrite a NaN. References: the brute force on the problem
// alone, and a solver configured for exactly that size (the same bits: the block changes nothing).
TEST(GraphInclusionSolver, ProblemsInTheLeadingBlockOfLargerArrays) {
  const int capacity = 8;
  std::mt19937 rng(31);
  std::normal_distribution<double> N(0.0, 1.0);
  const std::vector<MonotoneGraph> pool = {MonotoneGraph::relay(1.0), MonotoneGraph::complementarity(), MonotoneGraph::saturation(2.0, 1.0),
                                           MonotoneGraph::coulomb(0.5, 1.0), MonotoneGraph::zero()};
  const double nan = std::numeric_limits<double>::quiet_NaN();
  GraphInclusionSolver<Eigen::Dynamic> solver;
  solver.configure(capacity);
  int sizes_seen = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const int m = 1 + static_cast<int>(rng() % capacity);
    sizes_seen |= 1 << m;
    const Eigen::MatrixXd R = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd K = Eigen::MatrixXd::NullaryExpr(m, m, [&] { return N(rng); });
    const Eigen::MatrixXd D = R * R.transpose() / m + 0.2 * Eigen::MatrixXd::Identity(m, m) + 0.1 * (K - K.transpose());
    const Eigen::VectorXd q = Eigen::VectorXd::NullaryExpr(m, [&] { return 2.0 * N(rng); });
    std::vector<const MonotoneGraph*> g(capacity, nullptr);
    for (int i = 0; i < m; ++i) g[i] = &pool[rng() % pool.size()];

    Eigen::MatrixXd D_big = Eigen::MatrixXd::Constant(capacity, capacity, nan);
    Eigen::VectorXd q_big = Eigen::VectorXd::Constant(capacity, nan), u_big = q_big, w_big = q_big;
    D_big.topLeftCorner(m, m) = D;
    q_big.head(m) = q;
    solver.use_leading(m);
    GraphSolveStats st;
    ASSERT_TRUE(solver.solve(D_big, q_big, g.data(), u_big, w_big, st)) << "trial " << trial << " m " << m << " residual " << st.residual;

    GraphInclusionSolver<Eigen::Dynamic> exact;
    exact.configure(m);
    Eigen::VectorXd u(m), w(m);
    ASSERT_TRUE(exact.solve(D, q, g.data(), u, w, st)) << "trial " << trial;
    Eigen::VectorXd ub, wb;
    ASSERT_TRUE(BruteForce(D, q, std::vector<const MonotoneGraph*>(g.begin(), g.begin() + m), ub, wb)) << "trial " << trial;
    for (int i = 0; i < m; ++i) {
      EXPECT_EQ(u_big(i), u(i)) << "trial " << trial << " component " << i;
      EXPECT_EQ(w_big(i), w(i)) << "trial " << trial << " component " << i;
      EXPECT_NEAR(w(i), wb(i), 1e-9 * (1.0 + std::abs(wb(i)))) << "trial " << trial << " component " << i;
      EXPECT_NEAR(u(i), ub(i), 1e-9 * (1.0 + std::abs(ub(i)))) << "trial " << trial << " component " << i;
    }
    for (int i = m; i < capacity; ++i)
      EXPECT_TRUE(std::isnan(u_big(i)) && std::isnan(w_big(i))) << "trial " << trial << " wrote past m at " << i;
  }
  EXPECT_EQ(__builtin_popcount(sizes_seen), capacity);  // every size from 1 to 8 came up
}

// The pure LCP (every graph the corner law): 0 <= u = q + D (-w) perp -w >= 0.
TEST(GraphInclusionSolver, LinearComplementarityProblem) {
  const int m = 4;
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0.0, 1.0);
  const MonotoneGraph corner = MonotoneGraph::complementarity();
  std::vector<const MonotoneGraph*> g(m, &corner);
  GraphInclusionSolver<4> solver;
  solver.configure(m);
  for (int trial = 0; trial < 300; ++trial) {
    Eigen::Matrix4d R = Eigen::Matrix4d::NullaryExpr([&] { return N(rng); });
    const Eigen::Matrix4d D = R * R.transpose() + 0.1 * Eigen::Matrix4d::Identity();
    const Eigen::Vector4d q = Eigen::Vector4d::NullaryExpr([&] { return N(rng); });
    Eigen::Vector4d u, w;
    GraphSolveStats st;
    ASSERT_TRUE(solver.solve(D, q, g.data(), u, w, st));
    for (int i = 0; i < m; ++i) {
      EXPECT_GE(u(i), 0.0);
      EXPECT_LE(w(i), 0.0);
      EXPECT_TRUE(u(i) == 0.0 || w(i) == 0.0) << "complementarity is exact: u = " << u(i) << ", w = " << w(i);
    }
    EXPECT_LT((u + D * w - q).cwiseAbs().maxCoeff(), 1e-13);
  }
}

// A problem without a solution (D = -1, a wall) is reported as unsolved, never answered wrongly.
TEST(GraphInclusionSolver, UnsolvableProblemIsReported) {
  const MonotoneGraph mos = MonotoneGraph::mos(0.0, 1.0, 0.0);  // u in [-1, 1], w = 0 inside
  std::vector<const MonotoneGraph*> g = {&mos, &mos};
  GraphInclusionSolver<2> solver;
  solver.configure(2);
  Eigen::Matrix2d D;
  D << 0.0, 0.0, 0.0, 0.0;  // u = q: outside the domain, no w can help
  Eigen::Vector2d q(5.0, 0.0), u, w;
  GraphSolveStats st;
  EXPECT_FALSE(solver.solve(D, q, g.data(), u, w, st));
}

}  // namespace
}  // namespace moreau
