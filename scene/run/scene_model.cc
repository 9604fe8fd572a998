// Running a compiled Lagrangian scene: run_scene dispatches on the scheme (scheme.h) and the size
// (dispatch_dof) to the runners of scheme_runs.h, each instantiated in a translation unit of its own;
// the checks at recorded states (RecordedStateChecks), ForceTerms, and the variants a study compares.
#include "moreau/scene/scene_model.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

#include "moreau/core/large_abl_integrator.h"
#include "moreau/core/large_contact_integrator.h"
#include "scheme_runs.h"

namespace moreau::scene {

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

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts, bool check_recorded_states) {
  const SchemeTraits& row = traits(scene.scheme);
  if (row.system != SystemType::kLagrangian)
    throw std::invalid_argument(std::string("the ") + row.name + " scheme does not integrate a Lagrangian scene");
  std::optional<RecordedStateChecks> checks;
  if (check_recorded_states && row.recorded_state_checks) {
    checks.emplace(scene, observer);
    observer = &*checks;
  }
  RunSummary s;
  if (uses_large_abl_path(scene)) {
    LargeAblIntegrator integrator(*scene.compiled->large_abl, scene.settings.grid());
    s = integrator.run(Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n),
                       Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n), observer);
    if (checks) checks->record_into(s);
    return s;
  }
  if (uses_large_contact_path(scene)) {
    if (scene.scheme != Scheme::kMoreauJean)
      throw std::invalid_argument(std::string("the ") + row.name +
                                  " scheme does not run a scene beyond the dense limits; moreau-jean and abl do");
    MoreauJeanSettings settings = scene.contact_settings;
    settings.grid() = scene.settings.grid();
    LargeContactIntegrator integrator(*scene.compiled->large_contacts, settings);
    s = integrator.run(Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n),
                       Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n), observer, contacts);
    if (checks) checks->record_into(s);
    return s;
  }
  s = dispatch_dof(scene.n, [&](auto dof) {
    constexpr int N = decltype(dof)::value;
    switch (scene.scheme) {
      case Scheme::kMoreauJean: return run_moreau_jean<N>(scene, observer, contacts);
      case Scheme::kRegularized: return run_regularized<N>(scene, observer, contacts);
      case Scheme::kTracking: return run_tracking<N>(scene, observer, contacts);
      default: return run_abl<N>(scene, observer, contacts);  // kAbl and kExplicit (the system type is checked above)
    }
  });
  if (checks) checks->record_into(s);
  return s;
}

// From this many coordinates a scene with the large ABL structure (constant sparse M, C = 0, separable
// Phi, no constraints) runs on that path within the dense limits too: measured crossover (docs/scaling.md).
constexpr int kLargeAblFromDof = 8;

bool uses_large_abl_path(const LagrangianScene& scene) {
  const CompiledLagrangian* c = scene.compiled.get();
  return c && c->large_abl && scene.scheme == Scheme::kAbl && (!c->dense || scene.n >= kLargeAblFromDof);
}

bool uses_large_contact_path(const LagrangianScene& scene) {
  const CompiledLagrangian* c = scene.compiled.get();
  return c && c->large_contacts && scene.scheme == Scheme::kMoreauJean && (!c->dense || scene.n >= kLargeContactFromDof);
}

LagrangianScene scene_variant(const LagrangianScene& scene, Scheme scheme, double h) {
  if (traits(scheme).system != SystemType::kLagrangian)
    throw std::invalid_argument(std::string("the ") + scheme_name(scheme) + " scheme does not integrate a Lagrangian scene");
  const bool runs_at_scale = scene.compiled && (scheme == Scheme::kMoreauJean ? scene.compiled->large_contacts != nullptr
                                                : scheme == Scheme::kAbl      ? scene.compiled->large_abl != nullptr
                                                                              : false);
  if (scene.compiled && !scene.compiled->dense && !runs_at_scale)
    throw std::invalid_argument(std::string("the ") + scheme_name(scheme) + " scheme does not run a scene beyond the dense limits (" +
                                std::to_string(kMaxDof) + " coordinates, " + std::to_string(kMaxConstraints) + " constraints)");
  LagrangianScene at = scene;
  at.scheme = scheme;
  at.settings.h = h;
  if (scheme == Scheme::kExplicit) {
    at.settings.velocity_update = VelocityUpdate::kExplicit;
    at.settings.step_rule = StepRule::kFixed;
  } else if (scheme == Scheme::kAbl) {
    at.settings.velocity_update = VelocityUpdate::kImplicit;
  }
  return at;
}

}  // namespace moreau::scene
