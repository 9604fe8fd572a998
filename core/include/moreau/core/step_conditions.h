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
// Cost: closed forms for n = 1 and 2 (three square roots); for larger n, a Gershgorin lower bound on
// lambda_min(M) and the bound ||C||_2 <= sqrt(||C||_1 ||C||_inf) first, and eigenvalues only when those
// bounds cannot decide. The recorded worst ratio is therefore an upper bound on every r_k of the run
// (exact where eigenvalues were computed, and every violation is exact).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include <Eigen/Eigenvalues>

#include "moreau/core/run_summary.h"
#include "moreau/core/types.h"

namespace moreau {

// lambda_min(M) (or a positive lower bound that proves definiteness) and r_k^2 of (4.2) for one step, as
// the fraction ratio_sq_num / ratio_sq_den (valid when lambda_min_m > 0).
struct StepCheck {
  double lambda_min_m = 0.0;  // > 0: M(Q^k) is positive definite (exact for n <= 2, else exact or a lower bound)
  double ratio_sq_num = 0.0;  // (2 h_k ||C||_2)^2, or an upper bound when the bounds decided
  double ratio_sq_den = 1.0;  // lambda_min(M)^2, or the square of its lower bound
  double ratio() const { return std::sqrt(ratio_sq_num / ratio_sq_den); }
};

// Why a run stops when M(Q^k) is not positive definite, naming q (the recorder adds the step and t).
inline std::string not_positive_definite(double lambda_min, const double* q, int n) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", lambda_min);
  std::string why = std::string("M(q) is not positive definite (Assumption 3.1): lambda_min(M) = ") + buf + " at q = (";
  for (int i = 0; i < n; ++i) {
    std::snprintf(buf, sizeof buf, "%s%.17g", i ? ", " : "", q[i]);
    why += buf;
  }
  return why + ")";
}

template <int N>
class StepConditionChecker {
 public:
  explicit StepConditionChecker(int n) {
    if constexpr (N == Eigen::Dynamic) {
      CtC_.resize(n, n);
      sums_.resize(n);
    }
  }

  // M's definiteness only (Moreau-Jean, which has no condition (4.2)).
  double lambda_min(const Mat<N>& M) {
    if constexpr (N == 1) {
      return M(0, 0);
    } else if constexpr (N == 2) {
      return min_eig2(M(0, 0), 0.5 * (M(0, 1) + M(1, 0)), M(1, 1));
    } else {
      const double g = gershgorin_lower(M);
      if (g > 0.0) return g;
      return exact_lambda_min(M);
    }
  }

  // Both checks at (Q^k, V^k) with step h. For n <= 2 two square roots and no division.
  StepCheck check(const Mat<N>& M, const Mat<N>& C, double h) {
    StepCheck c;
    const double h2 = 4.0 * h * h;
    if constexpr (N == 1) {
      c.lambda_min_m = M(0, 0);
      c.ratio_sq_num = h2 * C(0, 0) * C(0, 0);
    } else if constexpr (N == 2) {
      c.lambda_min_m = min_eig2(M(0, 0), 0.5 * (M(0, 1) + M(1, 0)), M(1, 1));
      // ||C||_2^2 = lambda_max(C^T C) = (||C||_F^2 + sqrt(||C||_F^4 - 4 det(C)^2)) / 2.
      const double f2 = C.squaredNorm();
      const double det = C(0, 0) * C(1, 1) - C(0, 1) * C(1, 0);
      c.ratio_sq_num = h2 * 0.5 * (f2 + std::sqrt(std::max(0.0, f2 * f2 - 4.0 * det * det)));
    } else {
      // Bounds first: lambda_min(M) >= Gershgorin's bound, ||C||_2^2 <= ||C||_1 ||C||_inf.
      const double g = gershgorin_lower(M);
      const double c2_bound = C.cwiseAbs().colwise().sum().maxCoeff() * max_abs_row_sum(C);
      if (g > 0.0 && h2 * c2_bound <= g * g) {
        c.lambda_min_m = g;
        c.ratio_sq_num = h2 * c2_bound;
      } else {
        c.lambda_min_m = exact_lambda_min(M);
        CtC_.noalias() = C.transpose() * C;
        eig_.compute(CtC_, Eigen::EigenvaluesOnly);
        c.ratio_sq_num = h2 * std::max(0.0, eig_.eigenvalues()(eig_.eigenvalues().size() - 1));
      }
    }
    c.ratio_sq_den = c.lambda_min_m * c.lambda_min_m;
    return c;
  }

 private:
  static double min_eig2(double a, double b, double d) {
    const double m = 0.5 * (a + d), e = 0.5 * (a - d);
    return m - std::sqrt(e * e + b * b);
  }
  // Dynamic sizes sum the rows column by column (abs_row_sums, types.h); fixed sizes keep the row sums
  // they always had, so the recorded bounds of small scenes stay bit for bit the same.
  double gershgorin_lower(const Mat<N>& M) {
    double g = std::numeric_limits<double>::infinity();
    if constexpr (N == Eigen::Dynamic) {
      abs_row_sums(M, sums_);
      for (int i = 0; i < M.rows(); ++i) g = std::min(g, M(i, i) - (sums_(i) - std::abs(M(i, i))));
    } else {
      for (int i = 0; i < M.rows(); ++i) g = std::min(g, M(i, i) - (M.row(i).cwiseAbs().sum() - std::abs(M(i, i))));
    }
    return g;
  }
  double max_abs_row_sum(const Mat<N>& C) {
    if constexpr (N == Eigen::Dynamic) {
      abs_row_sums(C, sums_);
      return sums_.maxCoeff();
    } else {
      return C.cwiseAbs().rowwise().sum().maxCoeff();
    }
  }
  double exact_lambda_min(const Mat<N>& M) {
    eig_.compute(M, Eigen::EigenvaluesOnly);
    return eig_.eigenvalues()(0);
  }

  Mat<N> CtC_;
  Vec<N> sums_;
  Eigen::SelfAdjointEigenSolver<Mat<N>> eig_;
};

}  // namespace moreau
