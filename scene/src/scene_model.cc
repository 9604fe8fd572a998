// A compiled scene as a model of the ABL and Moreau-Jean integrators, a Lur'e scene on the theta-method,
// and the dispatch on the number of degrees of freedom (dispatch_dof; for Lur'e systems, states and
// outputs): fixed-size Eigen code for n <= 4, dynamic beyond.
#include "moreau/scene/scene_model.h"

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

template <int N, int Mo>
RunSummary run_lure(const LureScene& scene, RunObserver* observer, LureDiagnostics* diagnostics) {
  const Mat<N> A = scene.A;
  const Eigen::Matrix<double, N, Mo> B = scene.B;
  const Eigen::Matrix<double, Mo, N> C = scene.C;
  std::optional<Mat<N>> P;
  if (scene.storage) P = Mat<N>(*scene.storage);
  LureIntegrator<N, Mo> integrator(A, B, C, scene.feedback, scene.settings, P);
  const Vec<N> x0 = Eigen::Map<const Eigen::VectorXd>(scene.x0.data(), scene.n);
  return integrator.run(x0, observer, diagnostics);
}

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

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer) { return run_scene(scene, observer, nullptr); }

RunSummary run_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts) {
  return dispatch_dof(scene.n, [&](auto dof) {
    constexpr int N = decltype(dof)::value;
    if (scene.scheme == Scheme::kMoreauJean) return run_moreau_jean<N>(scene, observer, contacts);
    return run_fixed<N>(scene, observer);
  });
}

RunSummary run_lure_scene(const LureScene& scene, RunObserver* observer, LureDiagnostics* diagnostics) {
  const int n = scene.n, m = scene.m;
  if (n == 1 && m == 1) return run_lure<1, 1>(scene, observer, diagnostics);
  if (n == 2 && m == 1) return run_lure<2, 1>(scene, observer, diagnostics);
  if (n == 2 && m == 2) return run_lure<2, 2>(scene, observer, diagnostics);
  if (n == 3 && m == 1) return run_lure<3, 1>(scene, observer, diagnostics);
  if (n == 3 && m == 2) return run_lure<3, 2>(scene, observer, diagnostics);
  if (n == 3 && m == 3) return run_lure<3, 3>(scene, observer, diagnostics);
  if (n == 4 && m == 1) return run_lure<4, 1>(scene, observer, diagnostics);
  if (n == 4 && m == 2) return run_lure<4, 2>(scene, observer, diagnostics);
  return run_lure<Eigen::Dynamic, Eigen::Dynamic>(scene, observer, diagnostics);
}

}  // namespace moreau::scene
