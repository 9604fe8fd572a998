// The definition of run_tracking of scheme_runs.h, included only by the generated translation units that
// instantiate it (scheme_run.cc.in): the tracking integrator (tracking_integrator.h) over the plant
// SceneModel<N>, the nominal model's SceneModel<N> and the reference (tape or way points), on the scene's
// time grid.
#pragma once

#include <vector>

#include "moreau/core/tracking_integrator.h"
#include "moreau/scene/scene_model.h"
#include "scheme_runs.h"

namespace moreau::scene {

// q_d, q_d', q_d'' at t from the scene's reference: the way points' spline, or the expressions' tape
// (TrackingSpec::reference: inputs [t], outputs 3n). One per run: it holds the run's buffers.
template <int N>
class SceneReference {
 public:
  SceneReference(const TrackingSpec& spec, int n)
      : tape_(spec.reference.get()),
        spline_(spec.spline.get()),
        n_(n),
        out_(static_cast<std::size_t>(3 * n)),
        scratch_(tape_ ? tape_->scratch_size() : 0) {}
  bool at(double t, ReferencePoint<N>& r) const {
    if (spline_) return spline_->at(t, r, hint_);
    tape_->eval(&t, out_.data(), scratch_.data());
    for (int i = 0; i < n_; ++i) {
      r.q(i) = out_[static_cast<std::size_t>(i)];
      r.v(i) = out_[static_cast<std::size_t>(n_ + i)];
      r.a(i) = out_[static_cast<std::size_t>(2 * n_ + i)];
    }
    return r.q.allFinite() && r.v.allFinite() && r.a.allFinite();
  }

 private:
  const expr::Tape* tape_;
  const CubicSplineReference* spline_;
  int n_;
  mutable std::vector<double> out_, scratch_;
  mutable std::size_t hint_ = 0;  // the spline's interval of the last look-up
};

template <int N>
RunSummary run_tracking(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics*) {
  const TrackingSpec& spec = *scene.tracking;
  SceneModel<N> plant(scene);
  SceneModel<N> nominal(*spec.nominal);
  const SceneReference<N> reference(spec, scene.n);
  TrackingSettings<N> settings;
  settings.grid() = scene.settings.grid();
  settings.gains.lambda = Eigen::Map<const Eigen::VectorXd>(spec.lambda.data(), scene.n);
  settings.gains.phi.weights = spec.phi.weights;
  settings.gains.phi.gains = spec.phi.gains;
  settings.gains.phi.norm_gain = spec.phi.norm_gain;
  settings.gains.period = spec.sampled ? spec.period : scene.settings.h;
  settings.gains.boundary_layer = spec.boundary_layer;
  settings.sampled = spec.sampled;
  settings.nominal_scale = spec.nominal_scale;
  settings.quantum = spec.quantum;
  settings.noise = spec.noise;
  settings.seed = spec.seed;
  settings.band = spec.band;
  TrackingIntegrator<SceneModel<N>, SceneModel<N>, SceneReference<N>> integrator(plant, nominal, reference, settings);
  const Vec<N> q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n);
  const Vec<N> v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n);
  return integrator.run(q0, v0, observer);
}

}  // namespace moreau::scene
