#include "moreau/core/absolute_stability.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <vector>

#include "exact_frequency.h"
#include "lti_exact.h"
#include "lti_numerics.h"
#include "moreau/platform/number_text.h"

namespace moreau {
namespace ex = lti_exact;
using namespace lti_detail;

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
      const ex::ExactFrequency e = ex::exact_frequency(Ae, Be, Ce, res, r.wc);
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
