#include "moreau/scene/simulation.h"

#include <algorithm>
#include <mutex>

#include "moreau/scene/report.h"

namespace moreau::scene {

// The diagnostics of the most recent run(observer), for report_json(summary) / report_text(summary).
struct Simulation::Latest {
  std::mutex mutex;
  RunDiagnostics diagnostics;
};

namespace {
const std::string kLagrangian = "lagrangian";
const std::string kLure = "lure";

// One lambda per system kind, for std::visit.
template <class... F>
struct Overloaded : F... {
  using F::operator()...;
};
template <class... F>
Overloaded(F...) -> Overloaded<F...>;

// Calls f with the compiled scene, whichever kind it is.
template <class System, class F>
decltype(auto) on_scene(const System& system, F&& f) {
  return std::visit([&](const auto& scene) -> decltype(auto) { return f(*scene); }, system);
}
}  // namespace

Simulation Simulation::from_json(const nlohmann::json& doc) {
  Simulation sim;
  if (scene::system_type(doc) == "lure") {
    sim.system_ = std::make_shared<const LureScene>(load_lure_scene(doc));
  } else {
    sim.system_ = std::make_shared<const LagrangianScene>(load_scene(doc));
  }
  sim.latest_ = std::make_shared<Latest>();
  sim.units_ = units_of(doc, sim.lagrangian());
  return sim;
}

// /units is free-form (scene-format.md): its string members are the units; other members are ignored. A
// URDF robot's joints have the units URDF fixes (radians for revolute and continuous joints, metres for
// prismatic ones, seconds), unless /units says otherwise.
std::shared_ptr<const std::map<std::string, std::string>> Simulation::units_of(const nlohmann::json& doc, const LagrangianScene* scene) {
  auto units = std::make_shared<std::map<std::string, std::string>>();
  if (doc.is_object() && doc.contains("units") && doc["units"].is_object())
    for (const auto& [name, unit] : doc["units"].items())
      if (unit.is_string()) (*units)[name] = unit.get<std::string>();
  if (scene && scene->compiled && scene->compiled->robot) {
    units->emplace("t", "s");
    for (const RigidBody& body : scene->compiled->robot->bodies)
      units->emplace(body.joint_name, body.joint == JointType::kPrismatic ? "m" : "rad");
  }
  return units;
}

const std::map<std::string, std::string>& Simulation::units() const {
  static const std::map<std::string, std::string> kNone;
  return units_ ? *units_ : kNone;
}

namespace {

// The grid every scheme of the scene runs on (settings.grid()), capped.
void apply_limits(TimeGrid& grid, const RunLimits& limits) {
  if (limits.max_steps) grid.max_steps = std::min(grid.max_steps, *limits.max_steps);
  if (limits.output_every) grid.output_every = *limits.output_every;
}

}  // namespace

Simulation Simulation::from_scene(LagrangianScene scene, const RunLimits& limits, const nlohmann::json& doc) {
  Simulation sim;
  apply_limits(scene.settings.grid(), limits);
  sim.system_ = std::make_shared<const LagrangianScene>(std::move(scene));
  sim.latest_ = std::make_shared<Latest>();
  sim.units_ = units_of(doc, sim.lagrangian());
  return sim;
}

Simulation Simulation::from_file(const std::string& path, const std::vector<std::string>& overrides) {
  nlohmann::json doc = read_scene_file(path);
  for (const auto& o : overrides) apply_override(doc, o);
  return from_json(doc);
}

const LagrangianScene* Simulation::lagrangian() const {
  const auto* p = std::get_if<std::shared_ptr<const LagrangianScene>>(&system_);
  return p ? p->get() : nullptr;
}
const LureScene* Simulation::lure() const {
  const auto* p = std::get_if<std::shared_ptr<const LureScene>>(&system_);
  return p ? p->get() : nullptr;
}

const std::string& Simulation::name() const {
  return on_scene(system_, [](const auto& sc) -> const std::string& { return sc.name; });
}
const std::string& Simulation::system_type() const { return lure() ? kLure : kLagrangian; }
Scheme Simulation::scheme() const {
  return on_scene(system_, [](const auto& sc) { return sc.scheme; });
}
int Simulation::dof() const {
  return on_scene(system_, [](const auto& sc) { return sc.n; });
}
const std::vector<std::string>& Simulation::position_names() const {
  return std::visit(
      Overloaded{[](const std::shared_ptr<const LagrangianScene>& sc) -> const std::vector<std::string>& { return sc->coordinates; },
                 [](const std::shared_ptr<const LureScene>& sc) -> const std::vector<std::string>& { return sc->states; }},
      system_);
}
const std::vector<std::string>& Simulation::velocity_names() const {
  return std::visit(
      Overloaded{[](const std::shared_ptr<const LagrangianScene>& sc) -> const std::vector<std::string>& { return sc->velocities; },
                 [](const std::shared_ptr<const LureScene>& sc) -> const std::vector<std::string>& { return sc->state_rates; }},
      system_);
}
std::vector<std::string> Simulation::signal_names() const {
  std::vector<std::string> names;
  const LagrangianScene* sc = lagrangian();
  if (!sc || !sc->tracking) return names;
  for (const std::string& q : sc->coordinates)
    for (const char* prefix : {"qd_", "e_", "sigma_", "u_"}) names.push_back(prefix + q);
  return names;
}

double Simulation::t0() const {
  return on_scene(system_, [](const auto& sc) { return sc.settings.t0; });
}
double Simulation::t_end() const {
  return on_scene(system_, [](const auto& sc) { return sc.settings.t_end; });
}
double Simulation::h() const {
  return on_scene(system_, [](const auto& sc) { return sc.settings.h; });
}
std::int64_t Simulation::output_every() const {
  return on_scene(system_, [](const auto& sc) { return sc.settings.output_every; });
}
std::int64_t Simulation::planned_steps() const {
  return on_scene(system_, [](const auto& sc) { return fixed_step_count(sc.settings.t0, sc.settings.t_end, sc.settings.h); });
}
std::int64_t Simulation::max_steps() const {
  return on_scene(system_, [](const auto& sc) { return sc.settings.max_steps; });
}

Simulation Simulation::with_limits(const RunLimits& limits) const {
  Simulation out = *this;
  out.latest_ = std::make_shared<Latest>();
  std::visit(Overloaded{[&](const std::shared_ptr<const LagrangianScene>& scene) {
                          auto sc = std::make_shared<LagrangianScene>(*scene);
                          apply_limits(sc->settings.grid(), limits);
                          out.system_ = std::shared_ptr<const LagrangianScene>(std::move(sc));
                        },
                        [&](const std::shared_ptr<const LureScene>& scene) {
                          auto sc = std::make_shared<LureScene>(*scene);
                          apply_limits(sc->settings.grid(), limits);
                          out.system_ = std::shared_ptr<const LureScene>(std::move(sc));
                        }},
             system_);
  return out;
}

RunSummary Simulation::run(RunObserver* observer, RunDiagnostics* diagnostics) const {
  RunDiagnostics local;
  RunDiagnostics& d = diagnostics ? *diagnostics : local;
  d = RunDiagnostics{};
  return std::visit(Overloaded{[&](const std::shared_ptr<const LagrangianScene>& sc) {
                                 if (!traits(sc->scheme).contacts) return run_scene(*sc, observer);
                                 return run_scene(*sc, observer, &d.of.emplace<ContactDiagnostics>());
                               },
                               [&](const std::shared_ptr<const LureScene>& sc) {
                                 return run_lure_scene(*sc, observer, &d.of.emplace<LureDiagnostics>());
                               }},
                    system_);
}

RunSummary Simulation::run(RunObserver* observer) const {
  RunDiagnostics d;
  RunSummary s = run(observer, &d);
  if (latest_) {
    std::lock_guard<std::mutex> lock(latest_->mutex);
    latest_->diagnostics = std::move(d);
  }
  return s;
}

nlohmann::json Simulation::report_json(const RunSummary& summary, const RunDiagnostics& d) const {
  nlohmann::json j = std::visit(
      Overloaded{[&](const std::shared_ptr<const LagrangianScene>& sc) { return scene::report_json(*sc, summary, d.contacts()); },
                 [&](const std::shared_ptr<const LureScene>& sc) { return scene::report_json(*sc, summary, d.lure()); }},
      system_);
  // Time in the scene's unit: /units/t, or seconds once the scene gives any units (as its figures say).
  const auto& u = units();
  const auto t = u.find("t");
  j["summary"] = plain_summary(j, t != u.end() ? t->second : u.empty() ? "" : "s");
  return j;
}
std::string Simulation::report_text(const RunSummary& summary, const RunDiagnostics& d) const {
  return std::visit(
      Overloaded{[&](const std::shared_ptr<const LagrangianScene>& sc) { return scene::report_text(*sc, summary, d.contacts()); },
                 [&](const std::shared_ptr<const LureScene>& sc) { return scene::report_text(*sc, summary, d.lure()); }},
      system_);
}

Guarantees Simulation::guarantees(const RunSummary& summary) const {
  return std::visit(Overloaded{[&](const std::shared_ptr<const LagrangianScene>& sc) { return lagrangian_guarantees(*sc, summary); },
                               [&](const std::shared_ptr<const LureScene>& sc) { return lure_guarantees(*sc); }},
                    system_);
}

std::string Simulation::hypothesis_failure(const RunSummary& summary) const {
  if (const LagrangianScene* sc = lagrangian(); sc && lagrangian_guarantees(*sc, summary, Detail::kVerdicts).relied_on_failure().empty())
    return "";
  return guarantees(summary).relied_on_failure();
}

nlohmann::json Simulation::report_json(const RunSummary& summary) const {
  if (!latest_) return report_json(summary, RunDiagnostics{});
  std::lock_guard<std::mutex> lock(latest_->mutex);
  return report_json(summary, latest_->diagnostics);
}
std::string Simulation::report_text(const RunSummary& summary) const {
  if (!latest_) return report_text(summary, RunDiagnostics{});
  std::lock_guard<std::mutex> lock(latest_->mutex);
  return report_text(summary, latest_->diagnostics);
}

}  // namespace moreau::scene
