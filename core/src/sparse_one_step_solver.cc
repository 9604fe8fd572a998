// The one-step inclusion (6.5) at scale (sparse_one_step_solver.h).
#include "moreau/core/sparse_one_step_solver.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "moreau/core/sparse_lcp.h"

namespace moreau {

void SparseOneStepSolver::configure(const SparseMatrix& P, const Eigen::VectorXd& gains) {
  P_ = P;
  P_.makeCompressed();
  a_ = gains;
  const int n = size();
  Eigen::VectorXd row_sums = Eigen::VectorXd::Zero(n);
  for (int j = 0; j < n; ++j)
    for (SparseMatrix::InnerIterator it(P_, j); it; ++it) row_sums(it.row()) += std::abs(it.value());
  const int band = moreau::bandwidth(P_);
  p_norm_inf_ = n > 0 ? row_sums.maxCoeff() : 0.0;
  a_max_ = n > 0 ? a_.maxCoeff() : 0.0;
  banded_ = band <= BandedLdlt::kMaxBandwidth;
  band_ = band;
  if (banded_) banded_ldlt_.reserve(n, band);
  pattern_.assign(static_cast<std::size_t>(n), 0);
  local_.assign(static_cast<std::size_t>(n), -1);
  F_.clear();
  factored_F_.clear();
  factor_valid_ = false;
  w_.setZero(n);
  rhs_.setZero(n);
}

// P_FF, factorised unless F is the set factorised last. False when it is not positive definite within
// round-off (every pivot of L D L^T above 64 eps times its largest diagonal entry, as sparse_lcp.h).
bool SparseOneStepSolver::factorise() {
  if (factor_valid_ && F_ == factored_F_) return true;
  factor_valid_ = false;
  if (F_.empty()) {
    factored_F_.clear();
    factor_valid_ = true;
    return true;
  }
  ++factorisations_;
  if (banded_) {
    if (!banded_ldlt_.factorise(P_, F_, local_)) return false;
  } else {
    SparseLcpSolver::principal_submatrix(P_, F_, local_, triplets_, pff_);
    ldlt_.compute(pff_);
    const double pivot = ldlt_.info() == Eigen::Success ? ldlt_.vectorD().minCoeff() : -1.0;
    const double largest = pff_.diagonal().cwiseAbs().maxCoeff();
    if (!(pivot > 64.0 * std::numeric_limits<double>::epsilon() * largest)) return false;
  }
  factored_F_ = F_;
  factor_valid_ = true;
  return true;
}

// The pattern's equations: y_i = 0.0 for a resting component, P_FF y_F = -(x_F + a_F s_F) on the moving
// set F (every component with a_i = 0 is in F: nothing holds it). Then w_ = -(P y + x) everywhere.
bool SparseOneStepSolver::solve_pattern(const Eigen::VectorXd& x, Eigen::VectorXd& y) {
  const int n = size();
  F_.clear();
  for (int i = 0; i < n; ++i)
    if (!(a_(i) > 0.0) || pattern_[static_cast<std::size_t>(i)] != 0) F_.push_back(i);
  if (!factorise()) return false;
  y.setZero(n);
  if (!F_.empty()) {
    // rhs_ has n entries (configure): its head of |F| is the pattern's right-hand side, solved in place
    // within the band, with no allocation as F changes.
    const auto f = static_cast<Eigen::Index>(F_.size());
    for (Eigen::Index k = 0; k < f; ++k) {
      const int i = F_[static_cast<std::size_t>(k)];
      rhs_(k) = -(x(i) + a_(i) * pattern_[static_cast<std::size_t>(i)]);
    }
    if (banded_) {
      banded_ldlt_.solve(rhs_.head(f));
      for (Eigen::Index k = 0; k < f; ++k) y(F_[static_cast<std::size_t>(k)]) = rhs_(k);
    } else {
      yf_ = ldlt_.solve(rhs_.head(f));
      for (Eigen::Index k = 0; k < f; ++k) y(F_[static_cast<std::size_t>(k)]) = yf_(k);
    }
  }
  w_.noalias() = P_ * y;
  w_ = -(w_ + x);
  return y.allFinite() && w_.allFinite();
}

double SparseOneStepSolver::residual(const Eigen::VectorXd& y) const {
  double worst = 0.0;
  for (int i = 0; i < size(); ++i) {
    const double r = y(i) > 0.0 ? std::abs(w_(i) - a_(i)) : y(i) < 0.0 ? std::abs(w_(i) + a_(i)) : std::max(0.0, std::abs(w_(i)) - a_(i));
    worst = std::max(worst, r);
  }
  return worst;
}

bool SparseOneStepSolver::solve(const Eigen::VectorXd& x, Eigen::VectorXd& y, OneStepStats& stats) {
  const int n = size();
  stats = OneStepStats{};
  if (x.size() != n || !x.allFinite()) {
    stats.residual = std::numeric_limits<double>::quiet_NaN();
    stats.tolerance = std::numeric_limits<double>::quiet_NaN();
    return false;
  }
  const double x_inf = n > 0 ? x.cwiseAbs().maxCoeff() : 0.0;
  // 1. Lemma 6.1's closed form: -x in d phi(0).
  bool at_zero = true;
  for (int i = 0; i < n && at_zero; ++i) at_zero = std::abs(x(i)) <= a_(i);
  if (at_zero) {
    y.setZero(n);
    std::fill(pattern_.begin(), pattern_.end(), 0);
    stats.zero_by_closed_form = true;
    stats.tolerance = 64.0 * std::numeric_limits<double>::epsilon() * (x_inf + a_max_);
    return true;
  }
  // 2. Block principal pivoting from the last pattern, Murty's rule as the safeguard.
  const long max_passes = 100L * n + 1000;
  PivotingSafeguard safeguard;
  for (long pass = 0; pass < max_passes; ++pass) {
    ++stats.iterations;
    if (!solve_pattern(x, y)) {
      stats.residual = std::numeric_limits<double>::infinity();
      stats.tolerance = std::numeric_limits<double>::infinity();
      return false;
    }
    const double y_inf = y.cwiseAbs().maxCoeff();
    const double tol = 64.0 * std::numeric_limits<double>::epsilon() * (x_inf + p_norm_inf_ * y_inf + a_max_);
    int count = 0, first = -1;
    for (int i = 0; i < n; ++i) {
      if (!breaks(i, y, tol)) continue;
      ++count;
      if (first < 0) first = i;
    }
    if (count == 0) {
      stats.residual = residual(y);
      stats.tolerance = tol;
      return stats.residual <= tol;
    }
    const bool block = safeguard.block_pivot(count);
    // A broken moving component comes to rest; a broken resting one moves the way its multiplier left
    // [-a_i, a_i].
    for (int i = block ? 0 : first; i < (block ? n : first + 1); ++i)
      if (breaks(i, y, tol)) {
        std::int8_t& s = pattern_[static_cast<std::size_t>(i)];
        s = s != 0 ? 0 : (w_(i) > 0.0 ? 1 : -1);
      }
  }
  stats.residual = residual(y);
  stats.tolerance = 64.0 * std::numeric_limits<double>::epsilon() * (x_inf + a_max_);
  return false;
}

}  // namespace moreau
