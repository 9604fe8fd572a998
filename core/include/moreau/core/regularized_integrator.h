// The regularized peer of the ABL scheme, for studies: the set-valued Sign of the controller is replaced
// by a smooth approximation of width epsilon and the resulting stiff ODE is integrated by a trusted stiff
// solver, Boost.Odeint's rosenbrock4 (a 4th-order L-stable Rosenbrock method, Hairer and Wanner's
// RODAS-type coefficients) with error control and dense output:
//
//   q' = v
//   M(q) v' = -(C(q, v) v + grad V(q) + F(t, q, v) + W v + A sgn_eps(v) + a_norm v / max(||v||, eps))
//
// with sgn_eps(v) = tanh(v / eps) (kTanh) or clamp(v / eps, -1, 1) (kSaturation). This is what a user
// without a nonsmooth solver would do; its solution never rests exactly at v = 0 and its cost grows as
// eps shrinks (stiffness ~ a / (m eps)). The Jacobian is taken by forward differences (the model gives
// no derivatives of M, C, F), as is usual when rosenbrock4 is used without an analytic Jacobian.
//
// The study's step size h is used as the output interval and as both the absolute and relative error
// tolerance of the controlled stepper, so one ladder of h spans the peer's accuracy too. RunSummary::steps
// counts the stepper's steps (of a completed run); converged_step, like the observer's Sample::step, is an
// index into the output samples.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <boost/numeric/odeint.hpp>

#include "moreau/core/abl_integrator.h"  // LagrangianTerms, the model requirements
#include "moreau/core/regularization.h"
#include "moreau/core/stepping_driver.h"

namespace moreau {

// The grid: h is the output interval and the error tolerance (the solver chooses its own steps), and
// the observer sees every output_every-th output point; max_steps is not used, since the solver's own
// steps are capped through the work they do, max_rhs_evaluations.
struct RegularizedSettings : TimeGrid {
  double epsilon = 1e-3;  // width of the regularized sign
  Regularization kind = Regularization::kTanh;
  std::int64_t max_rhs_evaluations = 100'000'000;
};

template <class Model>
class RegularizedIntegrator {
 public:
  static constexpr int N = Model::kDof;
  using state_type = boost::numeric::ublas::vector<double>;
  using matrix_type = boost::numeric::ublas::matrix<double>;

  RegularizedIntegrator(Model& model, const RegularizedSettings& settings) : model_(model), s_(settings) {
    const int n = model_.dof();
    terms_.resize(n);
    q_.setZero(n);
    v_.setZero(n);
    rhs_.setZero(n);
    if constexpr (N == Eigen::Dynamic) lu_ = Eigen::PartialPivLU<Mat<N>>(n);
  }

  RunSummary run(const Vec<N>& q0, const Vec<N>& v0, RunObserver* observer = nullptr) {
    namespace odeint = boost::numeric::odeint;
    const auto start = std::chrono::steady_clock::now();
    const int n = model_.dof();
    RunSummary summary;
    state_type x(2 * n);
    for (int i = 0; i < n; ++i) {
      x(i) = q0(i);
      x(n + i) = v0(i);
    }
    std::int64_t samples = 0;
    double energy_prev = -1.0;
    std::int64_t rest_from = -1;
    double rest_time = 0.0, last_t = s_.t0;
    auto observe = [&](const state_type& z, double t) {
      for (int i = 0; i < n; ++i) {
        q_(i) = z(i);
        v_(i) = z(n + i);
      }
      model_.evaluate(t, q_, v_, terms_);
      rhs_.noalias() = terms_.M * v_;  // into a member: nested in dot(), a heap temporary at dynamic sizes
      const double energy = 0.5 * v_.dot(rhs_);
      if (samples == 0) summary.energy_initial = energy;
      if (energy_prev >= 0.0 &&
          energy - energy_prev > 64.0 * std::numeric_limits<double>::epsilon() * std::max(energy_prev, summary.energy_initial)) {
        ++summary.energy_increases;
        summary.energy_max_increase = std::max(summary.energy_max_increase, energy - energy_prev);
      }
      energy_prev = energy;
      if ((v_.array() == 0.0).all()) {
        if (rest_from < 0) {
          rest_from = samples;
          rest_time = t;
        }
      } else {
        rest_from = -1;
      }
      // Every output_every-th output point and the last (at t_end), numbered as SteppingDriver numbers them.
      const std::int64_t every = std::max<std::int64_t>(1, s_.output_every);
      if (observer && (samples % every == 0 || t == s_.t_end))
        observer->on_sample(
            Sample{samples, t, samples == 0 ? s_.h : t - last_t, n, q_.data(), v_.data(), energy, 0.0, (samples + every - 1) / every});
      last_t = t;
      summary.energy_final = energy;
      ++samples;
      if (observer && samples % 64 == 0 && !observer->keep_going(samples, t)) throw Cancelled{};
    };
    System system{this};
    Jacobian jacobian{this};
    std::size_t solver_steps = 0;
    try {
      // Output at t0 + k h and at t_end itself, so the last sample is the final state.
      std::vector<double> times;
      const FixedTimeGrid grid(s_.t0, s_.t_end, s_.h);
      times.reserve(static_cast<std::size_t>(grid.steps) + 1);
      for (std::int64_t k = 0; k <= grid.steps; ++k) times.push_back(grid.time(k));
      solver_steps = odeint::integrate_times(odeint::make_dense_output(s_.h, s_.h, odeint::rosenbrock4<double>()),
                                             std::make_pair(system, jacobian), x, times.begin(), times.end(), s_.h, observe);
      summary.status = RunStatus::kCompleted;
    } catch (const Cancelled&) {
      summary.status = RunStatus::kCancelled;
      summary.message = "cancelled";
    } catch (const std::exception& e) {
      summary.status = RunStatus::kFailed;
      summary.message = std::string("rosenbrock4: ") + e.what();
    }
    // The solver's own steps when it finished (the work a study compares), else the samples reached.
    summary.steps = summary.status == RunStatus::kCompleted ? static_cast<std::int64_t>(solver_steps) : (samples > 0 ? samples - 1 : 0);
    summary.t_final = last_t;
    summary.q_final.assign(q_.data(), q_.data() + n);
    summary.v_final.assign(v_.data(), v_.data() + n);
    summary.energy_nonincreasing = summary.energy_increases == 0;
    if (rest_from >= 0) {
      summary.rest_step = rest_from;
      summary.rest_time = rest_time;
      // The same window as RunRecorder::finish (a regularized law never rests, so this is for symmetry).
      if (samples - 1 - rest_from >= RunSummary::kMinRestSteps) {
        summary.converged_step = rest_from;
        summary.converged_time = rest_time;
      }
    }
    summary.solver.total_iterations = rhs_evaluations_;
    summary.h_min = summary.h_max = s_.h;
    summary.add_phase("integrate", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    return summary;
  }

 private:
  struct Cancelled {};

  double sign_eps(double v) const {
    const double r = v / s_.epsilon;
    return s_.kind == Regularization::kTanh ? std::tanh(r) : std::clamp(r, -1.0, 1.0);
  }

  // dz/dt at (z, t).
  void derivative(const state_type& z, state_type& dz, double t) {
    if (++rhs_evaluations_ > s_.max_rhs_evaluations) throw std::runtime_error("more right-hand-side evaluations than max_rhs_evaluations");
    const int n = model_.dof();
    for (int i = 0; i < n; ++i) {
      q_(i) = z(i);
      v_(i) = z(n + i);
    }
    model_.evaluate(t, q_, v_, terms_);
    const Controller<N>& phi = model_.controller();
    rhs_.noalias() = terms_.C * v_;
    rhs_ += terms_.g;
    rhs_ += phi.weights.cwiseProduct(v_);
    for (int i = 0; i < n; ++i) rhs_(i) += phi.gains(i) * sign_eps(v_(i));
    if (phi.norm_gain > 0.0) rhs_ += (phi.norm_gain / std::max(v_.norm(), s_.epsilon)) * v_;
    lu_.compute(terms_.M);
    rhs_ = -lu_.solve(rhs_);
    for (int i = 0; i < n; ++i) {
      dz(i) = z(n + i);
      dz(n + i) = rhs_(i);
    }
  }

  struct System {
    RegularizedIntegrator* self;
    void operator()(const state_type& z, state_type& dz, double t) const { self->derivative(z, dz, t); }
  };
  // Forward-difference Jacobian of the right-hand side, and its time derivative.
  struct Jacobian {
    RegularizedIntegrator* self;
    void operator()(const state_type& z, matrix_type& J, double t, state_type& dfdt) const {
      const std::size_t m = z.size();
      state_type f0(m), f1(m), zp(z);
      self->derivative(z, f0, t);
      for (std::size_t j = 0; j < m; ++j) {
        const double step = std::sqrt(std::numeric_limits<double>::epsilon()) * std::max(1.0, std::abs(z(j)));
        zp(j) = z(j) + step;
        self->derivative(zp, f1, t);
        for (std::size_t i = 0; i < m; ++i) J(i, j) = (f1(i) - f0(i)) / step;
        zp(j) = z(j);
      }
      const double dt = std::sqrt(std::numeric_limits<double>::epsilon()) * std::max(1.0, std::abs(t));
      self->derivative(z, f1, t + dt);
      for (std::size_t i = 0; i < m; ++i) dfdt(i) = (f1(i) - f0(i)) / dt;
    }
  };

  Model& model_;
  RegularizedSettings s_;
  LagrangianTerms<N> terms_;
  Vec<N> q_, v_, rhs_;
  Eigen::PartialPivLU<Mat<N>> lu_;
  std::int64_t rhs_evaluations_ = 0;
};

}  // namespace moreau
