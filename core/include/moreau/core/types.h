// Vector and matrix types of the core. N is the number of degrees of freedom, known at compile time for
// small systems (fixed-size Eigen: no allocation, unrolled loops) or Eigen::Dynamic.
#pragma once

#include <algorithm>

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

// Calls f(j, first, length) for each column j of A with the rows first .. first + length - 1 of its band
// |i - j| <= band.
template <class Matrix, class F>
void for_each_band_segment(const Matrix& A, int band, F&& f) {
  const Eigen::Index n = A.rows(), b = band;
  for (Eigen::Index j = 0; j < A.cols(); ++j) {
    const Eigen::Index first = std::max<Eigen::Index>(0, j - b), last = std::min<Eigen::Index>(n - 1, j + b);
    if (last >= first) f(j, first, last - first + 1);
  }
}

// sums(i) = sum_j |A(i, j)|, accumulated column by column: contiguous and vectorised for the
// column-major storage, where a row-by-row sum strides across the whole matrix. Each row is still summed
// in the order j = 0, 1, ..., n - 1. For dynamic sizes (n > 4), where the cost is n^2 per step.
//
// band >= 0: A is zero beyond `band` from its diagonal (a scene's banded M, C and P: AblSettings::bandwidth),
// and only the band is read, O(n band): the same sums bit for bit, since the entries left out add |0.0|.
template <int N>
void abs_row_sums(const Mat<N>& A, Vec<N>& sums, int band = -1) {
  sums.setZero(A.rows());
  if (band < 0) {
    for (Eigen::Index j = 0; j < A.cols(); ++j) sums += A.col(j).cwiseAbs();
    return;
  }
  for_each_band_segment(A, band, [&](Eigen::Index j, Eigen::Index first, Eigen::Index length) {
    sums.segment(first, length) += A.col(j).segment(first, length).cwiseAbs();
  });
}

// Whether every entry of A is finite, reading only its band when band >= 0 (A zero beyond it).
template <int N>
bool all_finite(const Mat<N>& A, int band = -1) {
  if (band < 0) return A.allFinite();
  bool finite = true;
  for_each_band_segment(A, band, [&](Eigen::Index j, Eigen::Index first, Eigen::Index length) {
    finite = finite && A.col(j).segment(first, length).allFinite();
  });
  return finite;
}

}  // namespace moreau
