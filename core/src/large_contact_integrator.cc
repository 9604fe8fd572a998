// The Moreau-Jean scheme for contact systems at scale (large_contact_integrator.h).
#include "moreau/core/large_contact_integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace moreau {

namespace {

constexpr double kEps64 = 64.0 * std::numeric_limits<double>::epsilon();

bool all_finite(const Eigen::VectorXd& x) { return x.allFinite(); }

}  // namespace

LargeContactIntegrator::LargeContactIntegrator(const LargeContactSystem& system, const MoreauJeanSettings& settings)
    : sys_(system), settings_(settings), invalid_(system.validate()) {
  if (invalid_.empty() && !sys_.linear() && settings_.correct_positions)
    invalid_ = "position correction is not taken with nonlinear gaps (one LCP projects onto linear gaps only)";
  if (!invalid_.empty()) return;
  sys_.gradients.makeCompressed();
  n_ = sys_.dof();
  nc_ = sys_.num_constraints();
  inv_mass_ = sys_.mass.cwiseInverse();
  accel_ = sys_.force.cwiseProduct(inv_mass_);
  min_mass_ = sys_.mass.minCoeff();
  H_ = sys_.gradients;
  row_abs_sum_.setZero(nc_);
  if (sys_.linear()) {
    // D = H M^{-1} H^T, formed once (M and H are constant), both triangles stored.
    const Eigen::SparseMatrix<double> Hc = H_;
    D_ = (Hc * inv_mass_.asDiagonal()) * Hc.transpose();
    D_.makeCompressed();
    step_lcp_.set_matrix(D_);
    impact_lcp_.set_matrix(D_);
    correction_lcp_.set_matrix(D_);
    for (int i = 0; i < nc_; ++i)
      for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, i); it; ++it) row_abs_sum_(i) += std::abs(it.value());
    offsets_ = sys_.offsets;
  } else {
    gap_scratch_ = sys_.nonlinear_gaps->make_scratch();
    offsets_.setZero(nc_);
    formed_.assign(static_cast<std::size_t>(nc_), 0);
  }
  for (Eigen::VectorXd* x : {&q_, &v_, &qn_, &vf_, &vn_, &vpos_}) x->setZero(n_);
  for (Eigen::VectorXd* x : {&gap_, &U_, &Un_, &Hvf_, &lcp_q_, &lcp_z_, &lcp_w_, &P_, &ref_q_, &ref_z_, &ref_w_}) x->setZero(nc_);
  in_F_.assign(static_cast<std::size_t>(nc_), 0);
  was_active_.assign(static_cast<std::size_t>(nc_), 0);
  ref_F_.assign(static_cast<std::size_t>(nc_), 0);
  impacting_.assign(static_cast<std::size_t>(nc_), 0);
  local_.assign(static_cast<std::size_t>(nc_), -1);
  active_rows_.reserve(static_cast<std::size_t>(nc_));
  rows_.reserve(static_cast<std::size_t>(nc_));
}

// h(q) into gap_; with nonlinear gaps also H_ = grad h(q)^T, and per contact the round-off scale of the
// active-set test (row_abs_sum_, offsets_: the constant of the gap's linearisation at q). False when a
// gap or a gradient entry is not finite (balls at the same centre: the distance has no gradient).
bool LargeContactIntegrator::evaluate_gaps(const Eigen::VectorXd& q) {
  sys_.evaluate(q, gap_, H_, gap_scratch_);
  if (sys_.linear()) return gap_.allFinite();
  bool finite = true;
  for (int i = 0; i < nc_; ++i) {
    double sum = 0.0, hq = 0.0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, i); it; ++it) {
      sum += std::abs(it.value());
      hq += it.value() * q(it.col());
    }
    row_abs_sum_(i) = sum;
    offsets_(i) = gap_(i) - hq;
    finite = finite && std::isfinite(sum) && std::isfinite(offsets_(i));
  }
  if (!finite) {
    for (int i = 0; i < nc_; ++i)
      if (!std::isfinite(row_abs_sum_(i)) || !std::isfinite(offsets_(i))) {
        nonfinite_contact_ = i;
        break;
      }
  }
  return finite;
}

// With nonlinear gaps, D = H M^{-1} H^T at Q^k on the rows of I_k, formed again only when H's values or
// I_k's rows are not those of the D formed last: a column at rest keeps its D and the LCP its factor.
void LargeContactIntegrator::form_delassus() {
  if (sys_.linear()) return;
  const Eigen::Index nnz = H_.nonZeros();
  bool current = delassus_current_ && std::equal(H_.valuePtr(), H_.valuePtr() + nnz, previous_H_.begin());
  for (std::size_t a = 0; current && a < active_rows_.size(); ++a) current = formed_[static_cast<std::size_t>(active_rows_[a])] != 0;
  if (current) return;
  triplets_.clear();
  std::fill(formed_.begin(), formed_.end(), 0);
  for (int i : active_rows_) {
    formed_[static_cast<std::size_t>(i)] = 1;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, i); it; ++it)
      triplets_.emplace_back(i, static_cast<int>(it.col()), it.value());
  }
  HI_.resize(nc_, n_);
  HI_.setFromTriplets(triplets_.begin(), triplets_.end());
  const Eigen::SparseMatrix<double> Hc = HI_;
  D_ = (Hc * inv_mass_.asDiagonal()) * Hc.transpose();
  D_.makeCompressed();
  step_lcp_.set_matrix(D_);
  impact_lcp_.set_matrix(D_);
  previous_H_.assign(H_.valuePtr(), H_.valuePtr() + nnz);
  delassus_current_ = true;
  polish_F_.clear();  // H_F moved: the polishing LU is of another matrix
}

RunSummary LargeContactIntegrator::run(const Eigen::VectorXd& q0, const Eigen::VectorXd& v0, RunObserver* observer,
                                       ContactDiagnostics* diag) {
  if (invalid_.empty() && (q0.size() != n_ || v0.size() != n_)) invalid_ = "the initial state does not have one entry per coordinate";
  if (invalid_.empty()) {
    q_ = q0;
    v_ = v0;
  }
  observer_ = observer;
  return SteppingDriver::run_with_diagnostics(*this, SteppingPlan{settings_.grid(), true}, observer, d_, diag);
}

double LargeContactIntegrator::energy_allowance(double /*e_old*/, double e_initial) const { return kEps64 * std::max(kinetic_, e_initial); }

double LargeContactIntegrator::kinetic(const Eigen::VectorXd& v) const { return 0.5 * v.cwiseProduct(v).dot(sys_.mass); }
double LargeContactIntegrator::potential(const Eigen::VectorXd& q) const { return sys_.force_is_potential ? sys_.force.dot(q) : 0.0; }

void LargeContactIntegrator::add_impulses(const std::vector<int>& rows, const Eigen::VectorXd& impulse, Eigen::VectorXd& v) const {
  for (int i : rows) {
    const double p = impulse(i);
    if (p == 0.0) continue;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, i); it; ++it)
      v(it.col()) += inv_mass_(it.col()) * (it.value() * p);
  }
}

bool LargeContactIntegrator::begin(double t, StepFailure& f) {
  rest_ = RestTracker{};
  if (!invalid_.empty()) return f.at(0, t, q_.data(), v_.data(), "invalid contact system: " + invalid_);
  rest_.update(v_);
  ContactDiagnostics& d = *d_;
  d = ContactDiagnostics{};
  d.constraints = nc_;
  d.impacts.reserve(static_cast<std::size_t>(std::clamp(settings_.max_recorded_impacts, 0, 100000)));
  d.settle_step.assign(static_cast<std::size_t>(nc_), -1);
  d.settle_time.assign(static_cast<std::size_t>(nc_), 0.0);
  d.correction_enabled = settings_.correct_positions;
  d.potential_known = sys_.force_is_potential;
  if (!all_finite(q_) || !all_finite(v_)) return f.at(0, t, q_.data(), v_.data(), "the initial state is not finite");
  delassus_current_ = false;
  if (!evaluate_gaps(q_)) return f.at(0, t, q_.data(), v_.data(), nonfinite_gap_message());
  for (int i = 0; i < nc_; ++i)
    if (gap_(i) < d.smallest_gap) {
      d.smallest_gap = gap_(i);
      d.smallest_gap_time = t;
      d.smallest_gap_constraint = i;
    }
  kinetic_ = kinetic(v_);
  potential_ = potential(q_);
  d.lagrange_dirichlet.start(kinetic_ + potential_);
  std::fill(in_F_.begin(), in_F_.end(), 0);
  std::fill(was_active_.begin(), was_active_.end(), 0);
  polish_F_.clear();
  polish_ok_ = false;
  return true;
}

bool LargeContactIntegrator::step(std::int64_t k, double t, double h, double t_next, RunRecorder& rec, StepFailure& f) {
  RunSummary& s = rec.summary();
  ContactDiagnostics& d = *d_;
  s.mass.record(min_mass_, true, k, t);  // Assumption 3.1: a constant diagonal M, its smallest entry

  vf_ = v_ - h * accel_;  // M V_free = M V^k - h g
  U_.noalias() = H_ * v_;
  Hvf_.noalias() = H_ * vf_;
  // I_k, with the round-off of the predicted gap h_i(Q^k) + h H_i V_free counted as contact: M^{-1} g
  // rounds differently for different masses (a stack of balls falling together has H_i V_free of 1e-18
  // either side of 0), and a contact that closes by round-off must not let a ball fall through it.
  active_rows_.clear();
  const double reach = q_.cwiseAbs().maxCoeff() + h * vf_.cwiseAbs().maxCoeff();
  for (int i = 0; i < nc_; ++i)
    if (gap_(i) + h * Hvf_(i) <= kEps64 * (row_abs_sum_(i) * reach + std::abs(offsets_(i)))) active_rows_.push_back(i);
  const bool any_active = !active_rows_.empty();
  d.active_steps += any_active;
  if (any_active) form_delassus();

  vn_ = vf_;
  P_.setZero();
  if (any_active) {
    for (int i : active_rows_) lcp_q_(i) = Hvf_(i) + sys_.restitution[static_cast<std::size_t>(i)] * std::min(U_(i), 0.0);
    // Warm start: a contact that was in I_{k-1} starts where the last answer left it; one that enters
    // I_k now starts closed (it was predicted to close), so a stack that lands at once needs one pass,
    // not one per contact.
    for (int i : active_rows_)
      if (!was_active_[static_cast<std::size_t>(i)]) in_F_[static_cast<std::size_t>(i)] = 1;
    SparseLcpStats st;
    if (!step_lcp_.solve(active_rows_, lcp_q_, lcp_z_, lcp_w_, in_F_, st)) {
      return f.at(k, t, q_.data(), v_.data(),
                  st.singular ? "the gradients of the closed contacts are linearly dependent (the Delassus operator is singular on "
                                "them): their impulses are not unique, and the large-contact path solves independent contacts only"
                              : "the one-step complementarity problem was not solved within " +
                                    std::to_string(SparseLcpSolver::pass_budget(static_cast<int>(active_rows_.size()))) + " passes");
    }
    rec.solver_step(st.passes, st.residual, st.murty_pivots > 0);
    for (int i : active_rows_) P_(i) = lcp_z_(i);
    add_impulses(active_rows_, P_, vn_);
    polish(vn_);
  } else {
    s.solver.total_iterations += 1;
    s.solver.max_iterations = std::max(s.solver.max_iterations, 1);
  }
  // Rows that left I_k are no longer closed for the next warm start.
  if (nc_ > 0) {
    std::size_t a = 0;
    for (int i = 0; i < nc_; ++i) {
      const bool in_active = a < active_rows_.size() && active_rows_[a] == i;
      was_active_[static_cast<std::size_t>(i)] = in_active;
      if (in_active)
        ++a;
      else
        in_F_[static_cast<std::size_t>(i)] = 0;
    }
  }

  // Impacts and the position velocity.
  vpos_ = vn_;
  bool any_impulse = false;
  int impacts_now = 0;
  rows_.clear();
  if (any_active) {
    Un_.noalias() = H_ * vn_;
    const double vmax = v_.cwiseAbs().maxCoeff();
    for (int i : active_rows_) {
      impacting_[static_cast<std::size_t>(i)] = 0;
      if (!(P_(i) > 0.0)) continue;
      any_impulse = true;
      if (!(U_(i) < -kEps64 * row_abs_sum_(i) * vmax)) continue;
      impacting_[static_cast<std::size_t>(i)] = 1;
      ++impacts_now;
      if (sys_.restitution[static_cast<std::size_t>(i)] > 0.0) rows_.push_back(i);  // rebounding
    }
    if (impacts_now > 0) record_impacts(d, k + 1, t_next, impacts_now);
    if (!rows_.empty() && settings_.position_update == PositionUpdate::kMdi) {
      // V_pos = V^{k+1} - M^{-1} H_R^T (H_R M^{-1} H_R^T)^{-1} U_R^{k+1}: D_RR is the Schur complement.
      SparseLcpSolver::principal_submatrix(D_, rows_, local_, triplets_, drr_);
      mdi_ldlt_.compute(drr_);
      if (mdi_ldlt_.info() != Eigen::Success)
        return f.at(k, t, q_.data(), v_.data(), "the gradients of the rebounding contacts are dependent");
      Eigen::VectorXd u(static_cast<Eigen::Index>(rows_.size()));
      for (std::size_t a = 0; a < rows_.size(); ++a) u(static_cast<Eigen::Index>(a)) = Un_(rows_[a]);
      const Eigen::VectorXd sol = mdi_ldlt_.solve(u);
      for (std::size_t a = 0; a < rows_.size(); ++a) ref_z_(rows_[a]) = -sol(static_cast<Eigen::Index>(a));
      add_impulses(rows_, ref_z_, vpos_);
    }
    for (int i : active_rows_) impacting_[static_cast<std::size_t>(i)] = 0;
  }
  d.impulse_steps += any_impulse;
  qn_ = q_ + h * vpos_;
  return true;
}

// The closed rows F (w == 0: H_F V = -b_F exactly). n of them with a well-conditioned H_F: V solved
// from them; otherwise a closed row with one nonzero fixes its coordinate. Kept where it agrees with the
// unpolished V to round-off.
void LargeContactIntegrator::polish(Eigen::VectorXd& v) {
  rows_.clear();
  for (int i : active_rows_)
    if (in_F_[static_cast<std::size_t>(i)]) rows_.push_back(i);
  if (rows_.empty()) return;
  const double scale = std::max(v.cwiseAbs().maxCoeff(), vf_.cwiseAbs().maxCoeff());
  const double allowance = 1e-9 * scale;
  if (static_cast<int>(rows_.size()) == n_) {
    if (rows_ != polish_F_) {
      polish_F_ = rows_;
      std::vector<Eigen::Triplet<double>> t;
      for (std::size_t a = 0; a < rows_.size(); ++a)
        for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, rows_[a]); it; ++it)
          t.emplace_back(static_cast<int>(a), static_cast<int>(it.col()), it.value());
      Eigen::SparseMatrix<double> HF(n_, n_);
      HF.setFromTriplets(t.begin(), t.end());
      HF.makeCompressed();
      polish_lu_.compute(HF);
      polish_ok_ = polish_lu_.info() == Eigen::Success;
    }
    if (polish_ok_) {
      polish_rhs_.resize(n_);
      bool zero = true;
      for (int a = 0; a < n_; ++a) {
        const int i = rows_[static_cast<std::size_t>(a)];
        polish_rhs_(a) = -sys_.restitution[static_cast<std::size_t>(i)] * std::min(U_(i), 0.0);
        zero = zero && polish_rhs_(a) == 0.0;
      }
      bool polished = false;
      if (zero) {  // H_F V = 0 with H_F nonsingular: V = 0 (a rest), exactly
        polished = v.cwiseAbs().maxCoeff() <= allowance;
        if (polished) v.setZero();
      } else {
        const Eigen::VectorXd exact = polish_lu_.solve(polish_rhs_);
        polished = exact.allFinite() && (exact - v).cwiseAbs().maxCoeff() <= allowance;
        if (polished) v = exact;
      }
      if (polished) {
        // The impulses that go with the polished V, from the momentum balance H_F^T P_F = M (V - V_free):
        // for a stack, P_i = P_{i+1} + h m_i g, the weight above each contact summed, instead of a solve
        // with D (whose condition grows as n^2).
        polish_rhs_ = sys_.mass.cwiseProduct(v - vf_);
        const Eigen::VectorXd p = polish_lu_.transpose().solve(polish_rhs_);
        if (p.allFinite() && p.minCoeff() >= 0.0)
          for (int a = 0; a < n_; ++a) P_(rows_[static_cast<std::size_t>(a)]) = p(a);
      }
      return;
    }
  }
  for (int i : rows_) {
    int nz = 0, col = -1;
    double c = 0.0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H_, i); it; ++it)
      if (it.value() != 0.0) {
        ++nz;
        col = static_cast<int>(it.col());
        c = it.value();
      }
    if (nz != 1) continue;
    const double exact = -sys_.restitution[static_cast<std::size_t>(i)] * std::min(U_(i), 0.0) / c;
    if (std::abs(exact - v(col)) <= allowance) v(col) = exact;
  }
}

// The impacts of this step, with eq. (9)'s reference: Moreau's impact law from V^k at Q^k for every
// contact that carries impulse in the step (impacting or closed), 0 <= U+_i + e_i min(U-_i, 0) perp
// P_i >= 0, U+ = U- + D P, solved exactly (sparse_lcp.h). Its kinetic energy change is
// 1/2 sum_i P_i (U+_i + U-_i) = 1/2 sum_i P_i (U-_i - e_i min(U-_i, 0)), which is eq. (9)'s
// 1/2 sum_i (1 - e_i) P_i U-_i on approaching contacts and 0 on closed ones.
void LargeContactIntegrator::record_impacts(ContactDiagnostics& d, std::int64_t step, double t, int impacts_now) {
  carrying_.clear();
  for (int i : active_rows_)
    if (P_(i) > 0.0) carrying_.push_back(i);
  for (int i : carrying_) {
    ref_q_(i) = U_(i) + sys_.restitution[static_cast<std::size_t>(i)] * std::min(U_(i), 0.0);
    ref_F_[static_cast<std::size_t>(i)] = 1;
  }
  SparseLcpStats st;
  const bool evaluated = impact_lcp_.solve(carrying_, ref_q_, ref_z_, ref_w_, ref_F_, st);
  double eq9 = 0.0;
  if (evaluated)
    for (int i : carrying_) eq9 += 0.5 * ref_z_(i) * (U_(i) - sys_.restitution[static_cast<std::size_t>(i)] * std::min(U_(i), 0.0));
  const double measured = kinetic(vn_) - kinetic_;
  const int closed = static_cast<int>(carrying_.size()) - impacts_now;
  for (int i : active_rows_) {
    if (!impacting_[static_cast<std::size_t>(i)]) continue;
    ImpactEvent ev;
    ev.step = step;
    ev.t = t;
    ev.constraint = i;
    ev.pre = U_(i);
    ev.post = Un_(i);
    ev.impulse = P_(i);
    ev.restitution = sys_.restitution[static_cast<std::size_t>(i)];
    ev.kinetic_change = measured;
    ev.reference_evaluated = evaluated;
    ev.reference_impulse = evaluated ? ref_z_(i) : 0.0;
    ev.eq9_change = evaluated ? eq9 : 0.0;
    ev.simultaneous = impacts_now;
    ev.closed_carrying = closed;
    count_impact(d, ev, settings_.max_recorded_impacts, observer_);
  }
  for (int i : carrying_) ref_F_[static_cast<std::size_t>(i)] = 0;
}

// Projects Q^{k+1} onto {H q + c >= 0} in the metric of M: the gaps are linear, so one LCP
// 0 <= h(Q^{k+1}) + D mu  perp  mu >= 0, delta q = M^{-1} H^T mu, lands every gap on >= 0 up to round-off.
bool LargeContactIntegrator::correct(ContactDiagnostics& d) {
  d.largest_violation = std::max(d.largest_violation, -gap_.minCoeff());
  const double before = potential(qn_);
  rows_.resize(static_cast<std::size_t>(nc_));
  for (int i = 0; i < nc_; ++i) rows_[static_cast<std::size_t>(i)] = i;
  std::vector<char> closed(static_cast<std::size_t>(nc_), 0);
  for (int i = 0; i < nc_; ++i) closed[static_cast<std::size_t>(i)] = gap_(i) < 0.0;
  Eigen::VectorXd mu(nc_), w(nc_);
  SparseLcpStats st;
  if (!correction_lcp_.solve(rows_, gap_, mu, w, closed, st)) return false;
  Eigen::VectorXd dq = Eigen::VectorXd::Zero(n_);
  add_impulses(rows_, mu, dq);
  qn_ += dq;
  gap_.noalias() = H_ * qn_;
  gap_ += sys_.offsets;
  ++d.corrected_steps;
  d.max_correction = std::max(d.max_correction, std::sqrt(2.0 * kinetic(dq)));
  if (d.potential_known) d.correction_energy += potential(qn_) - before;
  return true;
}

bool LargeContactIntegrator::arrive(std::int64_t k, double t, StepFailure& f) {
  ContactDiagnostics& d = *d_;
  if (!all_finite(qn_) || !all_finite(vn_)) return f.at(k, t, q_.data(), v_.data(), "the state became non-finite");
  if (!evaluate_gaps(qn_)) return f.at(k, t, q_.data(), v_.data(), nonfinite_gap_message());
  if (settings_.correct_positions && nc_ > 0 && gap_.minCoeff() < 0.0 && !correct(d))
    return f.at(k, t, q_.data(), v_.data(), "the position correction did not converge");
  q_ = qn_;
  v_ = vn_;
  for (int i = 0; i < nc_; ++i) {
    const bool closed = P_(i) > 0.0 && Un_(i) == 0.0;
    if (!closed) {
      d.settle_step[static_cast<std::size_t>(i)] = -1;
    } else if (d.settle_step[static_cast<std::size_t>(i)] < 0) {
      d.settle_step[static_cast<std::size_t>(i)] = k;
      d.settle_time[static_cast<std::size_t>(i)] = t;
    }
    if (gap_(i) < d.smallest_gap) {
      d.smallest_gap = gap_(i);
      d.smallest_gap_time = t;
      d.smallest_gap_constraint = i;
    }
  }
  const double kin_new = kinetic(v_);
  const double pot_new = potential(q_);
  const double allowance = kEps64 * (kinetic_ + std::abs(potential_) + kin_new + std::abs(pot_new));
  d.lagrange_dirichlet.step(k, t, kin_new + pot_new, allowance);
  kinetic_ = kin_new;
  potential_ = pot_new;
  return true;
}

void LargeContactIntegrator::finish(RunRecorder& rec, std::int64_t k, double t) {
  ContactDiagnostics& d = *d_;
  rec.finish(k, t, q_.data(), v_.data(), kinetic_);
  if (rec.rest_from() >= 0) {
    d.rest_step = rec.rest_from();
    d.rest_time = rec.rest_time();
  }
}

}  // namespace moreau
