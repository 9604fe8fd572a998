// A compiled Lagrangian scene on Moreau-Jean's scheme (moreau_jean_integrator.h), at the fixed size of
// dispatch_dof.
#include "moreau/scene/scene_model.h"
#include "runners.h"

namespace moreau::scene {
namespace {

template <int N>
RunSummary run_moreau_jean(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts) {
  SceneModel<N> model(scene);
  MoreauJeanSettings settings = scene.contact_settings;
  settings.output_every = scene.output_every;
  MoreauJeanIntegrator<SceneModel<N>> integrator(model, settings);
  const Vec<N> q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), scene.n);
  const Vec<N> v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), scene.n);
  return integrator.run(q0, v0, observer, contacts);
}

}  // namespace

RunSummary run_moreau_jean_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts) {
  return dispatch_dof(scene.n, [&](auto dof) { return run_moreau_jean<decltype(dof)::value>(scene, observer, contacts); });
}

}  // namespace moreau::scene
