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
//     pinned exactly), solved by LU; accept if every (u_i, w_i) lies on its piece, else move each
//     component that left its piece to the piece where its scalar resolvent u_i + D_ii w_i lands (the
//     primal-dual active-set update, i.e. semismooth Newton on the natural map). Warm-started from the
//     previous call's pattern.
//  3. if that stalls or cycles: every pattern (when there are at most kMaxEnumeration), exact; else
//     forward-backward splitting w <- J(w - gamma (D w - q)), J the resolvent of gamma G^{-1} (scalar,
//     exact), gamma = mu / L^2, whose iterate's pattern is polished by step 2's equations.
// Exactness: on a vertical piece u_i is the vertex abscissa itself (0.0 for a component at rest), on a
// horizontal piece w_i the vertex ordinate itself. A solution is accepted only when
// max_i |u_i + (D w)_i - q_i| and the distance of each (u_i, w_i) to its piece are within 256 eps of the
// problem's scale; otherwise solve() returns false and the caller must not take the step.
// No allocation after configure().
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/types.h"

namespace moreau {

struct GraphSolveStats {
  int iterations = 0;      // pattern solves (or scalar resolvents in the decoupled case), or FB sweeps
  double residual = 0.0;   // max of the equation residual and the distances to the pieces
  double tolerance = 0.0;  // the round-off bound the residual was accepted against
  bool used_fallback = false;
};

template <int M>
class GraphInclusionSolver {
 public:
  using Pieces = Eigen::Matrix<int, M, 1>;
  static constexpr long kMaxEnumeration = 59049;  // 3^10 patterns

  GraphInclusionSolver() = default;

  void configure(int m) {
    m_ = m;
    pieces_.setZero(m);
    trial_.setZero(m);
    K_.setZero(m, m);
    r_.setZero(m);
    t_.setZero(m);
    z_.setZero(m);
    last_graphs_.assign(static_cast<std::size_t>(m), nullptr);
    if constexpr (M == Eigen::Dynamic) lu_ = Eigen::PartialPivLU<Mat<M>>(m);
  }

  int size() const { return m_; }
  const Pieces& pieces() const { return pieces_; }
  // Whether component i of the last solution lies on a vertical piece of its graph (u_i exact).
  bool on_vertical_piece(int i) const { return graphs_ && graphs_[i]->piece(pieces_(i)).vertical; }

  bool solve(const Mat<M>& D, const Vec<M>& q, const MonotoneGraph* const* graphs, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    st = GraphSolveStats{};
    graphs_ = graphs;
    const int m = m_;
    if (m == 0) return true;
    if (m == 1) {  // the scalar resolvent, with the acceptance test written out
      const double d = D(0, 0), qq = q(0);
      double uu = 0.0, ww = 0.0;
      const int j = graphs[0]->resolve(qq, d, uu, ww);
      st.iterations = 1;
      if (j < 0 || d < 0.0) return false;
      pieces_(0) = j;
      last_graphs_[0] = graphs[0];
      u(0) = uu;
      w(0) = ww;
      const double scale = std::abs(qq) + std::abs(d * ww) + std::abs(uu) + std::abs(ww) + graphs[0]->scale();
      st.tolerance = 256.0 * std::numeric_limits<double>::epsilon() * std::max(scale, 1e-300);
      st.residual = std::max(std::abs(uu + d * ww - qq), graphs[0]->distance_to_piece(j, uu, ww));
      return std::isfinite(st.residual) && st.residual <= st.tolerance;
    }
    scale_d_ = D.cwiseAbs().rowwise().sum().maxCoeff();
    graph_scale_ = 0.0;
    for (int i = 0; i < m; ++i) graph_scale_ = std::max(graph_scale_, graphs[i]->scale());

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
      if (solve_pattern(D, q, pieces_, u, w) && consistent(pieces_, u, w, q)) return accept(D, q, u, w, pieces_, st);
      if (!update_pattern(D, u, w)) break;
    }

    st.used_fallback = true;
    if (enumerate(D, q, u, w, st)) return accept(D, q, u, w, pieces_, st);
    return forward_backward(D, q, u, w, st);
  }

 private:
  static bool is_diagonal(const Mat<M>& D) {
    const int n = static_cast<int>(D.rows());
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        if (i != j && D(i, j) != 0.0) return false;
    return true;
  }

  double diag(const Mat<M>& D, int i) const { return D(i, i) > 0.0 ? D(i, i) : std::max(scale_d_, 1e-300); }

  double round_off(const Vec<M>& q, const Vec<M>& u, const Vec<M>& w) const {
    const double scale =
        q.cwiseAbs().maxCoeff() + scale_d_ * w.cwiseAbs().maxCoeff() + u.cwiseAbs().maxCoeff() + w.cwiseAbs().maxCoeff() + graph_scale_;
    return std::numeric_limits<double>::epsilon() * std::max(scale, 1e-300);
  }

  // The equations of pattern p (see the header); false if they have no finite solution.
  bool solve_pattern(const Mat<M>& D, const Vec<M>& q, const Pieces& p, Vec<M>& u, Vec<M>& w) {
    const int m = m_;
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (g.vertical) {
        K_.row(i) = D.row(i);
        r_(i) = q(i) - g.u0;
      } else if (g.slope == 0.0) {
        K_.row(i).setZero();
        K_(i, i) = 1.0;
        r_(i) = g.w0;
      } else {
        K_.row(i) = g.slope * D.row(i);
        K_(i, i) += 1.0;
        r_(i) = g.w0 + g.slope * (q(i) - g.u0);
      }
    }
    // Pinned components (horizontal pieces): known w, moved to the right-hand side.
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (g.vertical || g.slope != 0.0) continue;
      for (int j = 0; j < m; ++j) {
        if (j == i) continue;
        r_(j) -= K_(j, i) * g.w0;
        K_(j, i) = 0.0;
      }
    }
    lu_.compute(K_);
    w.noalias() = lu_.solve(r_);
    if (!w.allFinite()) return false;
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (!g.vertical && g.slope == 0.0) w(i) = g.w0;  // exactly
    }
    u.noalias() = D * w;  // u = q - D w, the product into u itself (nested, it would be a heap temporary)
    u = q - u;
    for (int i = 0; i < m; ++i) {
      const GraphPiece& g = graphs_[i]->piece(p(i));
      if (g.vertical) u(i) = g.u0;  // exactly
    }
    return u.allFinite();
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
        return true;
      }
    }
    return false;
  }

  bool forward_backward(const Mat<M>& D, const Vec<M>& q, Vec<M>& u, Vec<M>& w, GraphSolveStats& st) {
    const Mat<M> Ds = 0.5 * (D + D.transpose());
    Eigen::SelfAdjointEigenSolver<Mat<M>> eig(Ds, Eigen::EigenvaluesOnly);
    const double mu = eig.eigenvalues()(0);
    Eigen::JacobiSVD<Mat<M>> svd(D);
    const double L = svd.singularValues()(0);
    if (!(mu > 0.0) || !(L > 0.0)) return false;
    const double gamma = mu / (L * L);
    w.setZero(m_);
    for (int it = 1; it <= 200000; ++it) {
      t_.noalias() = D * w;
      t_ -= q;
      z_ = w - gamma * t_;
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
    u.noalias() = q - D * w;
    accept(D, q, u, w, trial_, st);
    return false;
  }

  bool accept(const Mat<M>& D, const Vec<M>& q, const Vec<M>& u, const Vec<M>& w, const Pieces& p, GraphSolveStats& st) {
    st.tolerance = 256.0 * round_off(q, u, w);
    double res = 0.0;
    for (int i = 0; i < m_; ++i) {
      const double eq = std::abs(u(i) + D.row(i).dot(w) - q(i));
      const double on = graphs_[i]->distance_to_piece(p(i), u(i), w(i));
      res = std::max({res, eq, on});
    }
    st.residual = res;
    return std::isfinite(res) && res <= st.tolerance && u.allFinite() && w.allFinite();
  }

  int m_ = 0;
  const MonotoneGraph* const* graphs_ = nullptr;
  std::vector<const MonotoneGraph*> last_graphs_;
  double scale_d_ = 0.0, graph_scale_ = 0.0;
  Pieces pieces_, trial_;
  Mat<M> K_;
  Vec<M> r_, t_, z_;
  Eigen::PartialPivLU<Mat<M>> lu_;
};

}  // namespace moreau
