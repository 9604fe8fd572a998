// The hypotheses of Lemmas 1 and 2 of Brogliato (2003) for a Lur'e system (4), x' = A x - B y_L,
// y = C x, y_L in d phi(y): assumption a), G(s) = C (sI - A)^{-1} B strictly positive real (SPR) with a
// minimal realisation, which by the Kalman-Yakubovich-Popov lemma gives P = P^T > 0 with
// P A + A^T P = -Q < 0 and B^T P = C.
//
//  - check_storage_matrix(): given P, checks each of the three conditions (and reports its margin).
//  - check_minimality(): controllability and observability of (A, B, C).
//  - test_strict_positive_realness(): without P, decides SPR for a strictly proper square G by the
//    frequency-domain characterisation (Tao and Ioannou 1988):
//      (i)   A Hurwitz;
//      (ii)  Phi(jw) = G(jw) + G(jw)^H > 0 for every real w;
//      (iii) CB = (CB)^T > 0 and lim_{w->inf} w^2 Phi(jw) = -(CAB + (CAB)^T) > 0.
//
// Two kinds of decider, and the verdicts say which one decided.
//
// Exact (n <= kExactMaxStates): every double is a dyadic rational, so the matrices as stored have exact
// rational entries and each question has an exact answer, computed in rational arithmetic (no round-off,
// so nothing depends on how the state is scaled):
//   minimality: rank [B, AB, ..., A^{n-1} B] = n and rank [C; CA; ...; CA^{n-1}] = n (Kalman);
//   (i): Routh's test on d(s) = det(sI - A) (Faddeev-LeVerrier);
//   (iii): CB, CAB and the definiteness of CB and -(CAB + (CAB)^T) (Sylvester's criterion);
//   (ii): with adj(sI - A) from the same recursion, N(s) = P(s) d(-s) + P(-s)^T d(s), P(s) = C adj(sI - A) B,
//     is the numerator of the Popov function Phi(s) = G(s) + G(-s)^T = N(s) / (d(s) d(-s)); on the axis
//     Phi(jw) = N(jw) / |d(jw)|^2 has the inertia of N(jw). det N(s) is even: det N(jw) = q(w^2) for a real
//     polynomial q (interpolated exactly at integer points). Phi(jw) is continuous, so it is positive
//     definite for every w iff Phi(0) > 0 and q has no positive root. Sturm's theorem counts and isolates
//     those roots (the crossing frequencies, refined by bisection to the spacing of doubles); between two
//     crossings the inertia is constant, and one exact definiteness test of N(jw) per interval finds where
//     Phi < 0: the witness frequency. A crossing where Phi only touches 0 fails too (Phi singular there).
//   An exact "fails" of CB's symmetry by no more than the rounding of the entries (relative asymmetry
//   below 100 (n + 1) eps) is reported undetermined: the stored numbers cannot be symmetric in intent and
//   exact, and the failure it causes at high frequency says nothing about the system meant.
//
// Floating point (every n; the only decider above kExactMaxStates, a second independent one below it):
//   the realisation is first balanced by a diagonal similarity of powers of two (exact: it changes no
//   entry's mantissa; Parlett and Reinsch 1969 on [A B; C 0] with the input and output coordinates fixed),
//   so margins do not depend on how the state was scaled;
//   minimality: the Popov-Belevitch-Hautus margin min_l sigma_min([A - l I, B]) / max(|A|, |B|) (and the
//     dual), relative to the balanced matrices: holds above 1e-8, otherwise undetermined (a small margin is
//     never a proof of non-minimality);
//   (i): the eigenvalues of the balanced A, undetermined within sqrt(eps) |A| of the axis;
//   (ii): the Popov pencil. The zeros of Phi are the finite generalized eigenvalues of the Rosenbrock pencil
//     s N - M, M = [[A_P, B_P], [-C_P, 0]], N = diag(I_2n, 0) (QZ), the pencil form of the Hamiltonian test
//     of the KYP lemma for a strictly proper G. Every finite eigenvalue's |Im| is a candidate; between
//     consecutive candidates, and beyond the last, the sign of lambda_min(Phi(jw)) is constant, so evaluating
//     it at 0, at every candidate, at each midpoint and beyond the last decides (ii) up to round-off. The
//     value compared is (1 + (w/wc)^2) lambda_min(Phi(jw)), wc = max(1, rho(A)); a value within round-off
//     of 0 (estimated from the conditioning of jwI - A) gives "undetermined". A log sweep refined by golden
//     section gives the smallest value found (the margin reported).
//
// When SPR is not refuted, a certificate is sought: a symmetric P on the affine set {B^T P = C},
// maximising min(lambda_min(P), lambda_min(-(PA + A^T P))) (concave) by Nelder-Mead, on the realisation as
// given and, failing that, on the balanced one; a P that passes check_storage_matrix() is an independent
// proof (KYP) and gives the storage function W = 1/2 x^T P x.
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

// The largest n for which the exact deciders run. Their numbers grow with n (the entries of A^k B have
// about k times the bits of A's): measured on modal realisations with poles from 1e-2 to 1e9 rad/s and
// state scalings from 1e-7 to 1e7, minimality and SPR together took about 25 ms at n = 8 and 20 ms to
// 6 s at n = 10 to 12.
constexpr int kExactMaxStates = 8;

struct PositiveRealnessTest {
  Verdict spr = Verdict::kNotChecked;  // all_of(hurwitz, cb, high_frequency, frequency)
  std::string witness;                 // when spr is kFails: the first failing condition and its numbers
  std::string method;                  // how it was decided, in words
  bool exact = false;                  // (i), (ii), (iii) decided in exact rational arithmetic

  Verdict hurwitz = Verdict::kNotChecked;
  std::string hurwitz_method;      // "Routh (exact)" or "eigenvalues (floating point)"
  double spectral_abscissa = 0.0;  // max Re lambda(A), from the balanced A
  double hurwitz_tolerance = 0.0;  // the floating-point test's band: |spectral_abscissa| below this

  Verdict cb = Verdict::kNotChecked;  // CB = (CB)^T > 0
  double cb_min_eigenvalue = 0.0;
  double cb_asymmetry = 0.0;
  Verdict high_frequency = Verdict::kNotChecked;  // -(CAB + (CAB)^T) > 0
  double high_frequency_min_eigenvalue = 0.0;

  Verdict frequency = Verdict::kNotChecked;         // lambda_min(G(jw) + G(jw)^H) > 0 for every real w
  std::string frequency_method;                     // which test decided (ii): "Sturm (exact)" or "Popov pencil"
  Verdict frequency_exact = Verdict::kNotChecked;   // the exact Sturm test's own verdict
  Verdict frequency_pencil = Verdict::kNotChecked;  // the floating-point Popov-pencil test's own verdict
  std::vector<double> crossings;                    // exact test: the w > 0 where det Phi(jw) = 0, each to the spacing of doubles
  double min_frequency_eigenvalue = 0.0;            // smallest (1 + (w/wc)^2) lambda_min(G + G^H) found
  double argmin_omega = 0.0;
  double frequency_tolerance = 0.0;         // the round-off bound at argmin_omega
  double witness_omega = -1.0;              // a w where Phi(jw) is not positive definite, when frequency fails
  double witness_value = 0.0;               // (1 + (w/wc)^2) lambda_min(Phi(jw)) there
  std::vector<double> crossing_candidates;  // |Im| of the pencil's finite eigenvalues, sorted, unique
  int frequencies = 0;                      // evaluations of G(jw)
  double wc = 1.0;

  Verdict certificate = Verdict::kNotChecked;  // a P passing check_storage_matrix()
  std::string storage_method;
  Eigen::MatrixXd P;
  StorageMatrixCheck storage_check;
  bool storage_found() const { return certificate == Verdict::kHolds; }
};

// Minimality of (A, B, C). For n <= kExactMaxStates, exactly (the Kalman ranks in rational arithmetic:
// holds or fails, for the matrices as stored). The Popov-Belevitch-Hautus margins of the balanced
// realisation are computed in every case (for larger n they decide: holds above 1e-8, otherwise
// undetermined): min over the eigenvalues l of A of sigma_min([A - l I, B]) / max(|A|, |B|) (resp.
// [A - l I; C]), invariant to a diagonal scaling of the state.
struct MinimalityCheck {
  Verdict controllable = Verdict::kNotChecked;
  Verdict observable = Verdict::kNotChecked;
  bool exact = false;                   // decided by the exact ranks
  int controllability_rank = -1;        // exact rank of [B, AB, ..., A^{n-1} B] (-1: not computed)
  int observability_rank = -1;          // exact rank of [C; CA; ...; CA^{n-1}]
  double controllability_margin = 0.0;  // balanced PBH margins
  double observability_margin = 0.0;
  std::string method;  // how it was decided, in words
  Verdict verdict() const { return all_of(controllable, observable); }
};

MinimalityCheck check_minimality(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

PositiveRealnessTest test_strict_positive_realness(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

}  // namespace moreau
