// The hypotheses of Lemmas 1 and 2 of Brogliato (2003) for a Lur'e system (4), x' = A x - B y_L,
// y = C x, y_L in d phi(y): assumption a), G(s) = C (sI - A)^{-1} B strictly positive real (SPR) with a
// minimal realisation, which by the Kalman-Yakubovich-Popov lemma gives P = P^T > 0 with
// P A + A^T P = -Q < 0 and B^T P = C.
//
//  - check_storage_matrix(): given P, checks each of the three conditions (and reports its margin).
//  - test_strict_positive_realness(): without P, decides SPR for a strictly proper square G by the
//    frequency-domain characterisation (Tao and Ioannou 1988):
//      (i)   A Hurwitz;
//      (ii)  Phi(jw) = G(jw) + G(jw)^H > 0 for every real w;
//      (iii) CB = (CB)^T > 0 and lim_{w->inf} w^2 Phi(jw) = -(CAB + (CAB)^T) > 0.
//    (ii) is decided exactly, not by sampling: lambda_min(Phi(jw)) is continuous in w (A Hurwitz) and can
//    change sign only where det Phi(jw) = 0, i.e. at an imaginary-axis zero of the Popov function
//    Phi(s) = G(s) + G(-s)^T = [C, -B^T] (sI - diag(A, -A^T))^{-1} [B; C^T]. Its zeros are the finite
//    generalized eigenvalues of the Rosenbrock pencil s N - M, M = [[A_P, B_P], [-C_P, 0]],
//    N = diag(I_2n, 0) (QZ). Every finite eigenvalue's |Im| is taken as a candidate (a superset of the
//    crossings, robust to round-off that moves an imaginary eigenvalue off the axis); between consecutive
//    candidates, and beyond the last, the sign of lambda_min is constant, so evaluating it at 0, at every
//    candidate, at each midpoint and beyond the last decides (ii). A narrow dip between two crossings is
//    found however narrow. The value compared is (1 + (w/wc)^2) lambda_min(Phi(jw)), wc = max(1, rho(A)),
//    whose limit is finite; a value within round-off of 0 (estimated from the conditioning of jwI - A)
//    gives "undetermined", never "holds". A log sweep refined by golden section adds the smallest value
//    found (the margin reported); the decision does not depend on it.
//    Minimality is a separate check (check_minimality(), Popov-Belevitch-Hautus).
//    When (i)-(iii) hold, a certificate is sought: a symmetric P on the affine set {B^T P = C},
//    maximising min(lambda_min(P), lambda_min(-(PA + A^T P))) (concave) by Nelder-Mead; a P that passes
//    check_storage_matrix() is an independent proof (KYP) and gives the storage function W = 1/2 x^T P x.
// Computed once per scene, not per step (dynamic-size Eigen).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Dense>

#include "moreau/core/verdict.h"

namespace moreau {

struct StorageMatrixCheck {
  bool symmetric = false;
  double asymmetry = 0.0;  // max |P - P^T| / max |P|
  bool positive_definite = false;
  double min_eigenvalue = 0.0;     // of (P + P^T) / 2
  bool dissipative = false;        // P A + A^T P < 0
  double max_eigenvalue_pa = 0.0;  // largest eigenvalue of P A + A^T P (= -lambda_min(Q))
  bool output_matches = false;     // B^T P = C
  double output_residual = 0.0;    // max |B^T P - C| / (max |B| max |P| + max |C|)
  bool all() const { return symmetric && positive_definite && dissipative && output_matches; }
  // Each condition: kHolds when its margin clears round-off; kFails when it is violated by more than
  // round-off (an eigenvalue of the wrong sign, an asymmetry or residual above 1e-8); kUndetermined between.
  Verdict symmetric_verdict() const { return symmetric ? Verdict::kHolds : asymmetry > 1e-8 ? Verdict::kFails : Verdict::kUndetermined; }
  Verdict positive_definite_verdict() const {
    return positive_definite ? Verdict::kHolds : min_eigenvalue < 0.0 ? Verdict::kFails : Verdict::kUndetermined;
  }
  Verdict dissipative_verdict() const {
    return dissipative ? Verdict::kHolds : max_eigenvalue_pa > 0.0 ? Verdict::kFails : Verdict::kUndetermined;
  }
  Verdict output_verdict() const {
    return output_matches ? Verdict::kHolds : output_residual > 1e-8 ? Verdict::kFails : Verdict::kUndetermined;
  }
  Verdict verdict() const {
    return all_of(all_of(symmetric_verdict(), positive_definite_verdict()), all_of(dissipative_verdict(), output_verdict()));
  }
};

StorageMatrixCheck check_storage_matrix(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C,
                                        const Eigen::MatrixXd& P);

struct PositiveRealnessTest {
  Verdict spr = Verdict::kNotChecked;  // all_of(hurwitz, cb, high_frequency, frequency)
  std::string witness;                 // when spr is kFails: the first failing condition and its numbers
  std::string method;                  // how it was decided, in words

  Verdict hurwitz = Verdict::kNotChecked;
  double spectral_abscissa = 0.0;  // max Re lambda(A)
  double hurwitz_tolerance = 0.0;  // |spectral_abscissa| below this: undetermined

  Verdict cb = Verdict::kNotChecked;  // CB = (CB)^T > 0
  double cb_min_eigenvalue = 0.0;
  double cb_asymmetry = 0.0;
  Verdict high_frequency = Verdict::kNotChecked;  // -(CAB + (CAB)^T) > 0
  double high_frequency_min_eigenvalue = 0.0;

  Verdict frequency = Verdict::kNotChecked;  // lambda_min(G(jw) + G(jw)^H) > 0 for every real w
  double min_frequency_eigenvalue = 0.0;     // smallest (1 + (w/wc)^2) lambda_min(G + G^H) found
  double argmin_omega = 0.0;
  double frequency_tolerance = 0.0;  // the round-off bound at argmin_omega
  double witness_omega = -1.0;       // a w with (1 + (w/wc)^2) lambda_min < -tolerance, when frequency fails
  double witness_value = 0.0;
  std::vector<double> crossing_candidates;  // |Im| of the pencil's finite eigenvalues, sorted, unique
  int frequencies = 0;                      // evaluations of G(jw)
  double wc = 1.0;

  Verdict certificate = Verdict::kNotChecked;  // a P passing check_storage_matrix()
  std::string storage_method;
  Eigen::MatrixXd P;
  StorageMatrixCheck storage_check;
  bool storage_found() const { return certificate == Verdict::kHolds; }
};

// Minimality of (A, B, C) by the Popov-Belevitch-Hautus test: min over the eigenvalues l of A of
// sigma_min([A - l I, B]) (resp. [A - l I; C]) relative to max(1, |A|, |B|) (resp. |C|). At an
// uncontrollable mode it is about eps |A| (more for a defective eigenvalue): holds above 1e-8, fails
// below 1e-12, undetermined in between.
struct MinimalityCheck {
  Verdict controllable = Verdict::kNotChecked;
  Verdict observable = Verdict::kNotChecked;
  double controllability_margin = 0.0;
  double observability_margin = 0.0;
  Verdict verdict() const { return all_of(controllable, observable); }
};

MinimalityCheck check_minimality(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

PositiveRealnessTest test_strict_positive_realness(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

}  // namespace moreau
