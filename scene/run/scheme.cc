#include "moreau/scene/scheme.h"

namespace moreau::scene {

const char* scheme_name(Scheme scheme) {
  switch (scheme) {
    case Scheme::kAbl: return "abl";
    case Scheme::kMoreauJean: return "moreau-jean";
    case Scheme::kImplicitEuler: return "implicit-euler";
  }
  return "?";
}

const char* scheme_name(StudyScheme scheme) {
  switch (scheme) {
    case StudyScheme::kAbl: return "abl";
    case StudyScheme::kExplicit: return "explicit";
    case StudyScheme::kRegularized: return "regularized";
  }
  return "?";
}

std::optional<Scheme> scheme_from_name(std::string_view name) {
  for (Scheme s : {Scheme::kAbl, Scheme::kMoreauJean, Scheme::kImplicitEuler})
    if (name == scheme_name(s)) return s;
  return std::nullopt;
}

std::optional<StudyScheme> study_scheme_from_name(std::string_view name) {
  for (StudyScheme s : {StudyScheme::kAbl, StudyScheme::kExplicit, StudyScheme::kRegularized})
    if (name == scheme_name(s)) return s;
  return std::nullopt;
}

}  // namespace moreau::scene
