// The strict positive realness decision of core/absolute_stability.h against independent references:
// closed forms of Re G(jw) (its zeros as roots of a polynomial in w^2), a certificate P checked here with
// Eigen's eigen-solvers, and, on random systems, a dense frequency sweep computed with a matrix inverse.
// The decision must never say "holds" where a sample is negative, must find dips a log grid misses, and
// every witness it gives must be negative when recomputed here.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <random>

#include <Eigen/Dense>

#include "moreau/core/absolute_stability.h"

namespace moreau {
namespace {

// lambda_min(G(jw) + G(jw)^H), G = C (jwI - A)^{-1} B by an explicit inverse (not the solver's LU).
double PopovReference(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C, double w) {
  const int n = static_cast<int>(A.rows());
  Eigen::MatrixXcd Z = std::complex<double>(0.0, w) * Eigen::MatrixXcd::Identity(n, n) - A.cast<std::complex<double>>();
  const Eigen::MatrixXcd G = C.cast<std::complex<double>>() * Z.inverse() * B.cast<std::complex<double>>();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> eig(G + G.adjoint(), Eigen::EigenvaluesOnly);
  return eig.eigenvalues()(0);
}

// The certificate's three conditions, recomputed here.
void ExpectCertificate(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C, const Eigen::MatrixXd& P) {
  EXPECT_LE((P - P.transpose()).cwiseAbs().maxCoeff(), 1e-12 * P.cwiseAbs().maxCoeff());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> p(0.5 * (P + P.transpose()));
  EXPECT_GT(p.eigenvalues()(0), 0.0);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> q(P * A + A.transpose() * P);
  EXPECT_LT(q.eigenvalues()(q.eigenvalues().size() - 1), 0.0);
  EXPECT_LE((B.transpose() * P - C).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + C.cwiseAbs().maxCoeff()));
}

// G(s) = 1/(s + 1) + 0.01/(s^2 + 2e-4 s + 100): Re G(jw) < 0 on a band just above w = 10.
struct LightlyDamped {
  Eigen::MatrixXd A, B, C;
  explicit LightlyDamped(double damping) : A(3, 3), B(3, 1), C(1, 3) {
    A << -1, 0, 0, 0, 0, 1, 0, -100, -damping;
    B << 1, 0, 1;
    C << 1, 0.01, 0;
  }
};

TEST(AbsoluteStability, NarrowDipThatALogGridMissesIsFoundWithAWitness) {
  const LightlyDamped s(2e-4);
  // Re G(jw) = 1/(1 + u) + 0.01 (100 - u) / ((100 - u)^2 + 4e-8 u), u = w^2; its numerator is
  // 0.99 u^2 - (199.01 - 4e-8) u + 10001: two positive roots, the edges of the band where Re G < 0.
  const double a = 0.99, b = -(199.01 - 4e-8), c = 10001.0;
  const double disc = std::sqrt(b * b - 4 * a * c);
  const double w_lo = std::sqrt((-b - disc) / (2 * a)), w_hi = std::sqrt((-b + disc) / (2 * a));
  ASSERT_LT(w_lo, w_hi);
  auto re_g = [](double w) {
    const double u = w * w;
    return 1.0 / (1.0 + u) + 0.01 * (100.0 - u) / ((100.0 - u) * (100.0 - u) + 4e-8 * u);
  };
  EXPECT_LT(re_g(0.5 * (w_lo + w_hi)), 0.0);
  EXPECT_LT(re_g(10.0001), -2.0);  // u - 100 = 2e-3: 1/101 - 2e-5/8e-6
  // The 1201-point log grid of [1e-6, 1e6] x wc (wc = 10) that the decision used to rest on sees no dip.
  double grid_min = 1e300;
  for (int j = 0; j < 1201; ++j) grid_min = std::min(grid_min, re_g(1e-5 * std::pow(10.0, 12.0 * j / 1200)));
  EXPECT_GT(grid_min, 0.0);

  const PositiveRealnessTest t = test_strict_positive_realness(s.A, s.B, s.C);
  EXPECT_EQ(t.hurwitz, Verdict::kHolds);
  EXPECT_EQ(t.frequency, Verdict::kFails);
  EXPECT_EQ(t.spr, Verdict::kFails);
  EXPECT_EQ(t.certificate, Verdict::kNotChecked);
  // The witness lies in the band, and is negative when recomputed independently.
  EXPECT_GT(t.witness_omega, w_lo);
  EXPECT_LT(t.witness_omega, w_hi);
  EXPECT_LT(re_g(t.witness_omega), 0.0);
  EXPECT_LT(PopovReference(s.A, s.B, s.C, t.witness_omega), 0.0);
  EXPECT_NE(t.witness.find("not positive definite at w = 10.0"), std::string::npos) << t.witness;
  // Both band edges are among the crossing candidates (eigenvalues of the Popov pencil).
  for (double w : {w_lo, w_hi}) {
    bool found = false;
    for (double cand : t.crossing_candidates) found = found || std::abs(cand - w) <= 1e-7 * w;
    EXPECT_TRUE(found) << "crossing " << w << " not among the candidates";
  }
}

TEST(AbsoluteStability, DampedVersionHoldsWithACertificateCheckedIndependently) {
  const LightlyDamped s(2.0);  // 0.01/(s^2 + 2 s + 100): Re G(jw) > 0 for every w
  const PositiveRealnessTest t = test_strict_positive_realness(s.A, s.B, s.C);
  EXPECT_EQ(t.spr, Verdict::kHolds) << t.witness;
  EXPECT_EQ(t.frequency, Verdict::kHolds);
  EXPECT_GT(t.min_frequency_eigenvalue, t.frequency_tolerance);
  ASSERT_EQ(t.certificate, Verdict::kHolds) << t.storage_method;
  ExpectCertificate(s.A, s.B, s.C, t.P);
  for (int j = 0; j <= 20000; ++j) {
    const double w = 1e-3 * std::pow(10.0, 7.0 * j / 20000);
    ASSERT_GT(PopovReference(s.A, s.B, s.C, w), 0.0) << "w = " << w;
  }
}

// 1/(s + 1): (1 + w^2) * 2 Re G(jw) = 2 at every w (wc = 1): the margin is known exactly.
TEST(AbsoluteStability, FirstOrderLagMarginIsTheClosedForm) {
  Eigen::MatrixXd A(1, 1), B(1, 1), C(1, 1);
  A << -1;
  B << 1;
  C << 1;
  const PositiveRealnessTest t = test_strict_positive_realness(A, B, C);
  EXPECT_EQ(t.spr, Verdict::kHolds);
  EXPECT_NEAR(t.min_frequency_eigenvalue, 2.0, 1e-12);
  EXPECT_NEAR(t.high_frequency_min_eigenvalue, 2.0, 1e-15);  // -(CAB + (CAB)^T) = 2
  EXPECT_NEAR(t.P(0, 0), 1.0, 1e-12);
}

TEST(AbsoluteStability, MultiInputMultiOutput) {
  Eigen::MatrixXd A = Eigen::Vector2d(-1.0, -2.0).asDiagonal(), B = Eigen::MatrixXd::Identity(2, 2), C = B;
  PositiveRealnessTest t = test_strict_positive_realness(A, B, C);  // diag(1/(s+1), 1/(s+2)), P = I
  EXPECT_EQ(t.spr, Verdict::kHolds);
  ASSERT_EQ(t.certificate, Verdict::kHolds) << t.storage_method;
  ExpectCertificate(A, B, C, t.P);

  C << 1, 1, 0, 1;  // CB not symmetric: G(jw) + G(jw)^H has a term (CB - CB^T)/(jw), indefinite at large w
  t = test_strict_positive_realness(A, B, C);
  EXPECT_EQ(t.cb, Verdict::kFails);
  EXPECT_EQ(t.spr, Verdict::kFails);
  EXPECT_EQ(t.frequency, Verdict::kFails);  // the (CB - CB^T)/(jw) term wins at large w
  EXPECT_LT(PopovReference(A, B, C, t.witness_omega), 0.0);

  // The narrow dip hidden in one channel of a two-channel system.
  const LightlyDamped s(2e-4);
  Eigen::MatrixXd A4 = Eigen::MatrixXd::Zero(4, 4), B4 = Eigen::MatrixXd::Zero(4, 2), C4 = Eigen::MatrixXd::Zero(2, 4);
  A4.topLeftCorner(3, 3) = s.A;
  A4(3, 3) = -3.0;
  B4.block(0, 0, 3, 1) = s.B;
  B4(3, 1) = 1.0;
  C4.block(0, 0, 1, 3) = s.C;
  C4(1, 3) = 1.0;
  t = test_strict_positive_realness(A4, B4, C4);
  EXPECT_EQ(t.spr, Verdict::kFails);
  EXPECT_NEAR(t.witness_omega, 10.0, 0.06);
  EXPECT_LT(PopovReference(A4, B4, C4, t.witness_omega), 0.0);

  // Not square: positive realness is not defined.
  t = test_strict_positive_realness(A, B.leftCols(1), C);
  EXPECT_EQ(t.spr, Verdict::kFails);
  EXPECT_NE(t.witness.find("square"), std::string::npos);
}

TEST(AbsoluteStability, MinimalityByPopovBelevitchHautus) {
  Eigen::MatrixXd A(2, 2), B(2, 1), C(1, 2);
  A << -1, 0, 0, -2;
  B << 1, 0;  // the mode at -2 is not driven
  C << 1, 1;
  MinimalityCheck m = check_minimality(A, B, C);
  EXPECT_EQ(m.controllable, Verdict::kFails);
  EXPECT_EQ(m.observable, Verdict::kHolds);
  EXPECT_EQ(m.verdict(), Verdict::kFails);
  B << 1, 1;
  C << 0, 1;  // the mode at -1 is not seen
  m = check_minimality(A, B, C);
  EXPECT_EQ(m.controllable, Verdict::kHolds);
  EXPECT_EQ(m.observable, Verdict::kFails);
  C << 1, 1;
  EXPECT_EQ(check_minimality(A, B, C).verdict(), Verdict::kHolds);
}

// Random stable systems: the exact decision against a dense sweep. "holds" must never meet a negative
// sample; a negative sample (beyond round-off) must be a "fails"; every witness must recompute negative.
TEST(AbsoluteStability, RandomSystemsAgreeWithADenseSweep) {
  std::mt19937 rng(20261125);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> margin(0.05, 1.0);
  std::uniform_int_distribution<int> size(1, 4);
  int holds = 0, fails = 0;
  for (int trial = 0; trial < 150; ++trial) {
    const int n = size(rng);
    Eigen::MatrixXd A(n, n), B(n, 1), C(1, n);
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) A(i, j) = normal(rng);
      B(i, 0) = normal(rng);
    }
    Eigen::EigenSolver<Eigen::MatrixXd> eig(A, false);
    A -= (eig.eigenvalues().real().maxCoeff() + margin(rng)) * Eigen::MatrixXd::Identity(n, n);
    if (trial % 2 == 0) {
      // C = B^T P with P > 0 from a Lyapunov-like choice: often SPR, sometimes not.
      Eigen::MatrixXd R(n, n);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) R(i, j) = normal(rng);
      const Eigen::MatrixXd P = R * R.transpose() + 0.1 * Eigen::MatrixXd::Identity(n, n);
      C = B.transpose() * P;
    } else {
      for (int i = 0; i < n; ++i) C(0, i) = normal(rng);
    }
    const PositiveRealnessTest t = test_strict_positive_realness(A, B, C);
    double sweep_min = PopovReference(A, B, C, 0.0);
    for (int j = 0; j <= 4000; ++j) sweep_min = std::min(sweep_min, PopovReference(A, B, C, 1e-3 * std::pow(10.0, 6.0 * j / 4000)));
    if (t.spr == Verdict::kHolds) {
      ++holds;
      EXPECT_GT(sweep_min, 0.0) << "trial " << trial;
    }
    if (sweep_min < -1e-9) {
      EXPECT_EQ(t.spr, Verdict::kFails) << "trial " << trial;
    }
    if (t.frequency == Verdict::kFails) {
      ++fails;
      EXPECT_LT(PopovReference(A, B, C, t.witness_omega), 0.0) << "trial " << trial;
    }
  }
  // Both answers occur: the comparison is not vacuous.
  EXPECT_GT(holds, 10);
  EXPECT_GT(fails, 10);
}

}  // namespace
}  // namespace moreau
