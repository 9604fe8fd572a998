// Exact rational arithmetic on a realisation (A, B, C) given in doubles, for the deciders of
// absolute_stability.cc. Every finite double is a dyadic rational m 2^e, so the matrices as stored have
// exact rational entries, and ranks, characteristic polynomials, Routh arrays, definiteness and Sturm
// sequences computed from them in rational arithmetic answer the question for those matrices with no
// round-off at all. Boost.Multiprecision (header-only, already a dependency of core) supplies the
// integers and rationals. Costs grow quickly with n (the entries of A^k B have about k times the bits of
// A's): used for small realisations only (absolute_stability.cc says how small).
#pragma once

#include <vector>

#include <Eigen/Dense>
#include <boost/multiprecision/cpp_int.hpp>

namespace moreau::lti_exact {

// Without expression templates: every operation yields a value (no references to temporaries).
using Integer = boost::multiprecision::number<boost::multiprecision::cpp_int_backend<>, boost::multiprecision::et_off>;
using Rational = boost::multiprecision::number<boost::multiprecision::rational_adaptor<boost::multiprecision::cpp_int_backend<>>,
                                               boost::multiprecision::et_off>;

// The exact value of a finite double.
Rational to_rational(double x);
double to_double(const Rational& x);

// A dense matrix of rationals, row-major.
struct Matrix {
  int rows = 0, cols = 0;
  std::vector<Rational> a;
  Matrix() = default;
  Matrix(int r, int c) : rows(r), cols(c), a(static_cast<std::size_t>(r) * c) {}
  Rational& operator()(int i, int j) { return a[static_cast<std::size_t>(i) * cols + j]; }
  const Rational& operator()(int i, int j) const { return a[static_cast<std::size_t>(i) * cols + j]; }
  static Matrix from(const Eigen::MatrixXd& X);
  static Matrix identity(int n);
  Matrix transpose() const;
};
Matrix operator*(const Matrix& X, const Matrix& Y);
Matrix operator+(const Matrix& X, const Matrix& Y);

// Rank by Gaussian elimination over Q.
int rank(Matrix X);
// X symmetric positive definite: every pivot of Gaussian elimination without pivoting is > 0
// (Sylvester's criterion). X must be symmetric.
bool positive_definite(Matrix X);
bool symmetric(const Matrix& X);
// The determinant by Gaussian elimination over Q.
Rational determinant(Matrix X);

// A polynomial with rational coefficients, from the constant term up; no trailing zeros (the zero
// polynomial is empty).
using Poly = std::vector<Rational>;
int degree(const Poly& p);  // -1 for the zero polynomial
Rational evaluate(const Poly& p, const Rational& x);

// The characteristic polynomial d(s) = det(sI - A) = s^n + c_1 s^{n-1} + ... + c_n and the adjugate
// adj(sI - A) = sum_{k<n} M_k s^{n-1-k}, by the Faddeev-LeVerrier recursion M_0 = I,
// c_k = -tr(A M_{k-1}) / k, M_k = A M_{k-1} + c_k I (exact over Q).
struct Resolvent {
  Poly d;                 // degree n, monic
  std::vector<Matrix> M;  // M_0 .. M_{n-1}
};
Resolvent resolvent(const Matrix& A);

// Routh's test: every root of p (of positive leading coefficient or not) has negative real part. Exact:
// a zero or a sign change in the first column of the Routh array means a root with Re >= 0.
bool hurwitz(const Poly& p);

// The positive real roots of a polynomial q (not identically 0, q(0) != 0), each to within the spacing
// of doubles: Sturm's theorem on the square-free part of q isolates them, bisection refines them.
struct RootInterval {
  Rational lo, hi;  // lo < root < hi, or lo == hi == root
};
std::vector<RootInterval> positive_roots(const Poly& q);

}  // namespace moreau::lti_exact
