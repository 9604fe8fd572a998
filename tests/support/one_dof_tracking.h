// The tracking scene the tests share: one coordinate x of mass m = 2 (the parameter "m"), the force F on
// the left of (0.1) (the perturbation is d = -F), the reference q_d(t), Lambda = 3 and Phi(s) = a |s| with
// a = 4 unless `gain` says otherwise; `tracking_extra` adds to /system/tracking (law, period, ...).
// docs/tracking.md derives the closed forms the tests hold it to.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace moreau::test_support {

inline nlohmann::json one_dof_tracking(const std::string& force, const std::string& reference, const nlohmann::json& tracking_extra,
                                       double h, double t_end, double q0, double v0, double gain = 4.0) {
  nlohmann::json doc = {
      {"name", "tracking-1dof"},
      {"parameters", {{"m", 2.0}}},
      {"system",
       {{"type", "lagrangian"},
        {"coordinates", {"x"}},
        {"mass", {{"m"}}},
        {"force", {force}},
        {"tracking", {{"reference", {reference}}, {"lambda", {3.0}}, {"controller", {{{"type", "abs"}, {"gains", {gain}}}}}}}}},
      {"initial", {{"q", {q0}}, {"v", {v0}}}},
      {"integrator", {{"h", h}, {"t_end", t_end}}}};
  for (const auto& [k, val] : tracking_extra.items()) doc["system"]["tracking"][k] = val;
  return doc;
}

}  // namespace moreau::test_support
