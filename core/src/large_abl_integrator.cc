// The scheme (0.2) at scale (large_abl_integrator.h).
#include "moreau/core/large_abl_integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace moreau {

LargeAblIntegrator::LargeAblIntegrator(const LargeAblSystem& system, const TimeGrid& grid)
    : sys_(system), grid_(grid), invalid_(system.validate()) {
  n_ = std::max(0, sys_.dof());
  for (Eigen::VectorXd* x : {&q_, &v_, &g_, &Mv_, &x_, &y_}) x->setZero(n_);  // a failing run still reports a state of n entries
  if (!invalid_.empty()) return;
  sys_.mass.makeCompressed();
  lambda_min_ = certified_lambda_min(sys_.mass);
  if (!(lambda_min_ > 0.0)) {
    invalid_ = "M is not positive definite (Assumption 3.1): no Cholesky factor of M - s I for any s > 0 tried";
    return;
  }
  if (sys_.gradient) scratch_ = sys_.gradient->make_scratch();
}

RunSummary LargeAblIntegrator::run(const Eigen::VectorXd& q0, const Eigen::VectorXd& v0, RunObserver* observer) {
  if (q0.size() != n_ || v0.size() != n_) {
    if (invalid_.empty()) invalid_ = "the initial state does not have one entry per coordinate";
  } else {
    q_ = q0;
    v_ = v0;
  }
  return SteppingDriver::run(*this, SteppingPlan{grid_, true}, observer);
}

// Round-off in E_k itself: a few ulps of the run's energy scale (as abl_integrator.h).
double LargeAblIntegrator::energy_allowance(double e_old, double e_initial) const {
  return 64.0 * std::numeric_limits<double>::epsilon() * std::max(e_old, e_initial);
}

void LargeAblIntegrator::form_step_matrix(double h) {
  if (h == h_formed_) return;
  P_ = sys_.mass / h;
  for (int i = 0; i < n_; ++i) P_.coeffRef(i, i) += sys_.phi.weights(i);  // the diagonal is stored: M is positive definite
  P_.makeCompressed();
  solver_.configure(P_, sys_.phi.gains);
  h_formed_ = h;
}

bool LargeAblIntegrator::evaluate(std::int64_t k, double t, StepFailure& f) {
  sys_.evaluate(q_, g_, scratch_);
  if (!g_.allFinite())
    return f.at(k, t, q_.data(), v_.data(), "the generalized force grad V + F is not finite (an expression left its domain)");
  Mv_.noalias() = sys_.mass * v_;
  energy_ = 0.5 * v_.dot(Mv_);
  return true;
}

bool LargeAblIntegrator::begin(double t, StepFailure& f) {
  rest_ = RestTracker{};
  if (!invalid_.empty()) return f.at(0, t, q_.data(), v_.data(), "invalid system: " + invalid_);
  if (!q_.allFinite() || !v_.allFinite()) return f.at(0, t, q_.data(), v_.data(), "the initial state is not finite");
  rest_.update(v_);
  h_formed_ = 0.0;
  return evaluate(0, t, f);
}

bool LargeAblIntegrator::step(std::int64_t k, double t, double h, double /*t_next*/, RunRecorder& rec, StepFailure& f) {
  RunSummary& s = rec.summary();
  // Assumption 3.1 and (4.2) at every step: the constant M's certified bound, and r_k = 0 since C = 0.
  s.mass.record(lambda_min_, false, k, t);
  s.theorem41.record_squared(0.0, lambda_min_ * lambda_min_, BoundKind::kExact, k, t);
  form_step_matrix(h);
  x_ = g_ - Mv_ / h;  // x = g - M V^k / h
  if (!x_.allFinite())
    return f.at(k, t, q_.data(), v_.data(),
                "x = g - M V^k / h of the inclusion (6.5) is not finite: the state grew without bound ((0.2)'s explicit position "
                "update amplifies the potential's modes whose period is not long against h)");
  OneStepStats st;
  if (!solver_.solve(x_, y_, st)) {
    const std::string why = !std::isfinite(st.residual)
                                ? "the one-step inclusion (6.5) was not solved: P = M/h + W is not positive definite to working precision"
                                : "the one-step inclusion (6.5) was not solved to round-off (residual " +
                                      platform::significant(st.residual, 3) + " above the tolerance " +
                                      platform::significant(st.tolerance, 3) + ")";
    return f.at(k, t, q_.data(), v_.data(), why);
  }
  // h <xi, V^{k+1}> with xi in dPhi(V^{k+1}), as abl_integrator.h; the closed form y = 0 takes none.
  step_work_ = st.iterations != 0 ? h * dissipation_rate(sys_.phi.weights, sys_.phi.gains, 0.0, y_) : 0.0;
  rec.solver_step(st.iterations, st.residual, st.used_fallback);
  s.solver.rest_steps += (st.iterations == 0);
  q_ += h * v_;  // Q^{k+1} = Q^k + h V^k: explicit in position
  v_.swap(y_);
  rest_.update(v_, st.iterations == 0);
  return true;
}

bool LargeAblIntegrator::arrive(std::int64_t k, double t, StepFailure& f) {
  if (!q_.allFinite() || !v_.allFinite()) return f.at(k, t, q_.data(), v_.data(), "the state became non-finite");
  return evaluate(k, t, f);
}

// The summary, and Theorem 4.3's equilibrium inclusion at the final position: -F - grad V(Q) in dPhi(0)
// (g does not depend on v).
void LargeAblIntegrator::finish(RunRecorder& rec, std::int64_t k, double t) {
  RunSummary& s = rec.summary();
  sys_.evaluate(q_, g_, scratch_);
  const Eigen::VectorXd z = -g_;
  s.equilibrium.evaluated = z.allFinite();
  s.equilibrium.residual = sys_.phi.distance_to_subdifferential_at_zero(z);
  s.equilibrium.interior = sys_.phi.in_interior_of_subdifferential_at_zero(z);
  s.solver.linear_solver =
      (solver_.banded_factor() ? "LDL^T of P_FF = (M/h + W)_FF within its band (bandwidth " + std::to_string(solver_.bandwidth()) + ")"
                               : std::string("sparse LDL^T of P_FF = (M/h + W)_FF (minimum-degree order)")) +
      ", " + std::to_string(solver_.factorisations()) + " factorisations in the run";
  s.dissipation_tracked = true;
  rec.finish(k, t, q_.data(), v_.data(), energy_, s.equilibrium.evaluated && s.equilibrium.residual == 0.0);
}

}  // namespace moreau
