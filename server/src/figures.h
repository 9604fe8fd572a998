// The images of finished jobs' figures, drawn from their stored results by analysis/'s figures
// (figures.h, campaign_figures.h: the same figures as `moreau run --figure`, `moreau study --work` and
// `moreau campaign`): a run's from its trajectory, a study's from its table, a campaign's from its
// records. figures_routes.h serves them.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "moreau/analysis/figure_kind.h"

namespace moreau::scene {
class Simulation;
struct CampaignSpec;
}  // namespace moreau::scene

namespace moreau::server {

// Whether this build can draw figures (render/ was available).
bool figures_available();

// What a run's figure marks beyond its trajectory, from its report, and how its axes are drawn.
struct TrajectoryMarks {
  std::optional<double> converged_time;
  std::vector<double> impact_times;
  bool robust_y = false;  // render::FigureOptions::robust_y
};

// The image of trajectory figure `kind` for the trajectory CSV, as bytes, labelled for the kind of system
// `system` is (scene::label_for_system; null: a mechanical system's labels). Throws std::runtime_error
// (or render's std::invalid_argument) with a clear message.
std::string figure_image(scene::TrajectoryFigure kind, std::string_view csv, const TrajectoryMarks& marks, int width, int height,
                         const std::string& title, scene::FigureFormat format, const scene::Simulation* system = nullptr);

// The image of a study's figure, from its stored result.json. Throws std::runtime_error or
// std::invalid_argument with a clear message.
std::string study_figure_image(scene::StudyFigure kind, const std::string& result_json, int width, int height, scene::FigureFormat format);

// The image of a finished campaign's figure, from the records in its directory. Throws std::runtime_error
// with a clear message, also when the campaign has no such figure (no sample converged; fewer than two
// numeric inputs).
std::string campaign_figure_image(scene::CampaignFigure kind, const scene::CampaignSpec& spec, const std::string& dir, double t_end,
                                  int width, int height, scene::FigureFormat format);

}  // namespace moreau::server
