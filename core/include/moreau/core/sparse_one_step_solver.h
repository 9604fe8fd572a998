// The one-step inclusion (6.5) of the scheme (0.2) at scale, for a separable phi:
//
//   P y + x  in  -d phi(y),     phi(y) = sum_i a_i |y_i|,                                   (6.5)
//
// with P = M/h + W symmetric positive definite and sparse (large_abl_system.h: M constant and banded or
// sparse, W diagonal), so that (6.5) has exactly one solution (Theorem 4.1) and is the box-constrained
// LCP "P y + x + s = 0, s_i in a_i Sgn(y_i)" of a P-matrix.
//
// Method: the dense solver's exact pivoting (one_step_solver.h, principal_pivoting), on sparse matrices.
//  1. Closed form of Lemma 6.1: y = 0 when -x lies in d phi(0) (|x_i| <= a_i for every i): every
//     component exactly 0.0, no linear solve.
//  2. Block principal pivoting with the safeguard of Judice and Pires (Comput. Oper. Res. 21, 1994): a
//     sign pattern s in {-1, 0, +1}^n fixes y_i = 0.0 where s_i = 0 (and a_i > 0) and, on the moving set
//     F, P_FF y_F = -(x_F + a_F s_F); a component breaks the pattern when it moves with the wrong sign or
//     rests with its multiplier -(P y + x)_i outside [-a_i, a_i]. While the count of broken components
//     falls, all of them change state at once; after kTries passes without a new lowest count, only the
//     one of least index (Murty's rule, finite for P-matrices), until the count falls below its lowest.
//     Warm-started from the previous call's pattern, which a bar that moves or rests as it did in the
//     last step keeps: one pass, and the factor of P_FF is reused (two triangular solves).
// Exact like the dense path: the answer is a pattern's own solution, 0.0 where a component rests, and it
// is accepted only when dist(-(P y + x), d phi(y)) is within the round-off of the problem's scale (64 eps
// (|x|_inf + |P|_inf |y|_inf + max a_i), the dense solver's allowance); otherwise solve() returns false.
//
// Cost: a pass is O(nnz(P)) plus, when F differs from the factorised set, an LDL^T of P_FF: for P within
// BandedLdlt::kMaxBandwidth of its diagonal (a chain's, a bar's), the band's own (banded_ldlt.h, O(|F| b^2),
// no symbolic phase, no allocation); beyond, Eigen's sparse LDL^T with a minimum-degree order.
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <cstdint>
#include <vector>

#include "moreau/core/banded_ldlt.h"
#include "moreau/core/one_step_solver.h"

namespace moreau {

class SparseOneStepSolver {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;  // column-major, both triangles stored

  // P symmetric positive definite; gains a_i >= 0. Resets the warm start and the factor.
  void configure(const SparseMatrix& P, const Eigen::VectorXd& gains);
  // Solves (6.5) for y (resized). False when no pattern was accepted (P not positive definite to working
  // precision, non-finite data, or the pass budget spent, which the termination rule rules out in exact
  // arithmetic): the caller must not use y.
  bool solve(const Eigen::VectorXd& x, Eigen::VectorXd& y, OneStepStats& stats);

  int size() const { return static_cast<int>(P_.rows()); }
  // The sign pattern of the last answer (0: at rest; +1, -1: moving that way).
  const std::vector<std::int8_t>& pattern() const { return pattern_; }
  std::int64_t factorisations() const { return factorisations_; }
  // Whether P_FF is factorised within its band (P's bandwidth at most kBandedBandwidth), and that band.
  bool banded_factor() const { return banded_; }
  int bandwidth() const { return band_; }

 private:
  bool solve_pattern(const Eigen::VectorXd& x, Eigen::VectorXd& y);  // y of pattern_, w_ = -(P y + x)
  bool factorise();
  bool breaks(int i, const Eigen::VectorXd& y, double tol) const {
    if (!(a_(i) > 0.0)) return false;
    return pattern_[static_cast<std::size_t>(i)] != 0 ? y(i) * pattern_[static_cast<std::size_t>(i)] < 0.0 : std::abs(w_(i)) > a_(i) + tol;
  }
  double residual(const Eigen::VectorXd& y) const;  // dist(w_, d phi(y)), componentwise, max over i

  SparseMatrix P_;
  Eigen::VectorXd a_;
  double p_norm_inf_ = 0.0, a_max_ = 0.0;
  std::vector<std::int8_t> pattern_;
  std::vector<int> F_, factored_F_, local_;
  bool factor_valid_ = false;
  bool banded_ = false;
  std::int64_t factorisations_ = 0;
  SparseMatrix pff_;
  std::vector<Eigen::Triplet<double>> triplets_;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt_;
  int band_ = 0;            // P's bandwidth
  BandedLdlt banded_ldlt_;  // P_FF within its band (banded_)
  Eigen::VectorXd rhs_, yf_, w_;
};

}  // namespace moreau
