// moreau plot traj.csv --kind state -o state.png : figures from a trajectory written by `moreau run --out`;
// moreau plot a.csv --compare b.csv --kind tracking --labels implicit,explicit -o f.png : tracking runs side by side.
#include <iostream>
#include <memory>

#include "commands.h"
#include "figure_output.h"
#include "moreau/analysis/figures.h"

namespace moreau::cli {

void register_plot_command(CLI::App& app, Actions& actions) {
  struct Options {
    std::string csv, kind = scene::figure_name(scene::default_figure<scene::TrajectoryFigure>()), out, scene;
    std::vector<std::string> compare, labels;
    FigureFlags flags;
  };
  auto opt = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("plot", "Draw a figure of a trajectory CSV (PNG through OSMesa, or SVG)");
  cmd->add_option("trajectory", opt->csv, "Trajectory CSV from `moreau run --out`")->required();
  cmd->add_option("--kind", opt->kind, scene::figure_name_list<scene::TrajectoryFigure>())
      ->check(CLI::IsMember(scene::figure_names<scene::TrajectoryFigure>()))
      ->capture_default_str();
  cmd->add_option("-o,--output", opt->out, "Output file (.png or .svg)")->required();
  cmd->add_option("--scene", opt->scene,
                  "The scene the trajectory came from: labels its figures for its kind of system (a Lur'e system: state x, "
                  "output y = C x, storage W)");
  cmd->add_option("--compare", opt->compare,
                  "With --kind tracking: more trajectories of tracking runs (the implicit and the explicit controller, ...) drawn "
                  "beside the first, one colour each");
  cmd->add_option("--labels", opt->labels, "The runs' names in the comparison, in order (default: the file names)")->delimiter(',');
  opt->flags.add_to(cmd);
  actions[cmd] = [opt]() -> int {
    try {
      if (!opt->compare.empty()) {
        if (opt->kind != "tracking") throw std::runtime_error("--compare draws tracking runs side by side: give --kind tracking");
        std::vector<std::string> files = {opt->csv};
        files.insert(files.end(), opt->compare.begin(), opt->compare.end());
        if (!opt->labels.empty() && opt->labels.size() != files.size())
          throw std::runtime_error("--labels: " + std::to_string(opt->labels.size()) + " names for " + std::to_string(files.size()) +
                                   " runs");
        std::vector<std::pair<std::string, render::TimeSeriesData>> runs;
        for (std::size_t i = 0; i < files.size(); ++i)
          runs.emplace_back(opt->labels.empty() ? files[i] : opt->labels[i], read_trajectory_csv(files[i]));
        write_tracking_comparison(runs, opt->flags, opt->out);
        return 0;
      }
      render::TimeSeriesData data = read_trajectory_csv(opt->csv);
      if (!opt->scene.empty()) scene::label_for_system(data, scene::Simulation::from_file(opt->scene));
      write_figure(*scene::figure_from_name<scene::TrajectoryFigure>(opt->kind), data, opt->flags, opt->out);  // checked by --kind
      return 0;
    } catch (const std::exception& e) {
      std::cerr << "moreau plot: " << e.what() << "\n";
      return 2;
    }
  };
}

}  // namespace moreau::cli
