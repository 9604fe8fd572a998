// The floating-point numerics behind the deciders of core/absolute_stability.h: balancing, the Popov
// function's value and crossing candidates, PBH margins, the search for a certificate P, and the
// formatting of their numbers. Apart from absolute_stability.cc so that neither translation unit
// instantiates all of Eigen's dense and complex solvers at once (the build's largest unit before).
#pragma once

#include <complex>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "moreau/core/absolute_stability.h"

namespace moreau::lti_detail {

constexpr double kEps = std::numeric_limits<double>::epsilon();
using Complex = std::complex<double>;

// (1 + (w/wc)^2) lambda_min(Phi(jw)) and a bound on its round-off: the solve of (jwI - A) X = B loses
// about eps cond(jwI - A) relative to |X|, and Phi = C X + (C X)^H inherits it scaled by |C|.
struct PopovValue {
  double value = 0.0;
  double tolerance = 0.0;
};

// A diagonal similarity x = D x_b with D = diag(d), d_i powers of two: A_b = D^-1 A D, B_b = D^-1 B,
// C_b = C D, computed without rounding (only exponents change). Parlett and Reinsch's iteration (as in
// LAPACK's gebal) on [A B; C 0] with only the state coordinates scaled: each step brings the norm of a
// state's column of [A; C] and of its row of [A, B] (off the diagonal) within a factor of 2 of each other.
struct Balanced {
  Eigen::MatrixXd A, B, C;
  Eigen::VectorXd d;
  bool identity = true;
};

// A certificate P on {P = P^T, B^T P = C} (see the header): the search and its check.
struct Certificate {
  Verdict verdict = Verdict::kNotChecked;
  Eigen::MatrixXd P;
  StorageMatrixCheck check;
  std::string method;
};

int exponent_spread(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);
std::string why_not_exact(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);
double max_abs(const Eigen::MatrixXd& X);
Eigen::VectorXd sym_eigenvalues(const Eigen::MatrixXd& S);
PopovValue popov_value(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C, double w, double wc);
double pbh_margin(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::VectorXcd& eigenvalues);
Verdict banded(double value, double fails_below, double holds_above);
std::vector<double> crossing_candidates(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);
Balanced balance(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);
std::string exact_text(double v);
std::string g6(double v);
std::string g3(double v);
Certificate search_certificate(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

}  // namespace moreau::lti_detail
