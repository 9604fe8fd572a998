// A reference q_d(t) through way points (t_j, q_j), j = 0..m-1: the natural cubic spline of each
// coordinate. It is C2 (q_d, q_d' and q_d'' continuous, as the tracking controller's a_r = q_d'' - Lambda e'
// needs), passes through every way point exactly, and has q_d'' = 0 at both ends ("natural"). Its second
// derivatives M_j at the knots solve the tridiagonal system
//   h_{j-1} M_{j-1} + 2 (h_{j-1} + h_j) M_j + h_j M_{j+1} = 6 ((q_{j+1} - q_j) / h_j - (q_j - q_{j-1}) / h_{j-1}),
// M_0 = M_{m-1} = 0, h_j = t_{j+1} - t_j, which is strictly diagonally dominant (solved by elimination
// without pivoting). On [t_j, t_{j+1}], with a = (t_{j+1} - t) / h_j and b = 1 - a:
//   q_d   = a q_j + b q_{j+1} + ((a^3 - a) M_j + (b^3 - b) M_{j+1}) h_j^2 / 6
//   q_d'  = (q_{j+1} - q_j) / h_j + (-(3 a^2 - 1) M_j + (3 b^2 - 1) M_{j+1}) h_j / 6
//   q_d'' = a M_j + b M_{j+1}.
// Outside [t_0, t_{m-1}] (beyond round-off) it is not defined (at() returns false).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "moreau/core/tracking.h"
#include "moreau/core/types.h"

namespace moreau {

class CubicSplineReference {
 public:
  // What is wrong with way points t (m times) and q (m x n, row j at t_j), or empty: at least two points,
  // t finite and strictly increasing, q finite.
  static std::string problem(const std::vector<double>& t, const Eigen::MatrixXd& q) {
    if (t.size() < 2) return "at least two way points are needed";
    if (static_cast<std::size_t>(q.rows()) != t.size()) return "one row of q per time";
    for (std::size_t j = 0; j < t.size(); ++j) {
      if (!std::isfinite(t[j])) return "the times must be finite";
      if (j > 0 && !(t[j] > t[j - 1])) return "the times must increase strictly (row " + std::to_string(j + 1) + ")";
    }
    if (!q.allFinite()) return "the positions must be finite";
    return {};
  }

  // t and q must have no problem().
  CubicSplineReference(std::vector<double> t, Eigen::MatrixXd q) : t_(std::move(t)), q_(std::move(q)), m_(q_.rows(), q_.cols()) {
    const std::size_t m = t_.size();
    m_.setZero();
    if (m < 3) return;  // two points: a line, M = 0
    // Forward elimination of the interior equations j = 1..m-2 (the Thomas algorithm), for every
    // coordinate at once: c'_j and d'_j.
    std::vector<double> c(m, 0.0);
    Eigen::MatrixXd d = Eigen::MatrixXd::Zero(q_.rows(), q_.cols());
    for (std::size_t j = 1; j + 1 < m; ++j) {
      const double h0 = t_[j] - t_[j - 1], h1 = t_[j + 1] - t_[j];
      const double diag = 2.0 * (h0 + h1) - h0 * c[j - 1];
      c[j] = h1 / diag;
      const auto rhs = 6.0 * ((q_.row(j + 1) - q_.row(j)) / h1 - (q_.row(j) - q_.row(j - 1)) / h0);
      d.row(j) = (rhs - h0 * d.row(j - 1)) / diag;
    }
    for (std::size_t j = m - 2; j >= 1; --j) m_.row(j) = d.row(j) - c[j] * m_.row(j + 1);
  }

  int dof() const { return static_cast<int>(q_.cols()); }
  std::size_t points() const { return t_.size(); }
  double t_first() const { return t_.front(); }
  double t_last() const { return t_.back(); }

  // q_d, q_d', q_d'' at t. `hint` is the caller's (one per run, so that runs on other threads share the
  // spline): the interval of the last look-up, which this updates; 0 to start.
  template <int N>
  bool at(double t, ReferencePoint<N>& out, std::size_t& hint) const {
    // Times a run computes as t0 + k h (+ T_s) may pass an end by round-off: within 1e-9 of the span,
    // they are the end.
    const double slack = 1e-9 * (t_.back() - t_.front());
    if (!(t >= t_.front() - slack && t <= t_.back() + slack)) return false;
    t = std::clamp(t, t_.front(), t_.back());
    // The interval [t_j, t_{j+1}] holding t: the last one looked up, or its successor, in a run that
    // moves forward; else a binary search.
    std::size_t j = hint;
    if (!(j + 1 < t_.size() && t >= t_[j] && t <= t_[j + 1])) {
      if (j + 2 < t_.size() && t >= t_[j + 1] && t <= t_[j + 2]) {
        ++j;
      } else {
        j = static_cast<std::size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin());
        j = std::min(j == 0 ? 0 : j - 1, t_.size() - 2);
      }
      hint = j;
    }
    const double h = t_[j + 1] - t_[j];
    const double a = (t_[j + 1] - t) / h, b = 1.0 - a;
    for (int i = 0; i < dof(); ++i) {
      const double q0 = q_(j, i), q1 = q_(j + 1, i), m0 = m_(j, i), m1 = m_(j + 1, i);
      out.q(i) = a * q0 + b * q1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
      out.v(i) = (q1 - q0) / h + (-(3.0 * a * a - 1.0) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
      out.a(i) = a * m0 + b * m1;
    }
    return true;
  }

  // The second derivatives at the knots (row j at t_j), for tests.
  const Eigen::MatrixXd& knot_second_derivatives() const { return m_; }

 private:
  std::vector<double> t_;
  Eigen::MatrixXd q_, m_;
};

}  // namespace moreau
