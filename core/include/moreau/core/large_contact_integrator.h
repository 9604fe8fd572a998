// The Moreau-Jean scheme (eq. (8) of Brogliato 2003) for contact systems at scale: thousands of
// coordinates and contacts, each step in time and memory linear in their number.
//
// The system (large_contact_system.h): a constant diagonal mass matrix M, a constant force term g
// (gravity: M dv = -g dt + H^T dP), gaps h(q) with a sparse gradient H(q) = grad h(q)^T, linear (H
// constant: a stack of balls on a floor, a Newton's cradle) or nonlinear (balls against balls in a plane:
// a granular column), Newton restitution e_i per contact, no set-valued controller. The step is the step
// of moreau_jean_integrator.h with C = 0 and W = 0, so Wm = M, and H = H(Q^k):
//
//   V_free = V^k - h M^{-1} g,   U^k = H V^k,   I_k = {i : h_i(Q^k) + h H_i V_free <= 0 (to round-off)},
//   V^{k+1} = V_free + M^{-1} H_I^T P,   0 <= H_I V^{k+1} + e_I min(U_I^k, 0)  perp  P >= 0,   (LCP)
//   Q^{k+1} = Q^k + h V_pos^{k+1}  (V_pos as in moreau_jean_integrator.h: MDI by default),
//
// where it is structured rather than dense:
//  - M^{-1} is a vector; the Delassus operator D = H M^{-1} H^T (the LCP's matrix on I_k is D_II) is
//    sparse. With linear gaps it is formed once, since M, H and h are constant: the "factorise once" of a
//    constant M. With nonlinear gaps its rows on I_k are formed at a step whose H or I_k differs from the
//    last formed (a column at rest does not move: no new D, and the LCP's factor is reused);
//  - (LCP) is solved exactly by block principal pivoting with Murty's rule (sparse_lcp.h), which
//    terminates for the positive definite D of independent gradients and reuses the factor of D_FF while
//    neither the set of closed contacts nor D changes (a stack at rest: two triangular solves a step);
//  - every other pass (H V, H^T P, the gaps, energies, rest) is a sweep over the nonzeros; nonlinear gaps
//    and their gradients are evaluated once per step, at Q^{k+1} (the next step's Q^k).
// So a step costs O(n + nnz(H)) plus the factorisation of D_FF when the closed set or D changes, which
// for a banded D (a stack, a cradle, a column in a tube) is O(|F|) as well. Measured: docs/scaling.md.
//
// Exact values (the contract of the dense integrator): the rows of the closed set F have
// H_F V^{k+1} + e_F min(U_F^k, 0) == 0.0 in exact arithmetic; when F has n rows with a well-conditioned
// H_F, V^{k+1} is solved from them (a stack or a column at rest: V == 0.0 exactly), and a row of F with a
// single nonzero fixes its coordinate. The polished V is kept only where it is within the solve's
// round-off of the unpolished one.
//
// Impacts are recorded as the dense integrator records them, with the reference of eq. (9) computed over
// every contact that carries impulse in the step (the impacting ones and the closed contacts the impulse
// passes through, as in a touching Newton's cradle), by the same exact LCP solver: Moreau's impact law
// (simultaneous impacts, Newton restitution at each contact) from V^k at Q^k without smooth forces.
//
// Position correction (MoreauJeanSettings::correct_positions) projects onto {H q + c >= 0} in one LCP,
// exact for linear gaps; with nonlinear gaps that would be one Newton step of a projection, so it is not
// taken there (the run says so). Where this path is not the one: a mass matrix that is not constant and
// diagonal, a controller (dPhi), C or W nonzero: moreau_jean_integrator.h (dense, fixed-size where small).
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <Eigen/SparseLU>
#include <cstdint>
#include <string>
#include <vector>

#include "moreau/core/large_contact_system.h"
#include "moreau/core/moreau_jean_settings.h"
#include "moreau/core/observer.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/sparse_lcp.h"
#include "moreau/core/stepping_driver.h"

namespace moreau {

class LargeContactIntegrator {
 public:
  LargeContactIntegrator(const LargeContactIntegrator&) = delete;
  LargeContactIntegrator& operator=(const LargeContactIntegrator&) = delete;

  // Precondition: system.validate() is empty (checked again: a failing run says why).
  LargeContactIntegrator(const LargeContactSystem& system, const MoreauJeanSettings& settings);

  RunSummary run(const Eigen::VectorXd& q0, const Eigen::VectorXd& v0, RunObserver* observer = nullptr, ContactDiagnostics* diag = nullptr);

  // The Delassus operator D = H M^{-1} H^T (for inspection and tests).
  const Eigen::SparseMatrix<double>& delassus() const { return D_; }
  // The impulses P^{k+1} of the last step (0 outside I_k).
  const Eigen::VectorXd& impulses() const { return P_; }

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = false;
  static constexpr bool kTracksDissipation = false;
  void on_failure() {}
  int dof() const { return n_; }
  const double* q() const { return q_.data(); }
  const double* v() const { return v_.data(); }
  double energy() const { return kinetic_; }
  RestState rest_state() const { return rest_.update(v_); }
  double energy_allowance(double e_old, double e_initial) const;
  bool begin(double t, StepFailure& f);
  bool step(std::int64_t k, double t, double h, double t_next, RunRecorder& rec, StepFailure& f);
  bool arrive(std::int64_t k, double t, StepFailure& f);
  void finish(RunRecorder& rec, std::int64_t k, double t);

  double kinetic(const Eigen::VectorXd& v) const;
  double potential(const Eigen::VectorXd& q) const;
  void add_impulses(const std::vector<int>& rows, const Eigen::VectorXd& impulse,
                    Eigen::VectorXd& v) const;  // v += M^{-1} H_rows^T impulse
  void polish(Eigen::VectorXd& v);
  void record_impacts(ContactDiagnostics& d, std::int64_t step, double t, int impacts_now);
  bool correct(ContactDiagnostics& d);

  bool evaluate_gaps(const Eigen::VectorXd& q);  // gap_ (and H_, row_abs_sum_, offsets_ with nonlinear gaps)
  void form_delassus();                          // D_ on I_k from H_, when H_ or I_k changed (nonlinear gaps)
  std::string nonfinite_gap_message() const {
    return "the gap of contact " + std::to_string(nonfinite_contact_) + " or its gradient is not finite (coincident centres?)";
  }

  LargeContactSystem sys_;
  MoreauJeanSettings settings_;
  std::string invalid_;  // validate()'s answer at construction
  int n_ = 0, nc_ = 0;
  Eigen::VectorXd inv_mass_, accel_;  // M^{-1} and M^{-1} g
  double min_mass_ = 0.0;
  Eigen::SparseMatrix<double, Eigen::RowMajor> H_;  // grad h(Q^k)^T: the system's, or evaluated at Q^k
  Eigen::SparseMatrix<double> D_;                   // H M^{-1} H^T (nonlinear gaps: its rows on formed_)
  Eigen::VectorXd row_abs_sum_;                     // per contact: sum_j |H_ij|
  Eigen::VectorXd offsets_;                         // per contact: h_i(q) - H_i q (the constant c_i when linear)
  std::vector<double> gap_scratch_;                 // the nonlinear gap function's
  std::vector<double> previous_H_;                  // H_'s values when D_ was formed
  std::vector<char> formed_;                        // per contact: a row of the D_ formed last
  bool delassus_current_ = false;
  int nonfinite_contact_ = 0;  // evaluate_gaps(): the first contact whose gap or gradient is not finite                    // D_ is H_
                               // M^{-1} H_^T on every row of I_k
  Eigen::SparseMatrix<double, Eigen::RowMajor> HI_;  // scratch: H_'s rows on I_k
  SparseLcpSolver step_lcp_, impact_lcp_, correction_lcp_;

  Eigen::VectorXd q_, v_, qn_, vf_, vn_, vpos_;
  Eigen::VectorXd gap_, U_, Un_, Hvf_, lcp_q_, lcp_z_, lcp_w_, P_;
  std::vector<int> active_rows_;  // I_k, increasing
  std::vector<char> in_F_;        // per contact: closed (complementary set) in the last answer
  std::vector<char> was_active_;  // per contact: in I_{k-1}
  std::vector<char> impacting_;
  std::vector<int> rows_;  // scratch: a subset of the contacts
  double kinetic_ = 0.0, potential_ = 0.0;
  ContactDiagnostics* d_ = nullptr;
  RunObserver* observer_ = nullptr;
  mutable RestTracker rest_;

  // Polishing from the closed rows (see the header): the set factorised last and its LU.
  std::vector<int> polish_F_;
  bool polish_ok_ = false;
  Eigen::SparseLU<Eigen::SparseMatrix<double>> polish_lu_;
  Eigen::VectorXd polish_rhs_;
  // The MDI update's Schur complement D_RR on the rebounding contacts, and the reference impulses.
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> mdi_ldlt_;
  Eigen::SparseMatrix<double> drr_;
  std::vector<int> local_;                        // per contact: -1 (principal_submatrix's scratch)
  std::vector<Eigen::Triplet<double>> triplets_;  // principal_submatrix's scratch
  Eigen::VectorXd ref_q_, ref_z_, ref_w_;
  std::vector<char> ref_F_;
  std::vector<int> carrying_;  // the contacts carrying impulse in an impact step (record_impacts)
};

}  // namespace moreau
