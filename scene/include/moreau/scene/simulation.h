// A scene of any system type, validated and compiled, ready to run: the one entry point that the
// command line, the server and studies use. It owns the choice of model and scheme for the scene's
// system type:
//   - "lagrangian": the ABL scheme (eq. 0.2 of Adly, Brogliato and Le 2016), or moreau-jean when the
//     scene has unilateral constraints (eq. 8 of Brogliato 2003);
//   - "lure": the theta-method for x' = A x - B y_L, y = C x, y_L in d phi(y) (eq. 4 of Brogliato 2003).
// For a Lur'e system the trajectory's positions are the states x and its velocities the discrete
// derivative (x_{k+1} - x_k)/h (names x1..xn and x1_dot..xn_dot, or the scene's /system/states).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/core/observer.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/run_summary.h"
#include "moreau/scene/guarantees.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

// What a run reports beyond RunSummary, by system type: contacts (a lagrangian scene on moreau-jean),
// a Lur'e system's outputs and storage function, or nothing more (a lagrangian scene on abl).
struct RunDiagnostics {
  std::variant<std::monostate, ContactDiagnostics, LureDiagnostics> of;

  const ContactDiagnostics* contacts() const { return std::get_if<ContactDiagnostics>(&of); }
  const LureDiagnostics* lure() const { return std::get_if<LureDiagnostics>(&of); }
};

// Limits a caller (a server, a campaign) puts on a run, applied to a compiled Simulation: nothing is
// recompiled and the scene's JSON is never rewritten.
struct RunLimits {
  // At most this many steps: a lower max_steps (an adaptive rule then fails at it; a fixed-step run
  // needing more is the caller's to refuse before, see planned_steps()).
  std::optional<std::int64_t> max_steps;
  // The observer sees every output_every-th state (in place of the scene's /output/every).
  std::optional<std::int64_t> output_every;
};

class Simulation {
 public:
  // Validates and compiles. Throws SceneError naming the field.
  static Simulation from_json(const nlohmann::json& doc);
  // Reads a file, applies `--set PATH=VALUE` overrides in order, then validates. Throws SceneError.
  static Simulation from_file(const std::string& path, const std::vector<std::string>& overrides = {});
  // A Lagrangian scene compiled already (ParametricLagrangianScene::bind), under `limits` as with_limits
  // applies them (without copying the scene a second time). `doc`: the scene document it was compiled
  // from, whose /units label its figures and report (units()), as from_json takes them.
  static Simulation from_scene(LagrangianScene scene, const RunLimits& limits = {}, const nlohmann::json& doc = {});

  const std::string& name() const;
  const std::string& system_type() const;  // "lagrangian" or "lure"
  Scheme scheme() const;
  int dof() const;  // coordinates, or states of a Lur'e system
  // Column names of a trajectory: positions then velocities.
  const std::vector<std::string>& position_names() const;
  const std::vector<std::string>& velocity_names() const;
  // The names of a sample's signals (Sample::signals), in order: for a tracking scene qd_<q>, e_<q>,
  // sigma_<q> and u_<q> for each coordinate q; empty for other scenes.
  std::vector<std::string> signal_names() const;
  // The scene's /units, its string members (a coordinate's or a state's name, or "t", to the unit's text:
  // {"x1": "m", "th2": "rad", "t": "s"}), for the labels of figures and the report's summary; a URDF
  // robot's joints in radians or metres and time in seconds unless /units says otherwise; empty for a
  // scene without them.
  const std::map<std::string, std::string>& units() const;
  double t0() const;
  double t_end() const;
  double h() const;
  std::int64_t output_every() const;
  // The number of steps a fixed-step run takes (a lower bound for adaptive rules, whose h is the
  // largest step).
  std::int64_t planned_steps() const;
  // The largest number of steps a run may take (/integrator/max_steps, or a RunLimits').
  std::int64_t max_steps() const;

  // A copy with the limits applied: max_steps lowered to limits.max_steps when that is smaller, and
  // output_every replaced. The compiled model is shared with this one; the results of a run that stays
  // within the limits are those of this Simulation, bit for bit (sampling only changes which states the
  // observer sees).
  Simulation with_limits(const RunLimits& limits) const;

  // Runs to t_end; the observer sees every output_every-th state and may cancel. The run's diagnostics
  // (impacts, storage function, ...) are kept with this Simulation for report_json(summary) and
  // report_text(summary): those two report on the most recent run. Callers running one Simulation from
  // several threads at once should pass their own RunDiagnostics instead.
  RunSummary run(RunObserver* observer) const;
  RunSummary run(RunObserver* observer, RunDiagnostics* diagnostics) const;

  nlohmann::json report_json(const RunSummary& summary) const;
  std::string report_text(const RunSummary& summary) const;
  nlohmann::json report_json(const RunSummary& summary, const RunDiagnostics& diagnostics) const;
  std::string report_text(const RunSummary& summary, const RunDiagnostics& diagnostics) const;

  // The guarantees section of a run's report (guarantees.h): the hypotheses of each theorem the run
  // rests on, checked.
  Guarantees guarantees(const RunSummary& summary) const;
  // guarantees(summary).relied_on_failure(), with the detail text built only for a failure: what
  // `moreau run --strict`, a job's `strict` and each sample of a campaign check.
  std::string hypothesis_failure(const RunSummary& summary) const;

  // The underlying scene for Lagrangian systems (nullptr for other system types).
  const LagrangianScene* lagrangian() const;
  // The underlying scene for Lur'e systems (nullptr for other system types).
  const LureScene* lure() const;

 private:
  struct Latest;
  // The compiled system: exactly one kind, shared by copies (with_limits copies it only to change it).
  using System = std::variant<std::shared_ptr<const LagrangianScene>, std::shared_ptr<const LureScene>>;
  System system_;
  std::shared_ptr<Latest> latest_;
  std::shared_ptr<const std::map<std::string, std::string>> units_;
  static std::shared_ptr<const std::map<std::string, std::string>> units_of(const nlohmann::json& doc, const LagrangianScene* scene);
};

}  // namespace moreau::scene
