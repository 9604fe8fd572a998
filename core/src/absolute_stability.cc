#include "moreau/core/absolute_stability.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <vector>

#include "lti_exact.h"
#include "moreau/platform/number_text.h"

namespace moreau {
namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

// The exact deciders' numbers grow with the bits of the entries as well as with n: entries spread over
// 1e-300 to 1e300 (a hostile scene) made minimality take about 4 s and SPR 1.7 s at n = 8. The exact
// tests run only when the binary exponents of the nonzero entries of A, B and C span at most this many
// bits (about 1e-38 to 1e38 around 1); wider realisations take the floating-point tests on the balanced
// realisation, where a small margin is "undetermined", never "fails".
constexpr int kExactMaxExponentSpread = 256;

int exponent_spread(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  int lo = std::numeric_limits<int>::max(), hi = std::numeric_limits<int>::min();
  for (const Eigen::MatrixXd* X : {&A, &B, &C})
    for (Eigen::Index k = 0; k < X->size(); ++k) {
      const double x = X->data()[k];
      if (x == 0.0 || !std::isfinite(x)) continue;
      int e = 0;
      std::frexp(x, &e);
      lo = std::min(lo, e), hi = std::max(hi, e);
    }
  return hi < lo ? 0 : hi - lo;
}

// Why a realisation is decided in floating point, or empty when the exact tests run.
std::string why_not_exact(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  const int n = static_cast<int>(A.rows());
  if (n > kExactMaxStates) return "n = " + std::to_string(n) + " > " + std::to_string(kExactMaxStates) + ", too large for the exact test";
  const int spread = exponent_spread(A, B, C);
  if (spread > kExactMaxExponentSpread)
    return "entries spanning 2^" + std::to_string(spread) + " > 2^" + std::to_string(kExactMaxExponentSpread) +
           ", too wide for the exact test";
  return "";
}

double max_abs(const Eigen::MatrixXd& X) { return X.size() ? X.cwiseAbs().maxCoeff() : 0.0; }

Eigen::VectorXd sym_eigenvalues(const Eigen::MatrixXd& S) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (S + S.transpose()), Eigen::EigenvaluesOnly);
  return eig.eigenvalues();
}

// Maximises a function of z in R^k by Nelder-Mead (restarted from the best vertex).
Eigen::VectorXd nelder_mead_max(const std::function<double(const Eigen::VectorXd&)>& f, Eigen::VectorXd z0, double step, int max_evals) {
  const int k = static_cast<int>(z0.size());
  Eigen::VectorXd best = z0;
  double fbest = f(z0);
  int evals = 1;
  for (int restart = 0; restart < 4 && evals < max_evals; ++restart) {
    std::vector<Eigen::VectorXd> x(static_cast<std::size_t>(k + 1), best);
    std::vector<double> fx(static_cast<std::size_t>(k + 1), fbest);
    for (int i = 0; i < k; ++i) {
      x[i + 1](i) += step;
      fx[i + 1] = f(x[i + 1]);
      ++evals;
    }
    for (int it = 0; it < 200 * (k + 1) && evals < max_evals; ++it) {
      std::vector<int> order(static_cast<std::size_t>(k + 1));
      for (int i = 0; i <= k; ++i) order[i] = i;
      std::sort(order.begin(), order.end(), [&](int a, int b) { return fx[a] > fx[b]; });  // best first
      const int worst = order[k];
      const double spread = std::abs(fx[order[0]] - fx[worst]);
      if (spread <= 1e-13 * (1.0 + std::abs(fx[order[0]]))) break;
      Eigen::VectorXd centroid = Eigen::VectorXd::Zero(k);
      for (int i = 0; i < k; ++i) centroid += x[order[i]];
      centroid /= k;
      const Eigen::VectorXd xr = centroid + (centroid - x[worst]);
      const double fr = f(xr);
      ++evals;
      if (fr > fx[order[0]]) {
        const Eigen::VectorXd xe = centroid + 2.0 * (centroid - x[worst]);
        const double fe = f(xe);
        ++evals;
        if (fe > fr) {
          x[worst] = xe;
          fx[worst] = fe;
        } else {
          x[worst] = xr;
          fx[worst] = fr;
        }
      } else if (fr > fx[order[k - 1]]) {
        x[worst] = xr;
        fx[worst] = fr;
      } else {
        const Eigen::VectorXd xc = centroid + 0.5 * (x[worst] - centroid);
        const double fc = f(xc);
        ++evals;
        if (fc > fx[worst]) {
          x[worst] = xc;
          fx[worst] = fc;
        } else {
          for (int i = 1; i <= k; ++i) {
            x[order[i]] = x[order[0]] + 0.5 * (x[order[i]] - x[order[0]]);
            fx[order[i]] = f(x[order[i]]);
            ++evals;
          }
        }
      }
    }
    for (int i = 0; i <= k; ++i) {
      if (fx[i] > fbest) {
        fbest = fx[i];
        best = x[i];
      }
    }
    step *= 0.25;
  }
  return best;
}

}  // namespace

namespace {

using Complex = std::complex<double>;

// (1 + (w/wc)^2) lambda_min(Phi(jw)) and a bound on its round-off: the solve of (jwI - A) X = B loses
// about eps cond(jwI - A) relative to |X|, and Phi = C X + (C X)^H inherits it scaled by |C|.
struct PopovValue {
  double value = 0.0;
  double tolerance = 0.0;
};

PopovValue popov_value(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C, double w, double wc) {
  const int n = static_cast<int>(A.rows());
  Eigen::MatrixXcd Z = -A.cast<Complex>();
  for (int i = 0; i < n; ++i) Z(i, i) += Complex(0.0, w);
  const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(Z);
  const Eigen::MatrixXcd X = lu.solve(B.cast<Complex>());
  const Eigen::MatrixXcd G = C.cast<Complex>() * X;
  const Eigen::MatrixXcd H = G + G.adjoint();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig(H, Eigen::EigenvaluesOnly);
  const double scale = 1.0 + (w / wc) * (w / wc);
  const double rcond = std::max(lu.rcond(), kEps);
  PopovValue p;
  p.value = scale * eig.eigenvalues()(0);
  p.tolerance = scale * 100.0 * (n + 1) * kEps / rcond * (C.norm() * X.norm() + G.norm());
  return p;
}

// The Popov-Belevitch-Hautus margin: min over the eigenvalues l of A of sigma_min([A - l I, B]) / scale,
// scale = max(|A|, |B|): unchanged when A and B are multiplied by one number.
double pbh_margin(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::VectorXcd& eigenvalues) {
  const int n = static_cast<int>(A.rows()), m = static_cast<int>(B.cols());
  double scale = std::max(max_abs(A), max_abs(B));
  if (!(scale > 0.0)) scale = 1.0;
  double margin = std::numeric_limits<double>::infinity();
  for (int k = 0; k < eigenvalues.size(); ++k) {
    Eigen::MatrixXcd R(n, n + m);
    R.leftCols(n) = A.cast<Complex>();
    for (int i = 0; i < n; ++i) R(i, i) -= eigenvalues(k);
    R.rightCols(m) = B.cast<Complex>();
    Eigen::JacobiSVD<Eigen::MatrixXcd> svd(R);
    margin = std::min(margin, svd.singularValues()(n - 1) / scale);
  }
  return margin;
}

// Holds above `holds_above`, fails below `fails_below`, undetermined in between.
Verdict banded(double value, double fails_below, double holds_above) {
  if (value > holds_above) return Verdict::kHolds;
  if (value < fails_below) return Verdict::kFails;
  return Verdict::kUndetermined;
}

// |Im lambda| of every finite generalized eigenvalue of the Rosenbrock pencil of the Popov function
// Phi(s) = G(s) + G(-s)^T (see the header), with 0: the only frequencies where det Phi(jw) can vanish.
// Empty when QZ did not converge (then nothing may be concluded from the candidates).
std::vector<double> crossing_candidates(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  const int n = static_cast<int>(A.rows()), m = static_cast<int>(B.cols());
  const int d = 2 * n + m;
  Eigen::MatrixXd M = Eigen::MatrixXd::Zero(d, d), N = Eigen::MatrixXd::Zero(d, d);
  M.block(0, 0, n, n) = A;
  M.block(n, n, n, n) = -A.transpose();
  M.block(0, 2 * n, n, m) = B;  // B_P = [B; C^T]
  M.block(n, 2 * n, n, m) = C.transpose();
  M.block(2 * n, 0, m, n) = -C;  // -C_P = -[C, -B^T]
  M.block(2 * n, n, m, n) = B.transpose();
  N.topLeftCorner(2 * n, 2 * n).setIdentity();
  Eigen::GeneralizedEigenSolver<Eigen::MatrixXd> ges(M, N, false);
  if (ges.info() != Eigen::Success) return {};
  std::vector<double> w{0.0};
  const double big = 1e12 * std::max({1.0, max_abs(A), max_abs(B), max_abs(C)});
  for (int k = 0; k < d; ++k) {
    const Complex alpha = ges.alphas()(k);
    const double beta = ges.betas()(k);
    if (std::abs(beta) <= kEps * std::abs(alpha) || std::abs(beta) == 0.0) continue;  // an infinite eigenvalue
    const Complex lambda = alpha / beta;
    if (!std::isfinite(lambda.imag()) || std::abs(lambda) > big) continue;
    w.push_back(std::abs(lambda.imag()));
  }
  std::sort(w.begin(), w.end());
  w.erase(std::unique(w.begin(), w.end()), w.end());
  return w;
}

// A diagonal similarity x = D x_b with D = diag(d), d_i powers of two: A_b = D^-1 A D, B_b = D^-1 B,
// C_b = C D, computed without rounding (only exponents change). Parlett and Reinsch's iteration (as in
// LAPACK's gebal) on [A B; C 0] with only the state coordinates scaled: each step brings the norm of a
// state's column of [A; C] and of its row of [A, B] (off the diagonal) within a factor of 2 of each other.
struct Balanced {
  Eigen::MatrixXd A, B, C;
  Eigen::VectorXd d;
  bool identity = true;
};

Balanced balance(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  Balanced b{A, B, C, Eigen::VectorXd::Ones(A.rows()), true};
  const int n = static_cast<int>(A.rows());
  for (int sweep = 0; sweep < 200; ++sweep) {
    bool changed = false;
    for (int i = 0; i < n; ++i) {
      double c = b.C.col(i).norm(), r = b.B.row(i).norm();
      for (int k = 0; k < n; ++k)
        if (k != i) c = std::hypot(c, b.A(k, i)), r = std::hypot(r, b.A(i, k));
      if (!(c > 0.0) || !(r > 0.0) || !std::isfinite(c) || !std::isfinite(r)) continue;
      double f = 1.0;
      const double s = c + r;
      while (c < r / 2.0 && f < 0x1p500) c *= 2.0, r /= 2.0, f *= 2.0;
      while (c >= 2.0 * r && f > 0x1p-500) c /= 2.0, r *= 2.0, f /= 2.0;
      if (c + r >= 0.95 * s) continue;
      b.A.col(i) *= f;
      b.A.row(i) /= f;
      b.B.row(i) /= f;
      b.C.col(i) *= f;
      b.d(i) *= f;
      changed = true;
    }
    if (!changed) break;
  }
  b.identity = (b.d.array() == 1.0).all();
  return b;
}

namespace ex = lti_exact;

// The exact decision of (ii) (see the header): N(s) = P(s) d(-s) + P(-s)^T d(s), q(w^2) = det N(jw).
struct ExactFrequency {
  Verdict verdict = Verdict::kNotChecked;
  std::vector<double> crossings;
  double witness_omega = -1.0;
  bool witness_singular = false;     // Phi(jw) singular there (a crossing where Phi only touches 0)
  bool witness_beyond_last = false;  // the witness lies beyond the last crossing (high frequency)
  ex::Rational witness_w;            // the exact frequency checked
  bool witness_value_exact = false;  // SISO: the value below is Phi(jw) rounded once
  double witness_value = 0.0;
  int degree = 0;  // of q
};

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

// Numbers in verdicts' witnesses: frequencies exactly (they locate a crossing to the spacing of doubles, and
// may be read back), other values to 6 or 3 significant digits.
std::string exact_text(double v) { return platform::shortest(v); }
std::string g6(double v) { return platform::significant(v, 6); }
std::string g3(double v) { return platform::significant(v, 3); }

// A certificate P on {P = P^T, B^T P = C} (see the header): the search and its check.
struct Certificate {
  Verdict verdict = Verdict::kNotChecked;
  Eigen::MatrixXd P;
  StorageMatrixCheck check;
  std::string method;
};

Certificate search_certificate(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  Certificate r;
  const int n = static_cast<int>(A.rows());
  const int p = static_cast<int>(C.rows());
  const int np = n * (n + 1) / 2;
  std::vector<std::pair<int, int>> idx;
  for (int i = 0; i < n; ++i)
    for (int j = i; j < n; ++j) idx.emplace_back(i, j);
  auto assemble = [&](const Eigen::VectorXd& pv) {
    Eigen::MatrixXd P(n, n);
    for (int k = 0; k < np; ++k) P(idx[k].first, idx[k].second) = P(idx[k].second, idx[k].first) = pv(k);
    return P;
  };
  const int rows = p * n;
  Eigen::MatrixXd E(rows, np);
  for (int k = 0; k < np; ++k) {
    Eigen::VectorXd e = Eigen::VectorXd::Zero(np);
    e(k) = 1.0;
    const Eigen::MatrixXd BtP = B.transpose() * assemble(e);
    E.col(k) = Eigen::Map<const Eigen::VectorXd>(BtP.data(), rows);
  }
  const Eigen::VectorXd c = Eigen::Map<const Eigen::VectorXd>(C.data(), rows);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::VectorXd p0 = svd.solve(c);
  if ((E * p0 - c).cwiseAbs().maxCoeff() > 1e-10 * (1.0 + c.cwiseAbs().maxCoeff())) {
    r.verdict = Verdict::kFails;
    r.method = "no symmetric P satisfies B^T P = C (the linear equations are inconsistent)";
    return r;
  }
  const Eigen::VectorXd sv = svd.singularValues();
  const double tol = 1e-12 * std::max(1.0, sv.size() ? sv(0) : 1.0);
  int rank_e = 0;
  for (int i = 0; i < sv.size(); ++i)
    if (sv(i) > tol) ++rank_e;
  const Eigen::MatrixXd Nul = svd.matrixV().rightCols(np - rank_e);
  auto objective = [&](const Eigen::VectorXd& z) {
    const Eigen::MatrixXd P = assemble(p0 + Nul * z);
    const double lp = sym_eigenvalues(P)(0);
    const Eigen::VectorXd el = sym_eigenvalues(-(P * A + A.transpose() * P));
    return std::min(lp, el(0));
  };
  Eigen::VectorXd z = Eigen::VectorXd::Zero(Nul.cols());
  if (Nul.cols() > 0) z = nelder_mead_max(objective, z, std::max(1.0, p0.cwiseAbs().maxCoeff()), 20000);
  r.P = assemble(p0 + Nul * z);
  r.check = check_storage_matrix(A, B, C, r.P);
  // A search that does not find P proves nothing either way: the certificate is then undetermined.
  r.verdict = r.check.all() ? Verdict::kHolds : Verdict::kUndetermined;
  r.method = "searched the " + std::to_string(Nul.cols()) +
             "-dimensional affine set of symmetric P with B^T P = C for the largest min(lambda_min(P), "
             "lambda_min(-(PA + A^T P))) by Nelder-Mead: " +
             (r.verdict == Verdict::kHolds ? "found, and checked" : "none found") + " (margin " + g3(objective(z)) + ")";
  return r;
}

}  // namespace

StorageMatrixCheck check_storage_matrix(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C,
                                        const Eigen::MatrixXd& P) {
  StorageMatrixCheck c;
  const double pmax = std::max(max_abs(P), 1e-300);
  c.asymmetry = max_abs(P - P.transpose()) / pmax;
  c.symmetric = c.asymmetry <= 1e-12;
  const Eigen::VectorXd ev = sym_eigenvalues(P);
  c.min_eigenvalue = ev(0);
  c.positive_definite = c.min_eigenvalue > 64.0 * kEps * std::abs(ev(ev.size() - 1));
  const Eigen::MatrixXd L = P * A + A.transpose() * P;
  const Eigen::VectorXd el = sym_eigenvalues(L);
  c.max_eigenvalue_pa = el(el.size() - 1);
  c.dissipative = c.max_eigenvalue_pa < -64.0 * kEps * std::max(std::abs(el(0)), max_abs(P) * max_abs(A));
  const double scale = max_abs(B) * pmax + max_abs(C);
  c.output_residual = max_abs(B.transpose() * P - C) / std::max(scale, 1e-300);
  c.output_matches = c.output_residual <= 1e-10;
  return c;
}

MinimalityCheck check_minimality(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  MinimalityCheck c;
  const int n = static_cast<int>(A.rows());
  const Balanced bal = balance(A, B, C);
  Eigen::EigenSolver<Eigen::MatrixXd> eig(bal.A, false);
  c.controllability_margin = pbh_margin(bal.A, bal.B, eig.eigenvalues());
  c.observability_margin = pbh_margin(bal.A.transpose(), bal.C.transpose(), eig.eigenvalues());
  const std::string floating_point_because = why_not_exact(A, B, C);
  if (floating_point_because.empty()) {
    // Kalman's rank test on the matrices as stored, in rational arithmetic: a rank below n is an exact
    // uncontrollable (unobservable) subspace, not a small margin.
    const ex::Matrix Ae = ex::Matrix::from(A), Be = ex::Matrix::from(B), Ce = ex::Matrix::from(C);
    const int m = Be.cols, p = Ce.rows;
    ex::Matrix K(n, n * m), O(n * p, n);
    ex::Matrix AkB = Be, CAk = Ce;
    for (int k = 0; k < n; ++k) {
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) K(i, k * m + j) = AkB(i, j);
      for (int i = 0; i < p; ++i)
        for (int j = 0; j < n; ++j) O(k * p + i, j) = CAk(i, j);
      if (k + 1 < n) AkB = Ae * AkB, CAk = CAk * Ae;
    }
    c.exact = true;
    c.controllability_rank = ex::rank(K);
    c.observability_rank = ex::rank(O);
    c.controllable = c.controllability_rank == n ? Verdict::kHolds : Verdict::kFails;
    c.observable = c.observability_rank == n ? Verdict::kHolds : Verdict::kFails;
    c.method = "Kalman rank test, exact in rational arithmetic on the matrices as stored: rank [B, AB, ..., A^(n-1) B] = " +
               std::to_string(c.controllability_rank) + ", rank [C; CA; ...; CA^(n-1)] = " + std::to_string(c.observability_rank) +
               " (n = " + std::to_string(n) + ")";
  } else {
    // A small margin is no proof of a lost mode: only a clear margin decides.
    c.controllable = c.controllability_margin > 1e-8 ? Verdict::kHolds : Verdict::kUndetermined;
    c.observable = c.observability_margin > 1e-8 ? Verdict::kHolds : Verdict::kUndetermined;
    c.method = "Popov-Belevitch-Hautus margins of the balanced realisation (" + floating_point_because +
               "): holds above 1e-8, otherwise undetermined";
  }
  return c;
}

PositiveRealnessTest test_strict_positive_realness(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C) {
  PositiveRealnessTest r;
  const int n = static_cast<int>(A.rows());
  const int m = static_cast<int>(B.cols());
  const int p = static_cast<int>(C.rows());
  // The floating-point tests work on the balanced realisation: the same G(s), with margins that do not
  // depend on how the state was scaled.
  const Balanced bal = balance(A, B, C);
  const Eigen::MatrixXd& Ab = bal.A;
  const Eigen::MatrixXd& Bb = bal.B;
  const Eigen::MatrixXd& Cb = bal.C;
  // Why the floating-point tests decide, or empty when the exact ones can (a non-square G returns below).
  const std::string floating_point_because = why_not_exact(A, B, C);
  r.exact = floating_point_because.empty() && p == m;

  // (i) A Hurwitz. Exactly by Routh's test on det(sI - A); otherwise from the eigenvalues, which for a
  // non-normal A can move by about sqrt(eps) |A|: inside that band the answer is undetermined.
  Eigen::EigenSolver<Eigen::MatrixXd> eig(Ab, false);
  const Eigen::VectorXcd lambda = eig.eigenvalues();
  r.spectral_abscissa = lambda.real().maxCoeff();
  r.hurwitz_tolerance = std::sqrt(kEps) * std::max(1.0, max_abs(Ab));
  const double rho = lambda.cwiseAbs().maxCoeff();
  r.wc = std::max(1.0, rho);
  ex::Matrix Ae, Be, Ce;
  ex::Resolvent res;
  if (floating_point_because.empty()) {
    Ae = ex::Matrix::from(A), Be = ex::Matrix::from(B), Ce = ex::Matrix::from(C);
    res = ex::resolvent(Ae);
    r.hurwitz = ex::hurwitz(res.d) ? Verdict::kHolds : Verdict::kFails;
    r.hurwitz_method = "Routh's test on det(sI - A), exact";
  } else {
    r.hurwitz = banded(-r.spectral_abscissa, -r.hurwitz_tolerance, r.hurwitz_tolerance);
    r.hurwitz_method = "eigenvalues of the balanced A (floating point, band sqrt(eps) |A|)";
  }

  if (p != m) {
    r.cb = r.high_frequency = r.frequency = Verdict::kFails;
    r.spr = Verdict::kFails;
    r.witness = "G(s) is " + std::to_string(p) + " x " + std::to_string(m) + ": positive realness needs a square G";
    r.method = "not decided: G is not square";
    r.storage_method = "not attempted (G is not square)";
    return r;
  }

  // (iii) CB = (CB)^T > 0 and -(CAB + (CAB)^T) > 0. CB and CAB are invariant to the state's scaling; in
  // floating point they are computed from the balanced realisation, each with a round-off band.
  const Eigen::MatrixXd CB = Cb * Bb;
  const double cb_scale = std::max(max_abs(Cb) * max_abs(Bb), 1e-300);
  r.cb_asymmetry = max_abs(CB - CB.transpose()) / cb_scale;
  r.cb_min_eigenvalue = sym_eigenvalues(CB)(0);
  const Eigen::MatrixXd CAB = Cb * (Ab * Bb);
  r.high_frequency_min_eigenvalue = sym_eigenvalues(-(CAB + CAB.transpose()))(0);
  const double roundoff_asymmetry = 100.0 * (n + 1) * kEps;
  bool cb_roundoff_asymmetric = false;
  if (r.exact) {
    const ex::Matrix CBe = Ce * Be, CABe = Ce * (Ae * Be);
    if (ex::symmetric(CBe)) {
      r.cb = ex::positive_definite(CBe) ? Verdict::kHolds : Verdict::kFails;
    } else {
      // Not symmetric as stored; by no more than the rounding of the entries: undetermined (header).
      cb_roundoff_asymmetric = r.cb_asymmetry <= roundoff_asymmetry;
      r.cb = cb_roundoff_asymmetric ? Verdict::kUndetermined : Verdict::kFails;
    }
    ex::Matrix S = CABe + CABe.transpose();
    for (ex::Rational& v : S.a) v = -v;
    r.high_frequency = ex::positive_definite(S) ? Verdict::kHolds : Verdict::kFails;
  } else {
    const double cb_tol = 100.0 * (n + 1) * kEps * cb_scale;
    r.cb = r.cb_asymmetry > roundoff_asymmetry ? Verdict::kFails : banded(r.cb_min_eigenvalue, -cb_tol, cb_tol);
    if (r.cb == Verdict::kHolds && r.cb_asymmetry > 0.0) r.cb = Verdict::kUndetermined;  // symmetric only up to round-off
    const double hf_tol = 100.0 * (n + 1) * kEps * std::max(max_abs(Cb) * max_abs(Ab) * max_abs(Bb), 1e-300);
    r.high_frequency = banded(r.high_frequency_min_eigenvalue, -hf_tol, hf_tol);
  }

  int q_degree = 0;
  // (ii) Only meaningful for a Hurwitz A: otherwise G has poles on or right of the axis and SPR already
  // fails. The Popov-pencil test runs in every case (it gives the margin, and is the second decider); the
  // exact Sturm test decides when it ran.
  if (r.hurwitz == Verdict::kHolds) {
    r.crossing_candidates = crossing_candidates(Ab, Bb, Cb);
    const bool qz_converged = !r.crossing_candidates.empty();
    if (!qz_converged) r.crossing_candidates = {0.0};  // a failure found below still stands; "holds" cannot
    std::vector<double> points;
    const std::vector<double>& c = r.crossing_candidates;
    for (std::size_t i = 0; i < c.size(); ++i) {
      points.push_back(c[i]);
      if (i + 1 < c.size()) points.push_back(0.5 * (c[i] + c[i + 1]));
    }
    points.push_back(2.0 * c.back() + r.wc);
    for (int j = 0; j <= 240; ++j) points.push_back(1e-6 * r.wc * std::pow(10.0, 12.0 * j / 240));  // for the margin only
    std::sort(points.begin(), points.end());
    std::vector<PopovValue> values;
    values.reserve(points.size());
    for (double w : points) values.push_back(popov_value(Ab, Bb, Cb, w, r.wc));
    r.frequencies = static_cast<int>(points.size());
    std::size_t jmin = 0;
    bool undetermined = false;
    double pencil_witness = -1.0, pencil_value = 0.0;
    for (std::size_t j = 0; j < points.size(); ++j) {
      if (values[j].value < values[jmin].value) jmin = j;
      if (values[j].value < -values[j].tolerance) {
        if (pencil_witness < 0.0 || values[j].value < pencil_value) {
          pencil_witness = points[j];
          pencil_value = values[j].value;
        }
      } else if (values[j].value <= values[j].tolerance) {
        undetermined = true;
      }
    }
    // Refine the smallest value by golden section between its neighbours (the reported margin).
    double wmin = points[jmin], fmin = values[jmin].value, tmin = values[jmin].tolerance;
    {
      double a = points[jmin > 0 ? jmin - 1 : 0], b = points[std::min(points.size() - 1, jmin + 1)];
      const double g = 0.5 * (std::sqrt(5.0) - 1.0);
      double x1 = b - g * (b - a), x2 = a + g * (b - a);
      PopovValue f1 = popov_value(Ab, Bb, Cb, x1, r.wc), f2 = popov_value(Ab, Bb, Cb, x2, r.wc);
      r.frequencies += 2;
      for (int it = 0; it < 60 && b - a > 1e-15 * b; ++it) {
        if (f1.value < f2.value) {
          b = x2, x2 = x1, f2 = f1, x1 = b - g * (b - a), f1 = popov_value(Ab, Bb, Cb, x1, r.wc);
        } else {
          a = x1, x1 = x2, f1 = f2, x2 = a + g * (b - a), f2 = popov_value(Ab, Bb, Cb, x2, r.wc);
        }
        ++r.frequencies;
      }
      const PopovValue& best = f1.value < f2.value ? f1 : f2;
      if (best.value < fmin) {
        fmin = best.value, wmin = f1.value < f2.value ? x1 : x2, tmin = best.tolerance;
        if (best.value < -best.tolerance && (pencil_witness < 0.0 || best.value < pencil_value)) {
          pencil_witness = wmin;
          pencil_value = best.value;
        }
      }
    }
    r.frequency_pencil = pencil_witness >= 0.0 ? Verdict::kFails : undetermined || !qz_converged ? Verdict::kUndetermined : Verdict::kHolds;
    if (r.exact) {
      const ExactFrequency e = exact_frequency(Ae, Be, Ce, res, r.wc);
      q_degree = e.degree;
      r.frequency_exact = e.verdict;
      r.crossings = e.crossings;
      r.frequency = e.verdict;
      r.frequency_method = "Sturm (exact)";
      if (e.verdict == Verdict::kFails) {
        r.witness_omega = e.witness_omega;
        r.witness_value = e.witness_value_exact ? e.witness_value : popov_value(Ab, Bb, Cb, e.witness_omega, r.wc).value;
        if (e.witness_singular) r.witness_value = 0.0;
        // A failure beyond the last crossing caused by a CB asymmetric only by round-off (header).
        if (e.witness_beyond_last && cb_roundoff_asymmetric) r.frequency = Verdict::kUndetermined;
      }
      if (e.verdict == Verdict::kFails && !e.witness_singular && r.witness_value < fmin) {
        fmin = r.witness_value, wmin = r.witness_omega, tmin = 0.0;
      }
    } else {
      r.frequency = r.frequency_pencil;
      r.frequency_method = "Popov pencil (floating point)";
      r.witness_omega = pencil_witness;
      r.witness_value = pencil_value;
    }
    r.min_frequency_eigenvalue = fmin;
    r.argmin_omega = wmin;
    r.frequency_tolerance = tmin;
  } else {
    r.frequency = Verdict::kNotChecked;
  }

  r.spr = all_of(all_of(r.hurwitz, r.cb), r.high_frequency);
  if (r.hurwitz == Verdict::kHolds) r.spr = all_of(r.spr, r.frequency);
  if (r.hurwitz == Verdict::kFails) {
    r.witness = r.exact ? "A is not Hurwitz: Routh's test on det(sI - A) fails (exact; max Re lambda = " + g6(r.spectral_abscissa) + ")"
                        : "A is not Hurwitz: an eigenvalue has real part " + g6(r.spectral_abscissa) + " >= 0";
  } else if (r.frequency == Verdict::kFails) {
    if (r.witness_value == 0.0 && r.frequency_exact == Verdict::kFails) {
      r.witness =
          "G(jw) + G(jw)^H is singular at w = " + exact_text(r.witness_omega) + " (exact: det = 0 there, positive definite on both sides)";
    } else {
      r.witness = "G(jw) + G(jw)^H is not positive definite at w = " + exact_text(r.witness_omega) +
                  ": (1 + (w/wc)^2) lambda_min = " + g6(r.witness_value);
      if (r.frequency_exact == Verdict::kFails) r.witness += " (its sign decided exactly)";
    }
    // Where it fails, between which crossings (each located to the spacing of doubles).
    const std::vector<double>& x = r.crossings;
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (x[i] > r.witness_omega) {
        if (i > 0)
          r.witness += "; it fails between the crossings at w = " + exact_text(x[i - 1]) + " and " + exact_text(x[i]) + " (a band " +
                       g6(x[i] - x[i - 1]) + " wide)";
        break;
      }
      if (i + 1 == x.size() && r.witness_omega > x[i]) r.witness += "; it fails for every w beyond the crossing at w = " + exact_text(x[i]);
    }
  } else if (r.cb == Verdict::kFails) {
    r.witness = r.cb_asymmetry > 0.0 ? "CB is not symmetric (relative asymmetry " + g3(r.cb_asymmetry) + ")"
                                     : "CB is not positive definite: lambda_min(CB) = " + g6(r.cb_min_eigenvalue);
  } else if (r.high_frequency == Verdict::kFails) {
    r.witness = "-(CAB + (CAB)^T) is not positive definite (lambda_min = " + g6(r.high_frequency_min_eigenvalue) +
                "): G(jw) + G(jw)^H < 0 for large w";
  }
  const std::string wc = g3(r.wc);
  if (r.exact) {
    r.method =
        "frequency domain (strictly proper G, Tao and Ioannou 1988), decided exactly in rational arithmetic on the "
        "matrices as stored: A Hurwitz by Routh's test on det(sI - A); G(jw) + G(jw)^H > 0 for every w by a Sturm "
        "sequence of det N(jw) = q(w^2), N the numerator of the Popov function (degree " +
        std::to_string(q_degree) + " in w^2, " + std::to_string(r.crossings.size()) +
        " positive crossings; N(jw) > 0 tested exactly once between each two and beyond the last); CB = (CB)^T > 0 and "
        "-(CAB + (CAB)^T) > 0 for w -> infinity. Second decider, floating point on the balanced realisation: the "
        "Popov pencil (QZ, " +
        std::to_string(r.crossing_candidates.size()) + " candidate frequencies, " + std::to_string(r.frequencies) +
        " evaluations of G(jw), wc = " + wc + ") says " + to_string(r.frequency_pencil);
  } else {
    r.method =
        "frequency domain (strictly proper G, Tao and Ioannou 1988), in floating point on the balanced realisation "
        "(" +
        floating_point_because +
        "): A Hurwitz from its eigenvalues; G(jw) + G(jw)^H > 0 for every w, decided at "
        "the candidate frequencies where its determinant can vanish (" +
        std::to_string(r.crossing_candidates.size()) +
        ": 0 and the |Im| of the finite generalized eigenvalues of the Popov function's Rosenbrock pencil, by QZ), at "
        "the midpoints between them and beyond the last (" +
        std::to_string(r.frequencies) + " evaluations of G(jw) with a log sweep for the margin, wc = " + wc +
        "); CB = (CB)^T > 0 and -(CAB + (CAB)^T) > 0 for w -> infinity";
  }

  // A certificate P on {P = P^T, B^T P = C}: sought only when the frequency test says SPR (otherwise none
  // exists, by the KYP lemma).
  if (r.spr == Verdict::kFails) {
    r.storage_method = "not attempted: G is not strictly positive real, so no P exists";
    return r;
  }
  if (n > 12) {
    r.storage_method = "not attempted (n > 12)";
    return r;
  }
  Certificate cert = search_certificate(A, B, C);
  if (cert.verdict != Verdict::kHolds && cert.verdict != Verdict::kFails && !bal.identity) {
    // Badly scaled as given: search on the balanced realisation. Its P_b gives P = D^-1 P_b D^-1 for the
    // given one (D of powers of two: exact), and the conditions checked on (A_b, B_b, C_b, P_b) are those
    // on (A, B, C, P) by the similarity.
    Certificate cb = search_certificate(Ab, Bb, Cb);
    if (cb.verdict == Verdict::kHolds) {
      const Eigen::VectorXd dinv = bal.d.cwiseInverse();
      cb.P = dinv.asDiagonal() * cb.P * dinv.asDiagonal();
      cb.method +=
          " on the balanced realisation x = D x_b (D diagonal, powers of two; P = D^-1 P_b D^-1, checked on the balanced "
          "realisation)";
      cert = cb;
    }
  }
  r.certificate = cert.verdict;
  r.P = cert.P;
  r.storage_check = cert.check;
  r.storage_method = cert.method;
  if (r.spr == Verdict::kUndetermined && r.storage_found()) {
    // The frequency test was inside its round-off band, but a checked P proves SPR (KYP lemma, sufficiency).
    r.spr = Verdict::kHolds;
    r.method += "; the round-off band of the frequency test is settled by the certificate P (KYP lemma)";
  }
  return r;
}

}  // namespace moreau
