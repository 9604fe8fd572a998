// The Lur'e runner: the theta-method (lure_integrator.h) over fixed-size Eigen types for (states,
// outputs) = (N, Mo). Declared for lure_run.cc, which dispatches to it; defined here and instantiated
// one pair per translation unit, generated from lure_run.cc.in by scene/CMakeLists.txt (each pair is a
// large instantiation; apart they build in parallel).
#pragma once

#include "moreau/scene/scene.h"

namespace moreau::scene {

template <int N, int Mo>
RunSummary run_lure(const LureScene& scene, RunObserver* observer, LureDiagnostics* diagnostics);

#ifdef MOREAU_DEFINE_LURE_RUN
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
#endif

}  // namespace moreau::scene
