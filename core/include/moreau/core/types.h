// Vector and matrix types of the core. N is the number of degrees of freedom, known at compile time for
// small systems (fixed-size Eigen: no allocation, unrolled loops) or Eigen::Dynamic.
#pragma once

#include <Eigen/Dense>

namespace moreau {

template <int N>
using Vec = Eigen::Matrix<double, N, 1>;
template <int N>
using Mat = Eigen::Matrix<double, N, N>;

// Everything one step of (0.2) needs from the model at (t_k, Q^k, V^k).
template <int N>
struct LagrangianTerms {
  Mat<N> M;  // M(Q^k), symmetric positive definite
  Mat<N> C;  // C(Q^k, V^k), centrifugal and Coriolis matrix
  Vec<N> g;  // grad V(Q^k) + F(t_k, Q^k, V^k): the smooth generalized forces of (0.1)

  void resize(int n) {
    M.setZero(n, n);
    C.setZero(n, n);
    g.setZero(n);
  }
};

// sums(i) = sum_j |A(i, j)|, accumulated column by column: contiguous and vectorised for the
// column-major storage, where a row-by-row sum strides across the whole matrix. Each row is still summed
// in the order j = 0, 1, ..., n - 1. For dynamic sizes (n > 4), where the cost is n^2 per step.
template <int N>
void abs_row_sums(const Mat<N>& A, Vec<N>& sums) {
  sums.setZero(A.rows());
  for (Eigen::Index j = 0; j < A.cols(); ++j) sums += A.col(j).cwiseAbs();
}

}  // namespace moreau
