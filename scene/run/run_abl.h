// The definition of run_abl of scheme_runs.h, included only by the generated translation units that
// instantiate it (scheme_run.cc.in): the integrator over SceneModel<N>, on the scene's time grid
// (settings.grid()) with the scheme's own options.
#pragma once

#include "moreau/scene/scene_model.h"
#include "scheme_runs.h"

namespace moreau::scene {

template <int N>
RunSummary run_abl(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics*) {
  SceneModel<N> model(scene);
  AblIntegrator<SceneModel<N>> integrator(model, scene.settings);
  const Vec<N> q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n);
  const Vec<N> v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n);
  return integrator.run(q0, v0, observer);
}

}  // namespace moreau::scene
