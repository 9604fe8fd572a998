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
}  // namespace

Simulation Simulation::from_json(const nlohmann::json& doc) {
  Simulation sim;
  if (scene::system_type(doc) == "lure") {
    sim.lure_ = std::make_shared<const LureScene>(load_lure_scene(doc));
  } else {
    sim.lagrangian_ = std::make_shared<const LagrangianScene>(load_scene(doc));
  }
  sim.latest_ = std::make_shared<Latest>();
  return sim;
}

Simulation Simulation::from_file(const std::string& path, const std::vector<std::string>& overrides) {
  nlohmann::json doc = read_scene_file(path);
  for (const auto& o : overrides) apply_override(doc, o);
  return from_json(doc);
}

const std::string& Simulation::name() const { return lure_ ? lure_->name : lagrangian_->name; }
const std::string& Simulation::system_type() const { return lure_ ? kLure : kLagrangian; }
Scheme Simulation::scheme() const { return lure_ ? lure_->scheme : lagrangian_->scheme; }
int Simulation::dof() const { return lure_ ? lure_->n : lagrangian_->n; }
const std::vector<std::string>& Simulation::position_names() const { return lure_ ? lure_->states : lagrangian_->coordinates; }
const std::vector<std::string>& Simulation::velocity_names() const { return lure_ ? lure_->state_rates : lagrangian_->velocities; }
double Simulation::t0() const { return lure_ ? lure_->settings.t0 : lagrangian_->settings.t0; }
double Simulation::t_end() const { return lure_ ? lure_->settings.t_end : lagrangian_->settings.t_end; }
double Simulation::h() const { return lure_ ? lure_->settings.h : lagrangian_->settings.h; }
std::int64_t Simulation::output_every() const { return lure_ ? lure_->settings.output_every : lagrangian_->output_every; }
std::int64_t Simulation::planned_steps() const {
  if (lure_) return fixed_step_count(lure_->settings.t0, lure_->settings.t_end, lure_->settings.h);
  const auto& s = lagrangian_->settings;
  return fixed_step_count(s.t0, s.t_end, s.h);
}

std::int64_t Simulation::max_steps() const { return lure_ ? lure_->settings.max_steps : lagrangian_->settings.max_steps; }

Simulation Simulation::with_limits(const RunLimits& limits) const {
  Simulation out = *this;
  out.latest_ = std::make_shared<Latest>();
  if (lure_) {
    auto sc = std::make_shared<LureScene>(*lure_);
    if (limits.max_steps) sc->settings.max_steps = std::min(sc->settings.max_steps, *limits.max_steps);
    if (limits.output_every) sc->settings.output_every = *limits.output_every;
    out.lure_ = std::move(sc);
  } else {
    auto sc = std::make_shared<LagrangianScene>(*lagrangian_);
    if (limits.max_steps) {
      sc->settings.max_steps = std::min(sc->settings.max_steps, *limits.max_steps);
      sc->contact_settings.max_steps = sc->settings.max_steps;
    }
    if (limits.output_every) sc->output_every = *limits.output_every;
    out.lagrangian_ = std::move(sc);
  }
  return out;
}

RunSummary Simulation::run(RunObserver* observer, RunDiagnostics* diagnostics) const {
  RunDiagnostics local;
  RunDiagnostics& d = diagnostics ? *diagnostics : local;
  d = RunDiagnostics{};
  if (lure_) {
    d.lure.emplace();
    return run_lure_scene(*lure_, observer, &*d.lure);
  }
  if (lagrangian_->scheme == Scheme::kMoreauJean) {
    d.contacts.emplace();
    return run_scene(*lagrangian_, observer, &*d.contacts);
  }
  return run_scene(*lagrangian_, observer);
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
  if (lure_) return scene::report_json(*lure_, summary, d.lure ? &*d.lure : nullptr);
  return scene::report_json(*lagrangian_, summary, d.contacts ? &*d.contacts : nullptr);
}
std::string Simulation::report_text(const RunSummary& summary, const RunDiagnostics& d) const {
  if (lure_) return scene::report_text(*lure_, summary, d.lure ? &*d.lure : nullptr);
  return scene::report_text(*lagrangian_, summary, d.contacts ? &*d.contacts : nullptr);
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
