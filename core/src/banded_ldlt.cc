// LDL^T within a band (banded_ldlt.h).
#include "moreau/core/banded_ldlt.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace moreau {

int bandwidth(const Eigen::SparseMatrix<double>& A) {
  int b = 0;
  for (int j = 0; j < A.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) b = std::max(b, static_cast<int>(std::abs(it.row() - j)));
  return b;
}

void BandedLdlt::reserve(int n, int b) {
  b_ = std::clamp(b, 0, kMaxBandwidth);
  L_.assign(static_cast<std::size_t>(std::max(n, 0)) * static_cast<std::size_t>(std::max(b_, 1)), 0.0);
  D_.setZero(std::max(n, 0));
}

// Row a of L: L(a, c) = (A_FF(a, c) - sum_{k < c} L(a, k) D(k) L(c, k)) / D(c) for c in [a - b, a), then
// D(a) = A_FF(a, a) - sum_k L(a, k)^2 D(k).
bool BandedLdlt::factorise(const Eigen::SparseMatrix<double>& A, const std::vector<int>& F, std::vector<int>& local) {
  const int f = static_cast<int>(F.size()), b = b_;
  for (int a = 0; a < f; ++a) local[static_cast<std::size_t>(F[static_cast<std::size_t>(a)])] = a;
  double largest = 0.0, smallest_pivot = std::numeric_limits<double>::infinity();
  double row[kMaxBandwidth + 1];  // A_FF(a, a - 1 - k) at row[k], k < b; the diagonal at row[b]
  bool finite = true;
  for (int a = 0; a < f && finite; ++a) {
    std::fill(row, row + b + 1, 0.0);
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, F[static_cast<std::size_t>(a)]); it; ++it) {  // its row, A symmetric
      const int c = local[static_cast<std::size_t>(it.row())];
      if (c < 0 || c > a || a - c > b) continue;
      row[c == a ? b : a - 1 - c] = it.value();
    }
    double* La = L_.data() + static_cast<std::ptrdiff_t>(a) * b;
    for (int c = std::max(0, a - b); c < a; ++c) {
      const double* Lc = L_.data() + static_cast<std::ptrdiff_t>(c) * b;
      double sum = row[a - 1 - c];
      for (int k = std::max(0, a - b); k < c; ++k) sum -= La[a - 1 - k] * D_(k) * Lc[c - 1 - k];
      La[a - 1 - c] = sum / D_(c);
    }
    double d = row[b];
    largest = std::max(largest, std::abs(row[b]));
    for (int k = std::max(0, a - b); k < a; ++k) d -= La[a - 1 - k] * La[a - 1 - k] * D_(k);
    D_(a) = d;
    smallest_pivot = std::min(smallest_pivot, d);
    finite = std::isfinite(d);
  }
  for (int i : F) local[static_cast<std::size_t>(i)] = -1;
  return finite && smallest_pivot > 64.0 * std::numeric_limits<double>::epsilon() * largest;
}

void BandedLdlt::solve(Eigen::Ref<Eigen::VectorXd> x) const {
  const int f = static_cast<int>(x.size()), b = b_;
  for (int a = 0; a < f; ++a) {  // L z = x
    const double* La = L_.data() + static_cast<std::ptrdiff_t>(a) * b;
    double sum = x(a);
    for (int k = std::max(0, a - b); k < a; ++k) sum -= La[a - 1 - k] * x(k);
    x(a) = sum;
  }
  for (int a = 0; a < f; ++a) x(a) /= D_(a);  // D
  for (int a = f - 1; a >= 0; --a) {          // L^T y = z
    double sum = x(a);
    for (int c = a + 1; c <= std::min(f - 1, a + b); ++c) sum -= L_[static_cast<std::size_t>(c) * b + (c - 1 - a)] * x(c);
    x(a) = sum;
  }
}

}  // namespace moreau
