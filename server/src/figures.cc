#include "figures.h"

#include <istream>
#include <stdexcept>
#include <streambuf>

#include <nlohmann/json.hpp>

#include "moreau/analysis/campaign.h"
#include "moreau/analysis/study.h"

#ifdef MOREAU_SERVER_HAVE_RENDER
#include "moreau/analysis/campaign_figures.h"
#include "moreau/analysis/figures.h"
#endif

namespace moreau::server {

using scene::CampaignFigure;
using scene::FigureFormat;
using scene::StudyFigure;
using scene::TrajectoryFigure;

#ifdef MOREAU_SERVER_HAVE_RENDER

bool figures_available() { return true; }

std::string figure_image(TrajectoryFigure kind, std::string_view csv, const TrajectoryMarks& marks, int width, int height,
                         const std::string& title, FigureFormat format, const scene::Simulation* system) {
  // The stored CSV, read in place (no copy of what may be hundreds of megabytes).
  struct ViewBuffer : std::streambuf {
    explicit ViewBuffer(std::string_view s) {
      char* p = const_cast<char*>(s.data());  // read only: a get area is never written through
      setg(p, p, p + s.size());
    }
  } buffer(csv);
  std::istream in(&buffer);
  render::TimeSeriesData data = scene::time_series(scene::read_trajectory_csv(in, "the stored trajectory"));
  data.converged_time = marks.converged_time;
  data.impact_times = marks.impact_times;
  if (system) scene::label_for_system(data, *system);
  render::FigureOptions opt;
  opt.robust_y = marks.robust_y;
  opt.width_px = width;
  opt.height_px = height;
  opt.title = title;
  return scene::encode_figure(scene::trajectory_figure(kind, data, opt), format);
}

std::string study_figure_image(StudyFigure kind, const std::string& result_json, int width, int height, FigureFormat format) {
  const nlohmann::json j = nlohmann::json::parse(result_json, nullptr, false);
  if (j.is_discarded()) throw std::runtime_error("the stored study result is not valid JSON");
  const scene::StudyResult result = scene::StudyResult::from_json(j);
  render::FigureOptions opt;
  opt.width_px = width;
  opt.height_px = height;
  return scene::encode_figure(scene::study_figure(kind, result, opt), format);
}

std::string campaign_figure_image(CampaignFigure kind, const scene::CampaignSpec& spec, const std::string& dir, double t_end, int width,
                                  int height, FigureFormat format) {
  for (auto& [drawn, fig] : scene::campaign_figures(spec, scene::read_campaign_outcomes(spec, dir), t_end)) {
    if (drawn != kind) continue;
    fig.width_px = width;
    fig.height_px = height;
    return scene::encode_figure(fig, format);
  }
  throw std::runtime_error(kind == CampaignFigure::kSuccessMap ? "this campaign has no success map: it needs two numeric inputs"
                                                               : std::string("this campaign has no ") + scene::figure_name(kind) +
                                                                     " figure (no sample converged, or no numeric input)");
}

#else

bool figures_available() { return false; }

std::string campaign_figure_image(CampaignFigure, const scene::CampaignSpec&, const std::string&, double, int, int, FigureFormat) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

std::string study_figure_image(StudyFigure, const std::string&, int, int, FigureFormat) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

std::string figure_image(TrajectoryFigure, std::string_view, const TrajectoryMarks&, int, int, const std::string&, FigureFormat,
                         const scene::Simulation*) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

#endif

}  // namespace moreau::server
