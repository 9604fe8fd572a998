// moreau: run scenes locally, print their reports and write their trajectories.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "moreau/scene/report.h"
#include "moreau/scene/trajectory_csv.h"

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// A progress bar on stderr for runs longer than a second, redrawn at most ten times a second.
class ProgressBar : public moreau::RunObserver {
 public:
  ProgressBar(double t0, double t_end, bool enabled) : t0_(t0), t_end_(t_end), enabled_(enabled), start_(Clock::now()) {}
  ~ProgressBar() override { finish(); }
  void on_sample(const moreau::Sample&) override {}
  bool keep_going(std::int64_t step, double t) override {
    if (!enabled_) return true;
    const double elapsed = since(start_);
    if (elapsed < 1.0 || elapsed - last_draw_ < 0.1) return true;
    last_draw_ = elapsed;
    const double frac = std::clamp((t - t0_) / (t_end_ - t0_), 0.0, 1.0);
    const int width = 40, filled = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r[%.*s%*s] %5.1f%%  t = %-10.4g step %lld  %.1f s", filled,
                 "########################################", width - filled, "", 100.0 * frac, t,
                 static_cast<long long>(step), elapsed);
    std::fflush(stderr);
    drawn_ = true;
    return true;
  }
  void finish() {
    if (drawn_) std::fprintf(stderr, "\r%*s\r", 100, "");
    drawn_ = false;
  }

 private:
  double t0_, t_end_;
  bool enabled_;
  Clock::time_point start_;
  double last_draw_ = 0.0;
  bool drawn_ = false;
};

struct RunOptions {
  std::string scene_path;
  std::vector<std::string> overrides;
  bool json = false;
  std::string out_csv;
  std::string progress = "auto";
};

int run_command(const RunOptions& opt) {
  using namespace moreau;
  const auto t_parse = Clock::now();
  scene::LagrangianScene sc;
  double parse_s = 0.0, compile_s = 0.0;
  try {
    nlohmann::json doc = scene::read_scene_file(opt.scene_path);
    for (const auto& o : opt.overrides) scene::apply_override(doc, o);
    parse_s = since(t_parse);
    const auto t_compile = Clock::now();
    sc = scene::load_scene(doc);
    compile_s = since(t_compile);
  } catch (const scene::SceneError& e) {
    std::cerr << "moreau: invalid scene " << opt.scene_path << ": " << e.what() << "\n";
    return 2;
  }

  scene::ObserverFan fan;
  std::optional<scene::TrajectoryCsvWriter> csv;
  if (!opt.out_csv.empty()) {
    try {
      csv.emplace(opt.out_csv, sc.coordinates, sc.velocities);
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 2;
    }
    fan.add(&*csv);
  }
  const bool show_progress = opt.progress == "always" || (opt.progress == "auto" && isatty(STDERR_FILENO));
  ProgressBar progress(sc.settings.t0, sc.settings.t_end, show_progress);
  fan.add(&progress);

  RunSummary summary = scene::run_scene(sc, &fan);
  progress.finish();
  summary.phase_seconds.insert(summary.phase_seconds.begin(), {"compile", compile_s});
  summary.phase_seconds.insert(summary.phase_seconds.begin(), {"parse", parse_s});
  if (csv) {
    const auto t_close = Clock::now();
    try {
      csv->close();
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 1;
    }
    // Writing happened inside the integrate phase; report it as its own phase.
    const double write_s = csv->seconds() + since(t_close);
    for (auto& [name, s] : summary.phase_seconds)
      if (name == "integrate") s = std::max(0.0, s - csv->seconds());
    summary.add_phase("write", write_s);
  }
  if (opt.json) {
    std::cout << scene::report_json(sc, summary).dump(2) << "\n";
  } else {
    std::cout << scene::report_text(sc, summary);
  }
  return summary.status == RunStatus::kCompleted ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Moreau: simulation of nonsmooth dynamical systems (set-valued controllers, friction, impacts)"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "moreau 0.1.0");

  RunOptions run;
  auto* run_cmd = app.add_subcommand("run", "Run a scene locally and print its report");
  run_cmd->add_option("scene", run.scene_path, "Scene file (JSON, see docs/scene-format.md)")->required();
  run_cmd->add_option("--set", run.overrides, "Override a scene field: PATH=VALUE (integrator.h=1e-4, initial.v=[0,1])")
      ->allow_extra_args(false);
  run_cmd->add_flag("--json", run.json, "Print the report as one JSON object on stdout");
  run_cmd->add_option("--out", run.out_csv, "Write the trajectory as CSV (t, h, q..., v..., energy)");
  run_cmd->add_option("--progress", run.progress, "Progress bar on stderr: auto (when stderr is a terminal), always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (*run_cmd) return run_command(run);
  return 0;
}
