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
  int band = 0;
  for (int j = 0; j < n; ++j)
    for (SparseMatrix::InnerIterator it(P_, j); it; ++it) {
      row_sums(it.row()) += std::abs(it.value());
      band = std::max(band, static_cast<int>(std::abs(it.row() - j)));
    }
  p_norm_inf_ = n > 0 ? row_sums.maxCoeff() : 0.0;
  a_max_ = n > 0 ? a_.maxCoeff() : 0.0;
  banded_ = band <= kBandedBandwidth;
  band_ = band;
  if (banded_) {
    band_L_.assign(static_cast<std::size_t>(n) * static_cast<std::size_t>(std::max(band, 1)), 0.0);
    band_D_.setZero(n);
  }
  pattern_.assign(static_cast<std::size_t>(n), 0);
  local_.assign(static_cast<std::size_t>(n), -1);
  F_.clear();
  factored_F_.clear();
  factor_valid_ = false;
  w_.setZero(n);
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
    if (!factorise_band()) return false;
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

// LDL^T of P_FF within its band: F is increasing, so P_FF(a, c) == 0 when |a - c| > b (their coordinates
// are at least as far apart). Row a of L: L(a, c) = (P_FF(a, c) - sum_{k < c} L(a, k) D(k) L(c, k)) /
// D(c) for c in [a - b, a), then D(a) = P_FF(a, a) - sum_k L(a, k)^2 D(k). Every pivot must stay above
// 64 eps times P_FF's largest diagonal entry (positive definite within round-off, as sparse_lcp.h).
bool SparseOneStepSolver::factorise_band() {
  const int f = static_cast<int>(F_.size()), b = band_;
  for (int a = 0; a < f; ++a) local_[static_cast<std::size_t>(F_[static_cast<std::size_t>(a)])] = a;
  double largest = 0.0, smallest_pivot = std::numeric_limits<double>::infinity();
  double row[kBandedBandwidth + 1];  // P_FF(a, a - 1 - k) at row[k], k < b; the diagonal at row[b]
  bool ok = true;
  for (int a = 0; a < f && ok; ++a) {
    std::fill(row, row + b + 1, 0.0);
    const int i = F_[static_cast<std::size_t>(a)];
    for (SparseMatrix::InnerIterator it(P_, i); it; ++it) {  // column i of the symmetric P: its row i
      const int c = local_[static_cast<std::size_t>(it.row())];
      if (c < 0 || c > a || a - c > b) continue;
      row[c == a ? b : a - 1 - c] = it.value();
    }
    double* La = band_L_.data() + static_cast<std::ptrdiff_t>(a) * b;
    for (int c = std::max(0, a - b); c < a; ++c) {
      const double* Lc = band_L_.data() + static_cast<std::ptrdiff_t>(c) * b;
      double sum = row[a - 1 - c];
      for (int k = std::max(0, a - b); k < c; ++k) sum -= La[a - 1 - k] * band_D_(k) * Lc[c - 1 - k];
      La[a - 1 - c] = sum / band_D_(c);
    }
    double d = row[b];
    largest = std::max(largest, std::abs(row[b]));
    for (int k = std::max(0, a - b); k < a; ++k) d -= La[a - 1 - k] * La[a - 1 - k] * band_D_(k);
    band_D_(a) = d;
    smallest_pivot = std::min(smallest_pivot, d);
    ok = std::isfinite(d);
  }
  for (int i : F_) local_[static_cast<std::size_t>(i)] = -1;
  return ok && smallest_pivot > 64.0 * std::numeric_limits<double>::epsilon() * largest;
}

void SparseOneStepSolver::solve_band(Eigen::VectorXd& x) const {
  const int f = static_cast<int>(x.size()), b = band_;
  for (int a = 0; a < f; ++a) {  // L z = x
    const double* La = band_L_.data() + static_cast<std::ptrdiff_t>(a) * b;
    double sum = x(a);
    for (int k = std::max(0, a - b); k < a; ++k) sum -= La[a - 1 - k] * x(k);
    x(a) = sum;
  }
  for (int a = 0; a < f; ++a) x(a) /= band_D_(a);  // D
  for (int a = f - 1; a >= 0; --a) {               // L^T y = z
    double sum = x(a);
    for (int c = a + 1; c <= std::min(f - 1, a + b); ++c) sum -= band_L_[static_cast<std::size_t>(c) * b + (c - 1 - a)] * x(c);
    x(a) = sum;
  }
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
    rhs_.resize(static_cast<Eigen::Index>(F_.size()));
    for (std::size_t k = 0; k < F_.size(); ++k) {
      const int i = F_[k];
      rhs_(static_cast<Eigen::Index>(k)) = -(x(i) + a_(i) * pattern_[static_cast<std::size_t>(i)]);
    }
    if (banded_) {
      yf_ = rhs_;
      solve_band(yf_);
    } else {
      yf_ = ldlt_.solve(rhs_);
    }
    for (std::size_t k = 0; k < F_.size(); ++k) y(F_[k]) = yf_(static_cast<Eigen::Index>(k));
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
