#include "exact_frequency.h"

#include <algorithm>
#include <cmath>

namespace moreau::lti_exact {
namespace {

namespace ex = lti_exact;

// A polynomial matrix: entry (i, j) is a polynomial in s.
using PolyMatrix = std::vector<std::vector<ex::Poly>>;

ex::Poly poly_mul(const ex::Poly& a, const ex::Poly& b) {
  if (a.empty() || b.empty()) return {};
  ex::Poly c(a.size() + b.size() - 1);
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t j = 0; j < b.size(); ++j) c[i + j] += a[i] * b[j];
  while (!c.empty() && c.back() == 0) c.pop_back();
  return c;
}

ex::Poly poly_add(ex::Poly a, const ex::Poly& b) {
  if (a.size() < b.size()) a.resize(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) a[i] += b[i];
  while (!a.empty() && a.back() == 0) a.pop_back();
  return a;
}

ex::Poly reflect(ex::Poly p) {  // p(-s)
  for (std::size_t i = 1; i < p.size(); i += 2) p[i] = -p[i];
  return p;
}

// N(jw) is Hermitian: Re from the even powers, Im from the odd ones. Its definiteness is that of the real
// symmetric [[Re, -Im], [Im, Re]].
bool numerator_positive_definite(const PolyMatrix& N, const ex::Rational& w) {
  const int m = static_cast<int>(N.size());
  ex::Matrix H(2 * m, 2 * m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      ex::Rational re = 0, im = 0, wp = 1;
      for (std::size_t k = 0; k < N[i][j].size(); ++k) {
        // (jw)^k = j^k w^k: j^0 = 1, j^1 = j, j^2 = -1, j^3 = -j.
        const ex::Rational t = N[i][j][k] * wp;
        switch (k % 4) {
          case 0: re += t; break;
          case 1: im += t; break;
          case 2: re -= t; break;
          case 3: im -= t; break;
        }
        wp *= w;
      }
      H(i, j) = re;
      H(m + i, m + j) = re;
      H(i, m + j) = -im;
      H(m + i, j) = im;
    }
  return ex::positive_definite(H);
}

// A rational w with lo < w^2 < hi (hi < 0: no upper end), preferring a double near the middle.
ex::Rational frequency_in(const ex::Rational& lo, const ex::Rational& hi) {
  const bool open = hi < 0;
  const double mid = open ? 4.0 * ex::to_double(lo) + 1.0 : ex::to_double((lo + hi) / 2);
  const ex::Rational w0 = ex::to_rational(std::sqrt(mid));
  if (w0 * w0 > lo && (open || w0 * w0 < hi)) return w0;
  // Narrower than the spacing of doubles: bisect on w.
  ex::Rational a = 0, b = 1;
  while (b * b <= (open ? lo : hi)) b *= 2;
  if (open) return b;
  for (;;) {
    const ex::Rational c = (a + b) / 2;
    const ex::Rational c2 = c * c;
    if (c2 <= lo) {
      a = c;
    } else if (c2 >= hi) {
      b = c;
    } else {
      return c;
    }
  }
}

}  // namespace

ExactFrequency exact_frequency(const ex::Matrix& A, const ex::Matrix& B, const ex::Matrix& C, const ex::Resolvent& res, double wc) {
  const int n = A.rows, m = B.cols;
  ExactFrequency out;
  // P(s) = C adj(sI - A) B = sum_k C M_k B s^{n-1-k}.
  PolyMatrix P(m, std::vector<ex::Poly>(m, ex::Poly(n)));
  for (int k = 0; k < n; ++k) {
    const ex::Matrix CMB = C * (res.M[k] * B);
    for (int i = 0; i < m; ++i)
      for (int j = 0; j < m; ++j) P[i][j][n - 1 - k] = CMB(i, j);
  }
  const ex::Poly d = res.d, dm = reflect(res.d);
  PolyMatrix N(m, std::vector<ex::Poly>(m));
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) N[i][j] = poly_add(poly_mul(P[i][j], dm), poly_mul(reflect(P[j][i]), d));
  // r(v) with det N(s) = r(s^2); q(u) = r(-u), so that det N(jw) = q(w^2).
  ex::Poly r;
  if (m == 1) {
    for (std::size_t k = 0; k < N[0][0].size(); k += 2) r.push_back(N[0][0][k]);
  } else {
    const int deg_r = m * (2 * n - 1) / 2;
    std::vector<ex::Rational> x, y;
    for (int i = 0; i <= deg_r; ++i) {
      ex::Matrix Ni(m, m);
      for (int a = 0; a < m; ++a)
        for (int b = 0; b < m; ++b) Ni(a, b) = ex::evaluate(N[a][b], ex::Rational(i));
      x.push_back(ex::Rational(i * i));
      y.push_back(ex::determinant(Ni));
    }
    // Newton's divided differences, then the monomial coefficients.
    std::vector<ex::Rational> coef = y;
    for (int j = 1; j <= deg_r; ++j)
      for (int i = deg_r; i >= j; --i) coef[i] = (coef[i] - coef[i - 1]) / (x[i] - x[i - j]);
    r = {coef[deg_r]};
    for (int i = deg_r - 1; i >= 0; --i) {
      r = poly_mul(r, ex::Poly{-x[i], ex::Rational(1)});
      r = poly_add(r, ex::Poly{coef[i]});
    }
  }
  while (!r.empty() && r.back() == 0) r.pop_back();
  ex::Poly q = reflect(r);
  out.degree = ex::degree(q);
  auto siso_value = [&](const ex::Rational& w) {
    // Phi(jw) = N(jw) / |d(jw)|^2 (N even for m = 1), times 1 + (w/wc)^2.
    const ex::Rational u = w * w;
    ex::Rational dre = 0, dim = 0, wp = 1;
    for (std::size_t k = 0; k < d.size(); ++k) {
      const ex::Rational t = d[k] * wp;
      if (k % 4 == 0) dre += t;
      if (k % 4 == 1) dim += t;
      if (k % 4 == 2) dre -= t;
      if (k % 4 == 3) dim -= t;
      wp *= w;
    }
    const ex::Rational wcr = ex::to_rational(wc);
    return ex::to_double((1 + u / (wcr * wcr)) * ex::evaluate(q, u) / (dre * dre + dim * dim));
  };
  auto set_witness = [&](const ex::Rational& w, bool singular, bool beyond) {
    out.verdict = Verdict::kFails;
    out.witness_w = w;
    out.witness_omega = ex::to_double(w);
    out.witness_singular = singular;
    out.witness_beyond_last = beyond;
    if (m == 1) {
      out.witness_value = siso_value(w);
      out.witness_value_exact = true;
    }
  };
  if (!numerator_positive_definite(N, ex::Rational(0))) {
    set_witness(ex::Rational(0), ex::evaluate(q, ex::Rational(0)) == 0, false);
    return out;
  }
  const std::vector<ex::RootInterval> roots = ex::positive_roots(q);
  for (const ex::RootInterval& ri : roots) out.crossings.push_back(std::sqrt(ex::to_double((ri.lo + ri.hi) / 2)));
  // One exact definiteness test per interval between crossings (the first, from 0, is known positive).
  for (std::size_t g = 1; g <= roots.size(); ++g) {
    const ex::Rational lo = roots[g - 1].hi, hi = g < roots.size() ? roots[g].lo : ex::Rational(-1);
    const ex::Rational w = frequency_in(lo, hi);
    if (!numerator_positive_definite(N, w)) {
      set_witness(w, false, g == roots.size());
      return out;
    }
  }
  if (!roots.empty()) {
    // Positive on both sides of every crossing: Phi(jw) is singular at the crossing itself.
    const ex::RootInterval& ri = roots.front();
    set_witness(ri.lo == ri.hi ? ri.lo : (ri.lo + ri.hi) / 2, true, false);
    out.witness_omega = out.crossings.front();
    if (m == 1) out.witness_value = 0.0;
    return out;
  }
  out.verdict = Verdict::kHolds;
  return out;
}

}  // namespace moreau::lti_exact
