// Figures from the command line: `moreau run SCENE --figure [KIND=]FILE` and `moreau plot traj.csv`.
// Turns trajectories (recorded live or read back from CSV) into render::TimeSeriesData and writes PNG or
// SVG through render/. Knows nothing of the integrator beyond the observer's samples.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "moreau/analysis/figure_kind.h"
#include "moreau/core/observer.h"
#include "moreau/render/figures.h"

namespace moreau::cli {

// Collects the decimated samples of a run for figures.
class TimeSeriesRecorder : public RunObserver {
 public:
  TimeSeriesRecorder(std::vector<std::string> q_names, std::vector<std::string> v_names, std::vector<std::string> signal_names = {});
  void on_sample(const Sample& s) override;
  render::TimeSeriesData& data() { return data_; }

 private:
  render::TimeSeriesData data_;
};

// Options shared by `run --figure` and `plot`.
struct FigureFlags {
  std::string size = "1200x800";
  std::string title;
  std::vector<std::size_t> coordinates;
  std::optional<double> t0, t1;
  std::string y_scale;    // "", "linear" or "log"
  std::string format;     // "", "png" or "svg" (default: from the file name, else png)
  bool robust_y = false;  // --robust-y (render::FigureOptions::robust_y)

  void add_to(CLI::App* cmd);
};

// The finite-step convergence time of a trajectory: the first sample from which every velocity is
// exactly 0.0 up to the end.
std::optional<double> exact_rest_time(const render::TimeSeriesData& data);

// Draws figure `kind` of `data` (scene::trajectory_figure) into `path`. Throws std::runtime_error (or
// std::invalid_argument from render's validation) with a clear message.
void write_figure(scene::TrajectoryFigure kind, const render::TimeSeriesData& data, const FigureFlags& flags, const std::string& path);

// Draws several tracking runs side by side (render::tracking_comparison_figure), labelled, into `path`.
void write_tracking_comparison(const std::vector<std::pair<std::string, render::TimeSeriesData>>& runs, const FigureFlags& flags,
                               const std::string& path);

// Reads a trajectory CSV as written by `moreau run --out`: t, h, q..., v..., energy.
render::TimeSeriesData read_trajectory_csv(const std::string& path);

// Splits "KIND=FILE" (or a bare FILE, kind state), the kind as written.
std::pair<std::string, std::string> parse_figure_spec(const std::string& spec);

}  // namespace moreau::cli
