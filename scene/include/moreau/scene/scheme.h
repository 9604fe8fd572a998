// The integration schemes: one enum and one table. Each row says what a scheme is (its name in scene
// files, studies and reports), which systems it integrates, which settings and scene features it takes
// (the scene compilers validate against the row), whether the run checks Assumption 4.1 at the recorded
// states, and which theorems its report cites. Drake derives its integrator names from one list in the
// same way. Strings exist only at the boundary: the parsers turn a name into the enum at once
// (scheme_from_name), and only report and table writers turn it back (scheme_name). The one place that
// builds an integrator for a scheme is scene/run (run_scene, run_lure_scene).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::scene {

enum class Scheme {
  kAbl,            // eq. (0.2) of Adly, Brogliato and Le (2016): Lagrangian systems without contacts
  kExplicit,       // the explicit peer of (0.2) (AblSettings::velocity_update): a study's comparison
  kRegularized,    // the sign smoothed or saturated, integrated by a stiff ODE solver: a study's comparison
  kMoreauJean,     // Moreau-Jean with Newton restitution (eq. 8 and 17 of Brogliato 2003): contacts
  kImplicitEuler,  // the theta-method for Lur'e systems (eq. 4 of Brogliato 2003)
  kTracking,       // a reference tracked by the set-valued controller on sigma: continuous or sampled (tracking_integrator.h)
};

enum class SystemType { kLagrangian, kLure };

struct SchemeTraits {
  Scheme scheme;
  const char* name;  // in /integrator/scheme, --schemes, reports and tables
  SystemType system;
  bool scene_can_name;         // a scene may name it in /integrator/scheme (else only a study runs it)
  bool study_compares;         // a study may compare it (--schemes)
  bool contacts;               // integrates unilateral constraints (/system/constraints) with impacts
  bool step_rules;             // the step rules of Theorems 4.1 and 4.2, with k1 and k3
  bool norm_term;              // the norm term of the controller (not separable)
  bool position_options;       // /integrator/position_update and /integrator/position_correction
  bool theta;                  // /integrator/theta
  bool recorded_state_checks;  // Assumption 4.1 2)-3) and the energy balance at the recorded states
  bool theorems_4_1_to_4_3;    // it is the scheme (0.2): its report checks Theorems 4.1-4.3 and cites Remark 5.1
  const char* integrates;      // what it is, with the equation it implements
};

// The table, in the order of the enum.
const std::vector<SchemeTraits>& all_schemes();
const SchemeTraits& traits(Scheme scheme);
const char* scheme_name(Scheme scheme);
// The scheme a name denotes; nullopt for a name that is not one.
std::optional<Scheme> scheme_from_name(std::string_view name);
// The names of the schemes that a scene of `system` may name (or a study may compare), as "a, b or c".
std::string scheme_names_for_scenes(SystemType system);
std::string scheme_names_for_studies();

}  // namespace moreau::scene
