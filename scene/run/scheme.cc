#include "moreau/scene/scheme.h"

#include "moreau/scene/scene.h"

namespace moreau::scene {

namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

}  // namespace

const std::vector<SchemeTraits>& all_schemes() {
  // clang-format off
  static const std::vector<SchemeTraits> table = {
    //                          scene study contacts rules norm  position theta checks theorems
    {Scheme::kAbl, "abl", SystemType::kLagrangian,
                                 true,  true,  false,  true,  true,  false,  false, true,  true,
     "the implicit scheme (0.2) of Adly, Brogliato and Le (2016): velocity implicit, position explicit"},
    {Scheme::kExplicit, "explicit", SystemType::kLagrangian,
                                 false, true,  false,  false, true,  false,  false, true,  false,
     "the explicit peer of (0.2): everything at (Q^k, V^k) with the single-valued sign (Acary and Brogliato 2010)"},
    {Scheme::kRegularized, "regularized", SystemType::kLagrangian,
                                 false, true,  false,  false, true,  false,  false, false, false,
     "the sign replaced by a smooth (tanh) or saturated one, integrated by Rosenbrock's stiff solver"},
    {Scheme::kMoreauJean, "moreau-jean", SystemType::kLagrangian,
                                 true,  false, true,   false, false, true,   false, false, false,
     "Moreau-Jean with Newton restitution (eq. 8 and 17 of Brogliato 2003)"},
    {Scheme::kImplicitEuler, "implicit-euler", SystemType::kLure,
                                 true,  false, false,  false, false, false,  true,  false, false,
     "the theta-method for Lur'e systems (eq. 4 of Brogliato 2003)"},
    {Scheme::kTracking, "tracking", SystemType::kLagrangian,
                                 true,  false, false,  false, true,  false,  false, false, false,
     "tracking of /system/tracking's reference: the closed loop as (0.2) in sigma, or the digital controller with the plant by (0.2)"},
  };
  // clang-format on
  return table;
}

const SchemeTraits& traits(Scheme scheme) { return all_schemes()[static_cast<std::size_t>(scheme)]; }

const char* scheme_name(Scheme scheme) { return traits(scheme).name; }

std::optional<Scheme> scheme_from_name(std::string_view name) {
  for (const SchemeTraits& t : all_schemes())
    if (name == t.name) return t.scheme;
  return std::nullopt;
}

std::string scheme_names_for_scenes(SystemType system) {
  std::vector<std::string> names;
  for (const SchemeTraits& t : all_schemes())
    if (t.system == system && t.scene_can_name) names.push_back(t.name);
  return joined(names);
}

std::string scheme_names_for_studies() {
  std::vector<std::string> names;
  for (const SchemeTraits& t : all_schemes())
    if (t.study_compares) names.push_back(t.name);
  return joined(names);
}

const char* to_string(CoriolisSource source) {
  switch (source) {
    case CoriolisSource::kChristoffel: return "christoffel";
    case CoriolisSource::kExplicit: return "explicit";
    case CoriolisSource::kNone: return "none";
  }
  return "?";
}

const char* to_string(PositionUpdate update) { return update == PositionUpdate::kStandard ? "standard" : "mdi"; }

const char* position_correction_name(bool on) { return on ? "projection" : "none"; }

const char* to_string(Regularization kind) { return kind == Regularization::kSaturation ? "saturation" : "tanh"; }

std::optional<Regularization> regularization_from_name(std::string_view name) {
  for (Regularization r : {Regularization::kTanh, Regularization::kSaturation})
    if (name == to_string(r)) return r;
  return std::nullopt;
}

}  // namespace moreau::scene
