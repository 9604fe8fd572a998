// LDL^T of a principal submatrix A_FF of a symmetric sparse A whose entries lie within a small bandwidth
// b of its diagonal (a chain's or a bar's P = M/h + W, a stack's or a column's Delassus operator): F
// increasing keeps A_FF within b of its diagonal (its rows' coordinates are at least as far apart), so
// the factor is a band too. O(|F| b^2), no symbolic phase and no allocation after reserve(): what a step
// that changes its moving (or closed) set costs, where Eigen's sparse LDL^T spent most of its time in
// its symbolic analysis and allocations (measured: docs/scaling.md). Used by sparse_one_step_solver.h,
// which beyond kMaxBandwidth uses Eigen's sparse LDL^T with a minimum-degree order. (sparse_lcp.h keeps
// Eigen's natural-order LDL^T for banded D: with this one the granular column of 4 came to rest exactly one
// step later than on the dense step, a round-off difference in the polished velocity; not adopted there.)
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

namespace moreau {

// max |i - j| over the stored entries of A: the band within which BandedLdlt factorises.
int bandwidth(const Eigen::SparseMatrix<double>& A);

class BandedLdlt {
 public:
  static constexpr int kMaxBandwidth = 8;

  // Sizes the factor for submatrices of up to n rows of a matrix of bandwidth b <= kMaxBandwidth.
  void reserve(int n, int b);
  // Factorises A_FF, A symmetric with both triangles stored (column-major), F increasing. `local`: one
  // entry per row of A, all -1 (the caller's, reused), all -1 again on return. False when a pivot is not
  // above 64 eps times A_FF's largest diagonal entry (not positive definite within round-off).
  bool factorise(const Eigen::SparseMatrix<double>& A, const std::vector<int>& F, std::vector<int>& local);
  // x <- A_FF^{-1} x (x of |F| entries, a segment of a longer vector allowed), from the last factorisation.
  void solve(Eigen::Ref<Eigen::VectorXd> x) const;

 private:
  int b_ = 0;
  std::vector<double> L_;  // L(a, a - 1 - k) at a * b_ + k
  Eigen::VectorXd D_;
};

}  // namespace moreau
