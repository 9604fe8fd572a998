// The Moreau-Jean time-stepping scheme for Lagrangian systems with unilateral constraints and impacts,
// eq. (8) of Brogliato (2003), with the set-valued controller Phi of Adly, Brogliato and Le (2016):
//
//   M(q) dv + (C(q, v) v + grad U(q) + F(t, q, v)) dt + dPhi(v) dt  in  grad h(q) dP,
//   0 <= h(q) perp P >= 0,   Newton's law U(t+) = -e U(t-) on impacts (U = grad h(q)^T v),        (8)
//
// i.e. Moreau's second-order sweeping process (10) discretised in the style of Jean and Moreau's method: the
// impulses and dPhi implicit at V^{k+1} (theta = 1), the smooth forces explicit at (Q^k, V^k) and the position
// from V^{k+1}, so that for the smooth part it is a symplectic Euler, not the theta-method with implicit
// smooth forces (reports name it so):
//
//   M(Q^k) (V^{k+1} - V^k) + h C(Q^k, V^k) V^{k+1} + h g(t_k, Q^k, V^k) + h dPhi(V^{k+1})  in  H^T P^{k+1}
//   for i in I_k:  0 <= U_i^{k+1} + e_i min(U_i^k, 0)  perp  P_i^{k+1} >= 0;   P_i^{k+1} = 0 otherwise,
//   Q^{k+1} = Q^k + h V_pos^{k+1},
//
// with g = grad U + F (the forces of the core scene format, explicit), H = grad h(Q^k)^T, U^k = H V^k and
// the predicted active set I_k = {i : h_i(Q^k) + h grad h_i(Q^k)^T V_free <= 0}, V_free the velocity the
// step would have without contact and controller impulses (so a free step never ends below a linear
// gap). The restitution acts on approaching contacts only (min(U^k, 0)): a contact that is closed and
// not approaching gets 0 <= U^{k+1} (no rebound out of a resting contact).
//
// Writing Phi(v) = 1/2 <W v, v> + sum a_j |v_j|, the step is the generalized equation (GE) of
// graph_inclusion_solver.h in m = (#a_j > 0) + (#I_k) unknowns: u = G_v V^{k+1} + b, w the impulses,
// V^{k+1} = V_free - Wm^{-1} G_f^T w, Wm = M + h (C + W), each row either a controlled velocity
// (u_j = v_j, w_j in a_j Sign(u_j), impulse h w_j) or a contact i in I_k (u_i = U_i^{k+1} + e_i min(U_i^k, 0),
// w_i = -P_i in d psi_{R+}(u_i), the corner law); a contact outside I_k has P_i = 0 and no row. A contact whose
// gradient is c e_j, on a coordinate j that also has an abs term (a joint limit with joint friction),
// shares one row with it, whose law is the sum of the two (merge_rows). Solved exactly by
// GraphInclusionSolver: a velocity at rest is 0.0 (when n rows sit on vertical pieces, V^{k+1} is solved
// from them; otherwise a vertical row involving one coordinate fixes it), so a system at rest has
// V == 0.0 exactly. An unsolved step stops the run (RunStatus::kFailed).
//
// A step with controlled rows and no contact in I_k (every step of a system without constraints, most
// steps of a robot between its joint limits) is the one-step inclusion (6.5) of the scheme (0.2) of Adly,
// Brogliato and Le: (GE) divided by h is P V^{k+1} + x in -d phi(V^{k+1}) with P = M/h + C + W,
// x = g - M V^k / h, phi(v) = sum a_j |v_j|. It is solved by the same exact solver as that scheme
// (OneStepSolver: sign patterns, closed forms for n <= 2), without Wm's factorisation, the columns Y and
// D when the system has no constraints. So on a system without constraints a step computes, from the
// same (Q^k, V^k), the V^{k+1} of (0.2) bit for bit, and only the position update differs
// (Q^{k+1} = Q^k + h V^{k+1} here, Q^k + h V^k there). A step that solver does not accept goes through
// GraphInclusionSolver as above.
//
// Position update (`PositionUpdate`):
//  - kMdi (default): V_pos = V^{k+1}, except that the contacts that carried a positive impulse and
//    rebound (an impact with e_i > 0: U_i^{k+1} = -e_i U_i^k != 0) move with normal velocity 0, the velocity w = (U+ + e U-)/(1+e)
//    at which the paper's measure differential inclusion (10) imposes the constraint: V_pos = V^{k+1} -
//    M^{-1} H_R^T (H_R M^{-1} H_R^T)^{-1} U_R^{k+1}. The impulsive part of a step does not move the
//    position (dq = v dt has no atom). With constant M, a linear gap and linear forces this makes
//    W = 1/2 <M v, v> + U(q) non-increasing at every step, impacts included: free steps lose
//    1/2 |V^{k+1} - V^k|_M^2, impact steps lose 1/2 (1 - e^2) U^2 / (grad h^T M^{-1} grad h) (eq. 9).
//  - kStandard: V_pos = V^{k+1}, the textbook Moreau-Jean update. Its W can rise at a low-velocity impact
//    with e > 0 by up to e |U^k| P (the gravity impulse absorbed by the contact, paid back as rebound).
// Optional position correction (`correct_positions`): after the step, if some h_i(Q^{k+1}) < 0, Q^{k+1}
// is projected onto {h >= 0} in the kinetic metric (Newton steps on the linearised constraints, each an
// LCP solved by the same solver); the diagnostics count the corrections and the potential energy they added.
//
// Order 1 away from impacts; impact times within O(h). Zeno accumulations (the bouncing ball with e < 1)
// are passed through: once a rebound velocity falls below the step's gravity increment the contact closes
// with U == 0.0 and stays closed.
//
// Model requirements (the ABL model of abl_integrator.h plus the constraints):
//   static constexpr int kDof;  int dof() const;  const Controller<kDof>& controller() const;  (norm_gain 0)
//   bool constant_mass() const;  bool constant_terms() const;  void evaluate(t, q, v, LagrangianTerms<N>&);
//   void mass(q, Mat<N>&);
//   int num_constraints() const;  double restitution(int i) const;
//   void constraints(const Vec<N>& q, Eigen::VectorXd& gap, Eigen::Matrix<double, Eigen::Dynamic, N>& H);
//   bool has_potential() const;  double potential(const Vec<N>& q);
//   double evaluate_with_potential(t, q, v, LagrangianTerms<N>&);  (evaluate, and return potential(q))
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "moreau/core/controller.h"
#include "moreau/core/graph_inclusion_solver.h"
#include "moreau/core/maximal_monotone_graph.h"
#include "moreau/core/moreau_jean_settings.h"
#include "moreau/core/observer.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/run_summary.h"
#include "moreau/core/small_lu.h"
#include "moreau/core/sparse_lcp.h"
#include "moreau/core/step_conditions.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/core/time_grid.h"
#include "moreau/core/types.h"
#include "moreau/platform/number_text.h"

namespace moreau {

template <class Model>
class MoreauJeanIntegrator {
 public:
  static constexpr int N = Model::kDof;
  using RowsN = Eigen::Matrix<double, Eigen::Dynamic, N>;
  using ColsN = Eigen::Matrix<double, N, Eigen::Dynamic>;

  MoreauJeanIntegrator(const MoreauJeanIntegrator&) = delete;  // holds pointers into itself
  MoreauJeanIntegrator& operator=(const MoreauJeanIntegrator&) = delete;

  MoreauJeanIntegrator(Model& model, const MoreauJeanSettings& settings) : model_(model), settings_(settings) {
    n_ = model_.dof();
    nc_ = model_.num_constraints();
    const Controller<N>& phi = model_.controller();
    weights_ = phi.weights;
    row_of_dof_.assign(static_cast<std::size_t>(n_), -1);
    for (int j = 0; j < n_; ++j) {
      if (phi.gains(j) > 0.0) {
        row_of_dof_[static_cast<std::size_t>(j)] = static_cast<int>(ctrl_dof_.size());
        ctrl_dof_.push_back(j);
        relay_.push_back(MonotoneGraph::relay(phi.gains(j)));
        // The controlled row's law merged with a contact on its coordinate alone (see merge_rows): a wall
        // on the left (gradient c > 0) or on the right (c < 0), moved every step.
        merged_left_wall_.push_back(MonotoneGraph({0.0}, {0.0}, MonotoneGraph::End::kWall, 0.0, MonotoneGraph::End::kSlope, 0.0));
        merged_right_wall_.push_back(MonotoneGraph({0.0}, {0.0}, MonotoneGraph::End::kSlope, 0.0, MonotoneGraph::End::kWall, 0.0));
      }
    }
    norm_gain_ = phi.norm_gain;
    na_ = static_cast<int>(ctrl_dof_.size());
    m_ = na_ + nc_;
    restitution_.resize(static_cast<std::size_t>(nc_));
    for (int i = 0; i < nc_; ++i) restitution_[i] = model_.restitution(i);
    terms_.resize(n_);
    Wm_.setZero(n_, n_);
    vf_.setZero(n_);
    vn_.setZero(n_);
    vpos_.setZero(n_);
    rhs_.setZero(n_);
    Mv_.setZero(n_);
    qn_.setZero(n_);
    q_.setZero(n_);
    v_.setZero(n_);
    dq_.setZero(n_);
    Gsq_.setZero(n_, n_);
    rsq_.setZero(n_);
    vsq_.setZero(n_);
    if constexpr (N == Eigen::Dynamic) {
      lu_ = Eigen::PartialPivLU<Mat<N>>(n_);
      mlu_ = Eigen::PartialPivLU<Mat<N>>(n_);
      sqlu_ = Eigen::PartialPivLU<Mat<N>>(n_);
    }
    gap_.setZero(nc_);
    H_.setZero(nc_, n_);
    U_.setZero(nc_);
    Un_.setZero(nc_);
    active_.assign(static_cast<std::size_t>(nc_), 0);
    Gv_.setZero(m_, n_);
    Gf_.setZero(m_, n_);
    b_.setZero(m_);
    Y_.setZero(n_, m_);
    D_.setZero(m_, m_);
    qv_.setZero(m_);
    u_.setZero(m_);
    w_.setZero(m_);
    P_.setZero(nc_);
    contact_row_.assign(static_cast<std::size_t>(nc_), -1);
    ptrs_.assign(static_cast<std::size_t>(m_), &zero_);
    for (int r = 0; r < na_; ++r) ptrs_[r] = &relay_[r];
    merged_contact_.assign(static_cast<std::size_t>(na_), -1);
    merged_sign_.assign(static_cast<std::size_t>(na_), 0.0);
    solver_.configure(m_);
    controlled_solver_.configure(phi.gains, 0.0);
    inclusion_P_.setZero(n_, n_);
    inclusion_x_.setZero(n_);
    // Impact steps and position correction.
    Z_.setZero(n_, nc_);
    S_.setZero(nc_, nc_);
    Sd_.setZero(nc_, nc_);
    pref_.setZero(nc_);
    qref_.setZero(nc_);
    zref_.setZero(nc_);
    s_.setZero(nc_);
    rows_.assign(static_cast<std::size_t>(nc_), 0);
    impact_rows_.assign(static_cast<std::size_t>(nc_), 0);
    impacting_.assign(static_cast<std::size_t>(nc_), 0);
    corr_ptrs_.assign(static_cast<std::size_t>(nc_), &corner_);
    corr_solver_.configure(nc_);
    Dc_.setZero(nc_, nc_);
    qc_.setZero(nc_);
    uc_.setZero(nc_);
    wc_.setZero(nc_);
  }

  RunSummary run(const Vec<N>& q0, const Vec<N>& v0, RunObserver* observer = nullptr, ContactDiagnostics* diag = nullptr) {
    q_ = q0;
    v_ = v0;
    observer_ = observer;  // told of each impact (record_impacts)
    return SteppingDriver::run_with_diagnostics(*this, SteppingPlan{settings_.grid(), true}, observer, d_, diag);
  }

 private:
  friend struct SteppingDriver;
  static constexpr bool kAdaptiveSteps = false;
  static constexpr bool kTracksDissipation = false;
  void on_failure() {}

  // The scheme's part of the stepping loop (stepping_driver.h). Its energy is the kinetic energy; the
  // Lagrange-Dirichlet function of Lemma 3 is tracked in the contact diagnostics.
  int dof() const { return n_; }
  const double* q() const { return q_.data(); }
  const double* v() const { return v_.data(); }
  double energy() const { return kinetic_; }
  // Read from the values (RestTracker): 0.0 exactly, not reached through the subnormal numbers. The
  // driver asks once per step, after the step is complete (and at the start): the update happens here,
  // on the state as it stands then (updating the same state twice changes nothing).
  RestState rest_state() const { return rest_.update(v_); }
  double energy_allowance(double /*e_old*/, double e_initial) const {
    return 64.0 * std::numeric_limits<double>::epsilon() * std::max(kinetic_, e_initial);
  }

  // <M x, x> with M = M(Q^k) of terms_; M x is left in Mv_.
  double m_norm2(const Vec<N>& x) {
    Mv_.noalias() = terms_.M * x;
    return x.dot(Mv_);
  }

  bool begin(double t, StepFailure& f) {
    rest_ = RestTracker{};
    rest_.update(v_);  // the initial state, as given
    ContactDiagnostics& d = *d_;
    d = ContactDiagnostics{};
    d.constraints = nc_;
    d.impacts.reserve(static_cast<std::size_t>(std::max(0, settings_.max_recorded_impacts)));
    d.settle_step.assign(static_cast<std::size_t>(nc_), -1);
    d.settle_time.assign(static_cast<std::size_t>(nc_), 0.0);
    d.correction_enabled = settings_.correct_positions;
    d.potential_known = model_.has_potential();
    if (norm_gain_ > 0.0) return f.at(0, t, q_.data(), v_.data(), "the norm controller term is not supported by the moreau-jean scheme");

    model_.evaluate(t, q_, v_, terms_);
    if (!terms_.M.allFinite() || !terms_.C.allFinite() || !terms_.g.allFinite())
      return f.at(0, t, q_.data(), v_.data(), "model terms are not finite at the initial state");
    terms_vary_ = !model_.constant_terms();  // constant: terms_ keeps them for the whole run
    if (nc_ > 0) model_.constraints(q_, gap_, H_);
    note_gaps(d, t);
    kinetic_ = 0.5 * m_norm2(v_);
    potential_ = d.potential_known ? model_.potential(q_) : 0.0;
    d.lagrange_dirichlet.start(kinetic_ + potential_);
    return true;
  }

  // One step of (8): the free velocity, the one-step generalized equation, impacts and Q^{k+1}.
  bool step(std::int64_t k, double t, double h, double t_next, RunRecorder& rec, StepFailure& f) {
    RunSummary& s = rec.summary();
    ContactDiagnostics& d = *d_;
    const Vec<N>& q = q_;
    const Vec<N>& v = v_;
    // Assumption 3.1 at the visited states: M(Q^k) positive definite, else the run stops here.
    bool exact = true;
    const double lambda_m = checker_.lambda_min(terms_.M, exact);
    s.mass.record(lambda_m, exact, k, t);
    if (!(lambda_m > 0.0)) return f.at(k, t, q.data(), v.data(), not_positive_definite(lambda_m, q.data(), n_));

    // The free velocity, for the predicted active set and for a step without any impulse; a system
    // without constraints whose step has controlled rows needs it only where the solver of (6.5) does not
    // accept its solution (solve_controlled_rows).
    const bool free_first = nc_ > 0 || na_ == 0;
    if (free_first) free_velocity(h);

    // Predicted active set and the rows of (GE).
    bool any_active = false;
    if (nc_ > 0) {
      for (int i = 0; i < nc_; ++i) U_(i) = H_.row(i).dot(v);
      for (int i = 0; i < nc_; ++i) {
        const double predicted = gap_(i) + h * H_.row(i).dot(vf_);
        active_[i] = predicted <= 0.0;
        any_active = any_active || active_[i];
      }
    }
    d.active_steps += any_active;
    const bool solves = m_ > 0 && (na_ > 0 || any_active);  // else no impulse at all: V^{k+1} = V_free
    // by_rows: the step's impulses are those of the rows of (GE) (w_, contact_row_); not after the
    // controlled rows alone were solved as (6.5).
    bool by_rows = solves;
    if (solves && !any_active && solve_controlled_rows(h, rec)) by_rows = false;
    if (by_rows) {
      if (!free_first) free_velocity(h);  // (6.5) was not accepted: the general rows need V_free
      // The rows of (GE): the controlled coordinates, then the contacts of I_k only. A contact outside
      // I_k has P_i = 0 (a known impulse), so its row would change no other row's solution; leaving it out
      // spares its solve with Wm and its row and column of D (a robot's inactive joint limits).
      for (int r = 0; r < na_; ++r) {
        Gv_.row(r).setZero();
        Gv_(r, ctrl_dof_[r]) = 1.0;
        Gf_.row(r).setZero();
        Gf_(r, ctrl_dof_[r]) = h;
        b_(r) = 0.0;
      }
      for (int r = 0; r < na_; ++r) {
        ptrs_[r] = &relay_[static_cast<std::size_t>(r)];
        merged_contact_[static_cast<std::size_t>(r)] = -1;
      }
      int m = na_;  // this step's rows
      for (int i = 0; i < nc_; ++i) {
        if (!active_[i]) {
          contact_row_[i] = -1;
          continue;
        }
        const int r = m++;
        contact_row_[i] = r;
        Gv_.row(r) = H_.row(i);
        Gf_.row(r) = H_.row(i);
        b_(r) = restitution_[i] * std::min(U_(i), 0.0);
        ptrs_[r] = &corner_;
        merge_rows(i, h);
      }
      // Small dense pieces, column by column with fixed-size N: no dynamic-size GEMM per step. D is the
      // leading m x m block of D_ (the solver's use_leading: no reallocation as I_k changes).
      for (int r = 0; r < m; ++r) {
        rhs_ = Gf_.row(r).transpose();
        Y_.col(r).noalias() = lu_.solve(rhs_);
      }
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) D_(i, j) = Gv_.row(i).dot(Y_.col(j));
        qv_(i) = Gv_.row(i).dot(vf_) + b_(i);
      }
      solver_.use_leading(m);
      GraphSolveStats st;
      if (!solver_.solve(D_, qv_, ptrs_.data(), u_, w_, st)) {
        return f.at(k, t, q.data(), v.data(),
                    "the one-step complementarity problem was not solved to round-off (residual " + platform::significant(st.residual, 3) +
                        ", tolerance " + platform::significant(st.tolerance, 3) + ")");
      }
      rec.solver_step(st.iterations, st.residual, st.used_fallback);
      vn_ = vf_;
      for (int j = 0; j < m; ++j)
        if (w_(j) != 0.0) vn_ -= w_(j) * Y_.col(j);
      polish(vn_, m);
      split_merged_impulses(h);
    } else if (!solves) {
      vn_ = vf_;
      s.solver.total_iterations += 1;
      s.solver.max_iterations = std::max(s.solver.max_iterations, 1);
    }

    // Impulses, impacts, position velocity.
    vpos_ = vn_;
    bool any_impulse = false;
    int rebounds = 0;
    if (nc_ > 0) {
      for (int i = 0; i < nc_; ++i) Un_(i) = H_.row(i).dot(vn_);
      int impacts_now = 0;
      const double vmax = v.cwiseAbs().maxCoeff();
      for (int i = 0; i < nc_; ++i) {
        impacting_[i] = 0;
        const int r = contact_row_[static_cast<std::size_t>(i)];
        P_(i) = by_rows && r >= 0 ? -w_(r) : 0.0;  // P_i^{k+1}: 0 outside I_k
        if (!(P_(i) > 0.0)) continue;
        any_impulse = true;
        // An impact: the contact was approaching by more than the round-off of U = grad h^T V.
        const double approach = 64.0 * std::numeric_limits<double>::epsilon() * H_.row(i).cwiseAbs().sum() * vmax;
        if (!(U_(i) < -approach)) continue;
        impacting_[i] = 1;
        ++impacts_now;
        if (restitution_[i] > 0.0) rows_[rebounds++] = i;  // U+ = -e U- != 0: the rebounding contacts
      }
      if (impacts_now > 0 || (rebounds > 0 && settings_.position_update == PositionUpdate::kMdi)) mlu_.compute(terms_.M);
      if (impacts_now > 0) record_impacts(d, k + 1, t_next, impacts_now);
      if (rebounds > 0 && settings_.position_update == PositionUpdate::kMdi) {
        // V_pos = V^{k+1} - M^{-1} H_R^T (H_R M^{-1} H_R^T)^{-1} U_R^{k+1}.
        for (int a = 0; a < rebounds; ++a) {
          rhs_ = H_.row(rows_[a]).transpose();
          Z_.col(a).noalias() = mlu_.solve(rhs_);
        }
        for (int a = 0; a < rebounds; ++a) {
          for (int b = 0; b < rebounds; ++b) S_(a, b) = H_.row(rows_[a]).dot(Z_.col(b));
          s_(a) = Un_(rows_[a]);
        }
        if (!lu_solve_in_place(S_, s_, rebounds))
          return f.at(k, t, q.data(), v.data(), "the gradients of the rebounding contacts are dependent");
        for (int a = 0; a < rebounds; ++a) vpos_ -= s_(a) * Z_.col(a);
      }
    }
    d.impulse_steps += any_impulse;

    qn_ = q + h * vpos_;
    return true;
  }

  // Q^{k+1}, V^{k+1} become the state: finiteness, the gaps (and the optional position correction), the
  // settled contacts, and the terms and energies at the new state.
  bool arrive(std::int64_t k, double t, StepFailure& f) {
    ContactDiagnostics& d = *d_;
    if (!qn_.allFinite() || !vn_.allFinite()) return f.at(k, t, q_.data(), v_.data(), "the state became non-finite");
    if (nc_ > 0) {
      model_.constraints(qn_, gap_, H_);
      if (settings_.correct_positions && gap_.minCoeff() < 0.0) {
        if (!correct(d, qn_)) return f.at(k, t, q_.data(), v_.data(), "the position correction did not converge");
      }
    }
    q_ = qn_;
    v_ = vn_;

    for (int i = 0; i < nc_; ++i) {
      const bool closed = P_(i) > 0.0 && Un_(i) == 0.0;
      if (!closed) {
        d.settle_step[i] = -1;
      } else if (d.settle_step[i] < 0) {
        d.settle_step[i] = k;
        d.settle_time[i] = t;
      }
    }

    double pot_new = 0.0;
    if (terms_vary_) {
      const NewTerms e = evaluate_terms(t, d.potential_known);
      if (!e.finite) return f.at(k, t, q_.data(), v_.data(), "model terms are not finite (an expression left its domain)");
      pot_new = e.potential;
    } else if (d.potential_known) {
      pot_new = model_.potential(q_);
    }
    note_gaps(d, t);
    const double kin_new = 0.5 * m_norm2(v_);
    const double allowance =
        64.0 * std::numeric_limits<double>::epsilon() * (kinetic_ + std::abs(potential_) + kin_new + std::abs(pot_new));
    d.lagrange_dirichlet.step(k, t, kin_new + pot_new, allowance);
    kinetic_ = kin_new;
    potential_ = pot_new;
    return true;
  }

  // M, C, g at the new state, whether they are all finite, and V with them where it is known. Not
  // inlined: it is the larger part of arrive() and runs only where the terms vary, and inlined it made
  // GCC keep arrive() out of the stepping loop for systems with constant terms too (callgrind: +28
  // instructions per step on the damped relay, +33 on the ball). Returned by value, in registers.
  struct NewTerms {
    bool finite;
    double potential;
  };
  [[gnu::noinline]] NewTerms evaluate_terms(double t, bool with_potential) {
    double potential = 0.0;
    if (with_potential) {
      potential = model_.evaluate_with_potential(t, q_, v_, terms_);
    } else {
      model_.evaluate(t, q_, v_, terms_);
    }
    return {terms_.M.allFinite() && terms_.C.allFinite() && terms_.g.allFinite(), potential};
  }

  void finish(RunRecorder& rec, std::int64_t k, double t) {
    ContactDiagnostics& d = *d_;
    rec.finish(k, t, q_.data(), v_.data(), kinetic_);
    if (rec.rest_from() >= 0) {
      d.rest_step = rec.rest_from();
      d.rest_time = rec.rest_time();
    }
  }

  // A contact whose gradient is c e_j (a joint limit: c = +-1) on a coordinate j that also has an abs
  // term a_j |v_j| (Coulomb friction, the controller): both laws act on v_j alone, and at rest on the
  // contact their two rows would be parallel and both vertical, with a reaction that does not divide
  // uniquely between them. They become one row on v_j, with the sum of the two laws as its graph, which
  // is maximal monotone: impulse h a_j Sgn(v_j) + c d psi_{R+}(c v_j + b_i), i.e. a wall at
  // v0 = -b_i / c (the Newton target) and, beside it, the friction level h a_j sign(c); the contact's own
  // row then carries w = 0. The solution of the one-step problem is the same; only this row is solved for
  // the total. split_merged_impulses gives each law its part afterwards.
  void merge_rows(int i, double h) {
    int col = -1, nonzero = 0;
    for (int j = 0; j < n_; ++j)
      if (H_(i, j) != 0.0) {
        ++nonzero;
        col = j;
      }
    if (nonzero != 1) return;
    const int r = row_of_dof_[static_cast<std::size_t>(col)];
    if (r < 0 || merged_contact_[static_cast<std::size_t>(r)] >= 0) return;  // no abs term, or merged already
    const double c = H_(i, col);
    const double a = relay_[static_cast<std::size_t>(r)].w().back();  // the relay's level a_j
    const int row = contact_row_[static_cast<std::size_t>(i)];
    const double v0 = -b_(row) / c;
    MonotoneGraph& g = c > 0.0 ? merged_left_wall_[static_cast<std::size_t>(r)] : merged_right_wall_[static_cast<std::size_t>(r)];
    g.move_single_vertex(v0, c > 0.0 ? h * a : -h * a);
    Gf_(r, col) = 1.0;  // the row's w is now the whole impulse along e_j (the relay row's was h times it)
    ptrs_[r] = &g;
    ptrs_[row] = &zero_;
    merged_contact_[static_cast<std::size_t>(r)] = i;
    merged_sign_[static_cast<std::size_t>(r)] = c;
  }

  // After a step with merged rows: the total impulse W of row r (along e_j) as friction f in
  // h a_j Sgn(v_j) and contact impulse, W = f + c w_c. Off the wall (or on a wall away from v_j = 0) the
  // friction part is h a_j sign(v_j) exactly; at v_j = 0 the split is not unique and the contact takes
  // only what friction cannot hold, f = clamp(W, -h a_j, h a_j). Row r and the contact's row then hold
  // the values the unmerged rows would (w_r: the friction level, impulse h w_r; w_i = -P_i).
  void split_merged_impulses(double h) {
    for (int r = 0; r < na_; ++r) {
      const int i = merged_contact_[static_cast<std::size_t>(r)];
      if (i < 0) continue;
      const double a = relay_[static_cast<std::size_t>(r)].w().back();
      const double W = w_(r), vj = u_(r), c = merged_sign_[static_cast<std::size_t>(r)];
      const double f = vj != 0.0 ? h * a * (vj > 0.0 ? 1.0 : -1.0) : std::clamp(W, -h * a, h * a);
      w_(contact_row_[static_cast<std::size_t>(i)]) = (W - f) / c;
      w_(r) = f / h;
    }
  }

  // Wm V_free = M V^k - h g, Wm = M + h (C + W), factorised in lu_ for the rows of (GE).
  void free_velocity(double h) {
    Wm_ = terms_.M;
    Wm_.noalias() += h * terms_.C;
    Wm_.diagonal() += h * weights_;
    lu_.compute(Wm_);
    // M V^k is Mv_ (m_norm2 of the last arrive()), but computed again here: reading Mv_ cost the bouncing
    // ball 9 more instructions per step than the 1 x 1 product (callgrind; GCC 12 allocates the step's
    // registers differently); at larger n the product (n^2 multiplications) is the smaller part beside
    // Wm's factorisation (n^3 / 3).
    rhs_.noalias() = terms_.M * v_;
    rhs_ -= h * terms_.g;
    vf_.noalias() = lu_.solve(rhs_);
  }

  // The step's (GE) with the controlled rows alone (no contact in I_k), as the inclusion (6.5):
  // P V^{k+1} + x in -d phi(V^{k+1}), P = M/h + C + W, x = g - M V^k / h (the header). P and x are formed
  // as the abl scheme forms them, entry by entry the same roundings. False, with nothing recorded, when
  // the solver does not accept a solution: the general path solves the step then.
  bool solve_controlled_rows(double h, RunRecorder& rec) {
    const double inv_h = 1.0 / h;
    inclusion_P_.noalias() = inv_h * terms_.M + terms_.C;
    inclusion_P_.diagonal() += weights_;
    inclusion_x_ = terms_.g - inv_h * Mv_;  // Mv_ = M V^k
    OneStepStats st;
    if (!controlled_solver_.solve(inclusion_P_, inclusion_x_, vn_, st)) return false;
    rec.solver_step(st.iterations, st.residual, st.used_fallback);
    return true;
  }

  // Exact values from the rows on vertical pieces (u_r exact): when there are n of them with independent
  // velocity maps they fix V^{k+1} = G_V^{-1} (u_V - b_V) (0.0 exactly for a system at rest); otherwise a
  // row whose velocity map involves one coordinate fixes that coordinate.
  void polish(Vec<N>& v, int m) {
    int nv = 0;
    for (int r = 0; r < m && nv <= n_; ++r) {
      if (!solver_.on_vertical_piece(r)) continue;
      if (nv < n_) {
        Gsq_.row(nv) = Gv_.row(r);
        rsq_(nv) = u_(r) - b_(r);
      }
      ++nv;
    }
    if (nv == 0) return;  // no exact velocity to impose (every row moving)
    if (nv == n_ && n_ == 1) {
      if (Gsq_(0, 0) != 0.0) {
        v(0) = rsq_(0) / Gsq_(0, 0);
        return;
      }
    } else if (nv == n_ && n_ > 0) {
      sqlu_.compute(Gsq_);
      // Independent rows: no pivot of U negligible against the largest entry.
      const double big = Gsq_.cwiseAbs().maxCoeff();
      const double smallest_pivot = sqlu_.matrixLU().diagonal().cwiseAbs().minCoeff();
      if (smallest_pivot > 1e-12 * big) {
        vsq_.noalias() = sqlu_.solve(rsq_);
        if (vsq_.allFinite()) {
          v = vsq_;
          return;
        }
      }
    }
    for (int r = 0; r < m; ++r) {
      if (!solver_.on_vertical_piece(r)) continue;
      int nz = 0, col = -1;
      for (int j = 0; j < n_; ++j)
        if (Gv_(r, j) != 0.0) {
          ++nz;
          col = j;
        }
      if (nz == 1) v(col) = (u_(r) - b_(r)) / Gv_(r, col);
    }
  }

  void note_gaps(ContactDiagnostics& d, double t) const {
    for (int i = 0; i < nc_; ++i) {
      if (gap_(i) < d.smallest_gap) {
        d.smallest_gap = gap_(i);
        d.smallest_gap_time = t;
        d.smallest_gap_constraint = i;
      }
    }
  }

  // The impacts of this step: contacts with a positive impulse that were approaching (U^k < 0 beyond
  // round-off). Measured: the step's kinetic energy change in the metric of M(Q^k),
  // 1/2 <M V^{k+1}, V^{k+1}> - 1/2 <M V^k, V^k> (the same for contacts impacting together). Reference:
  // Moreau's impact law alone (no smooth forces, no controller) from V^k at Q^k for every contact that
  // carries impulse in the step, the impacting ones and the closed ones the impulse passes through (a
  // touching Newton's cradle: a simultaneous multiple impact), V+ = V^k + M^{-1} H_C^T P,
  // 0 <= U+_i + e_i min(U-_i, 0) perp P_i >= 0, solved exactly in the Delassus matrix H_C M^{-1} H_C^T by
  // block principal pivoting (sparse_lcp.h; independent of the step's solver). Its energy change is
  // 1/2 sum_i P_i (U+_i + U-_i) = 1/2 sum_i P_i (U-_i - e_i min(U-_i, 0)): eq. (9)'s
  // 1/2 sum_i (1 - e_i) P_i U-_i on the approaching contacts, 0 on closed ones. The two differ by what the
  // step adds over h (smooth forces, controller): exactly 0 for a ball, O(h) in general.
  void record_impacts(ContactDiagnostics& d, std::int64_t step, double t, int simultaneous) {
    double eq9 = 0.0;
    int carrying = 0;
    const bool evaluated = solve_impact_law(eq9, carrying);
    rhs_.noalias() = terms_.M * vn_;
    const double measured = 0.5 * vn_.dot(rhs_) - kinetic_;  // kinetic_ = 1/2 <M V^k, V^k>
    for (int i = 0; i < nc_; ++i) {
      if (!impacting_[i]) continue;
      ImpactEvent ev;
      ev.step = step;
      ev.t = t;
      ev.constraint = i;
      ev.pre = U_(i);
      ev.post = Un_(i);
      ev.impulse = P_(i);
      ev.restitution = restitution_[static_cast<std::size_t>(i)];
      ev.kinetic_change = measured;
      ev.reference_evaluated = evaluated;
      ev.reference_impulse = evaluated ? pref_(i) : 0.0;
      ev.eq9_change = evaluated ? eq9 : 0.0;
      ev.simultaneous = simultaneous;
      ev.closed_carrying = carrying - simultaneous;
      count_impact(d, ev, settings_.max_recorded_impacts, observer_);
    }
  }

  // Moreau's impact law for the contacts that carry impulse in the step (see record_impacts) into pref_
  // (indexed by contact), their number, and its energy change. Up to kMaxEnumeratedImpacts of them the
  // LCP is solved by trying its 2^r active sets (no allocation, the step stays allocation-free); beyond,
  // by block principal pivoting (sparse_lcp.h). False when no active set satisfies it within round-off
  // or their Delassus matrix is singular (dependent gradients: the impulses are not unique).
  bool solve_impact_law(double& energy_change, int& carrying) {
    int r = 0;
    for (int i = 0; i < nc_; ++i)
      if (P_(i) > 0.0) impact_rows_[r++] = i;
    carrying = r;
    double scale = 0.0;
    for (int a1 = 0; a1 < r; ++a1) {
      rhs_ = H_.row(impact_rows_[a1]).transpose();
      Z_.col(a1).noalias() = mlu_.solve(rhs_);
    }
    for (int a1 = 0; a1 < r; ++a1) {
      for (int b1 = 0; b1 < r; ++b1) Sd_(a1, b1) = H_.row(impact_rows_[a1]).dot(Z_.col(b1));  // Delassus
      const double u = U_(impact_rows_[a1]);
      qref_(a1) = u + restitution_[impact_rows_[a1]] * std::min(u, 0.0);  // U+ + e min(U-, 0) at P = 0
      scale = std::max(scale, std::abs(u));
    }
    bool solved = false;
    if (r <= kMaxEnumeratedImpacts) {
      const double tol = 1e-10 * scale;
      for (int set = 1; set < (1 << r) && !solved; ++set) {
        // Active contacts: (S P)_i = -qref_i; the others P_i = 0.
        int m = 0;
        for (int a1 = 0; a1 < r; ++a1) {
          if (!(set & (1 << a1))) continue;
          int mm = 0;
          for (int b1 = 0; b1 < r; ++b1)
            if (set & (1 << b1)) S_(m, mm++) = Sd_(a1, b1);
          s_(m++) = -qref_(a1);
        }
        if (!lu_solve_in_place(S_, s_, m)) continue;
        int k1 = 0;
        for (int a1 = 0; a1 < r; ++a1) zref_(a1) = (set & (1 << a1)) ? s_(k1++) : 0.0;
        bool ok = true;
        for (int a1 = 0; a1 < r && ok; ++a1) {
          double w = qref_(a1);
          for (int b1 = 0; b1 < r; ++b1) w += Sd_(a1, b1) * zref_(b1);
          ok = zref_(a1) >= -tol && w >= -tol;
        }
        solved = ok;
      }
    } else {
      impact_lcp_.set_matrix(Sd_.topLeftCorner(r, r).sparseView());
      impact_set_.resize(static_cast<std::size_t>(r));
      for (int a1 = 0; a1 < r; ++a1) impact_set_[static_cast<std::size_t>(a1)] = a1;
      impact_closed_.assign(static_cast<std::size_t>(r), 1);
      Eigen::VectorXd q = qref_.head(r), z(r), w(r);
      SparseLcpStats st;
      solved = impact_lcp_.solve(impact_set_, q, z, w, impact_closed_, st);
      if (solved) zref_.head(r) = z;
    }
    if (!solved) return false;
    energy_change = 0.0;
    pref_.setZero();
    for (int a1 = 0; a1 < r; ++a1) {
      const int i = impact_rows_[a1];
      pref_(i) = zref_(a1);
      energy_change += 0.5 * zref_(a1) * (U_(i) - restitution_[i] * std::min(U_(i), 0.0));
    }
    return true;
  }

  // Projects qn_ onto {h >= 0} in the metric of M(Q^k): Newton steps on the linearised constraints,
  // each the LCP 0 <= h + H M^{-1} H^T mu perp mu >= 0, delta q = M^{-1} H^T mu.
  bool correct(ContactDiagnostics& d, Vec<N>& qn) {
    mlu_.compute(terms_.M);
    const double before = d.potential_known ? model_.potential(qn) : 0.0;
    d.largest_violation = std::max(d.largest_violation, -gap_.minCoeff());
    double total_norm2 = 0.0;
    dq_.setZero();
    for (int it = 0; it < 20; ++it) {
      for (int i = 0; i < nc_; ++i) {
        rhs_ = H_.row(i).transpose();
        Z_.col(i).noalias() = mlu_.solve(rhs_);
      }
      Dc_.noalias() = H_ * Z_.leftCols(nc_);
      qc_ = gap_;
      GraphSolveStats st;
      if (!corr_solver_.solve(Dc_, qc_, corr_ptrs_.data(), uc_, wc_, st)) return false;
      rhs_.noalias() = Z_.leftCols(nc_) * wc_;  // delta q = M^{-1} H^T mu, mu = -w (the product into rhs_ itself: no temporary)
      rhs_ = -rhs_;
      qn += rhs_;
      dq_ += rhs_;
      model_.constraints(qn, gap_, H_);
      // Linear gaps land on 0 up to the round-off of h(q) itself.
      const double allowance = 64.0 * std::numeric_limits<double>::epsilon() * (1.0 + qn.cwiseAbs().maxCoeff() * H_.cwiseAbs().maxCoeff());
      if (gap_.minCoeff() >= -allowance) break;
      if (it == 19) return false;
    }
    total_norm2 = m_norm2(dq_);
    ++d.corrected_steps;
    d.max_correction = std::max(d.max_correction, std::sqrt(std::max(0.0, total_norm2)));
    if (d.potential_known) d.correction_energy += model_.potential(qn) - before;
    return true;
  }

  Model& model_;
  MoreauJeanSettings settings_;
  int n_ = 0, nc_ = 0, na_ = 0, m_ = 0;
  Vec<N> weights_;
  double norm_gain_ = 0.0;
  std::vector<int> ctrl_dof_;
  std::vector<MonotoneGraph> relay_;
  std::vector<MonotoneGraph> merged_left_wall_, merged_right_wall_;  // per controlled row (merge_rows)
  std::vector<int> row_of_dof_;                                      // controlled row of each coordinate, -1 without an abs term
  std::vector<int> merged_contact_;                                  // per controlled row: the contact merged into it this step, or -1
  std::vector<double> merged_sign_;                                  // its gradient's entry c
  MonotoneGraph corner_ = MonotoneGraph::complementarity();
  MonotoneGraph zero_ = MonotoneGraph::zero();
  std::vector<double> restitution_;
  RunObserver* observer_ = nullptr;  // of the current run: told of each impact
  LagrangianTerms<N> terms_;
  bool terms_vary_ = true;  // false: the model's terms are constant, and terms_ holds them
  Mat<N> Wm_;
  Eigen::PartialPivLU<Mat<N>> lu_, mlu_, sqlu_;
  StepConditionChecker<N> checker_{model_.dof()};
  Vec<N> q_, v_;                            // the state (Q^k, V^k)
  double kinetic_ = 0.0, potential_ = 0.0;  // 1/2 <M V^k, V^k> and U(Q^k)
  ContactDiagnostics* d_ = nullptr;         // where the running run records
  Vec<N> vf_, vn_, vpos_, rhs_, qn_, dq_, rsq_, vsq_;
  // M(Q^k) V^k from the kinetic energy of begin() and arrive() (m_norm2), used by the next step's (6.5)
  // instead of a second product (correct() uses it as scratch before arrive() sets it). A member: a
  // product nested in dot() would be a heap temporary at dynamic sizes.
  Vec<N> Mv_;
  Mat<N> Gsq_;
  Eigen::VectorXd gap_, U_, Un_;
  RowsN H_;
  std::vector<char> active_;
  RowsN Gv_, Gf_;
  Eigen::VectorXd b_;
  ColsN Y_;
  Eigen::MatrixXd D_;
  Eigen::VectorXd qv_, u_, w_;    // (GE) in its leading rows: na_ controlled coordinates, then the contacts of I_k
  std::vector<int> contact_row_;  // per contact: its row in (GE) this step, or -1 outside I_k
  Eigen::VectorXd P_;             // per contact: the impulse P_i^{k+1} of the step (0 outside I_k)
  std::vector<const MonotoneGraph*> ptrs_;
  GraphInclusionSolver<Eigen::Dynamic> solver_;
  OneStepSolver<N> controlled_solver_;  // a step's controlled rows when no contact is in I_k (solve_controlled_rows)
  Mat<N> inclusion_P_;                  // its P = M/h + C + W
  Vec<N> inclusion_x_;                  // its x = g - M V^k / h
  ColsN Z_;
  Eigen::MatrixXd S_, Sd_;
  Eigen::VectorXd s_, pref_;
  static constexpr int kMaxEnumeratedImpacts = 10;  // Moreau's impact law by enumeration: 2^10 active sets at most
  Eigen::VectorXd qref_, zref_;                     // its LCP's q and solution, by carrying contact
  SparseLcpSolver impact_lcp_;                      // beyond kMaxEnumeratedImpacts contacts
  std::vector<int> impact_set_;
  std::vector<char> impact_closed_;
  std::vector<int> rows_;         // the rebounding contacts of an impact step
  std::vector<int> impact_rows_;  // the impacting contacts (Moreau's impact law)
  std::vector<char> impacting_;
  std::vector<const MonotoneGraph*> corr_ptrs_;
  GraphInclusionSolver<Eigen::Dynamic> corr_solver_;
  Eigen::MatrixXd Dc_;
  Eigen::VectorXd qc_, uc_, wc_;
  mutable RestTracker rest_;
};

}  // namespace moreau
