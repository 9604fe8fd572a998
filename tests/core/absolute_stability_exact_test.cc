// The deciders of core/absolute_stability.h (minimality, A Hurwitz, strict positive realness) on badly
// scaled realisations, against exact references computed here independently of the code under test:
//  - constructed G(s) = 1/(s + 1) + a/(s^2 + b s + w0^2) (or + a s/(...)), whose Re G(jw) has a closed form
//    with a quadratic numerator in u = w^2, solved here in rational arithmetic and 50-digit floating point;
//  - random realisations (block-diagonal modal forms and companion forms, poles and resonances up to 1e9
//    rad/s) whose transfer function n(s)/d(s) is assembled here from the blocks or read off the companion
//    form in rational arithmetic; minimality is decided by gcd(n, d) (not by a rank), positivity of
//    Re[n(jw) d(-jw)] on u = w^2 >= 0 by Descartes' rule of signs with bisection (not by a Sturm sequence).
// Every realisation is also transformed by diagonal state scalings from 1e-7 to 1e7 (powers of two, which
// change no mantissa, and powers of ten, which round): the verdicts must not change.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <boost/multiprecision/cpp_bin_float.hpp>
#include <boost/multiprecision/cpp_int.hpp>

#include "moreau/core/absolute_stability.h"

namespace moreau {
namespace {

// Without expression templates: every operation yields a value.
using Q = boost::multiprecision::number<boost::multiprecision::rational_adaptor<boost::multiprecision::cpp_int_backend<>>,
                                        boost::multiprecision::et_off>;
using F50 = boost::multiprecision::cpp_bin_float_50;
using Poly = std::vector<Q>;  // from the constant term up

// The exact value of a double: its mantissa times a power of two.
Q Exact(double x) {
  if (x == 0.0) return Q(0);
  int e = 0;
  const double f = std::frexp(x, &e);
  Q q(static_cast<long long>(std::ldexp(f, 53)));
  e -= 53;
  boost::multiprecision::number<boost::multiprecision::cpp_int_backend<>, boost::multiprecision::et_off> p2 = 1;
  p2 <<= std::abs(e);
  return e >= 0 ? q * Q(p2) : q / Q(p2);
}

F50 ToF50(const Q& q) { return F50(boost::multiprecision::numerator(q)) / F50(boost::multiprecision::denominator(q)); }

void Trim(Poly& p) {
  while (!p.empty() && p.back() == 0) p.pop_back();
}
Poly Mul(const Poly& a, const Poly& b) {
  if (a.empty() || b.empty()) return {};
  Poly c(a.size() + b.size() - 1);
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t j = 0; j < b.size(); ++j) c[i + j] += a[i] * b[j];
  Trim(c);
  return c;
}
Poly Add(Poly a, const Poly& b) {
  if (a.size() < b.size()) a.resize(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) a[i] += b[i];
  Trim(a);
  return a;
}
Q Eval(const Poly& p, const Q& x) {
  Q v = 0;
  for (auto it = p.rbegin(); it != p.rend(); ++it) v = v * x + *it;
  return v;
}
Poly Rem(Poly a, const Poly& b) {
  while (a.size() >= b.size() && !a.empty()) {
    const Q f = a.back() / b.back();
    const std::size_t shift = a.size() - b.size();
    for (std::size_t i = 0; i < b.size(); ++i) a[i + shift] -= f * b[i];
    a.pop_back();
    Trim(a);
  }
  return a;
}
Poly Gcd(Poly a, Poly b) {
  while (!b.empty()) {
    Poly r = Rem(a, b);
    a = b;
    b = r;
  }
  return a;
}
Poly Derivative(const Poly& p) {
  Poly d;
  for (std::size_t i = 1; i < p.size(); ++i) d.push_back(p[i] * static_cast<int>(i));
  Trim(d);
  return d;
}
Poly Quotient(Poly a, const Poly& b) {
  Poly q(a.size() >= b.size() ? a.size() - b.size() + 1 : 0);
  while (a.size() >= b.size() && !a.empty()) {
    const Q f = a.back() / b.back();
    const std::size_t shift = a.size() - b.size();
    q[shift] = f;
    for (std::size_t i = 0; i < b.size(); ++i) a[i + shift] -= f * b[i];
    a.pop_back();
    Trim(a);
  }
  return q;
}

int SignVariations(const Poly& p) {
  int v = 0, last = 0;
  for (const Q& c : p) {
    const int s = c > 0 ? 1 : c < 0 ? -1 : 0;
    if (s == 0) continue;
    if (last != 0 && s != last) ++v;
    last = s;
  }
  return v;
}

// (1 + y)^deg p((lo + hi y) / (1 + y)): its positive roots y are the roots of p in (lo, hi).
Poly Mobius(const Poly& p, const Q& lo, const Q& hi) {
  const int deg = static_cast<int>(p.size()) - 1;
  Poly out;
  for (int i = 0; i <= deg; ++i) {
    Poly t{p[i]};
    for (int k = 0; k < i; ++k) t = Mul(t, Poly{lo, hi});
    for (int k = i; k < deg; ++k) t = Mul(t, Poly{Q(1), Q(1)});
    out = Add(out, t);
  }
  return out;
}

// Whether the square-free polynomial p has a root in (lo, hi): Descartes' rule of signs on the Mobius
// transform (0 variations: none; 1: exactly one), bisecting otherwise (Vincent's theorem: it ends).
bool RootIn(const Poly& p, const Q& lo, const Q& hi, int depth = 0) {
  const int v = SignVariations(Mobius(p, lo, hi));
  if (v == 0) return false;
  if (v == 1) return true;
  EXPECT_LT(depth, 2000) << "Descartes bisection did not end";
  if (depth >= 2000) return true;
  const Q mid = (lo + hi) / 2;
  if (Eval(p, mid) == 0) return true;
  return RootIn(p, lo, mid, depth + 1) || RootIn(p, mid, hi, depth + 1);
}

// p(u) > 0 for every u >= 0.
bool PositiveOnHalfLine(Poly p) {
  Trim(p);
  if (p.empty() || p[0] <= 0) return false;
  const Poly g = Gcd(p, Derivative(p));
  if (g.size() > 1) p = Quotient(p, g);
  Q bound = 0;  // Cauchy's bound on the roots
  for (std::size_t i = 0; i + 1 < p.size(); ++i) bound = std::max(bound, Q(boost::multiprecision::abs(p[i] / p.back())));
  return !RootIn(p, Q(0), bound + 1);
}

// The exact verdicts for G = n/d (d monic of degree n, the realisation's order), from the polynomials.
struct Reference {
  bool minimal = false, spr = false;
};
Reference Decide(const Poly& num, const Poly& den, bool hurwitz) {
  const int n = static_cast<int>(den.size()) - 1;
  Reference r;
  r.minimal = !num.empty() && Gcd(num, den).size() == 1;
  // G = CB / s + CAB / s^2 + ...: CB = n_{n-1}, CAB = n_{n-2} - d_{n-1} n_{n-1}.
  auto coef = [](const Poly& p, int k) { return k >= 0 && k < static_cast<int>(p.size()) ? p[k] : Q(0); };
  const Q cb = coef(num, n - 1), cab = coef(num, n - 2) - coef(den, n - 1) * coef(num, n - 1);
  // Re[n(jw) d(-jw)] = sum_i (-1)^i e_{2i} u^i with e(s) = n(s) d(-s).
  Poly dm = den;
  for (std::size_t i = 1; i < dm.size(); i += 2) dm[i] = -dm[i];
  const Poly e = Mul(num, dm);
  Poly p;
  for (std::size_t i = 0; 2 * i < e.size(); ++i) p.push_back(i % 2 ? -e[2 * i] : e[2 * i]);
  r.spr = hurwitz && cb > 0 && -cab > 0 && PositiveOnHalfLine(p);
  return r;
}

// x = D x_s: (D^-1 A D, D^-1 B, C D).
struct Realisation {
  Eigen::MatrixXd A, B, C;
  Realisation Scaled(const Eigen::VectorXd& d) const {
    return {d.cwiseInverse().asDiagonal() * A * d.asDiagonal(), d.cwiseInverse().asDiagonal() * B, C * d.asDiagonal()};
  }
};

// G(s) = 1/(s + 1) + (c1 s + c0)/(s^2 + b s + w0^2) in a companion form for the second term.
Realisation LagPlusResonance(double c0, double c1, double b, double w0sq) {
  Realisation r{Eigen::MatrixXd::Zero(3, 3), Eigen::MatrixXd(3, 1), Eigen::MatrixXd(1, 3)};
  r.A(0, 0) = -1.0;
  r.A(1, 2) = 1.0;
  r.A(2, 1) = -w0sq;
  r.A(2, 2) = -b;
  r.B << 1.0, 0.0, 1.0;
  r.C << 1.0, c0, c1;
  return r;
}

// Re G(jw) (1 + u) ((w0^2 - u)^2 + b^2 u) for G = 1/(s + 1) + c0 / (s^2 + b s + w0^2), u = w^2: a quadratic.
Poly LagPlusResonanceNumerator(double c0, double b, double w0sq) {
  const Q a = Exact(c0), bb = Exact(b) * Exact(b), w2 = Exact(w0sq);
  // (w2 - u)^2 + bb u + a (w2 - u)(1 + u)
  return {w2 * w2 + a * w2, bb - 2 * w2 + a * w2 - a, 1 - a};
}

std::vector<Eigen::VectorXd> Scalings(int n) {
  std::vector<Eigen::VectorXd> out;
  Eigen::VectorXd d(n);
  for (int i = 0; i < n; ++i) d(i) = std::pow(10.0, -7.0 + 14.0 * i / std::max(1, n - 1));
  out.push_back(d);
  out.push_back(d.reverse());
  for (int i = 0; i < n; ++i) d(i) = std::ldexp(1.0, i % 2 ? 23 : -23);  // 2^+-23, about 1e+-7, exact
  out.push_back(d);
  return out;
}

// ---- the three failures of the issue -------------------------------------------------------------------

// G(s) = 1/(s + 1) + 0.5 s/(s^2 + s + 1e14): minimal, Hurwitz, strictly positive real (both terms are
// positive real, the first strictly: Re G(jw) = 1/(1 + u) + 0.5 u / ((1e14 - u)^2 + u) > 0). Its PBH
// margin relative to max(1, |A|, |B|) was 1e-21, and the report said "minimal: fails", "A Hurwitz:
// undetermined" (sqrt(eps) |A| = 1.5e6) and "-(CAB + (CAB)^T) > 0: undetermined" (value 3, band 8.9).
TEST(AbsoluteStabilityExact, BadlyScaledMinimalRealisationIsMinimalAndStrictlyPositiveReal) {
  const Realisation s = LagPlusResonance(0.0, 0.5, 1.0, 1e14);
  // Kalman's determinants, exactly: det [B, AB, A^2 B] and det [C; CA; CA^2] are far from 0.
  auto det3 = [](const Eigen::Matrix3d& M) -> Q {
    Q m[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[i][j] = Exact(M(i, j));
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  };
  Eigen::Matrix3d K, O;
  K << s.B, s.A * s.B, s.A * s.A * s.B;
  O << s.C, s.C * s.A, s.C * s.A * s.A;
  EXPECT_GT(boost::multiprecision::abs(det3(K)), Q(1e13));
  EXPECT_GT(boost::multiprecision::abs(det3(O)), Q(1e13));

  for (const Realisation& r : {s, s.Scaled(Eigen::Vector3d(1.0, 1e-7, 1.0)), s.Scaled(Eigen::Vector3d(1e7, 1.0, 1e-7)),
                               s.Scaled(Eigen::Vector3d(1e-7, 3e3, 1e7))}) {
    const MinimalityCheck m = check_minimality(r.A, r.B, r.C);
    EXPECT_EQ(m.verdict(), Verdict::kHolds) << m.method;
    EXPECT_TRUE(m.exact);
    EXPECT_EQ(m.controllability_rank, 3);
    EXPECT_EQ(m.observability_rank, 3);
    const PositiveRealnessTest t = test_strict_positive_realness(r.A, r.B, r.C);
    EXPECT_EQ(t.hurwitz, Verdict::kHolds) << t.hurwitz_method;
    EXPECT_EQ(t.cb, Verdict::kHolds);
    EXPECT_EQ(t.high_frequency, Verdict::kHolds);
    EXPECT_NEAR(t.high_frequency_min_eigenvalue, 3.0, 1e-6);  // -(CAB + (CAB)^T) = 2 (1 + 0.5)
    EXPECT_EQ(t.frequency, Verdict::kHolds) << t.method;
    EXPECT_EQ(t.frequency_exact, Verdict::kHolds);
    EXPECT_TRUE(t.crossings.empty());
    EXPECT_EQ(t.spr, Verdict::kHolds) << t.witness;
  }
  // The balanced PBH margins do not depend on the state's scaling (powers of two balance exactly alike).
  const MinimalityCheck m0 = check_minimality(s.A, s.B, s.C);
  const Realisation r2 = s.Scaled(Eigen::Vector3d(0x1p-20, 0x1p23, 0x1p-3));
  const MinimalityCheck m2 = check_minimality(r2.A, r2.B, r2.C);
  // Balancing ends within a factor of 2 per coordinate of a balanced form, from wherever it starts.
  EXPECT_GT(m2.controllability_margin / m0.controllability_margin, 1.0 / 16);
  EXPECT_LT(m2.controllability_margin / m0.controllability_margin, 16.0);
  EXPECT_GT(m2.observability_margin / m0.observability_margin, 1.0 / 16);
  EXPECT_LT(m2.observability_margin / m0.observability_margin, 16.0);
}

// The exact deciders' cost grows with the bits of the entries: a realisation whose entries span more than
// 2^256 (here the same G(s) as above, its state scaled by powers of two up to 2^+-400, which change no
// mantissa) is decided in floating point on the balanced realisation, where a small margin is
// "undetermined", never "fails": G is minimal and SPR, so neither verdict may be "fails". Within the cap
// the exact deciders still run, and decide both.
TEST(AbsoluteStabilityExact, EntriesSpreadBeyondTheCapAreDecidedOnTheBalancedRealisation) {
  const Realisation s = LagPlusResonance(0.0, 0.5, 1.0, 1e14);
  const Realisation wide = s.Scaled(Eigen::Vector3d(0x1p-400, 1.0, 0x1p400));
  const MinimalityCheck m = check_minimality(wide.A, wide.B, wide.C);
  EXPECT_FALSE(m.exact);
  EXPECT_NE(m.method.find("too wide for the exact test"), std::string::npos) << m.method;
  EXPECT_NE(m.verdict(), Verdict::kFails) << m.method;
  const PositiveRealnessTest t = test_strict_positive_realness(wide.A, wide.B, wide.C);
  EXPECT_FALSE(t.exact);
  EXPECT_NE(t.method.find("too wide for the exact test"), std::string::npos) << t.method;
  EXPECT_NE(t.spr, Verdict::kFails) << t.witness;

  const Realisation within = s.Scaled(Eigen::Vector3d(0x1p-60, 1.0, 0x1p60));
  const MinimalityCheck e = check_minimality(within.A, within.B, within.C);
  EXPECT_TRUE(e.exact) << e.method;
  EXPECT_EQ(e.verdict(), Verdict::kHolds);
  const PositiveRealnessTest te = test_strict_positive_realness(within.A, within.B, within.C);
  EXPECT_TRUE(te.exact) << te.method;
  EXPECT_EQ(te.spr, Verdict::kHolds) << te.witness;
}

// Re G(jw) of G = 1/(s + 1) + a/(s^2 + 0.1 s + 100) dips to -1e-9 on a band 4.6e-5 rad/s wide near
// w = 10.05: the numerator quadratic has two positive roots (exact discriminant > 0). It was "undetermined".
TEST(AbsoluteStabilityExact, DipToMinusOneBillionthFailsWithItsCrossings) {
  const double a = 0.01970492319332368, b = 0.1, w0sq = 100.0;
  const Poly q = LagPlusResonanceNumerator(a, b, w0sq);
  const Q disc = q[1] * q[1] - 4 * q[2] * q[0];
  ASSERT_GT(disc, 0);
  ASSERT_LT(q[1], 0);  // both roots positive (q[0], q[2] > 0)
  const F50 sq = boost::multiprecision::sqrt(ToF50(disc));
  const F50 u1 = (-ToF50(q[1]) - sq) / (2 * ToF50(q[2])), u2 = (-ToF50(q[1]) + sq) / (2 * ToF50(q[2]));
  const double w1 = static_cast<double>(boost::multiprecision::sqrt(u1)), w2 = static_cast<double>(boost::multiprecision::sqrt(u2));
  auto re_g = [&](const Q& u) {  // exact
    const Q w2q = Exact(w0sq), bq = Exact(b);
    return 1 / (1 + u) + Exact(a) * (w2q - u) / ((w2q - u) * (w2q - u) + bq * bq * u);
  };
  // The dip: about -1e-9 at its deepest (between the roots, at the minimum of the closed form).
  Q deepest = 1;
  for (int k = 1; k < 200; ++k) {
    const Q u = Exact(static_cast<double>(u1 + (u2 - u1) * k / 200));
    deepest = std::min(deepest, re_g(u));
  }
  EXPECT_LT(deepest, Q(-0.9e-9));
  EXPECT_GT(deepest, Q(-1.1e-9));

  const Realisation s = LagPlusResonance(a, 0.0, b, w0sq);
  const std::vector<Eigen::VectorXd> scalings = Scalings(3);
  const std::vector<Realisation> variants{s, s.Scaled(scalings[0]), s.Scaled(scalings[1]), s.Scaled(scalings[2])};
  for (std::size_t v = 0; v < variants.size(); ++v) {
    const Realisation& r = variants[v];
    {
      const PositiveRealnessTest t = test_strict_positive_realness(r.A, r.B, r.C);
      EXPECT_EQ(t.hurwitz, Verdict::kHolds);
      EXPECT_EQ(t.frequency, Verdict::kFails) << t.method;
      EXPECT_EQ(t.frequency_method, "Sturm (exact)");
      EXPECT_EQ(t.spr, Verdict::kFails);
      ASSERT_EQ(t.crossings.size(), 2u);
      if (v == 0 || v == 3) {
        // Powers of two leave G exactly as it is: the crossings are the closed form's to the spacing of doubles.
        EXPECT_NEAR(t.crossings[0], w1, 4e-16 * w1);
        EXPECT_NEAR(t.crossings[1], w2, 4e-16 * w2);
      } else {
        EXPECT_NEAR(t.crossings[0], w1, 1e-9 * w1);
        EXPECT_NEAR(t.crossings[1], w2, 1e-9 * w2);
      }
      EXPECT_GT(t.witness_omega, w1);
      EXPECT_LT(t.witness_omega, w2);
      EXPECT_LT(re_g(Exact(t.witness_omega) * Exact(t.witness_omega)), 0);
      EXPECT_LT(t.witness_value, 0.0);
      EXPECT_NE(t.witness.find("between the crossings"), std::string::npos) << t.witness;
    }
  }
}

// G = 1/(s + 1) + 0.5/(s^2 + b s + 1e14), b = 2928932.14...: Re G(jw) < 0 only on a band about 740 rad/s
// wide near w = 1.189e7 (verified here from the closed form). It was "undetermined", with the frequency
// test "not checked" (A Hurwitz undetermined).
TEST(AbsoluteStabilityExact, BandOf740RadPerSecondNearTenMegaradiansFails) {
  const double a = 0.5, b = 2928932.1413939656, w0sq = 1e14;
  const Poly q = LagPlusResonanceNumerator(a, b, w0sq);
  const Q disc = q[1] * q[1] - 4 * q[2] * q[0];
  ASSERT_GT(disc, 0);
  ASSERT_LT(q[1], 0);
  const F50 sq = boost::multiprecision::sqrt(ToF50(disc));
  const F50 w1 = boost::multiprecision::sqrt((-ToF50(q[1]) - sq) / (2 * ToF50(q[2])));
  const F50 w2 = boost::multiprecision::sqrt((-ToF50(q[1]) + sq) / (2 * ToF50(q[2])));
  EXPECT_GT(w2 - w1, 700);
  EXPECT_LT(w2 - w1, 780);
  EXPECT_GT(w1, 1.1e7);
  EXPECT_LT(w2, 1.2e7);

  const Realisation s = LagPlusResonance(a, 0.0, b, w0sq);
  std::vector<Realisation> variants{s};
  for (const Eigen::VectorXd& d : Scalings(3)) variants.push_back(s.Scaled(d));
  for (const Realisation& r : variants) {
    {
      EXPECT_EQ(check_minimality(r.A, r.B, r.C).verdict(), Verdict::kHolds);
      const PositiveRealnessTest t = test_strict_positive_realness(r.A, r.B, r.C);
      EXPECT_EQ(t.hurwitz, Verdict::kHolds) << t.hurwitz_method;
      EXPECT_EQ(t.cb, Verdict::kHolds);
      EXPECT_EQ(t.high_frequency, Verdict::kHolds);  // -(CAB + (CAB)^T) = 2 (1 - 0.5)
      EXPECT_EQ(t.frequency, Verdict::kFails) << t.method;
      EXPECT_EQ(t.frequency_method, "Sturm (exact)");
      EXPECT_EQ(t.spr, Verdict::kFails);
      ASSERT_EQ(t.crossings.size(), 2u);
      EXPECT_NEAR(t.crossings[0], static_cast<double>(w1), 1e-9 * static_cast<double>(w1));
      EXPECT_NEAR(t.crossings[1], static_cast<double>(w2), 1e-9 * static_cast<double>(w2));
      EXPECT_GT(t.witness_omega, static_cast<double>(w1));
      EXPECT_LT(t.witness_omega, static_cast<double>(w2));
    }
  }
}

// ---- random realisations against the exact references --------------------------------------------------

struct Case {
  Realisation r;
  Poly num, den;
  bool hurwitz = true;
};

// Block-diagonal (modal) form: blocks -s (1 x 1) and [[sigma, w], [-w, sigma]] (2 x 2), B and C random;
// sometimes a block's B or C is 0 (not minimal, exactly), sometimes C = B^T (then P = I proves SPR when
// every sigma < 0), sometimes one sigma > 0.
Case RandomModal(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal;
  auto decade = [&](double lo, double hi) { return std::pow(10.0, lo + (hi - lo) * unit(rng)); };
  const int blocks = 1 + static_cast<int>(unit(rng) * 3.0);
  std::vector<int> sizes;
  int n = 0;
  for (int k = 0; k < blocks; ++k) {
    sizes.push_back(unit(rng) < 0.5 ? 1 : 2);
    n += sizes.back();
  }
  Case c;
  c.r = {Eigen::MatrixXd::Zero(n, n), Eigen::MatrixXd(n, 1), Eigen::MatrixXd(1, n)};
  const bool passive = unit(rng) < 0.5;
  const int dead = unit(rng) < 0.2 ? static_cast<int>(unit(rng) * blocks) : -1;
  const bool dead_input = unit(rng) < 0.5;
  const int unstable = unit(rng) < 0.1 ? static_cast<int>(unit(rng) * blocks) : -1;
  c.num = {};
  c.den = {Q(1)};
  int at = 0;
  for (int k = 0; k < blocks; ++k) {
    const int sz = sizes[k];
    const double sigma = (k == unstable ? 1.0 : -1.0) * decade(-2.0, sz == 1 ? 9.0 : 8.0);
    Poly dk, nk;
    if (sz == 1) {
      c.r.A(at, at) = sigma;
      dk = {-Exact(sigma), Q(1)};
    } else {
      const double w = decade(-2.0, 9.0);
      c.r.A(at, at) = c.r.A(at + 1, at + 1) = sigma;
      c.r.A(at, at + 1) = w;
      c.r.A(at + 1, at) = -w;
      dk = {Exact(sigma) * Exact(sigma) + Exact(w) * Exact(w), -2 * Exact(sigma), Q(1)};
    }
    for (int i = 0; i < sz; ++i) {
      c.r.B(at + i, 0) = normal(rng);
      c.r.C(0, at + i) = passive ? c.r.B(at + i, 0) : normal(rng);
      if (!passive && unit(rng) < 0.3) c.r.C(0, at + i) = c.r.B(at + i, 0) * (1.0 + 0.3 * normal(rng));
    }
    if (k == dead) {
      for (int i = 0; i < sz; ++i) (dead_input ? c.r.B(at + i, 0) : c.r.C(0, at + i)) = 0.0;
    }
    // The block's C_k adj(sI - A_k) B_k, exactly.
    if (sz == 1) {
      nk = {Exact(c.r.C(0, at)) * Exact(c.r.B(at, 0))};
    } else {
      // adj(sI - A_k) = [[s - sigma, w], [-w, s - sigma]].
      const Q c0 = Exact(c.r.C(0, at)), c1 = Exact(c.r.C(0, at + 1)), b0 = Exact(c.r.B(at, 0)), b1 = Exact(c.r.B(at + 1, 0));
      const Q sg = Exact(sigma), w = Exact(c.r.A(at, at + 1));
      nk = {-sg * (c0 * b0 + c1 * b1) + w * (c0 * b1 - c1 * b0), c0 * b0 + c1 * b1};
    }
    Trim(nk);
    c.num = Add(Mul(c.num, dk), Mul(nk, c.den));
    c.den = Mul(c.den, dk);
    c.hurwitz = c.hurwitz && sigma < 0.0;
    at += sz;
  }
  return c;
}

// Companion (controllable canonical) form of n(s)/d(s) with d from random stable roots up to 1e9 in
// magnitude (coefficients then span up to 50 decades): A = [0 I; -d_0 ... -d_{n-1}], B = e_n,
// C = (n_0, ..., n_{n-1}). G is read off the stored doubles exactly.
Case RandomCompanion(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal;
  auto decade = [&](double lo, double hi) { return std::pow(10.0, lo + (hi - lo) * unit(rng)); };
  // d(s) from roots, in long double, then rounded: the stored coefficients define the system.
  std::vector<long double> d{1.0L};
  auto mul = [&](std::vector<long double> f) {
    std::vector<long double> out(d.size() + f.size() - 1, 0.0L);
    for (std::size_t i = 0; i < d.size(); ++i)
      for (std::size_t j = 0; j < f.size(); ++j) out[i + j] += d[i] * f[j];
    d = out;
  };
  const int factors = 1 + static_cast<int>(unit(rng) * 3.0);
  const double scale = decade(-1.0, 8.0);  // the system's frequency scale
  for (int k = 0; k < factors; ++k) {
    const long double p = scale * decade(-1.0, 1.0);
    if (unit(rng) < 0.5) {
      mul({p, 1.0L});
    } else {
      const long double zeta = decade(-3.0, 0.0);
      mul({p * p, 2.0L * zeta * p, 1.0L});
    }
  }
  const int n = static_cast<int>(d.size()) - 1;
  Case c;
  c.r = {Eigen::MatrixXd::Zero(n, n), Eigen::MatrixXd::Zero(n, 1), Eigen::MatrixXd(1, n)};
  for (int i = 0; i + 1 < n; ++i) c.r.A(i, i + 1) = 1.0;
  for (int i = 0; i < n; ++i) c.r.A(n - 1, i) = -static_cast<double>(d[i] / d[n]);
  c.r.B(n - 1, 0) = 1.0;
  // Numerator: n_{n-1} = 1 (CB > 0), the others about d's, sometimes a common factor with d.
  std::vector<long double> num(static_cast<std::size_t>(n), 0.0L);
  num[n - 1] = 1.0L;
  if (n >= 2) {
    for (int i = 0; i + 1 < n; ++i) num[i] = d[i + 1] / d[n] * (0.5L + unit(rng)) * (unit(rng) < 0.15 ? -1.0L : 1.0L);
  }
  for (int i = 0; i < n; ++i) c.r.C(0, i) = static_cast<double>(num[i]);
  for (int i = 0; i < n; ++i) c.den.push_back(-Exact(c.r.A(n - 1, i)));
  c.den.push_back(Q(1));
  for (int i = 0; i < n; ++i) c.num.push_back(Exact(c.r.C(0, i)));
  Trim(c.num);
  // Hurwitz: the stored coefficients' roots, by Routh's test here (written independently of the code's).
  {
    std::vector<Q> p = c.den;  // constant first
    std::vector<Q> r0, r1;
    for (int k = n; k >= 0; k -= 2) r0.push_back(p[k]);
    for (int k = n - 1; k >= 0; k -= 2) r1.push_back(p[k]);
    bool ok = true;
    for (int row = 0; row < n && ok; ++row) {
      if (r1.empty() || r1[0] <= 0) {
        ok = false;
        break;
      }
      std::vector<Q> r2;
      for (std::size_t j = 0; j + 1 < r0.size(); ++j) r2.push_back(r0[j + 1] - r0[0] / r1[0] * (j + 1 < r1.size() ? r1[j + 1] : Q(0)));
      r0 = r1;
      r1 = r2;
    }
    c.hurwitz = ok;
  }
  return c;
}

void CheckAgainstReference(const Case& c, const std::string& what) {
  const Reference ref = Decide(c.num, c.den, c.hurwitz);
  const Verdict want_minimal = ref.minimal ? Verdict::kHolds : Verdict::kFails;
  const Verdict want_hurwitz = c.hurwitz ? Verdict::kHolds : Verdict::kFails;
  const Verdict want_spr = ref.spr ? Verdict::kHolds : Verdict::kFails;
  const int n = static_cast<int>(c.r.A.rows());
  std::vector<Realisation> variants{c.r};
  for (const Eigen::VectorXd& d : Scalings(n)) variants.push_back(c.r.Scaled(d));
  // The reference is exact for the unscaled realisation and for the scaling by powers of two (the same
  // G exactly); the powers of ten round each entry once, which moves no verdict of a generic system.
  for (std::size_t v = 0; v < variants.size(); ++v) {
    const Realisation& r = variants[v];
    const MinimalityCheck m = check_minimality(r.A, r.B, r.C);
    const PositiveRealnessTest t = test_strict_positive_realness(r.A, r.B, r.C);
    EXPECT_EQ(m.verdict(), want_minimal) << what << " variant " << v << ": " << m.method;
    EXPECT_EQ(t.hurwitz, want_hurwitz) << what << " variant " << v;
    EXPECT_EQ(t.spr, want_spr) << what << " variant " << v << ": " << t.witness << " / " << t.method;
  }
}

TEST(AbsoluteStabilityExact, RandomModalRealisationsAgreeWithTheExactReference) {
  std::mt19937 rng(20270101);
  int spr = 0, not_spr = 0, non_minimal = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Case c = RandomModal(rng);
    const Reference ref = Decide(c.num, c.den, c.hurwitz);
    spr += ref.spr;
    not_spr += !ref.spr;
    non_minimal += !ref.minimal;
    CheckAgainstReference(c, "modal trial " + std::to_string(trial));
  }
  // Every answer occurs: the comparison is not vacuous.
  EXPECT_GT(spr, 5);
  EXPECT_GT(not_spr, 5);
  EXPECT_GT(non_minimal, 3);
}

TEST(AbsoluteStabilityExact, RandomCompanionRealisationsAgreeWithTheExactReference) {
  std::mt19937 rng(20270102);
  int spr = 0, not_spr = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Case c = RandomCompanion(rng);
    const Reference ref = Decide(c.num, c.den, c.hurwitz);
    spr += ref.spr;
    not_spr += !ref.spr;
    CheckAgainstReference(c, "companion trial " + std::to_string(trial));
  }
  EXPECT_GT(spr, 5);
  EXPECT_GT(not_spr, 5);
}

}  // namespace
}  // namespace moreau
