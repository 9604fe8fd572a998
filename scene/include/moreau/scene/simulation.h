// A scene of any system type, validated and compiled, ready to run: the one entry point that the
// command line, the server and studies use. It owns the choice of model and scheme for the scene's
// system type (today: Lagrangian systems with a set-valued controller and the ABL scheme).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/core/observer.h"
#include "moreau/core/run_summary.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

class Simulation {
 public:
  // Validates and compiles. Throws SceneError naming the field.
  static Simulation from_json(const nlohmann::json& doc);
  // Reads a file, applies `--set PATH=VALUE` overrides in order, then validates. Throws SceneError.
  static Simulation from_file(const std::string& path, const std::vector<std::string>& overrides = {});

  const std::string& name() const;
  int dof() const;
  // Column names of a trajectory: positions then velocities.
  const std::vector<std::string>& position_names() const;
  const std::vector<std::string>& velocity_names() const;
  double t0() const;
  double t_end() const;
  double h() const;
  std::int64_t output_every() const;
  // The number of steps a fixed-step run takes (an upper bound's estimate for adaptive rules).
  std::int64_t planned_steps() const;

  // Runs to t_end; the observer sees every output_every-th state and may cancel.
  RunSummary run(RunObserver* observer) const;

  nlohmann::json report_json(const RunSummary& summary) const;
  std::string report_text(const RunSummary& summary) const;

  // The underlying scene for Lagrangian systems (nullptr for other system types).
  const LagrangianScene* lagrangian() const { return lagrangian_.get(); }

 private:
  std::shared_ptr<const LagrangianScene> lagrangian_;
};

}  // namespace moreau::scene
