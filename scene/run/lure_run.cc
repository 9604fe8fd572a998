// A compiled Lur'e scene on the theta-method (lure_integrator.h): fixed-size Eigen code for the listed
// (states, outputs) pairs, dynamic beyond.
#include "moreau/scene/scene_model.h"

namespace moreau::scene {
namespace {

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

}  // namespace

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
