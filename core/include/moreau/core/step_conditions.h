// Hypotheses of Adly, Brogliato and Le (2016) checked at every step, from the M(Q^k) and C(Q^k, V^k)
// the step has already evaluated (no extra model evaluation):
//
//  - Assumption 3.1 (M_1) at the visited states: M(Q^k) positive definite, lambda_min(M(Q^k)) > 0. A
//    run whose M stops being positive definite is stopped: (0.2) is then not the scheme of the paper and
//    its kinetic energy can be negative.
//  - Theorem 4.1, condition (4.2): h_k k3 ||V^k|| <= k1 / 2, which makes B^k of (4.3) monotone and hence
//    the step (0.2) uniquely solvable. Checked with the constants at the step itself,
//    k1 = lambda_min(M(Q^k)) and k3 ||V^k|| = ||C(Q^k, V^k)||_2 (the bound (4.1) with equality), as the
//    ratio r_k = 2 h_k ||C(Q^k, V^k)||_2 / lambda_min(M(Q^k)); (4.2) holds when r_k <= 1. The rule
//    "theorem-4.1" chooses h_k so that r_k <= 1; the rule "fixed" does not, and this check is what says
//    whether its steps were covered by the theorem.
//
// Cost: closed forms for n = 1 and 2 (one square root for lambda_min(M); two more for ||C||_2, only on the
// steps where r_k may exceed the largest ratio recorded so far, see check()). For larger n, certified
// two-sided bounds first, and eigenvalues only when the bounds cannot decide (r_k <= 1, or r_k > 1 +
// round-off, for certain):
//  - lambda_min(M) >= Gershgorin's bound, and ||C||_2^2 <= ||C||_1 ||C||_inf;
//  - lambda_min(M) <= x^T M x and ||C||_2^2 >= ||C u||^2 for unit x and u (Rayleigh quotients). x and u
//    track the eigenvectors of lambda_min(M) and of ||C||_2^2 (of C^T C): set by the last eigenvalue
//    computation and moved at every step by one step of inverse iteration (x) and of power iteration
//    (u), so they follow M(Q^k) and C(Q^k, V^k) as these move by O(h) per step, and the quotients'
//    error is quadratic in the vectors' error;
//  - lambda_min(M) > s = (1 - 1e-3) x^T M x when M - s I has a Cholesky factor (a symmetric matrix is
//    positive definite iff it has one), and ||C||_2^2 < t = (1 + 1e-3)^2 ||C u||^2 when t I - C^T C has.
// So where a certificate decided, a recorded lambda_min is within 0.1% below the true one, an upper
// bound of r_k within about 0.2% above it, and where (4.2) fails for certain the recorded r_k is a lower
// bound from the Rayleigh quotients; StepCheck says which values are bounds. Cholesky in floating point is backward stable, so
// a certificate holds unless M is so ill conditioned that 1e-3 lambda_min(M) is below about
// n eps ||M||_2 (a condition number above ~1e12).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "moreau/core/run_summary.h"
#include "moreau/core/types.h"
#include "moreau/platform/number_text.h"

namespace moreau {

// lambda_min(M) (or a positive lower bound that proves definiteness) and r_k^2 of (4.2) for one step, as
// the fraction ratio_sq_num / ratio_sq_den (valid when lambda_min_m > 0).
struct StepCheck {
  double lambda_min_m = 0.0;                 // > 0: M(Q^k) is positive definite (exact for n <= 2, else exact or a lower bound)
  bool exact = true;                         // lambda_min_m is lambda_min(M) itself (false: a certified lower bound)
  double ratio_sq_num = 0.0;                 // (2 h_k ||C||_2)^2, or a bound of it (ratio_kind)
  double ratio_sq_den = 1.0;                 // lambda_min(M)^2, or a bound of it
  BoundKind ratio_kind = BoundKind::kExact;  // kUpperBound: r_k <= ratio() <= 1; kLowerBound: r_k >= ratio() > 1
  double ratio() const { return std::sqrt(ratio_sq_num / ratio_sq_den); }
};

// Why a run stops when M(Q^k) is not positive definite, naming q (the recorder adds the step and t).
// q is written to read back exactly (the state where the run stopped), lambda_min to 6 digits.
inline std::string not_positive_definite(double lambda_min, const double* q, int n) {
  std::string why = "M(q) is not positive definite (Assumption 3.1): lambda_min(M) = " + platform::significant(lambda_min, 6) + " at q = (";
  for (int i = 0; i < n; ++i) {
    if (i) why += ", ";
    why += platform::shortest(q[i]);
  }
  return why + ")";
}

template <int N>
class StepConditionChecker {
 public:
  explicit StepConditionChecker(int n) : llt_(sized_llt(n)) {
    if constexpr (N == Eigen::Dynamic) {
      CtC_.resize(n, n);
      shifted_.resize(n, n);
      sums_.resize(n);
      x_.resize(n);
      u_.resize(n);
      w_.resize(n);
    }
  }

  // M's definiteness only (Moreau-Jean, which has no condition (4.2)): lambda_min(M) or a certified
  // lower bound (exact says which).
  double lambda_min(const Mat<N>& M, bool& exact) {
    exact = true;
    if constexpr (N == 1) {
      return M(0, 0);
    } else if constexpr (N == 2) {
      return min_eig2(M(0, 0), 0.5 * (M(0, 1) + M(1, 0)), M(1, 1));
    } else {
      exact = false;
      double lo = gershgorin_lower(M), up = std::numeric_limits<double>::infinity();
      if (lo > 0.0) return lo;
      bound_lambda_min(M, lo, up);
      if (lo > 0.0) return lo;
      return lambda_min_exact(M, exact);
    }
  }

  // Both checks at (Q^k, V^k) with step h. For n <= 2 at most three square roots and no division. r_k^2
  // matters only where it may exceed ratio_sq_ceiling (StepConditionTrack::ceiling: the largest ratio
  // recorded so far, capped at 1, less a margin; recording a ratio below it changes nothing). For n = 2,
  // where the upper bound 4 h^2 ||C||_F^2 / lambda_min(M)^2 is below it, that bound is returned
  // (kUpperBound) without the closed form of ||C||_2: most steps of a run.
  // band >= 0: M and C are zero beyond it from the diagonal, and the bounds read the band only (the same
  // values: the entries left out add |0.0|).
  StepCheck check(const Mat<N>& M, const Mat<N>& C, double h, double ratio_sq_ceiling, int band = -1) {
    StepCheck c;
    const double h2 = 4.0 * h * h;
    if constexpr (N == 1) {
      c.lambda_min_m = M(0, 0);
      c.ratio_sq_num = h2 * C(0, 0) * C(0, 0);
    } else if constexpr (N == 2) {
      c.lambda_min_m = min_eig2(M(0, 0), 0.5 * (M(0, 1) + M(1, 0)), M(1, 1));
      const double f2 = C.squaredNorm();
      if (h2 * f2 <= ratio_sq_ceiling * (c.lambda_min_m * c.lambda_min_m)) {
        c.ratio_sq_num = h2 * f2;  // ||C||_2 <= ||C||_F
        c.ratio_sq_den = c.lambda_min_m * c.lambda_min_m;
        c.ratio_kind = BoundKind::kUpperBound;
        return c;
      }
      // ||C||_2^2 = lambda_max(C^T C) = (||C||_F^2 + sqrt(||C||_F^4 - 4 det(C)^2)) / 2.
      const double det = C(0, 0) * C(1, 1) - C(0, 1) * C(1, 0);
      c.ratio_sq_num = h2 * 0.5 * (f2 + std::sqrt(std::max(0.0, f2 * f2 - 4.0 * det * det)));
    } else {
      // Bounds first (see the top of this file); exact values only where the bounds cannot decide.
      const double g = gershgorin_lower(M, band);
      const double c2_bound = max_abs_column_sum(C, band) * max_abs_row_sum(C, band);
      if (g > 0.0 && h2 * c2_bound <= g * g) {
        c.lambda_min_m = g;
        c.exact = false;
        c.ratio_sq_num = h2 * c2_bound;
        c.ratio_sq_den = g * g;
        c.ratio_kind = BoundKind::kUpperBound;
        return c;
      }
      // lambda_min(M) in [lam_lo, lam_up] and ||C||_2^2 in [c2_lo, c2_up].
      double lam_lo = g, lam_up = std::numeric_limits<double>::infinity();
      bound_lambda_min(M, lam_lo, lam_up);
      double c2_lo = 0.0, c2_up = c2_bound;
      if (have_u_) {
        w_.noalias() = C * u_;
        c2_lo = w_.squaredNorm();
        u_.noalias() = C.transpose() * w_;  // one power step for the next steps
        if (u_.squaredNorm() > 0.0) {
          u_.normalize();
        } else {
          have_u_ = false;
        }
        const double t = (1.0 + kMargin) * (1.0 + kMargin) * c2_lo;
        if (lam_lo > 0.0 && h2 * c2_up > lam_lo * lam_lo && t < c2_up && h2 * t <= lam_lo * lam_lo && norm_sq_below(C, t)) c2_up = t;
      }
      constexpr double kViolation = (1.0 + StepConditionTrack::kRoundoff) * (1.0 + StepConditionTrack::kRoundoff);
      if (lam_lo > 0.0 && h2 * c2_up <= lam_lo * lam_lo) {
        c.lambda_min_m = lam_lo;  // (4.2) holds, r_k <= ratio()
        c.exact = false;
        c.ratio_sq_num = h2 * c2_up;
        c.ratio_sq_den = lam_lo * lam_lo;
        c.ratio_kind = BoundKind::kUpperBound;
        return c;
      }
      if (lam_lo > 0.0 && h2 * c2_lo > lam_up * lam_up * kViolation) {
        c.lambda_min_m = lam_lo;  // (4.2) fails for certain, r_k >= ratio()
        c.exact = false;
        c.ratio_sq_num = h2 * c2_lo;
        c.ratio_sq_den = lam_up * lam_up;
        c.ratio_kind = BoundKind::kLowerBound;
        return c;
      }
      // Undecided: both exactly, and new vectors for the next steps' bounds.
      c.lambda_min_m = lambda_min_exact(M, c.exact);
      CtC_.noalias() = C.transpose() * C;
      ++eigenvalue_computations_;
      eig_.compute(CtC_, Eigen::ComputeEigenvectors);
      const int last = static_cast<int>(eig_.eigenvalues().size()) - 1;
      u_ = eig_.eigenvectors().col(last);
      have_u_ = true;
      c.ratio_sq_num = h2 * std::max(0.0, eig_.eigenvalues()(last));
    }
    c.ratio_sq_den = c.lambda_min_m * c.lambda_min_m;
    return c;
  }

  // How many eigenvalue problems the checks solved (the certificates' cost model, for tests).
  std::int64_t eigenvalue_computations() const { return eigenvalue_computations_; }

 private:
  // The factorisation's storage sized once (no allocation in compute()), built in place: Eigen's LLT(Index)
  // leaves its `info` unset, so copying or moving it in (as an assignment would) reads an indeterminate
  // enum, which UBSan reports.
  static Eigen::LLT<Mat<N>> sized_llt(int n) {
    if constexpr (N == Eigen::Dynamic) {
      return Eigen::LLT<Mat<N>>(n);
    } else {
      return Eigen::LLT<Mat<N>>();
    }
  }
  static double min_eig2(double a, double b, double d) {
    const double m = 0.5 * (a + d), e = 0.5 * (a - d);
    return m - std::sqrt(e * e + b * b);
  }
  // Dynamic sizes sum the rows column by column (abs_row_sums, types.h); fixed sizes keep the row sums
  // they always had, so the recorded bounds of small scenes stay bit for bit the same.
  double gershgorin_lower(const Mat<N>& M, int band = -1) {
    double g = std::numeric_limits<double>::infinity();
    if constexpr (N == Eigen::Dynamic) {
      abs_row_sums(M, sums_, band);
      for (int i = 0; i < M.rows(); ++i) g = std::min(g, M(i, i) - (sums_(i) - std::abs(M(i, i))));
    } else {
      for (int i = 0; i < M.rows(); ++i) g = std::min(g, M(i, i) - (M.row(i).cwiseAbs().sum() - std::abs(M(i, i))));
    }
    return g;
  }
  double max_abs_row_sum(const Mat<N>& C, int band = -1) {
    if constexpr (N == Eigen::Dynamic) {
      abs_row_sums(C, sums_, band);
      return sums_.maxCoeff();
    } else {
      return C.cwiseAbs().rowwise().sum().maxCoeff();
    }
  }
  // max_j sum_i |C(i, j)|, over the band when band >= 0 (the same sums up to the order of their
  // additions: an ulp).
  double max_abs_column_sum(const Mat<N>& C, int band = -1) {
    if (band < 0 || C.cols() == 0) return C.cwiseAbs().colwise().sum().maxCoeff();
    double largest = 0.0;
    for_each_band_segment(C, band, [&](Eigen::Index j, Eigen::Index first, Eigen::Index length) {
      largest = std::max(largest, C.col(j).segment(first, length).cwiseAbs().sum());
    });
    return largest;
  }
  double lambda_min_exact(const Mat<N>& M, bool& exact) {
    ++eigenvalue_computations_;
    eig_.compute(M, Eigen::ComputeEigenvectors);
    x_ = eig_.eigenvectors().col(0);
    have_x_ = true;
    exact = true;
    return eig_.eigenvalues()(0);
  }
  // Tightens lo <= lambda_min(M) <= up with the Rayleigh quotient of x_ and the Cholesky certificate just
  // below it, and moves x_ by one step of inverse iteration with that factor.
  void bound_lambda_min(const Mat<N>& M, double& lo, double& up) {
    if (!have_x_) return;
    w_.noalias() = M * x_;
    up = x_.dot(w_);
    const double s = (1.0 - kMargin) * up;
    if (s > lo && exceeds(M, s)) {
      lo = s;
      llt_.solveInPlace(x_);
      x_.normalize();
    }
  }
  // M - s I positive definite (so lambda_min(M) > s): it has a Cholesky factor.
  bool exceeds(const Mat<N>& M, double s) {
    shifted_ = M;
    shifted_.diagonal().array() -= s;
    llt_.compute(shifted_);
    return llt_.info() == Eigen::Success;
  }
  // t I - C^T C positive definite (so ||C||_2^2 < t).
  bool norm_sq_below(const Mat<N>& C, double t) {
    shifted_.noalias() = -C.transpose() * C;
    shifted_.diagonal().array() += t;
    llt_.compute(shifted_);
    return llt_.info() == Eigen::Success;
  }

  // The certificates' relative margin below the Rayleigh quotient of M and above that of C^T C.
  static constexpr double kMargin = 1e-3;
  Vec<N> x_, u_, w_;  // unit vectors near the eigenvectors of lambda_min(M) and of ||C||_2^2; scratch
  bool have_x_ = false, have_u_ = false;
  std::int64_t eigenvalue_computations_ = 0;
  Mat<N> CtC_, shifted_;
  Eigen::LLT<Mat<N>> llt_;
  Vec<N> sums_;
  Eigen::SelfAdjointEigenSolver<Mat<N>> eig_;
};

}  // namespace moreau
