// Runners of a compiled scene that live in their own translation units (each instantiates its
// integrator for every fixed size of dispatch_dof, which is most of the library's compile time).
#pragma once

#include "moreau/scene/scene.h"

namespace moreau::scene {

// Moreau-Jean's scheme over SceneModel (moreau_jean_run.cc).
RunSummary run_moreau_jean_scene(const LagrangianScene& scene, RunObserver* observer, ContactDiagnostics* contacts);

}  // namespace moreau::scene
