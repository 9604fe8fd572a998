// Piecewise-linear maximal monotone graphs G of R x R: the feedback laws y -> y_L in d phi(y) of the
// Lur'e systems (4) of Brogliato (2003), section 3 and Figure 3, and the contact and controller laws of
// the Moreau-Jean one-step problem (moreau_jean_integrator.h).
//
// A graph is a polyline through vertices (u_0, w_0), ..., (u_{K-1}, w_{K-1}) with u and w both
// non-decreasing (consecutive vertices distinct: a vertical segment is two vertices with the same u),
// continued at each end either by a ray of slope s >= 0 or by an infinite vertical wall (at the left end
// w -> -inf at u = u_0, at the right end w -> +inf at u = u_{K-1}). Such a curve is a complete
// non-decreasing curve of R^2, i.e. the graph of a maximal monotone mapping (section 2 of the paper), and
// every such piecewise-linear mapping with finitely many vertices is of this form: it is d phi for the
// convex, piecewise-quadratic phi whose derivative it is. Every named law below is an instance:
//
//   relay a Sign(u)                 vertices (0,-a), (0,a);  slopes 0, 0
//   coulomb a Sign(u) + k u         vertices (0,-a), (0,a);  slopes k, k        (Figure 3d)
//   saturation k u clipped at +-L   vertices (-L/k,-L), (L/k,L); slopes 0, 0    (Figure 3b)
//   dead zone k (|u| - d)+ sign u   vertices (-d,0), (d,0);  slopes k, k        (Figure 3a)
//   complementarity d psi_{R+}(u)   vertex (0,0); left wall, right slope 0      (Figure 3c, the LCS (6))
//   mos                             walls at u = +-a, dead zone [-b, b], slope k in between (Figure 3e)
//   adhesive                        wall at u = 0, then w = min(k u, f) for u > 0  (Figure 3f)
//   zero (w = 0 for every u)        vertex (0,0); slopes 0, 0 (an inactive contact)
//
// The scalar resolvent: for d > 0, the line u + d w = q meets the graph in exactly one point, because
// u + d w strictly increases along the curve. resolve() computes that point exactly: on a vertical piece
// u is the vertex abscissa itself (so a component at rest is 0.0, not round-off), on a horizontal piece w
// is the vertex ordinate itself. This is the building block of the exact one-step solver
// (graph_inclusion_solver.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "moreau/platform/number_text.h"

namespace moreau {

// One piece of a graph. Vertical: u = u0 and w in [lo, hi]. Non-vertical: w = w0 + slope (u - u0) and
// u in [lo, hi]. lo may be -inf and hi +inf (the end pieces).
struct GraphPiece {
  bool vertical = false;
  double u0 = 0.0, w0 = 0.0, slope = 0.0;
  double lo = 0.0, hi = 0.0;
};

class MonotoneGraph {
 public:
  enum class End { kSlope, kWall };

  // Why a description is not a maximal monotone graph: `field` is "vertices" (with `index` the offending
  // vertex and `coordinate` 0 for u, 1 for w, -1 for the whole vertex), "left" or "right".
  struct Problem {
    std::string field;
    int index = -1;
    int coordinate = -1;
    std::string reason;
  };

  MonotoneGraph() : MonotoneGraph(zero()) {}

  // Checks a description; returns true when it is a maximal monotone graph, else fills `problem`.
  static bool check(const std::vector<double>& u, const std::vector<double>& w, End left, double left_slope, End right, double right_slope,
                    Problem* problem) {
    auto fail = [&](std::string field, int index, int coordinate, std::string reason) {
      if (problem) *problem = Problem{std::move(field), index, coordinate, std::move(reason)};
      return false;
    };
    if (u.empty() || u.size() != w.size()) return fail("vertices", -1, -1, "a graph needs at least one vertex [u, w]");
    for (std::size_t k = 0; k < u.size(); ++k) {
      if (!std::isfinite(u[k])) return fail("vertices", static_cast<int>(k), 0, "u is not finite");
      if (!std::isfinite(w[k])) return fail("vertices", static_cast<int>(k), 1, "w is not finite");
      if (k == 0) continue;
      if (u[k] < u[k - 1])
        return fail("vertices", static_cast<int>(k), 0,
                    "not monotone: u decreases from " + fmt(u[k - 1]) + " to " + fmt(u[k]) +
                        " (vertices must be listed with u and w both non-decreasing)");
      if (w[k] < w[k - 1])
        return fail(
            "vertices", static_cast<int>(k), 1,
            "not monotone: w decreases from " + fmt(w[k - 1]) + " to " + fmt(w[k]) + " (a monotone graph never goes down as u increases)");
      if (u[k] == u[k - 1] && w[k] == w[k - 1]) return fail("vertices", static_cast<int>(k), -1, "repeats the previous vertex");
      // A sloped segment (neither vertical nor horizontal) has slope rise / run (build_pieces): near the
      // largest double the run or the rise overflows (1e308 - -1e308), and a short steep segment's
      // slope does; the piece would carry inf, NaN, or 0 for a slope.
      if (u[k] != u[k - 1] && w[k] != w[k - 1]) {
        const double run = u[k] - u[k - 1], rise = w[k] - w[k - 1], slope = rise / run;
        if (!std::isfinite(run) || !std::isfinite(rise) || !std::isfinite(slope))
          return fail("vertices", static_cast<int>(k), -1,
                      "the segment from the previous vertex overflows a double: u rises by " + fmt(run) + ", w by " + fmt(rise) +
                          ", slope " + fmt(slope));
      }
    }
    if (left == End::kSlope && !(left_slope >= 0.0 && std::isfinite(left_slope)))
      return fail("left", -1, -1, "the slope of the left ray must be finite and >= 0 (monotone), got " + fmt(left_slope));
    if (right == End::kSlope && !(right_slope >= 0.0 && std::isfinite(right_slope)))
      return fail("right", -1, -1, "the slope of the right ray must be finite and >= 0 (monotone), got " + fmt(right_slope));
    return true;
  }

  // Builds a graph; the description must pass check() (otherwise the graph is the zero graph).
  MonotoneGraph(std::vector<double> u, std::vector<double> w, End left, double left_slope, End right, double right_slope)
      : u_(std::move(u)), w_(std::move(w)), left_(left), right_(right), left_slope_(left_slope), right_slope_(right_slope) {
    if (!check(u_, w_, left_, left_slope_, right_, right_slope_, nullptr)) {
      u_ = {0.0};
      w_ = {0.0};
      left_ = right_ = End::kSlope;
      left_slope_ = right_slope_ = 0.0;
    }
    build_pieces();
  }

  // ---- the named graphs of Figure 3 ---------------------------------------------------------------
  static MonotoneGraph relay(double a) { return coulomb(a, 0.0); }
  static MonotoneGraph coulomb(double a, double k) {
    if (a == 0.0) return MonotoneGraph({0.0}, {0.0}, End::kSlope, k, End::kSlope, k);
    return MonotoneGraph({0.0, 0.0}, {-a, a}, End::kSlope, k, End::kSlope, k);
  }
  static MonotoneGraph saturation(double k, double limit) {
    return MonotoneGraph({-limit / k, limit / k}, {-limit, limit}, End::kSlope, 0.0, End::kSlope, 0.0);
  }
  static MonotoneGraph dead_zone(double half_width, double k) {
    if (half_width == 0.0) return MonotoneGraph({0.0}, {0.0}, End::kSlope, k, End::kSlope, k);
    return MonotoneGraph({-half_width, half_width}, {0.0, 0.0}, End::kSlope, k, End::kSlope, k);
  }
  static MonotoneGraph complementarity() { return MonotoneGraph({0.0}, {0.0}, End::kWall, 0.0, End::kSlope, 0.0); }
  static MonotoneGraph mos(double threshold, double limit, double k) {
    const double top = k * (limit - threshold);
    std::vector<double> u, w;
    if (threshold == 0.0) {
      u = {-limit, 0.0, limit};
      w = {-top, 0.0, top};
    } else {
      u = {-limit, -threshold, threshold, limit};
      w = {-top, 0.0, 0.0, top};
    }
    if (top == 0.0) {  // no slope: a dead zone between two walls
      u = {-limit, limit};
      w = {0.0, 0.0};
    }
    return MonotoneGraph(u, w, End::kWall, 0.0, End::kWall, 0.0);
  }
  // stiffness <= 0 or infinite: rigid adhesion (a vertical segment from 0 to f at u = 0).
  static MonotoneGraph adhesive(double force, double stiffness) {
    if (force == 0.0) return complementarity();
    if (!(stiffness > 0.0) || !std::isfinite(stiffness)) return MonotoneGraph({0.0, 0.0}, {0.0, force}, End::kWall, 0.0, End::kSlope, 0.0);
    return MonotoneGraph({0.0, force / stiffness}, {0.0, force}, End::kWall, 0.0, End::kSlope, 0.0);
  }
  static MonotoneGraph zero() { return MonotoneGraph({0.0}, {0.0}, End::kSlope, 0.0, End::kSlope, 0.0); }

  // ---- description --------------------------------------------------------------------------------
  const std::vector<double>& u() const { return u_; }
  const std::vector<double>& w() const { return w_; }
  End left() const { return left_; }
  End right() const { return right_; }
  double left_slope() const { return left_slope_; }
  double right_slope() const { return right_slope_; }
  int num_pieces() const { return static_cast<int>(pieces_.size()); }
  const GraphPiece& piece(int j) const { return pieces_[j]; }
  // The largest |coordinate| of a vertex: the graph's own scale, for round-off allowances.
  double scale() const { return scale_; }
  // Whether (0, 0) is on the graph (Lemma 2 assumes it).
  bool contains_origin() const {
    double lo, hi;
    return values(0.0, lo, hi) && lo <= 0.0 && 0.0 <= hi;
  }

  bool operator==(const MonotoneGraph& o) const {
    return u_ == o.u_ && w_ == o.w_ && left_ == o.left_ && right_ == o.right_ && (left_ == End::kWall || left_slope_ == o.left_slope_) &&
           (right_ == End::kWall || right_slope_ == o.right_slope_);
  }

  // ---- evaluation ---------------------------------------------------------------------------------
  // G(u) = [lo, hi] (a point off the vertical pieces). Returns false when u is outside the domain.
  bool values(double u, double& lo, double& hi) const {
    lo = std::numeric_limits<double>::infinity();
    hi = -lo;
    bool any = false;
    for (const GraphPiece& p : pieces_) {
      double a, b;
      if (p.vertical) {
        if (u != p.u0) continue;
        a = p.lo;
        b = p.hi;
      } else {
        if (u < p.lo || u > p.hi) continue;
        a = b = p.slope == 0.0 ? p.w0 : p.w0 + p.slope * (u - p.u0);
      }
      lo = std::min(lo, a);
      hi = std::max(hi, b);
      any = true;
    }
    return any;
  }
  bool in_domain(double u) const {
    double lo, hi;
    return values(u, lo, hi);
  }
  // The element of G(u) nearest 0 (u must be in the domain).
  double least_norm_value(double u) const {
    double lo, hi;
    if (!values(u, lo, hi)) return std::numeric_limits<double>::quiet_NaN();
    return std::clamp(0.0, lo, hi);
  }

  // Euclidean distance from (u, w) to piece j, and to the graph.
  double distance_to_piece(int j, double u, double w) const {
    const GraphPiece& p = pieces_[j];
    if (p.vertical) {
      const double dw = w < p.lo ? p.lo - w : (w > p.hi ? w - p.hi : 0.0);
      return norm2(u - p.u0, dw);
    }
    // Project onto the line w = w0 + slope (u - u0), parametrised by its u offset, then clamp.
    const double t = std::clamp(((u - p.u0) + p.slope * (w - p.w0)) / (1.0 + p.slope * p.slope), p.lo - p.u0, p.hi - p.u0);
    return norm2(u - (p.u0 + t), w - (p.w0 + p.slope * t));
  }
  double distance(double u, double w) const {
    double d = std::numeric_limits<double>::infinity();
    for (int j = 0; j < num_pieces(); ++j) d = std::min(d, distance_to_piece(j, u, w));
    return d;
  }

  // Moves the only vertex of a one-vertex graph to (u, w), keeping its ends: the same graph translated.
  // Allocation-free (the pieces are rebuilt in the storage they had), for graphs that change every step.
  void move_single_vertex(double u, double w) {
    if (u_.size() != 1) return;
    u_[0] = u;
    w_[0] = w;
    build_pieces();
  }

  // The piece on which u + d w = q meets the graph (d > 0), without computing the point.
  int locate(double q, double d) const {
    const int K = static_cast<int>(u_.size());
    for (int k = 0; k < K; ++k)
      if (q <= u_[k] + d * w_[k]) return k;  // piece k lies before vertex k
    return K;
  }

  // Solves u + d w = q, w in G(u), for d > 0 (see the header comment). Returns the piece index.
  // d == 0: u = q and w = G(q), which must be single-valued there; returns -1 otherwise.
  int resolve(double q, double d, double& u, double& w) const {
    if (d == 0.0) {
      double lo, hi;
      if (!values(q, lo, hi) || lo != hi) return -1;
      u = q;
      w = lo;
      for (int j = 0; j < num_pieces(); ++j)
        if (!pieces_[j].vertical && q >= pieces_[j].lo && q <= pieces_[j].hi) return j;
      return -1;
    }
    const int j = locate(q, d);
    // On a vertex exactly: return the vertex itself.
    if (j < static_cast<int>(u_.size()) && q == u_[j] + d * w_[j]) {
      u = u_[j];
      w = w_[j];
      return j;
    }
    point_on_piece(j, q, d, u, w);
    return j;
  }

  // The point of piece j on the line u + d w = q (d > 0), clamped into the piece.
  void point_on_piece(int j, double q, double d, double& u, double& w) const {
    const GraphPiece& p = pieces_[j];
    if (p.vertical) {
      u = p.u0;
      w = std::clamp((q - p.u0) / d, p.lo, p.hi);
    } else if (p.slope == 0.0) {
      w = p.w0;
      u = std::clamp(q - d * p.w0, p.lo, p.hi);
    } else {
      u = std::clamp((q - d * (p.w0 - p.slope * p.u0)) / (1.0 + d * p.slope), p.lo, p.hi);
      w = p.w0 + p.slope * (u - p.u0);
    }
  }

 private:
  // sqrt(a^2 + b^2) without overflow: std::hypot, which C defines to be exactly |a| when b is +-0 (and
  // symmetrically); those cases, a point on its piece along one axis, skip its call.
  static double norm2(double a, double b) {
    if (b == 0.0) return std::abs(a);
    if (a == 0.0) return std::abs(b);
    return std::hypot(a, b);
  }
  static std::string fmt(double v) { return platform::significant(v, 10); }

  void build_pieces() {
    const double inf = std::numeric_limits<double>::infinity();
    const int K = static_cast<int>(u_.size());
    pieces_.clear();
    pieces_.reserve(static_cast<std::size_t>(K + 1));
    // Left end: piece 0.
    if (left_ == End::kWall)
      pieces_.push_back(GraphPiece{true, u_[0], w_[0], 0.0, -inf, w_[0]});
    else
      pieces_.push_back(GraphPiece{false, u_[0], w_[0], left_slope_, -inf, u_[0]});
    // Segments between vertices k-1 and k: piece k.
    for (int k = 1; k < K; ++k) {
      if (u_[k] == u_[k - 1]) {
        pieces_.push_back(GraphPiece{true, u_[k], w_[k - 1], 0.0, w_[k - 1], w_[k]});
      } else {
        const double s = w_[k] == w_[k - 1] ? 0.0 : (w_[k] - w_[k - 1]) / (u_[k] - u_[k - 1]);
        pieces_.push_back(GraphPiece{false, u_[k - 1], w_[k - 1], s, u_[k - 1], u_[k]});
      }
    }
    // Right end: piece K.
    if (right_ == End::kWall)
      pieces_.push_back(GraphPiece{true, u_[K - 1], w_[K - 1], 0.0, w_[K - 1], inf});
    else
      pieces_.push_back(GraphPiece{false, u_[K - 1], w_[K - 1], right_slope_, u_[K - 1], inf});
    scale_ = 0.0;
    for (int k = 0; k < K; ++k) scale_ = std::max({scale_, std::abs(u_[k]), std::abs(w_[k])});
  }

  std::vector<double> u_, w_;
  End left_ = End::kSlope, right_ = End::kSlope;
  double left_slope_ = 0.0, right_slope_ = 0.0;
  std::vector<GraphPiece> pieces_;
  double scale_ = 0.0;
};

}  // namespace moreau
