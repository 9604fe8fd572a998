// Solves A x = b for the leading r x r block of A by LU with partial pivoting, in place: A is overwritten
// by its factors and b by x. For the small dense systems of the one-step problems whose size changes from
// step to step: the free components of a piece pattern (graph_inclusion_solver.h) and the contacts of an
// impact (moreau_jean_integrator.h).
//
// Why not Eigen::PartialPivLU: it factorises a matrix of its own, sized at compile time or allocated at
// run time, so a system whose size changes every step would allocate every step. This works on the leading
// block of storage sized once.
//
// The arithmetic is Eigen 3.4's for a dynamic-size matrix, operation for operation: the unblocked
// factorisation (pivot: the first entry of largest |a_ik| in column k at or below the diagonal; the
// column below it divided by the pivot; the rank-one update a_ij -= l_ik u_kj), and the column-oriented
// substitutions of its triangular solves (an entry of the right-hand side that is exactly 0 skips its
// column). So for r <= 8 the result is bit for bit Eigen's PartialPivLU solve of the same system; for larger
// r Eigen's panelled substitution (r > 8) and blocked factorisation (r > 16) may round differently.
//
// A pivot that is exactly 0 does not stop the solve (as in Eigen): x then holds infinities or NaN unless
// the zero pivot meets a zero right-hand side. The return value says whether every pivot was nonzero.
#pragma once

#include <cmath>
#include <utility>

namespace moreau {

template <class MatrixA, class VectorB>
bool lu_solve_in_place(MatrixA& A, VectorB& b, int r) {
  bool nonsingular = true;
  for (int k = 0; k < r; ++k) {
    int p = k;
    double biggest = std::abs(A(k, k));
    for (int i = k + 1; i < r; ++i) {
      const double a = std::abs(A(i, k));
      if (a > biggest) {
        biggest = a;
        p = i;
      }
    }
    if (biggest != 0.0) {
      if (p != k) {
        for (int j = 0; j < r; ++j) std::swap(A(k, j), A(p, j));
        std::swap(b(k), b(p));  // P b, one transposition at a time in the order they are found
      }
      for (int i = k + 1; i < r; ++i) A(i, k) /= A(k, k);
    } else {
      nonsingular = false;
    }
    for (int j = k + 1; j < r; ++j)
      for (int i = k + 1; i < r; ++i) A(i, j) -= A(i, k) * A(k, j);
  }
  for (int i = 0; i < r; ++i) {  // L y = P b, L unit lower triangular
    if (b(i) == 0.0) continue;
    for (int j = i + 1; j < r; ++j) b(j) -= b(i) * A(j, i);
  }
  for (int i = r - 1; i >= 0; --i) {  // U x = y
    if (b(i) == 0.0) continue;
    b(i) /= A(i, i);
    for (int j = 0; j < i; ++j) b(j) -= b(i) * A(j, i);
  }
  return nonsingular;
}

}  // namespace moreau
