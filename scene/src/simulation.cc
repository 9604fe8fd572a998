#include "moreau/scene/simulation.h"

#include "moreau/scene/report.h"

namespace moreau::scene {

Simulation Simulation::from_json(const nlohmann::json& doc) {
  Simulation sim;
  sim.lagrangian_ = std::make_shared<const LagrangianScene>(load_scene(doc));
  return sim;
}

Simulation Simulation::from_file(const std::string& path, const std::vector<std::string>& overrides) {
  nlohmann::json doc = read_scene_file(path);
  for (const auto& o : overrides) apply_override(doc, o);
  return from_json(doc);
}

const std::string& Simulation::name() const { return lagrangian_->name; }
int Simulation::dof() const { return lagrangian_->n; }
const std::vector<std::string>& Simulation::position_names() const { return lagrangian_->coordinates; }
const std::vector<std::string>& Simulation::velocity_names() const { return lagrangian_->velocities; }
double Simulation::t0() const { return lagrangian_->settings.t0; }
double Simulation::t_end() const { return lagrangian_->settings.t_end; }
double Simulation::h() const { return lagrangian_->settings.h; }
std::int64_t Simulation::output_every() const { return lagrangian_->output_every; }
std::int64_t Simulation::planned_steps() const {
  const auto& s = lagrangian_->settings;
  return fixed_step_count(s.t0, s.t_end, s.h);
}

RunSummary Simulation::run(RunObserver* observer) const { return run_scene(*lagrangian_, observer); }

nlohmann::json Simulation::report_json(const RunSummary& summary) const {
  return scene::report_json(*lagrangian_, summary);
}
std::string Simulation::report_text(const RunSummary& summary) const {
  return scene::report_text(*lagrangian_, summary);
}

}  // namespace moreau::scene
