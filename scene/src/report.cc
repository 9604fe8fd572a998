#include "moreau/scene/report.h"

#include <cstdio>
#include <sstream>

namespace moreau::scene {
namespace {

const char* rule_name(StepRule r) {
  switch (r) {
    case StepRule::kFixed: return "fixed";
    case StepRule::kTheorem41: return "theorem-4.1";
    case StepRule::kTheorem42: return "theorem-4.2";
  }
  return "?";
}

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

std::string vec(const std::vector<double>& v) {
  std::string out = "(";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + fmt(v[i]);
  return out + ")";
}

// JSON has no NaN or Inf: a non-finite value becomes null rather than an invalid document.
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& s) {
  nlohmann::json j;
  j["scene"] = scene.name;
  j["status"] = to_string(s.status);
  if (!s.message.empty()) j["message"] = s.message;
  j["scheme"] = scene.scheme;
  j["step_rule"] = rule_name(scene.settings.step_rule);
  j["h"] = scene.settings.h;
  j["coordinates"] = scene.coordinates;
  j["steps"] = s.steps;
  j["t_final"] = num(s.t_final);
  j["converged_step"] = s.converged_step ? nlohmann::json(*s.converged_step) : nlohmann::json(nullptr);
  j["converged_time"] = s.converged_time ? num(*s.converged_time) : nlohmann::json(nullptr);
  j["final"] = {{"q", s.q_final}, {"v", s.v_final}};
  j["energy_nonincreasing"] = s.energy_nonincreasing;
  j["energy"] = {{"initial", num(s.energy_initial)},
                 {"final", num(s.energy_final)},
                 {"max_increase", num(s.energy_max_increase)},
                 {"increases", s.energy_increases}};
  j["equilibrium"] = {{"residual", num(s.equilibrium.residual)}, {"interior", s.equilibrium.interior}};
  j["solver"] = {{"max_iterations", s.solver.max_iterations},
                 {"max_residual", num(s.solver.max_residual)},
                 {"total_iterations", s.solver.total_iterations},
                 {"fallback_steps", s.solver.fallback_steps},
                 {"rest_steps", s.solver.rest_steps}};
  j["h_min"] = num(s.h_min);
  j["h_max"] = num(s.h_max);
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, seconds] : s.phase_seconds) phases[name] = seconds;
  j["phase_seconds"] = phases;
  j["wall_seconds"] = s.wall_seconds();
  return j;
}

std::string report_text(const LagrangianScene& scene, const RunSummary& s) {
  std::ostringstream os;
  std::string names;
  for (std::size_t i = 0; i < scene.coordinates.size(); ++i) names += (i ? ", " : "") + scene.coordinates[i];
  os << "Moreau: " << (scene.name.empty() ? "scene" : scene.name) << " (" << scene.n << " DOF: " << names << "), scheme "
     << scene.scheme << ", " << rule_name(scene.settings.step_rule) << " h = " << fmt(scene.settings.h) << ", t in ["
     << fmt(scene.settings.t0) << ", " << fmt(scene.settings.t_end) << "]\n";
  os << "  status        " << to_string(s.status) << ": " << s.steps << " steps to t = " << fmt(s.t_final);
  if (scene.settings.step_rule != StepRule::kFixed) os << " (h_k from " << fmt(s.h_min) << " to " << fmt(s.h_max) << ")";
  os << "\n";
  if (!s.message.empty()) os << "  message       " << s.message << "\n";
  os << "  final state   q = " << vec(s.q_final) << "\n";
  os << "                v = " << vec(s.v_final) << "\n";
  if (s.converged_step) {
    os << "  convergence   v == 0.0 exactly from step " << *s.converged_step << " (t = " << fmt(*s.converged_time)
       << ") to the end [Theorem 4.3]\n";
  } else {
    os << "  convergence   v is not exactly 0 at the last step\n";
  }
  if (s.equilibrium.evaluated) {
    os << "  equilibrium   dist(-F(t,Q,0) - grad V(Q), dPhi(0)) = " << fmt(s.equilibrium.residual)
       << (s.equilibrium.residual == 0.0 ? " (an equilibrium)" : " (not an equilibrium)") << "; in the interior: "
       << (s.equilibrium.interior ? "yes" : "no") << "\n";
  }
  os << "  energy        E_k = 1/2 <M(Q^k) V^k, V^k> " << (s.energy_nonincreasing ? "non-increasing" : "increased")
     << ": E_0 = " << fmt(s.energy_initial) << ", E_N = " << fmt(s.energy_final);
  if (!s.energy_nonincreasing) {
    os << " (" << s.energy_increases << " rises, largest " << fmt(s.energy_max_increase) << ")";
    os << "\n                Theorem 4.2 promises a non-increasing E_k only with step_rule theorem-4.2 and\n"
          "                Assumption 4.1 (||F|| <= beta < alpha, ||grad V|| <= (alpha - beta)/2)";
  }
  os << "\n";
  os << "  solver        max " << s.solver.max_iterations << " iterations per step, " << s.solver.total_iterations
     << " in all, max residual " << fmt(s.solver.max_residual) << ", " << s.solver.rest_steps << " steps at rest, "
     << s.solver.fallback_steps << " fallback steps\n";
  os << "  wall time     ";
  for (const auto& [name, seconds] : s.phase_seconds) os << name << " " << fmt(seconds * 1e3) << " ms, ";
  os << "total " << fmt(s.wall_seconds() * 1e3) << " ms\n";
  return os.str();
}

}  // namespace moreau::scene
