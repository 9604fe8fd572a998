// The runners of a compiled Lagrangian scene, one per integrator, each a template over the fixed size N
// of dispatch_dof (scene_model.h). They are declared here and defined in run_abl.h, run_moreau_jean.h,
// run_regularized.h and run_tracking.h; CMake instantiates each runner for each size in a translation
// unit of its own (scheme_run.cc.in), so that the instantiations, which are most of the library's compile time, build in parallel and none
// is large. run_scene (scene_model.cc) dispatches to them and is their only caller.
#pragma once

#include "moreau/scene/scene.h"

namespace moreau::scene {

// The scheme (0.2), or its explicit peer (AblIntegrator with the scene's settings).
template <int N>
RunSummary run_abl(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts);
// Moreau-Jean (MoreauJeanIntegrator), filling `contacts` when given.
template <int N>
RunSummary run_moreau_jean(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts);
// The regularized peer (RegularizedIntegrator).
template <int N>
RunSummary run_regularized(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts);
// Tracking of /system/tracking's reference (TrackingIntegrator); no contacts.
template <int N>
RunSummary run_tracking(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts);

}  // namespace moreau::scene
