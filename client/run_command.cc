// moreau run SCENE [--json] [--out traj.csv] [--set PATH=VALUE]... : runs a scene locally and prints its
// report.
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "commands.h"
#include "figure_output.h"
#include "terminal_text.h"
#include "moreau/analysis/figures.h"
#include "moreau/scene/simulation.h"
#include "moreau/scene/trajectory_csv.h"
#include "progress_bar.h"

namespace moreau::cli {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct RunOptions {
  std::string scene_path;
  std::vector<std::string> overrides;
  bool json = false;
  std::string out_csv;
  std::string progress = "auto";
  std::vector<std::string> figures;
  FigureFlags figure_flags;
  bool strict = false;
};

int run(const RunOptions& opt) {
  const auto t_load = Clock::now();
  std::optional<scene::Simulation> sim;
  try {
    sim = scene::Simulation::from_file(opt.scene_path, opt.overrides);
  } catch (const scene::SceneError& e) {
    std::cerr << "moreau: invalid scene " << opt.scene_path << ": " << e.what() << "\n";
    return 2;
  }
  const double load_s = since(t_load);
  // Parameters nothing reads: likely a misspelt name; the report says so too.
  const std::vector<std::string>* unread = sim->lagrangian() ? &sim->lagrangian()->unread_parameters : &sim->lure()->unread_parameters;
  warn_unread_parameters("moreau", *unread);

  ObserverFan fan;
  std::optional<scene::TrajectoryCsvWriter> csv;
  if (!opt.out_csv.empty()) {
    try {
      csv.emplace(opt.out_csv, sim->position_names(), sim->velocity_names(), sim->signal_names());
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 2;
    }
    fan.add(&*csv);
  }
  std::optional<TimeSeriesRecorder> recorder;
  std::vector<std::pair<scene::TrajectoryFigure, std::string>> figures;  // kind, file
  for (const auto& spec : opt.figures) {
    const auto [name, path] = parse_figure_spec(spec);
    const std::optional<scene::TrajectoryFigure> kind = scene::figure_from_name<scene::TrajectoryFigure>(name);
    if (!kind) {
      std::cerr << "moreau: --figure " << spec << ": unknown kind '" << name << "' (expected "
                << scene::figure_name_list<scene::TrajectoryFigure>() << ")\n";
      return 2;
    }
    figures.emplace_back(*kind, path);
  }
  if (!opt.figures.empty()) {
    recorder.emplace(sim->position_names(), sim->velocity_names(), sim->signal_names());
    fan.add(&*recorder);
  }
  const bool show_progress = opt.progress == "always" || (opt.progress == "auto" && isatty(STDERR_FILENO));
  ProgressBar progress(sim->t0(), sim->t_end(), show_progress);
  fan.add(&progress);

  scene::RunDiagnostics diagnostics;
  RunSummary summary = sim->run(&fan, &diagnostics);
  progress.finish();
  summary.phase_seconds.insert(summary.phase_seconds.begin(), {"load", load_s});
  // The impacts' times, marked on the figures' time axes and written beside the CSV.
  std::vector<double> impacts;
  if (const ContactDiagnostics* contacts = diagnostics.contacts())
    for (const auto& impact : contacts->impacts) impacts.push_back(impact.t);
  if (csv) {
    const auto t_close = Clock::now();
    try {
      csv->close();
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 1;
    }
    // Rows were written inside the integrate phase: move that time to its own phase.
    for (auto& [name, s] : summary.phase_seconds)
      if (name == "integrate") s = std::max(0.0, s - csv->seconds());
    // Beside the CSV, what its columns are, so that `moreau plot` labels a bare CSV as this run's figures.
    const std::string meta_path = scene::trajectory_metadata_path(opt.out_csv);
    std::ofstream meta(meta_path, std::ios::binary | std::ios::trunc);
    meta << scene::trajectory_metadata(*sim, std::filesystem::path(opt.out_csv).filename().string(), summary.converged_time, impacts);
    meta.close();
    if (!meta) {
      std::cerr << "moreau: cannot write '" << meta_path << "'\n";
      return 1;
    }
    summary.add_phase("write", csv->seconds() + since(t_close));
  }
  if (recorder) {
    const auto t_fig = Clock::now();
    if (summary.converged_time) recorder->data().converged_time = *summary.converged_time;
    scene::label_for_system(recorder->data(), *sim);  // a Lur'e system: state x, output y, storage W
    recorder->data().impact_times = impacts;
    for (const auto& [kind, path] : figures) {
      try {
        write_figure(kind, recorder->data(), opt.figure_flags, path);
      } catch (const std::exception& e) {
        std::cerr << "moreau: figure " << path << ": " << e.what() << "\n";
        return 1;
      }
    }
    summary.add_phase("figures", since(t_fig));
  }
  if (opt.json) {
    std::cout << sim->report_json(summary, diagnostics).dump(2) << "\n";
  } else {
    std::cout << sim->report_text(summary, diagnostics);
  }
  if (summary.status != RunStatus::kCompleted) return 1;
  // A hypothesis the run relies on fails: a warning, or with --strict the exit status 3.
  const std::string failure = sim->hypothesis_failure(summary);
  if (!failure.empty()) {
    std::cerr << "moreau: " << (opt.strict ? "error" : "warning") << ": " << failure << "\n";
    if (opt.strict) return 3;
  }
  return 0;
}

}  // namespace

void register_run_command(CLI::App& app, Actions& actions) {
  auto opt = std::make_shared<RunOptions>();
  auto* cmd = app.add_subcommand("run", "Run a scene locally and print its report");
  cmd->add_option("scene", opt->scene_path, "Scene file (JSON, see docs/scene-format.md)")->required();
  cmd->add_option("--set", opt->overrides, "Override a scene field: PATH=VALUE (integrator.h=1e-4, initial.v=[0,1])");
  cmd->add_flag("--json", opt->json, "Print the report as one JSON object on stdout");
  cmd->add_option("--out", opt->out_csv, "Write the trajectory as CSV: t, h, q..., v..., energy");
  cmd->add_option("--progress", opt->progress, "Progress bar on stderr: auto (when stderr is a terminal), always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}));
  cmd->add_option("--figure", opt->figures,
                  "Draw a figure: FILE (state figure) or KIND=FILE, KIND one of state, energy, step, phase, tracking; "
                  ".png through OSMesa or .svg");
  cmd->add_flag("--strict", opt->strict,
                "Exit with status 3 when a hypothesis of a theorem the run relies on fails (see the report's guarantees)");
  opt->figure_flags.add_to(cmd);
  actions[cmd] = [opt] { return run(*opt); };
}

}  // namespace moreau::cli
