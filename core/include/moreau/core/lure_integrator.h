// The theta-method for Lur'e systems with maximal monotone feedback, eq. (4) of Brogliato (2003):
//
//   x' = A x - B y_L,   y = C x,   y_L in d phi(y),   d phi(y) = (G_1(y_1), ..., G_m(y_m))        (4)
//
// each G_i a piecewise-linear maximal monotone graph (maximal_monotone_graph.h, Figure 3).
//
// Update rule (theta in [1/2, 1]; the multiplier is fully implicit):
//
//   x_{k+1} = x_k + h (A x_{k+theta} - B w_{k+1}),   x_{k+theta} = theta x_{k+1} + (1 - theta) x_k,
//   w_{k+1} in d phi(y_{k+1}),   y_{k+1} = C x_{k+1}.
//
// With Wt = (I - h theta A)^{-1}: x_{k+1} = x_free - h Wt B w_{k+1}, x_free = Wt (I + h (1-theta) A) x_k, so
// the step is the generalized equation (GE) of graph_inclusion_solver.h,
//
//   u + D w = q,   w_i in G_i(u_i),   u = y_{k+1},  D = h C Wt B,  q = C x_free,
//
// solved exactly: an output at rest comes out as the vertex abscissa itself (y_i == 0.0). The state then
// inherits the exact value where it can: x_j = u_i / C_ij when row i of C has a single non-zero entry
// C_ij, and x = C^{-1} u when every output is on a vertical piece and C is square and invertible (so that
// x' = -x - Sign(x) reaches x == 0.0 bit-exactly at the discrete time of ln(1 + x0), and stays there).
//
// Order: 1. Theta weights the linear part only (the multiplier is implicit, so that an output at rest
// stays at rest): theta = 1/2 is second order only where the feedback is locally constant (a horizontal
// piece, e.g. a saturated relay). Lemma 1 (existence, uniqueness) and Lemma 2
// (W = 1/2 x^T P x non-increasing, x -> 0) hold when (A, B, C) is strictly positive real with P = P^T > 0,
// PA + A^T P < 0, B^T P = C (absolute_stability.h); then D + D^T is positive definite for every h, so the
// step has a unique solution. For theta = 1 the discrete W_k is non-increasing as well:
// W_{k+1} - W_k = -1/2 h x_{k+1}^T Q x_{k+1} - h <y_{k+1}, w_{k+1}> - 1/2 |x_{k+1} - x_k|_P^2 <= 0 when
// (0, 0) is on every graph. For theta < 1 the term (1-theta) <y_k, w_{k+1}> has no sign; the report says
// what happened.
//
// No allocation and no virtual call per step; the observer sees x as positions and the discrete
// derivative (x_{k+1} - x_k)/h as velocities (for theta = 1 exactly A x_{k+1} - B w_{k+1}, an element of
// the right-hand side of (4) at x_{k+1}); row 0 holds A x_0 - B w_0 with w_0 the least-norm element of
// d phi(C x_0). The sample's energy is W_k (or |x_k|^2 / 2 without a storage matrix).
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "moreau/core/graph_inclusion_solver.h"
#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/observer.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/core/time_grid.h"
#include "moreau/core/types.h"
#include "moreau/platform/number_text.h"

namespace moreau {

// The grid (a fixed step) and the theta of the theta-method.
struct LureSettings : TimeGrid {
  double theta = 1.0;  // in [1/2, 1]
};

template <int N, int Mo>
class LureIntegrator {
 public:
  using MatB = Eigen::Matrix<double, N, Mo>;
  using MatC = Eigen::Matrix<double, Mo, N>;
  using MatD = Mat<Mo>;

  // graphs: one per output; P (optional) the storage matrix of W = 1/2 x^T P x.
  LureIntegrator(const Mat<N>& A, const MatB& B, const MatC& C, const std::vector<MonotoneGraph>& graphs, const LureSettings& settings,
                 const std::optional<Mat<N>>& P = std::nullopt)
      : A_(A), B_(B), C_(C), graphs_(graphs), settings_(settings), P_(P) {
    n_ = static_cast<int>(A.rows());
    m_ = static_cast<int>(C.rows());
    graph_ptrs_.resize(graphs_.size());
    for (std::size_t i = 0; i < graphs_.size(); ++i) graph_ptrs_[i] = &graphs_[i];
    solver_.configure(m_);
    xf_.setZero(n_);
    x_.setZero(n_);
    xn_.setZero(n_);
    v_.setZero(n_);
    q_.setZero(m_);
    u_.setZero(m_);
    w_.setZero(m_);
    // Exact-value transfer from outputs to states: row i of C with one non-zero entry.
    unit_col_.assign(static_cast<std::size_t>(m_), -1);
    for (int i = 0; i < m_; ++i) {
      int nz = 0, col = -1;
      for (int j = 0; j < n_; ++j)
        if (C_(i, j) != 0.0) {
          ++nz;
          col = j;
        }
      if (nz == 1) unit_col_[i] = col;
    }
    square_invertible_ = false;
    if (m_ == n_) {
      const Eigen::MatrixXd Cd = C_;
      Eigen::FullPivLU<Eigen::MatrixXd> full(Cd);
      if (full.rank() == n_) {
        c_square_.setZero(n_, n_);
        for (int i = 0; i < n_; ++i)
          for (int j = 0; j < n_; ++j) c_square_(i, j) = C_(i, j);
        c_lu_.compute(c_square_);
        square_invertible_ = true;
      }
    }
    cx_.setZero(n_);
    Px_.setZero(n_);
  }

  RunSummary run(const Vec<N>& x0, RunObserver* observer = nullptr, LureDiagnostics* diag = nullptr) {
    x_ = x0;
    const FixedTimeGrid grid(settings_.t0, settings_.t_end, settings_.h);
    last_step_ = grid.steps - 1;
    last_h_ = grid.last_h;
    return SteppingDriver::run_with_diagnostics(*this, SteppingPlan{settings_.grid(), true}, observer, d_, diag);
  }

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = false;
  static constexpr bool kTracksDissipation = false;

  // The scheme's part of the stepping loop (stepping_driver.h): the observer sees x and its discrete
  // derivative; the energy is W_k.
  int dof() const { return n_; }
  const double* q() const { return x_.data(); }
  const double* v() const { return v_.data(); }
  double energy() const { return energy_; }
  // Read from the values (RestTracker): 0.0 exactly, not reached through the subnormal numbers. The
  // driver asks once per step, after the step is complete (and at the start): the update happens here,
  // on the state as it stands then (updating the same state twice changes nothing).
  RestState rest_state() const { return rest_.update(x_); }
  double energy_allowance(double e_old, double /*e_initial*/) const { return storage_allowance(x_, e_old); }

  // Row 0: y_0 = C x_0, w_0 the least-norm element of d phi(y_0).
  bool begin(double t, StepFailure& f) {
    rest_ = RestTracker{};
    rest_.update(x_);  // the initial state, as given
    LureDiagnostics& d = *d_;
    d = LureDiagnostics{};
    d.output_rest_step.assign(static_cast<std::size_t>(m_), -1);
    d.output_rest_time.assign(static_cast<std::size_t>(m_), 0.0);
    prepare(settings_.h, main_);
    prepare(last_h_, last_);
    u_.noalias() = C_ * x_;
    for (int i = 0; i < m_; ++i) w_(i) = graphs_[i].least_norm_value(u_(i));
    if (!w_.allFinite()) return f.at(0, t, x_.data(), nullptr, "C x0 is outside the domain of d phi (Lemma 1 needs C x(0) in dom d phi)");
    v_.noalias() = A_ * x_ - B_ * w_;
    energy_ = storage(x_);
    if (P_) d.storage.start(energy_);
    for (int i = 0; i < m_; ++i)
      if (u_(i) == 0.0) d.output_rest_step[i] = 0;
    return true;
  }

  // One step of (4): the generalized equation for y_{k+1}, w_{k+1}, then x_{k+1}.
  bool step(std::int64_t k, double t, double /*h_k*/, double /*t_next*/, RunRecorder& rec, StepFailure& f) {
    const StepMatrices& sm = k == last_step_ ? last_ : main_;
    xf_.noalias() = sm.Phi * x_;
    q_.noalias() = C_ * xf_;
    GraphSolveStats st;
    if (!solver_.solve(sm.D, q_, graph_ptrs_.data(), u_, w_, st)) {
      return f.at(k, t, x_.data(), nullptr,
                  "the one-step generalized equation was not solved to round-off (residual " + platform::significant(st.residual, 3) +
                      ", tolerance " + platform::significant(st.tolerance, 3) + ")");
    }
    rec.solver_step(st.iterations, st.residual, st.used_fallback);
    xn_.noalias() = xf_ - sm.G * w_;
    polish(xn_);
    v_ = (xn_ - x_) / sm.h;
    x_ = xn_;
    return true;
  }

  bool arrive(std::int64_t k, double t, StepFailure& f) {
    LureDiagnostics& d = *d_;
    if (!x_.allFinite()) return f.at(k, t, x_.data(), nullptr, "the state became non-finite");
    for (int i = 0; i < m_; ++i) {
      if (u_(i) != 0.0) {
        d.output_rest_step[i] = -1;
      } else if (d.output_rest_step[i] < 0) {
        d.output_rest_step[i] = k;
        d.output_rest_time[i] = t;
      }
    }
    const double e_new = storage(x_);
    if (P_) d.storage.step(k, t, e_new, storage_allowance(x_, energy_));
    energy_ = e_new;
    return true;
  }

  void finish(RunRecorder& rec, std::int64_t k, double t) {
    LureDiagnostics& d = *d_;
    rec.finish(k, t, x_.data(), v_.data(), energy_);
    d.y_final.assign(u_.data(), u_.data() + u_.size());
    d.y_l_final.assign(w_.data(), w_.data() + w_.size());
    for (int i = 0; i < m_; ++i)
      if (d.output_rest_step[i] < 0) d.output_rest_time[i] = 0.0;
  }

  // A failed run also reports the last outputs.
  void on_failure() {
    d_->y_final.assign(u_.data(), u_.data() + u_.size());
    d_->y_l_final.assign(w_.data(), w_.data() + w_.size());
  }

  struct StepMatrices {
    double h = 0.0;
    Mat<N> Phi;  // Wt (I + h (1 - theta) A)
    MatB G;      // h Wt B
    MatD D;      // C G
  };

  void prepare(double h, StepMatrices& sm) const {
    sm.h = h;
    const double th = settings_.theta;
    Mat<N> I = Mat<N>::Identity(n_, n_);
    Eigen::PartialPivLU<Mat<N>> lu(Mat<N>(I - h * th * A_));
    sm.Phi = lu.solve(Mat<N>(I + h * (1.0 - th) * A_));
    sm.G = lu.solve(MatB(h * B_));
    sm.D = C_ * sm.G;
  }

  // Exact values from the outputs on vertical pieces (see the header).
  void polish(Vec<N>& x) {
    bool all_vertical = m_ > 0;
    for (int i = 0; i < m_; ++i) {
      if (!solver_.on_vertical_piece(i)) {
        all_vertical = false;
        continue;
      }
      if (unit_col_[i] >= 0) x(unit_col_[i]) = u_(i) / C_(i, unit_col_[i]);
    }
    if (all_vertical && square_invertible_) {
      for (int i = 0; i < n_; ++i) cx_(i) = u_(i);
      x.noalias() = c_lu_.solve(cx_);
    }
  }

  // W = 1/2 x^T P x (P x into a member: nested in dot(), the product would be a heap temporary at dynamic
  // sizes, an allocation per step).
  double storage(const Vec<N>& x) {
    if (!P_) return 0.5 * x.squaredNorm();
    Px_.noalias() = *P_ * x;
    return 0.5 * x.dot(Px_);
  }
  // Round-off in W itself: a few ulps of |x|^2 ||P||.
  double storage_allowance(const Vec<N>& x, double w_old) const {
    const double pn = P_ ? P_->cwiseAbs().rowwise().sum().maxCoeff() : 1.0;
    return 64.0 * std::numeric_limits<double>::epsilon() * std::max(pn * x.squaredNorm(), std::abs(w_old));
  }

  Mat<N> A_;
  MatB B_;
  MatC C_;
  std::vector<MonotoneGraph> graphs_;
  std::vector<const MonotoneGraph*> graph_ptrs_;
  LureSettings settings_;
  std::optional<Mat<N>> P_;
  int n_ = 0, m_ = 0;
  StepMatrices main_, last_;
  GraphInclusionSolver<Mo> solver_;
  Vec<N> x_;                      // the state x_k
  double energy_ = 0.0;           // W_k
  std::int64_t last_step_ = 0;    // the index of the grid's last step, which takes its own h
  double last_h_ = 0.0;           // that step's h
  LureDiagnostics* d_ = nullptr;  // where the running run records
  Vec<N> xf_, xn_, v_, cx_, Px_;
  Vec<Mo> q_, u_, w_;
  std::vector<int> unit_col_;
  bool square_invertible_ = false;
  Mat<N> c_square_;
  Eigen::PartialPivLU<Mat<N>> c_lu_;
  mutable RestTracker rest_;
};

}  // namespace moreau
