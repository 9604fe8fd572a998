// The one-step problem of the second paper's schemes: given D (m x m) and q, find u and w in R^m with
//
//   u + D w = q,        w_i in G_i(u_i)   (i = 1..m),                                          (GE)
//
// each G_i a piecewise-linear maximal monotone graph (maximal_monotone_graph.h). The implicit Euler
// step of a Lur'e system (4) of Brogliato (2003) is (GE) with u = y_{k+1} and w = y_L (lure_integrator.h);
// the Moreau-Jean step is (GE) with u the constrained velocities (contact velocities U + e U_k and the
// controlled velocities) and w the impulses (moreau_jean_integrator.h); with every G_i the corner law
// (Figure 3c) it is the linear complementarity problem LCP(q, D) of contact dynamics.
//
// Existence and uniqueness: when D + D^T is positive definite, w -> D w - q is strongly monotone and
// (GE) is 0 in D w - q + G^{-1}(w) with G^{-1} maximal monotone, which has exactly one solution (the
// argument of Lemma 1 of the paper and of Theorem 4.1 of Adly, Brogliato and Le 2016).
//
// Method (the exact active-set idea of one_step_solver.h, generalised from sign patterns to pieces):
//  1. m = 1 or D diagonal: the components decouple; each is the scalar resolvent of its graph, exact.
//  2. piece patterns: choose one piece per component; the pieces fix m linear equations (u_i = u0 on a
//     vertical piece, w_i = w0 + s (u_i - u0) on a sloped one, w_i = w0 on a horizontal one, which is
//     pinned exactly and leaves the system), solved by LU; accept if every (u_i, w_i) lies on its
//     piece, else move each component that left its piece to the piece where its scalar resolvent
//     u_i + D_ii w_i lands (the primal-dual active-set update, i.e. semismooth Newton on the natural
//     map). Warm-started from the previous call's pattern.
//  3. if that stalls or cycles: piecewise-linear path following (below), exact and finite when D is a
//     P-matrix. Only if the path meets a singular pattern (D not a P-matrix, e.g. positive semidefinite
//     with dependent rows) or its safety cap: every pattern (when there are at most kMaxEnumeration),
//     else forward-backward splitting w <- J(w - gamma (D w - q)), J the resolvent of gamma G^{-1}
//     (scalar, exact), gamma = mu / L^2, whose iterate's pattern is polished by step 2's equations.
//
// Path following (Katzenelson, Bell System Tech. J. 44, 1965; Fujisawa and Kuh, SIAM J. Appl. Math. 22,
// 1972; Eaves, "A short course in solving equations with PL homotopies", 1976). Parametrise each graph by
// t_i = u_i + d_i w_i (d_i = D_ii > 0), which increases strictly along the curve: (u_i, w_i) = (U_i(t_i),
// W_i(t_i)), U_i and W_i piecewise linear, the cells of R^m the products of pieces. (GE) is F(t) = U(t) +
// D W(t) - q = 0, F affine on each cell with Jacobian J = diag(a) + D diag((1 - a) / d), a_i = 1 / (1 +
// d_i s_i) in [0, 1] (0 on a vertical piece, 1 on a horizontal one). Expanding det(J diag(d)) column by
// column, it is the sum over index sets S of prod_{i not in S} a_i d_i prod_{i in S} (1 - a_i) det D_SS:
// positive on every cell when D is a P-matrix (every principal minor positive; in particular when D + D^T
// is positive definite). So F is piecewise affine and coherently oriented, a homeomorphism of R^m, and the
// preimage of the segment from F(t0) to 0 is a polygonal path from any start t0 to the solution.
//
// It is followed cell by cell: in the current cell the pattern's own solution (step 2's equations) is the
// zero of the cell's affine piece of F, so moving from the current point towards it keeps F(t) on the
// segment (F shrinks by the factor 1 - lambda); if it lies in the cell, it is the solution; otherwise the
// point moves to the cell's boundary and the components that reach it move to their adjacent piece. With
// one component on the boundary, the new cell's direction continues it across (Cramer's rule: the two
// Jacobians differ in that column only and have determinants of one sign); with several (a degenerate
// point: ties, q at a breakpoint), the subsets of them that may switch are tried, fewest first, and the
// first whose pattern's direction points into its cell for each of them is taken (the path continues in
// one such cell). Start: the active-set iteration's last point, put onto the graphs by the scalar
// resolvents.
//
// Termination: the path visits each cell in one interval of the homotopy parameter, and each pivot either
// ends the path or leaves a cell for good, so it ends after at most the number of cells. That bound is
// exponential in m, as for Lemke's method, which Murty (Math. Programming Study 7, 1978) showed to take
// 2^m pivots on some P-matrix problems; on the problems measured the path takes about as many pivots as
// components change piece (docs/numerics.md, "The graph inclusion solver's fallback"). With every graph
// the corner law it is the path of Lemke's scheme for LCP(q, D) with covering vector F(t0), entered at the
// point t0 that solves the problem perturbed by it instead of at z = 0 (Cottle, Pang and Stone, "The
// Linear Complementarity Problem", 1992, section 4.4). A cap of 20 m + 100 pivots stops a rounding-driven
// loop; it is a safety net, never a tolerance. The path's end is the final pattern's own solution, checked
// by the acceptance test below like every other answer.
//
// Exactness: on a vertical piece u_i is the vertex abscissa itself (0.0 for a component at rest), on a
// horizontal piece w_i the vertex ordinate itself. A solution is accepted only when max_i |u_i + (D w)_i -
// q_i| and the distance of each (u_i, w_i) to its piece are within 256 eps of the problem's scale;
// otherwise solve() returns false and the caller must not take the step.
// Where D is only positive semidefinite (dependent contact gradients), existence rests on the problem's
// structure rather than on D (a positive semidefinite LCP that is feasible is solvable), and a pattern's
// equations may be singular: the path then stops and the enumeration or forward-backward route of step 3
// is tried, still under the acceptance test.
// No allocation after configure().
#pragma once

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/small_lu.h"
#include "moreau/core/types.h"

namespace moreau {

// Which step of the method (graph_inclusion_solver.h) gave the answer.
enum class GraphSolveRoute { kDecoupled, kActiveSet, kPath, kEnumeration, kForwardBackward };

struct GraphSolveStats {
  int iterations = 0;          // pattern solves (or scalar resolvents in the decoupled case), or FB sweeps
  double residual = 0.0;       // max of the equation residual and the distances to the pieces
  double tolerance = 0.0;      // the round-off bound the residual was accepted against
  bool used_fallback = false;  // the active-set iteration did not finish (step 3 ran)
  GraphSolveRoute route = GraphSolveRoute::kDecoupled;
};

template <int M>
class GraphInclusionSolver {
 public:
  using Pieces = Eigen::Matrix<int, M, 1>;
  static constexpr long kMaxEnumeration = 59049;  // 3^10 patterns

  // What follows the active-set iteration (step 3). kPath: path following (the default). kEnumeration:
  // the former route, every pattern up to kMaxEnumeration then forward-backward, kept for comparison
  // (bench/core_bench.cc). kPathOnly: path following from the decoupled start, without the active-set
  // iteration, so that tests exercise it on every problem.
  enum class Fallback { kPath, kEnumeration, kPathOnly };
  void set_fallback(Fallback f) { fallback_ = f; }

  GraphInclusionSolver() = default;

  // Sizes the solver's arrays for problems of up to m components (and sets m as the current size).
  void configure(int m) {
    m_ = m;
    capacity_ = m;
    pieces_.setZero(m);
    trial_.setZero(m);
    K_.setZero(m, m);
    r_.setZero(m);
    t_.setZero(m);
    z_.setZero(m);
    free_.setZero(m);
    pinned_.setZero(m);
    last_graphs_.assign(static_cast<std::size_t>(m), nullptr);
    cu_.setZero(m);
    cw_.setZero(m);
    tied_.setZero(m);
    tied_up_.setZero(m);
  }

  // The problems to come have m <= the configured size components, in the leading m rows and columns of
  // the D, q, u, w given to solve() (which may be larger): nothing is reallocated. The warm start
  // (solve_coupled) keeps the pattern of each leading component whose graph is unchanged.
  void use_leading(int m) {
    assert(m >= 0 && m <= capacity_);
    m_ = m;
  }

  int size() const { return m_; }
  const Pieces& pieces() const { return pieces_; }
  // Whether component i of the last solution lies on a vertical piece of its graph (u_i exact).
  bool on_vertical_piece(int i) const { return graphs_ && graphs_[i]->piece(pieces_(i)).vertical; }

  bool solve(const Mat<M>& D, const Vec<M>& q, const MonotoneGraph* const* graphs, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    st = GraphSolveStats{};
    graphs_ = graphs;
    if (m_ == 0) return true;
    if (M == 1 || m_ == 1) return solve_scalar(D(0, 0), q(0), graphs[0], u(0), w(0), st);
    return solve_coupled(D, q, graphs, u, w, st);
  }

  // The oracle of the tests: every pattern in turn (at most kMaxEnumeration of them), the first whose
  // solution lies on its pieces, under the same acceptance test. Exact, and exponential in m.
  bool solve_by_enumeration(const Mat<M>& D, const Vec<M>& q, const MonotoneGraph* const* graphs, Vec<M>& u, Vec<M>& w,
                            GraphSolveStats& st) {
    st = GraphSolveStats{};
    graphs_ = graphs;
    if (m_ == 0) return true;
    set_scales(D, graphs);
    st.used_fallback = true;
    return enumerate(D, q, u, w, st) && accept(D, q, u, w, pieces_, st);
  }

 private:
  // m = 1: the scalar resolvent, with the acceptance test written out. (Apart from solve_coupled, so
  // that a one-component solver, M = 1, compiles to this alone.)
  bool solve_scalar(double d, double qq, const MonotoneGraph* graph, double& u0, double& w0, GraphSolveStats& st) {
    double uu = 0.0, ww = 0.0;
    const int j = graph->resolve(qq, d, uu, ww);
    st.iterations = 1;
    if (j < 0 || d < 0.0) return false;
    pieces_(0) = j;
    last_graphs_[0] = graph;
    u0 = uu;
    w0 = ww;
    const double scale = std::abs(qq) + std::abs(d * ww) + std::abs(uu) + std::abs(ww) + graph->scale();
    st.tolerance = 256.0 * std::numeric_limits<double>::epsilon() * std::max(scale, 1e-300);
    st.residual = std::max(std::abs(uu + d * ww - qq), graph->distance_to_piece(j, uu, ww));
    return std::isfinite(st.residual) && st.residual <= st.tolerance;
  }

  bool solve_coupled(const Mat<M>& D, const Vec<M>& q, const MonotoneGraph* const* graphs, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    const int m = m_;
    set_scales(D, graphs);

    if (is_diagonal(D)) {
      for (int i = 0; i < m; ++i) {
        const int j = graphs[i]->resolve(q(i), D(i, i), u(i), w(i));
        if (j < 0 || D(i, i) < 0.0) {
          st.iterations = 1;
          return false;
        }
        pieces_(i) = j;
        last_graphs_[i] = graphs[i];
      }
      st.iterations = 1;
      return accept(D, q, u, w, pieces_, st);
    }

    if (fallback_ == Fallback::kPathOnly) {
      for (int i = 0; i < m; ++i) last_graphs_[i] = graphs[i];
      st.used_fallback = true;
      if (follow_path(D, q, q, nullptr, u, w, st)) return true;
      return enumerate(D, q, u, w, st) ? accept(D, q, u, w, pieces_, st) : forward_backward(D, q, u, w, st);
    }
    // Warm start: the previous pattern where the graph is the same, else the decoupled guess.
    for (int i = 0; i < m; ++i) {
      if (last_graphs_[i] != graphs[i] || pieces_(i) < 0 || pieces_(i) >= graphs[i]->num_pieces()) {
        pieces_(i) = graphs[i]->locate(q(i), diag(D, i));
      }
      last_graphs_[i] = graphs[i];
    }
    const int max_iter = 2 * m + 8;
    for (int it = 0; it < max_iter; ++it) {
      ++st.iterations;
      if (solve_pattern(D, q, pieces_, u, w) && consistent(pieces_, u, w, q)) {
        st.route = GraphSolveRoute::kActiveSet;
        return accept(D, q, u, w, pieces_, st);
      }
      if (!update_pattern(D, u, w)) break;
    }

    st.used_fallback = true;
    if (fallback_ != Fallback::kEnumeration) {
      // Start from the active-set iteration's last point where it is finite: t_i = u_i + d_i w_i.
      if (finite(u) && finite(w) && follow_path(D, q, u, &w, u, w, st)) return true;
    }
    if (enumerate(D, q, u, w, st)) return accept(D, q, u, w, pieces_, st);
    return forward_backward(D, q, u, w, st);
  }

  void set_scales(const Mat<M>& D, const MonotoneGraph* const* graphs) {
    const int m = m_;
    scale_d_ = 0.0;  // max_i sum_j |D_ij|
    for (int i = 0; i < m; ++i) {
      double row = std::abs(D(i, 0));
      for (int j = 1; j < m; ++j) row += std::abs(D(i, j));
      scale_d_ = std::max(scale_d_, row);
    }
    graph_scale_ = 0.0;
    for (int i = 0; i < m; ++i) graph_scale_ = std::max(graph_scale_, graphs[i]->scale());
  }

  // The path following of step 3 (see the header). Start: t_i = a_i + d_i b_i (b null: t_i = a_i), moved
  // onto the graph by the scalar resolvent. cu_, cw_ hold the path's current point, on the pieces of
  // pieces_; u, w the current pattern's solution. Returns true with an accepted solution in u, w; false
  // when a pattern is singular, no continuation passes the direction test, or the cap is reached.
  bool follow_path(const Mat<M>& D, const Vec<M>& q, const Vec<M>& a, const Vec<M>* b, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    const int m = m_;
    for (int i = 0; i < m; ++i) {
      const double d = diag(D, i);
      const double t = b ? a(i) + d * (*b)(i) : a(i);
      pieces_(i) = graphs_[i]->resolve(t, d, cu_(i), cw_(i));
      if (pieces_(i) < 0) return false;
    }
    const int max_pivots = 20 * m + 100;
    bool solved = false;  // u, w hold pieces_'s solution already (from the continuation test)
    for (int pivot = 0; pivot < max_pivots; ++pivot) {
      if (!solved) {
        ++st.iterations;
        if (!solve_pattern(D, q, pieces_, u, w)) return false;
      }
      solved = false;
      if (consistent(pieces_, u, w, q)) {
        st.route = GraphSolveRoute::kPath;
        return accept(D, q, u, w, pieces_, st);
      }
      // The largest step towards the pattern's solution that stays in the cell, and the components
      // that reach its boundary with it (within kTie: a tie is resolved by the direction test).
      constexpr double kTie = 1e-12;
      double lambda = 1.0;
      for (int i = 0; i < m; ++i) {
        const double li = exit_fraction(i, u, w);
        if (li < lambda) lambda = li;
      }
      int nt = 0;
      for (int i = 0; i < m; ++i) {
        const double li = exit_fraction(i, u, w);
        if (li <= lambda + kTie) tied_(nt++) = i;
      }
      if (nt == 0) return false;  // rounding: the solution is off the cell yet nothing leaves it
      for (int k = 0; k < nt; ++k) tied_up_(k) = upward(tied_(k), u, w) ? 1 : 0;
      // Move: the non-tied components along their pieces, the tied ones exactly onto the vertex they reach.
      for (int i = 0; i < m; ++i) {
        const GraphPiece& g = graphs_[i]->piece(pieces_(i));
        if (g.vertical) {
          cw_(i) = std::clamp(cw_(i) + lambda * (w(i) - cw_(i)), g.lo, g.hi);
        } else {
          cu_(i) = std::clamp(cu_(i) + lambda * (u(i) - cu_(i)), g.lo, g.hi);
          cw_(i) = g.slope == 0.0 ? g.w0 : g.w0 + g.slope * (cu_(i) - g.u0);
        }
      }
      for (int k = 0; k < nt; ++k) {
        const int i = tied_(k);
        const int v = tied_up_(k) ? pieces_(i) : pieces_(i) - 1;  // piece j runs from vertex j - 1 to j
        cu_(i) = graphs_[i]->u()[v];
        cw_(i) = graphs_[i]->w()[v];
      }
      // The continuation: the subsets of the tied components that switch to their adjacent piece, fewest
      // first (one tied component: it switches), the first whose direction enters its cell.
      if (nt > 12) return false;
      bool found = false;
      for (int size = 1; size <= nt && !found; ++size) {
        for (unsigned mask = 1; mask < (1u << nt) && !found; ++mask) {
          if (__builtin_popcount(mask) != size) continue;
          trial_ = pieces_;
          for (int k = 0; k < nt; ++k)
            if (mask & (1u << k)) trial_(tied_(k)) += tied_up_(k) ? 1 : -1;
          ++st.iterations;
          if (!solve_pattern(D, q, trial_, z_, t_)) continue;  // z_ = u, t_ = w of the trial pattern
          found = enters(D, mask, nt, z_, t_);
        }
      }
      if (!found) return false;
      pieces_ = trial_;
      u = z_;
      w = t_;
      solved = true;
    }
    return false;
  }

  // The fraction of the way from the path's current point to the pattern's solution (u, w) at which
  // component i leaves its piece (+inf if it does not).
  double exit_fraction(int i, const Vec<M>& u, const Vec<M>& w) const {
    const GraphPiece& g = graphs_[i]->piece(pieces_(i));
    const double x0 = g.vertical ? cw_(i) : cu_(i), x1 = g.vertical ? w(i) : u(i);
    if (x1 > g.hi) return (g.hi - x0) / (x1 - x0);
    if (x1 < g.lo) return (g.lo - x0) / (x1 - x0);
    return std::numeric_limits<double>::infinity();
  }
  // Whether component i moves up its graph (towards larger t) on the way to (u, w).
  bool upward(int i, const Vec<M>& u, const Vec<M>& w) const {
    const GraphPiece& g = graphs_[i]->piece(pieces_(i));
    return g.vertical ? w(i) > cw_(i) : u(i) > cu_(i);
  }
  // Whether the direction towards the trial pattern's solution (u, w) enters the trial cell at each tied
  // component, within round-off: t_i = u_i + d_i w_i moves on in the direction the component was going
  // where it switched piece, and does not where it stayed (the vertex bounds its piece on that side).
  bool enters(const Mat<M>& D, unsigned mask, int nt, const Vec<M>& u, const Vec<M>& w) const {
    for (int k = 0; k < nt; ++k) {
      const int i = tied_(k);
      const double d = diag(D, i);
      const double t0 = cu_(i) + d * cw_(i), t1 = u(i) + d * w(i);
      const double slack = 1e-12 * (std::abs(t0) + std::abs(t1) + graphs_[i]->scale()) + 1e-300;
      const bool switched = (mask >> k) & 1u;
      const bool onward = tied_up_(k) ? t1 > t0 + slack : t1 < t0 - slack;
      const bool back = tied_up_(k) ? t1 < t0 - slack : t1 > t0 + slack;
      if (switched ? back : onward) return false;
    }
    return true;
  }

  bool is_diagonal(const Mat<M>& D) const {
    const int n = m_;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        if (i != j && D(i, j) != 0.0) return false;
    return true;
  }

  // sum_j D_ij w_j, the terms added in order of j, as Eigen's dynamic-size matrix-vector product
  // (from_zero: its sum starts at 0 + D_i0 w_0) and dot product (from the j = 0 term) add them, written
  // as a loop over m terms without their dispatch.
  double row_times(const Mat<M>& D, int i, const Vec<M>& w, bool from_zero) const {
    double s = from_zero ? 0.0 + D(i, 0) * w(0) : D(i, 0) * w(0);
    for (int j = 1; j < m_; ++j) s += D(i, j) * w(j);
    return s;
  }

  double diag(const Mat<M>& D, int i) const { return D(i, i) > 0.0 ? D(i, i) : std::max(scale_d_, 1e-300); }

  double round_off(const Vec<M>& q, const Vec<M>& u, const Vec<M>& w) const {
    double qmax = 0.0, umax = 0.0, wmax = 0.0;  // one pass for the three max norms
    for (int i = 0; i < m_; ++i) {
      qmax = std::max(qmax, std::abs(q(i)));
      umax = std::max(umax, std::abs(u(i)));
      wmax = std::max(wmax, std::abs(w(i)));
    }
    const double scale = qmax + scale_d_ * wmax + umax + wmax + graph_scale_;
    return std::numeric_limits<double>::epsilon() * std::max(scale, 1e-300);
  }

  // The equations of pattern p (see the header); false if they have no finite solution. A component on
  // a horizontal piece is pinned (w_i = w0 exactly) and leaves the linear system: its column times w0
  // moves to the right-hand side, and only the free components (vertical and sloped pieces) are solved
  // for, by an LU of their block (small_lu.h, in the leading block of K_: no allocation). The result is
  // that of an LU of the whole m x m system with the pinned rows as identity rows, which is
  // block-triangular up to a permutation, in fewer operations: a moving controlled coordinate or an
  // inactive contact costs no elimination at all.
  bool solve_pattern(const Mat<M>& D, const Vec<M>& q, const Pieces& p, Vec<M>& u, Vec<M>& w) {
    const int m = m_;
    int nf = 0, np = 0;
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (!g.vertical && g.slope == 0.0) {
        w(i) = g.w0;  // exactly
        pinned_(np++) = i;
      } else {
        free_(nf++) = i;
      }
    }
    for (int a = 0; a < nf; ++a) {
      const int i = free_(a);
      const GraphPiece& g = graphs_[i]->piece(p(i));
      // Row i, with u_i = q_i - D_i. w: D_i. w = q_i - u0 on a vertical piece; on a sloped one
      // w_i = w0 + s (u_i - u0), i.e. (e_i + s D_i.) w = w0 + s (q_i - u0).
      double ri;
      if (g.vertical) {
        for (int b = 0; b < nf; ++b) K_(a, b) = D(i, free_(b));
        ri = q(i) - g.u0;
      } else {
        for (int b = 0; b < nf; ++b) K_(a, b) = g.slope * D(i, free_(b));
        K_(a, a) += 1.0;
        ri = g.w0 + g.slope * (q(i) - g.u0);
      }
      for (int c = 0; c < np; ++c) {  // the pinned columns, in order
        const int j = pinned_(c);
        ri -= (g.vertical ? D(i, j) : g.slope * D(i, j)) * w(j);
      }
      r_(a) = ri;
    }
    lu_solve_in_place(K_, r_, nf);
    for (int a = 0; a < nf; ++a) w(free_(a)) = r_(a);
    if (!finite(w)) return false;
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (g.vertical) {
        u(i) = g.u0;  // exactly
      } else {
        u(i) = q(i) - row_times(D, i, w, true);
      }
    }
    return finite(u);
  }

  // The leading m_ entries of x are finite.
  bool finite(const Vec<M>& x) const {
    if constexpr (M != Eigen::Dynamic) {
      return x.allFinite();  // m_ == M
    } else {
      return x.head(m_).allFinite();
    }
  }

  // Whether every (u_i, w_i) lies on its piece within round-off; clamps it onto the piece if so.
  bool consistent(const Pieces& p, Vec<M>& u, Vec<M>& w, const Vec<M>& q) {
    const double tol = 64.0 * round_off(q, u, w);
    for (int i = 0; i < m_; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      const double x = g.vertical ? w(i) : u(i);
      if (x < g.lo - tol || x > g.hi + tol) return false;
    }
    for (int i = 0; i < m_; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (g.vertical) {
        w(i) = std::clamp(w(i), g.lo, g.hi);
      } else {
        u(i) = std::clamp(u(i), g.lo, g.hi);
      }
    }
    return true;
  }

  // Moves every component that left its piece to the piece of its scalar resolvent. Returns whether
  // the pattern changed.
  bool update_pattern(const Mat<M>& D, const Vec<M>& u, const Vec<M>& w) {
    bool changed = false;
    for (int i = 0; i < m_; ++i) {
      const GraphPiece& g = graphs_[i]->piece(pieces_(i));
      const double x = g.vertical ? w(i) : u(i);
      if (x >= g.lo && x <= g.hi) continue;
      const int j = graphs_[i]->locate(u(i) + diag(D, i) * w(i), diag(D, i));
      if (j != pieces_(i)) {
        pieces_(i) = j;
        changed = true;
      }
    }
    return changed;
  }

  bool enumerate(const Mat<M>& D, const Vec<M>& q, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    long total = 1;
    for (int i = 0; i < m_; ++i) {
      total *= graphs_[i]->num_pieces();
      if (total > kMaxEnumeration) return false;
    }
    for (long code = 0; code < total; ++code) {
      long c = code;
      for (int i = 0; i < m_; ++i) {
        const int np = graphs_[i]->num_pieces();
        trial_(i) = static_cast<int>(c % np);
        c /= np;
      }
      ++st.iterations;
      if (solve_pattern(D, q, trial_, u, w) && consistent(trial_, u, w, q)) {
        pieces_ = trial_;
        st.route = GraphSolveRoute::kEnumeration;
        return true;
      }
    }
    return false;
  }

  bool forward_backward(const Mat<M>& D, const Vec<M>& q, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    st.route = GraphSolveRoute::kForwardBackward;
    const Mat<M> Dm = D.topLeftCorner(m_, m_);  // the problem's block (use_leading); the fallback may allocate
    const Mat<M> Ds = 0.5 * (Dm + Dm.transpose());
    Eigen::SelfAdjointEigenSolver<Mat<M>> eig(Ds, Eigen::EigenvaluesOnly);
    const double mu = eig.eigenvalues()(0);
    Eigen::JacobiSVD<Mat<M>> svd(Dm);
    const double L = svd.singularValues()(0);
    if (!(mu > 0.0) || !(L > 0.0)) return false;
    const double gamma = mu / (L * L);
    w.head(m_).setZero();
    for (int it = 1; it <= 200000; ++it) {
      t_.head(m_).noalias() = Dm * w.head(m_);
      t_.head(m_) -= q.head(m_);
      z_.head(m_) = w.head(m_) - gamma * t_.head(m_);
      for (int i = 0; i < m_; ++i) {
        double ui = 0.0, wi = 0.0;
        trial_(i) = graphs_[i]->resolve(z_(i) / gamma, 1.0 / gamma, ui, wi);
        w(i) = wi;
      }
      ++st.iterations;
      if (it % 64 == 0) {
        if (solve_pattern(D, q, trial_, u, z_) && consistent(trial_, u, z_, q)) {
          w = z_;
          pieces_ = trial_;
          return accept(D, q, u, w, pieces_, st);
        }
      }
    }
    u.head(m_).noalias() = q.head(m_) - Dm * w.head(m_);
    accept(D, q, u, w, trial_, st);
    return false;
  }

  bool accept(const Mat<M>& D, const Vec<M>& q, const Vec<M>& u, const Vec<M>& w, const Pieces& p, GraphSolveStats& st) {
    st.tolerance = 256.0 * round_off(q, u, w);
    double res = 0.0;
    for (int i = 0; i < m_; ++i) {
      const double eq = std::abs(u(i) + row_times(D, i, w, false) - q(i));
      const double on = graphs_[i]->distance_to_piece(p(i), u(i), w(i));
      res = std::max({res, eq, on});
    }
    st.residual = res;
    return std::isfinite(res) && res <= st.tolerance && finite(u) && finite(w);
  }

  int m_ = 0;         // the current problem's size (use_leading)
  int capacity_ = 0;  // the size the arrays were configured for
  const MonotoneGraph* const* graphs_ = nullptr;
  std::vector<const MonotoneGraph*> last_graphs_;
  double scale_d_ = 0.0, graph_scale_ = 0.0;
  Pieces pieces_, trial_;
  Pieces tied_, tied_up_;  // the path's components that reach the cell's boundary, and whether going up
  Vec<M> cu_, cw_;         // the path's current point
  Fallback fallback_ = Fallback::kPath;
  Pieces free_, pinned_;  // the free and the pinned components of the pattern being solved (solve_pattern)
  Mat<M> K_;              // their equations' matrix, in its leading block
  Vec<M> r_, t_, z_;
};

}  // namespace moreau
