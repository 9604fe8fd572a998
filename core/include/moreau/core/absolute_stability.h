// The hypotheses of Lemmas 1 and 2 of Brogliato (2003) for a Lur'e system (4), x' = A x - B y_L,
// y = C x, y_L in d phi(y): assumption a), G(s) = C (sI - A)^{-1} B strictly positive real (SPR) with a
// minimal realisation, which by the Kalman-Yakubovich-Popov lemma gives P = P^T > 0 with
// P A + A^T P = -Q < 0 and B^T P = C.
//
//  - check_storage_matrix(): given P, checks each of the three conditions (and reports its margin).
//  - test_strict_positive_realness(): without P, tests SPR in the frequency domain, for a strictly proper
//    G (Tao and Ioannou 1988): A Hurwitz; G(jw) + G(jw)^H > 0 for every real w, evaluated (scaled by
//    1 + (w/wc)^2, wc = max(1, spectral radius of A), so that the decay like 1/w^2 does not hide the margin)
//    at w = 0 and on a logarithmic grid refined by golden-section search around its smallest value; and the
//    high-frequency conditions CB = (CB)^T > 0 and lim w^2 (G(jw) + G(jw)^H) = -(CAB + (CAB)^T) > 0.
//    Controllability and observability (minimality) are reported as well. Then it looks for a
//    certificate: a symmetric P on the affine set {B^T P = C}, maximising
//    min(lambda_min(P), lambda_min(-(PA + A^T P))) (a concave function) by Nelder-Mead; a P that passes
//    check_storage_matrix() proves the Lemma's hypotheses and is used for the storage function
//    W = 1/2 x^T P x.
// Computed once per scene, not per step (dynamic-size Eigen).
#pragma once

#include <string>

#include <Eigen/Dense>

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
};

StorageMatrixCheck check_storage_matrix(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C,
                                        const Eigen::MatrixXd& P);

struct PositiveRealnessTest {
  bool hurwitz = false;
  double spectral_abscissa = 0.0;  // max Re lambda(A)
  bool controllable = false;
  bool observable = false;
  bool cb_symmetric_positive = false;  // CB = (CB)^T > 0
  double cb_min_eigenvalue = 0.0;
  bool high_frequency = false;  // -(CAB + (CAB)^T) > 0
  double high_frequency_min_eigenvalue = 0.0;
  bool frequency = false;                 // lambda_min(G(jw) + G(jw)^H) > 0 on the sweep
  double min_frequency_eigenvalue = 0.0;  // min over the sweep of (1 + (w/wc)^2) lambda_min(G + G^H)
  double argmin_omega = 0.0;
  int frequencies = 0;  // evaluations of G(jw)
  double omega_min = 0.0, omega_max = 0.0;
  bool spr = false;    // all of the above except minimality
  std::string method;  // how it was tested, in words

  bool storage_found = false;  // a P passing check_storage_matrix()
  bool storage_attempted = false;
  std::string storage_method;
  Eigen::MatrixXd P;
  StorageMatrixCheck storage_check;
};

PositiveRealnessTest test_strict_positive_realness(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B, const Eigen::MatrixXd& C);

}  // namespace moreau
