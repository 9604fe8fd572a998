#include "lti_exact.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace moreau::lti_exact {

Rational to_rational(double x) {
  if (!std::isfinite(x)) throw std::invalid_argument("lti_exact: a non-finite entry has no rational value");
  if (x == 0.0) return Rational(0);
  int e = 0;
  const double f = std::frexp(x, &e);  // x = f 2^e, 0.5 <= |f| < 1: f 2^53 is an integer
  const auto mantissa = static_cast<long long>(std::ldexp(f, 53));
  e -= 53;
  Integer num(mantissa);
  Integer den(1);
  if (e >= 0) {
    num <<= e;
  } else {
    den <<= -e;
  }
  return Rational(num, den);
}

double to_double(const Rational& x) { return x.convert_to<double>(); }

Matrix Matrix::from(const Eigen::MatrixXd& X) {
  Matrix R(static_cast<int>(X.rows()), static_cast<int>(X.cols()));
  for (int i = 0; i < R.rows; ++i)
    for (int j = 0; j < R.cols; ++j) R(i, j) = to_rational(X(i, j));
  return R;
}

Matrix Matrix::identity(int n) {
  Matrix I(n, n);
  for (int i = 0; i < n; ++i) I(i, i) = 1;
  return I;
}

Matrix Matrix::transpose() const {
  Matrix T(cols, rows);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) T(j, i) = (*this)(i, j);
  return T;
}

Matrix operator*(const Matrix& X, const Matrix& Y) {
  Matrix Z(X.rows, Y.cols);
  for (int i = 0; i < X.rows; ++i)
    for (int k = 0; k < X.cols; ++k) {
      if (X(i, k) == 0) continue;
      for (int j = 0; j < Y.cols; ++j)
        if (Y(k, j) != 0) Z(i, j) += X(i, k) * Y(k, j);
    }
  return Z;
}

Matrix operator+(const Matrix& X, const Matrix& Y) {
  Matrix Z = X;
  for (std::size_t i = 0; i < Z.a.size(); ++i) Z.a[i] += Y.a[i];
  return Z;
}

namespace {

// Row echelon form in place (partial pivoting on non-zero, which is exact over Q); returns the rank and
// the determinant's sign flips through `swaps`.
int eliminate(Matrix& X, int* swaps) {
  int r = 0;
  for (int c = 0; c < X.cols && r < X.rows; ++c) {
    int p = r;
    while (p < X.rows && X(p, c) == 0) ++p;
    if (p == X.rows) continue;
    if (p != r) {
      for (int j = 0; j < X.cols; ++j) std::swap(X(p, j), X(r, j));
      if (swaps) ++*swaps;
    }
    for (int i = r + 1; i < X.rows; ++i) {
      if (X(i, c) == 0) continue;
      const Rational f = X(i, c) / X(r, c);
      for (int j = c; j < X.cols; ++j) X(i, j) -= f * X(r, j);
    }
    ++r;
  }
  return r;
}

}  // namespace

int rank(Matrix X) { return eliminate(X, nullptr); }

bool symmetric(const Matrix& X) {
  if (X.rows != X.cols) return false;
  for (int i = 0; i < X.rows; ++i)
    for (int j = 0; j < i; ++j)
      if (X(i, j) != X(j, i)) return false;
  return true;
}

bool positive_definite(Matrix X) {
  const int n = X.rows;
  for (int k = 0; k < n; ++k) {
    if (X(k, k) <= 0) return false;
    for (int i = k + 1; i < n; ++i) {
      if (X(i, k) == 0) continue;
      const Rational f = X(i, k) / X(k, k);
      for (int j = k; j < n; ++j) X(i, j) -= f * X(k, j);
    }
  }
  return true;
}

Rational determinant(Matrix X) {
  int swaps = 0;
  if (eliminate(X, &swaps) < X.rows) return Rational(0);
  Rational d = swaps % 2 ? -1 : 1;
  for (int i = 0; i < X.rows; ++i) d *= X(i, i);
  return d;
}

int degree(const Poly& p) { return static_cast<int>(p.size()) - 1; }

Rational evaluate(const Poly& p, const Rational& x) {
  Rational v = 0;
  for (auto it = p.rbegin(); it != p.rend(); ++it) v = v * x + *it;
  return v;
}

Resolvent resolvent(const Matrix& A) {
  const int n = A.rows;
  Resolvent r;
  r.d.assign(static_cast<std::size_t>(n + 1), Rational(0));
  r.d[n] = 1;
  Matrix M = Matrix::identity(n);
  for (int k = 1; k <= n; ++k) {
    r.M.push_back(M);
    Matrix AM = A * M;
    Rational trace = 0;
    for (int i = 0; i < n; ++i) trace += AM(i, i);
    const Rational c = -trace / k;
    r.d[n - k] = c;
    for (int i = 0; i < n; ++i) AM(i, i) += c;
    M = std::move(AM);
  }
  while (!r.d.empty() && r.d.back() == 0) r.d.pop_back();
  return r;
}

bool hurwitz(const Poly& p) {
  const int n = degree(p);
  if (n < 0) return false;
  if (n == 0) return true;
  // Rows of the Routh array, highest power first; the first column must keep one strict sign.
  std::vector<Rational> prev, cur;
  for (int k = n; k >= 0; k -= 2) prev.push_back(p[k]);
  for (int k = n - 1; k >= 0; k -= 2) cur.push_back(p[k]);
  const int sign = p[n] > 0 ? 1 : -1;
  for (int row = 1; row <= n; ++row) {
    if (cur.empty() || cur[0] == 0 || (cur[0] > 0 ? 1 : -1) != sign) return false;
    std::vector<Rational> next;
    for (std::size_t j = 0; j + 1 < prev.size(); ++j) {
      const Rational b = j + 1 < cur.size() ? cur[j + 1] : Rational(0);
      next.push_back((cur[0] * prev[j + 1] - prev[0] * b) / cur[0]);
    }
    prev = std::move(cur);
    cur = std::move(next);
  }
  return true;
}

namespace {

// Polynomials with integer coefficients: the Sturm sequence is kept primitive (divided by the positive
// content) so that its coefficients do not swell; a positive factor changes no sign.
using IPoly = std::vector<Integer>;

void trim(Poly& p) {
  while (!p.empty() && p.back() == 0) p.pop_back();
}

IPoly primitive(const Poly& p) {
  Integer l = 1;
  for (const Rational& c : p) l = boost::multiprecision::lcm(l, boost::multiprecision::denominator(c));
  IPoly q;
  Integer g = 0;
  for (const Rational& c : p) {
    q.push_back(boost::multiprecision::numerator(c) * (l / boost::multiprecision::denominator(c)));
    g = boost::multiprecision::gcd(g, q.back());
  }
  if (g > 1)
    for (Integer& c : q) c /= g;
  return q;
}

Poly to_poly(const IPoly& p) { return Poly(p.begin(), p.end()); }

// The remainder of a / b over Q (b not zero).
Poly remainder(Poly a, const Poly& b) {
  const int db = degree(b);
  while (degree(a) >= db) {
    const int shift = degree(a) - db;
    const Rational f = a.back() / b.back();
    for (int i = 0; i <= db; ++i) a[i + shift] -= f * b[i];
    a.pop_back();
    trim(a);
  }
  return a;
}

// The quotient of a / b when b divides a exactly.
Poly quotient(Poly a, const Poly& b) {
  const int db = degree(b);
  Poly q(static_cast<std::size_t>(std::max(0, degree(a) - db + 1)));
  while (degree(a) >= db) {
    const int shift = degree(a) - db;
    const Rational f = a.back() / b.back();
    q[shift] = f;
    for (int i = 0; i <= db; ++i) a[i + shift] -= f * b[i];
    a.pop_back();
    trim(a);
  }
  return q;
}

Poly derivative(const Poly& p) {
  Poly d;
  for (std::size_t i = 1; i < p.size(); ++i) d.push_back(p[i] * static_cast<int>(i));
  trim(d);
  return d;
}

Poly gcd(Poly a, Poly b) {
  while (!b.empty()) {
    Poly r = remainder(a, b);
    a = std::move(b);
    b = to_poly(primitive(r));
  }
  return a;
}

// The sign of p(x) for x = num / den, den > 0: the sign of den^deg p(x) = sum p_i num^i den^(deg - i),
// in integers.
int sign_at(const IPoly& p, const Rational& x) {
  const Integer num = boost::multiprecision::numerator(x), den = boost::multiprecision::denominator(x);
  Integer v = 0;
  Integer dp = 1;
  const int d = static_cast<int>(p.size()) - 1;
  std::vector<Integer> den_pow(static_cast<std::size_t>(d + 1));
  for (int i = 0; i <= d; ++i) {
    den_pow[i] = dp;
    dp *= den;
  }
  for (int i = d; i >= 0; --i) v = v * num + p[i] * den_pow[d - i];
  return v > 0 ? 1 : v < 0 ? -1 : 0;
}

struct Sturm {
  std::vector<IPoly> seq;
  explicit Sturm(const Poly& p) {
    Poly a = p, b = derivative(p);
    seq.push_back(primitive(a));
    while (!b.empty()) {
      seq.push_back(primitive(b));
      Poly r = remainder(a, b);
      for (Rational& c : r) c = -c;
      a = std::move(b);
      b = std::move(r);
    }
  }
  int variations(const Rational& x) const {
    int v = 0, last = 0;
    for (const IPoly& s : seq) {
      const int sg = sign_at(s, x);
      if (sg == 0) continue;
      if (last != 0 && sg != last) ++v;
      last = sg;
    }
    return v;
  }
};

}  // namespace

std::vector<RootInterval> positive_roots(const Poly& q_in) {
  Poly q = q_in;
  trim(q);
  if (degree(q) < 1) return {};
  // The square-free part: every root simple, so it changes sign at each.
  const Poly g = gcd(q, derivative(q));
  if (degree(g) > 0) q = quotient(q, g);
  const IPoly qi = primitive(q);
  const Sturm sturm(q);
  // Cauchy's bound: every root has |u| < 1 + max |q_i / q_deg|.
  Rational bound = 0;
  for (std::size_t i = 0; i + 1 < q.size(); ++i) bound = std::max(bound, Rational(boost::multiprecision::abs(q[i] / q.back())));
  Rational hi = 1;
  while (hi <= bound + 1) hi *= 2;  // a power of two above the bound: short numbers
  std::vector<RootInterval> out;
  // Bisection on (lo, hi] by the number of roots in it, V(lo) - V(hi); neither end is a root.
  struct Piece {
    Rational lo, hi;
    int vlo, vhi;
  };
  std::vector<Piece> stack{{Rational(0), hi, sturm.variations(Rational(0)), sturm.variations(hi)}};
  while (!stack.empty()) {
    Piece p = stack.back();
    stack.pop_back();
    const int count = p.vlo - p.vhi;
    if (count <= 0) continue;
    if (count == 1) {
      out.push_back({p.lo, p.hi});
      continue;
    }
    Rational mid = (p.lo + p.hi) / 2;
    for (int k = 3; sign_at(qi, mid) == 0; ++k) mid = p.lo + (p.hi - p.lo) / k;  // never a root
    const int vmid = sturm.variations(mid);
    stack.push_back({mid, p.hi, vmid, p.vhi});
    stack.push_back({p.lo, mid, p.vlo, vmid});
  }
  // Refine each to a relative width of 2^-120 by the sign change of the square-free part.
  const Rational tiny = Rational(1, Integer(1) << 120);
  for (RootInterval& r : out) {
    const int slo = sign_at(qi, r.lo);
    while (r.hi - r.lo > tiny * r.lo) {
      const Rational mid = (r.lo + r.hi) / 2;
      const int s = sign_at(qi, mid);
      if (s == 0) {
        r.lo = r.hi = mid;
        break;
      }
      if (s == slo) {
        r.lo = mid;
      } else {
        r.hi = mid;
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const RootInterval& a, const RootInterval& b) { return a.lo < b.lo; });
  return out;
}

}  // namespace moreau::lti_exact
