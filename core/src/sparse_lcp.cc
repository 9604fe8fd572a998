// Block principal pivoting with Murty's fallback (sparse_lcp.h).
#include "moreau/core/sparse_lcp.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace moreau {

void SparseLcpSolver::set_matrix(const SparseMatrix& D) {
  D_ = D;
  D_.makeCompressed();
  const int m = static_cast<int>(D_.rows());
  Eigen::VectorXd row_sums = Eigen::VectorXd::Zero(m);
  for (int j = 0; j < D_.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(D_, j); it; ++it) row_sums(it.row()) += std::abs(it.value());
  d_norm_inf_ = m > 0 ? row_sums.maxCoeff() : 0.0;
  int bandwidth = 0;
  for (int j = 0; j < D_.outerSize(); ++j)
    for (SparseMatrix::InnerIterator it(D_, j); it; ++it) bandwidth = std::max(bandwidth, std::abs(static_cast<int>(it.row()) - j));
  banded_ = bandwidth <= kNaturalOrderingBandwidth;
  local_.assign(static_cast<std::size_t>(m), -1);
  role_.assign(static_cast<std::size_t>(m), 0);
  factor_valid_ = false;
  factored_F_.clear();
}

void SparseLcpSolver::principal_submatrix(const SparseMatrix& D, const std::vector<int>& rows, std::vector<int>& local,
                                          std::vector<Eigen::Triplet<double>>& scratch, SparseMatrix& out) {
  scratch.clear();
  for (std::size_t a = 0; a < rows.size(); ++a) local[static_cast<std::size_t>(rows[a])] = static_cast<int>(a);
  for (std::size_t a = 0; a < rows.size(); ++a)
    for (SparseMatrix::InnerIterator it(D, rows[a]); it; ++it) {
      const int b = local[static_cast<std::size_t>(it.row())];
      if (b >= 0) scratch.emplace_back(b, static_cast<int>(a), it.value());
    }
  for (int r : rows) local[static_cast<std::size_t>(r)] = -1;
  const auto size = static_cast<Eigen::Index>(rows.size());
  out.resize(size, size);
  out.setFromTriplets(scratch.begin(), scratch.end());
}

// D_FF, factorised unless the set is the one factorised last.
bool SparseLcpSolver::factorise(SparseLcpStats& stats) {
  if (factor_valid_ && F_ == factored_F_) return true;
  principal_submatrix(D_, F_, local_, triplets_, dff_);
  ++stats.factorisations;
  factor_valid_ = false;
  // The smallest pivot of D_FF = L D L^T, or -1 when the factorisation failed.
  const auto smallest_pivot = [&](auto& ldlt) {
    ldlt.compute(dff_);
    return ldlt.info() == Eigen::Success ? ldlt.vectorD().minCoeff() : -1.0;
  };
  const double pivot = banded_ ? smallest_pivot(banded_ldlt_) : smallest_pivot(ldlt_);
  // Positive definite within round-off: every pivot of D above 64 eps times the largest diagonal entry.
  const double largest = dff_.diagonal().cwiseAbs().maxCoeff();
  if (!(pivot > 64.0 * std::numeric_limits<double>::epsilon() * largest)) return false;
  factored_F_ = F_;
  factor_valid_ = true;
  return true;
}

// Projected Gauss-Seidel sweeps over the problem's rows, forward then backward, from z with its negative
// entries set to 0: z_r <- max(0, z_r - w_r / D_rr). One sweep carries an impulse along a whole chain
// of contacts, where a block pass closes one more contact of an impact wave per pass (each pass a
// factorisation); the rows it leaves with z > 0 become the complementary set the passes start from. A
// guess only: the answer is still a pass's exact solution.
void SparseLcpSolver::guess_by_gauss_seidel(const std::vector<int>& rows, const Eigen::VectorXd& q, Eigen::VectorXd& z, int sweeps) {
  for (int r : rows) z(r) = std::max(0.0, z(r));
  const auto relax = [&](int r) {
    double w = q(r), diagonal = 0.0;
    for (SparseMatrix::InnerIterator it(D_, r); it; ++it) {  // column r of the symmetric D: its row r
      if (role_[static_cast<std::size_t>(it.row())] == 0) continue;
      if (it.row() == r) diagonal = it.value();
      w += it.value() * z(it.row());
    }
    if (diagonal > 0.0) z(r) = std::max(0.0, z(r) - w / diagonal);
  };
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    for (int r : rows) relax(r);
    for (auto it = rows.rbegin(); it != rows.rend(); ++it) relax(*it);
  }
  for (int r : rows) role_[static_cast<std::size_t>(r)] = z(r) > 0.0 ? 2 : 1;
}

bool SparseLcpSolver::solve(const std::vector<int>& rows, const Eigen::VectorXd& q, Eigen::VectorXd& z, Eigen::VectorXd& w,
                            std::vector<char>& in_F, SparseLcpStats& stats) {
  stats = SparseLcpStats{};
  const int m = static_cast<int>(rows.size());
  double q_inf = 0.0;
  for (int r : rows) q_inf = std::max(q_inf, std::abs(q(r)));
  for (int r : rows) role_[static_cast<std::size_t>(r)] = in_F[static_cast<std::size_t>(r)] ? 2 : 1;
  // z as the caller left it (the previous step's impulses): where the first guess starts from.
  z_start_.resize(m);
  for (int a = 0; a < m; ++a) z_start_(a) = z(rows[static_cast<std::size_t>(a)]);

  int best = m + 1, retries = std::max(0, options.block_retries);
  int sweeps = options.guess_sweeps, guesses = 0, guessed_at = 0;
  bool accepted = false;
  const double eps64 = 64.0 * std::numeric_limits<double>::epsilon();
  while (stats.passes < pass_budget(m)) {
    ++stats.passes;
    F_.clear();
    G_.clear();
    for (int r : rows) (role_[static_cast<std::size_t>(r)] == 2 ? F_ : G_).push_back(r);

    // z_F = -D_FF^{-1} q_F, z_G = 0; w_F = 0, w_G = q_G + D_GF z_F.
    double z_inf = 0.0;
    if (!F_.empty()) {
      if (!factorise(stats)) {
        stats.singular = true;
        break;
      }
      const int nf = static_cast<int>(F_.size());
      rhs_.resize(nf);
      for (int a = 0; a < nf; ++a) rhs_(a) = -q(F_[static_cast<std::size_t>(a)]);
      if (banded_)
        zf_ = banded_ldlt_.solve(rhs_);
      else
        zf_ = ldlt_.solve(rhs_);
      for (int a = 0; a < nf; ++a) {
        const int r = F_[static_cast<std::size_t>(a)];
        z(r) = zf_(a);
        w(r) = 0.0;
        z_inf = std::max(z_inf, std::abs(zf_(a)));
      }
    }
    for (int r : G_) {
      z(r) = 0.0;
      w(r) = q(r);
    }
    for (int r : F_) {
      const double zr = z(r);
      if (zr == 0.0) continue;
      for (SparseMatrix::InnerIterator it(D_, r); it; ++it)
        if (role_[static_cast<std::size_t>(it.row())] == 1) w(it.row()) += it.value() * zr;
    }

    const double tol_w = eps64 * (q_inf + d_norm_inf_ * z_inf);
    const double tol_z = eps64 * z_inf;
    int infeasible = 0, last = -1;
    for (int r : rows) {
      const bool bad = role_[static_cast<std::size_t>(r)] == 2 ? z(r) < -tol_z : w(r) < -tol_w;
      if (bad) {
        ++infeasible;
        last = r;
      }
    }
    if (infeasible == 0) {
      accepted = true;
      stats.tolerance = q_inf > 0.0 ? tol_w / q_inf : 0.0;
      break;
    }
    // The warm start failed, or the passes since the last guess did not end: a guess by Gauss-Seidel
    // sweeps, a bounded number of times (then the rules below alone, whose termination is Murty's).
    const bool guess_now = stats.passes == 1 || stats.passes - guessed_at >= kPassesBeforeNewGuess;
    if (!options.least_index_only && options.guess_sweeps > 0 && guess_now && guesses <= options.guess_restarts) {
      if (guesses++ > 0) sweeps *= 4;
      // The first guess starts from the caller's z, not from the failed pass: a warm start that was right
      // but for a few rows pulls a whole chain of contacts negative in its pass, and sweeps from that
      // (negative entries set to 0) would lose the chain (the landing column of 1024: 521 passes in one
      // step, against 10).
      if (stats.passes == 1)
        for (int a = 0; a < m; ++a) z(rows[static_cast<std::size_t>(a)]) = z_start_(a);
      guess_by_gauss_seidel(rows, q, z, sweeps);
      guessed_at = stats.passes;
      best = m + 1;
      retries = std::max(0, options.block_retries);
      continue;
    }
    if (infeasible < best && !options.least_index_only) {
      best = infeasible;
      retries = std::max(0, options.block_retries);
    } else if (retries > 0 && !options.least_index_only) {
      --retries;
    } else {
      // Murty's least-index rule: only the infeasible row of largest index changes sides.
      ++stats.murty_pivots;
      char& role = role_[static_cast<std::size_t>(last)];
      role = role == 2 ? 1 : 2;
      continue;
    }
    // Rows leaving F: those whose z is at least removal_fraction as negative as the most negative one
    // (all of them when it is 0). A wrong row in F pulls z negative along a whole chain of
    // contacts; removing only the chain's few strongly negative rows keeps the rest of a good guess.
    double most_negative = 0.0;
    for (int r : rows)
      if (role_[static_cast<std::size_t>(r)] == 2) most_negative = std::min(most_negative, z(r));
    const double leave_below = std::min(-tol_z, options.removal_fraction * most_negative);
    for (int r : rows) {
      char& role = role_[static_cast<std::size_t>(r)];
      const bool bad = role == 2 ? z(r) < leave_below : w(r) < -tol_w;
      if (bad) role = role == 2 ? 1 : 2;
    }
  }

  double residual = 0.0;
  for (int r : rows) {
    residual = std::max(residual, std::abs(std::min(z(r), w(r))));
    in_F[static_cast<std::size_t>(r)] = role_[static_cast<std::size_t>(r)] == 2;
    role_[static_cast<std::size_t>(r)] = 0;
  }
  stats.residual = q_inf > 0.0 ? residual / q_inf : residual;
  return accepted;
}

}  // namespace moreau
