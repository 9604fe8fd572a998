// The implicit scheme (0.2) of Adly, Brogliato and Le (2016) at scale: thousands of coordinates, each
// step in time and memory linear in their number (the system: large_abl_system.h).
//
// With M constant, C = 0 and Phi = 1/2 <W v, v> + sum_i a_i |v_i|, the step of abl_integrator.h is
//
//   P V^{k+1} + x_k  in  -d phi(V^{k+1}),   P = M/h + W,   x_k = g(Q^k) - M V^k / h,        (6.5)
//   Q^{k+1} = Q^k + h V^k,
//
// g = grad V + F, where it is structured rather than dense: P is sparse and constant (formed once for h
// and again only for a different last step landing on t_end: the "factorise once" of a constant M), x_k
// is a sparse product, and (6.5) is solved exactly by SparseOneStepSolver (sparse_one_step_solver.h),
// which reuses the factor of P_FF while the moving set F stays (a bar that slides, or rests, as in the last
// step: two triangular solves). A step costs O(nnz(M)) plus a factorisation of P_FF, O(n b^2) for a band
// b, when F changes. Measured: docs/scaling.md.
//
// The fixed step only: with M constant and C = 0 the step rules of Theorems 4.1 and 4.2 choose h itself
// (k3 = 0, and eps_k of (4.9) is 0 for every h), so a scene's rule gives the same run. The per-step checks
// stay at every step: Assumption 3.1 with a certified lower bound of lambda_min(M) (the constant M's,
// certified_lambda_min, computed once) and (4.2) with r_k = 0 (C = 0).
//
// Exact values, as the dense scheme: a component at rest is 0.0 (Lemma 6.1's closed form when every one
// rests; the pattern's equations otherwise), never a small number.
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <cstdint>
#include <string>
#include <vector>

#include "moreau/core/large_abl_system.h"
#include "moreau/core/observer.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/sparse_one_step_solver.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/core/time_grid.h"

namespace moreau {

class LargeAblIntegrator {
 public:
  LargeAblIntegrator(const LargeAblIntegrator&) = delete;
  LargeAblIntegrator& operator=(const LargeAblIntegrator&) = delete;

  // Precondition: system.validate() is empty and M positive definite (checked again: a failing run says why).
  LargeAblIntegrator(const LargeAblSystem& system, const TimeGrid& grid);

  RunSummary run(const Eigen::VectorXd& q0, const Eigen::VectorXd& v0, RunObserver* observer = nullptr);

  // The certified lower bound of lambda_min(M) the steps record.
  double lambda_min_bound() const { return lambda_min_; }
  const SparseOneStepSolver& solver() const { return solver_; }

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = false;
  static constexpr bool kTracksDissipation = true;
  double step_dissipation() const { return step_work_; }
  void on_failure() {}
  int dof() const { return n_; }
  const double* q() const { return q_.data(); }
  const double* v() const { return v_.data(); }
  double energy() const { return energy_; }
  RestState rest_state() const { return rest_.state(); }
  double energy_allowance(double e_old, double e_initial) const;
  bool begin(double t, StepFailure& f);
  bool step(std::int64_t k, double t, double h, double t_next, RunRecorder& rec, StepFailure& f);
  bool arrive(std::int64_t k, double t, StepFailure& f);
  void finish(RunRecorder& rec, std::int64_t k, double t);

  bool evaluate(std::int64_t k, double t, StepFailure& f);  // g(Q^k), M V^k and E_k
  void form_step_matrix(double h);                          // P = M/h + W, and the solver configured for it

  LargeAblSystem sys_;
  TimeGrid grid_;
  std::string invalid_;  // validate()'s answer, or the certificate's, at construction
  int n_ = 0;
  double lambda_min_ = 0.0;
  double h_formed_ = 0.0;  // the h of P (0: none formed)
  Eigen::SparseMatrix<double> P_;
  SparseOneStepSolver solver_;
  std::vector<double> scratch_;
  Eigen::VectorXd q_, v_, g_, Mv_, x_, y_;
  double energy_ = 0.0, step_work_ = 0.0;
  RestTracker rest_;
};

}  // namespace moreau
