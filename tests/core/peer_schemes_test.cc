// The peers of the ABL scheme used by studies: the regularized ODE integrated by rosenbrock4 approaches
// the exact solution of the damped relay as eps and the tolerance shrink, but never rests at 0.0.
#include "moreau/core/regularized_integrator.h"

#include <gtest/gtest.h>

#include <cmath>

#include "moreau/core/models/oscillator1.h"

namespace moreau {
namespace {

using models::Oscillator1;

// v(t) = (v0 + a/c) e^{-ct/m} - a/c before t* = (m/c) ln(1 + c v0/a) = 4 ln 2.5.
double ExactV(double t) { return t >= 4.0 * std::log(2.5) ? 0.0 : 5.0 * std::exp(-t / 4.0) - 2.0; }

TEST(RegularizedPeer, ApproachesTheDampedRelayButNeverRests) {
  for (auto kind : {Regularization::kTanh, Regularization::kSaturation}) {
    Oscillator1 model(2.0, 0.0, 0.0, 0.5, 1.0);  // the damped relay
    RegularizedSettings s;
    s.h = 1e-4;
    s.t_end = 6.0;
    s.epsilon = 1e-4;
    s.kind = kind;
    RegularizedIntegrator<Oscillator1> integrator(model, s);
    struct Probe : RunObserver {
      double max_err = 0.0;
      int samples = 0;
      void on_sample(const Sample& x) override {
        ++samples;
        if (std::abs(x.t - 4.0 * std::log(2.5)) > 0.01) max_err = std::max(max_err, std::abs(x.v[0] - ExactV(x.t)));
      }
    } probe;
    const RunSummary r = integrator.run(Vec<1>(0.0), Vec<1>(3.0), &probe);
    ASSERT_EQ(r.status, RunStatus::kCompleted) << r.message;
    EXPECT_LT(probe.max_err, 1e-3);
    EXPECT_NE(r.v_final[0], 0.0) << "a regularized sign cannot hold v at exactly 0";
    EXPECT_LT(std::abs(r.v_final[0]), 1e-4);
    EXPECT_GT(r.solver.total_iterations, 0);
    EXPECT_EQ(probe.samples, 60001) << "output at every h, t0 and t_end included";
    // steps counts rosenbrock4's own steps: with dense output it steps over many output times.
    EXPECT_GT(r.steps, 0);
    EXPECT_LT(r.steps, 60000);
    RecordProperty("rhs_evaluations", std::to_string(r.solver.total_iterations));
  }
}

}  // namespace
}  // namespace moreau
