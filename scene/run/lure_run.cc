// A compiled Lur'e scene on the theta-method (lure_integrator.h): fixed-size Eigen code for the listed
// (states, outputs) pairs, dynamic beyond; each pair is instantiated in its own translation unit
// (run_lure.h).
#include "moreau/scene/scene_model.h"
#include "run_lure.h"

namespace moreau::scene {

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
