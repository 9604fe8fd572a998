// A compiled scene as a model of the ABL integrator, and the dispatch on the number of degrees of
// freedom: fixed-size Eigen code for n <= 4, dynamic beyond.
#include "moreau/scene/scene_model.h"

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

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer) {
  switch (scene.n) {
    case 1: return run_fixed<1>(scene, observer);
    case 2: return run_fixed<2>(scene, observer);
    case 3: return run_fixed<3>(scene, observer);
    case 4: return run_fixed<4>(scene, observer);
    default: return run_fixed<Eigen::Dynamic>(scene, observer);
  }
}

}  // namespace moreau::scene
