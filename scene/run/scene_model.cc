// Running a compiled Lagrangian scene: the scheme (0.2) (AblIntegrator over SceneModel, with the
// checks at recorded states) here, Moreau-Jean in moreau_jean_run.cc and Lur'e scenes in lure_run.cc (one
// translation unit each, so that their fixed-size instantiations compile in parallel); ForceTerms.
#include "moreau/scene/scene_model.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "runners.h"

namespace moreau::scene {
namespace {

template <int N>
RunSummary run_fixed(const LagrangianScene& scene, RunObserver* observer) {
  SceneModel<N> model(scene);
  AblSettings settings = scene.settings;
  settings.output_every = scene.output_every;
  AblIntegrator<SceneModel<N>> integrator(model, settings);
  const Vec<N> q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n);
  const Vec<N> v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n);
  return integrator.run(q0, v0, observer);
}

}  // namespace

ForceTerms::ForceTerms(const CompiledLagrangian& compiled)
    : c_(compiled),
      split_scratch_(compiled.split_force_tape.scratch_size(), 0.0),
      potential_scratch_(compiled.potential_tape.scratch_size(), 0.0),
      gravity_(static_cast<std::size_t>(compiled.n), 0.0) {
  c_.split_force_tape.load_constants(split_scratch_.data());
  c_.potential_tape.load_constants(potential_scratch_.data());
  if (c_.robot) robot_data_ = std::make_unique<RigidBodyData>(*c_.robot);
}

void ForceTerms::split(double t, const double* q, const double* v, double* grad_v, double* force) {
  const double* sources[] = {&t, q, v};  // CompiledLagrangian::Source
  double* sinks[] = {grad_v, force};     // CompiledLagrangian::split_force_tape
  c_.split_force_tape.run_wired(split_scratch_.data(), sources, sinks);
  if (c_.robot) {
    const int n = c_.n;
    gravity_torque(*c_.robot, *robot_data_, q, Eigen::Map<Eigen::VectorXd>(gravity_.data(), n));
    for (int i = 0; i < n; ++i) grad_v[i] += gravity_[static_cast<std::size_t>(i)];
  }
}

double ForceTerms::potential(const double* q) {
  double value = 0.0;
  if (c_.potential_tape.num_outputs() > 0) {
    const double* sources[] = {q};  // CompiledLagrangian::potential_tape
    double* sinks[] = {&value};
    c_.potential_tape.run_wired(potential_scratch_.data(), sources, sinks);
  }
  if (c_.robot) value += potential_energy(*c_.robot, *robot_data_, q);
  return value;
}

RecordedStateChecks::RecordedStateChecks(const LagrangianScene& scene, RunObserver* next)
    : ForwardingObserver(next),
      terms_(*scene.compiled),
      n_(scene.n),
      alpha_(scene.controller.alpha()),
      has_potential_(scene.compiled->has_potential),
      grad_(static_cast<std::size_t>(scene.n)),
      force_(static_cast<std::size_t>(scene.n)) {}

void RecordedStateChecks::on_sample(const Sample& s) {
  if (s.index % kStride == 0 && !force_bounds_.failed) force_bound(s);
  if (s.index % kEnergyStride == 0 && has_potential_) energy(s);
  ForwardingObserver::on_sample(s);
}

void RecordedStateChecks::record_into(RunSummary& s) const {
  s.force_bounds = force_bounds_;
  s.mechanical = mechanical_;
}

void RecordedStateChecks::force_bound(const Sample& s) {
  ForceBoundTrack& track = force_bounds_;
  terms_.split(s.t, s.q, s.v, grad_.data(), force_.data());
  double g2 = 0.0, f2 = 0.0;
  for (int i = 0; i < n_; ++i) {
    g2 += grad_[i] * grad_[i];
    f2 += force_[i] * force_[i];
  }
  ++track.samples;
  if (f2 > track.max_force * track.max_force) {
    track.max_force = std::sqrt(f2);
    track.max_force_time = s.t;
  }
  if (g2 > track.max_gradient * track.max_gradient) {
    track.max_gradient = std::sqrt(g2);
    track.max_gradient_time = s.t;
  }
  track.failed = track.max_force >= alpha_ || track.max_gradient > 0.5 * (alpha_ - track.max_force);
}

void RecordedStateChecks::energy(const Sample& s) {
  MechanicalEnergyTrack& track = mechanical_;
  const double e = s.kinetic_energy + terms_.potential(s.q);
  if (track.samples++ == 0) track.initial = e;
  const double rise = e - track.initial, balance = std::abs(rise + s.dissipated_work);
  if (rise > track.max_rise) {
    track.max_rise = rise;
    track.max_rise_time = s.t;
  }
  if (balance > track.max_balance) {
    track.max_balance = balance;
    track.max_balance_time = s.t;
  }
}

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer) { return run_scene(scene, observer, nullptr); }

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts) {
  if (scene.scheme == Scheme::kMoreauJean) return run_moreau_jean_scene(scene, observer, contacts);
  // Assumption 4.1 concerns the scheme (0.2) only.
  RecordedStateChecks checks(scene, observer);
  RunSummary s = dispatch_dof(scene.n, [&](auto dof) { return run_fixed<decltype(dof)::value>(scene, &checks); });
  checks.record_into(s);
  return s;
}

}  // namespace moreau::scene
