// The integration schemes, as types. A scene names its scheme with a string (/integrator/scheme) and a
// study its peers (--schemes, "schemes"); the parsers turn those strings into these enums at once, and
// only the report and table writers turn them back into names (scheme_name). Code in between compares
// enums, never strings.
#pragma once

#include <optional>
#include <string_view>

namespace moreau::scene {

// How a scene's system is integrated.
enum class Scheme {
  kAbl,            // eq. (0.2) of Adly, Brogliato and Le (2016): Lagrangian systems without contacts
  kMoreauJean,     // Moreau-Jean with Newton restitution (eq. 8 and 17 of Brogliato 2003): contacts
  kImplicitEuler,  // the theta-method for Lur'e systems (eq. 4 of Brogliato 2003)
};

// The schemes a study compares on one Lagrangian scene.
enum class StudyScheme {
  kAbl,          // the scheme (0.2)
  kExplicit,     // everything at (Q^k, V^k) with the single-valued sign (AblSettings::velocity_update)
  kRegularized,  // the sign replaced by a smooth or saturated one, integrated by a stiff ODE solver
};

const char* scheme_name(Scheme scheme);
const char* scheme_name(StudyScheme scheme);
// The enum a name denotes; nullopt for a name that is not one.
std::optional<Scheme> scheme_from_name(std::string_view name);
std::optional<StudyScheme> study_scheme_from_name(std::string_view name);

}  // namespace moreau::scene
