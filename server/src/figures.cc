#include "figures.h"

#include <istream>
#include <stdexcept>
#include <streambuf>

#include <nlohmann/json.hpp>

#include "moreau/analysis/campaign.h"
#include "moreau/analysis/study.h"

#ifdef MOREAU_SERVER_HAVE_RENDER
#include "moreau/analysis/campaign_figures.h"
#include "moreau/render/figures.h"
#include "moreau/render/render.h"
#include "moreau/analysis/figures.h"
#endif

namespace moreau::server {

bool is_figure_kind(std::string_view kind) { return kind == "state" || kind == "energy" || kind == "step" || kind == "phase"; }

#ifdef MOREAU_SERVER_HAVE_RENDER

bool figures_available() { return true; }

namespace {
std::string encode(const render::Figure& fig, FigureFormat format) {
  if (format == FigureFormat::kSvg) return render::render_svg(fig);
  const std::vector<std::uint8_t> png = render::render_png_bytes(fig);
  return std::string(png.begin(), png.end());
}
}  // namespace

std::string figure_image(std::string_view kind, std::string_view csv, std::optional<double> converged_time, int width, int height,
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
  data.converged_time = converged_time;
  if (system) scene::label_for_system(data, *system);
  render::FigureOptions opt;
  opt.width_px = width;
  opt.height_px = height;
  opt.title = title;
  render::Figure fig;
  if (kind == "state")
    fig = render::state_figure(data, opt);
  else if (kind == "energy")
    fig = render::energy_figure(data, opt);
  else if (kind == "step")
    fig = render::step_figure(data, opt);
  else if (kind == "phase")
    fig = render::phase_figure(data, opt);
  else
    throw std::runtime_error("unknown figure kind (expected state, energy, step or phase)");
  return encode(fig, format);
}

std::string study_figure_image(std::string_view kind, const std::string& result_json, int width, int height, FigureFormat format) {
  const nlohmann::json j = nlohmann::json::parse(result_json, nullptr, false);
  if (j.is_discarded()) throw std::runtime_error("the stored study result is not valid JSON");
  const scene::StudyResult result = scene::StudyResult::from_json(j);
  render::FigureOptions opt;
  opt.width_px = width;
  opt.height_px = height;
  return encode(scene::study_figure(std::string(kind), result, opt), format);
}

std::string campaign_figure_image(std::string_view kind, const scene::CampaignSpec& spec, const std::string& dir, double t_end, int width,
                                  int height, FigureFormat format) {
  for (auto& [name, fig] : scene::campaign_figures(spec, scene::read_campaign_outcomes(spec, dir), t_end)) {
    if (name != kind) continue;
    fig.width_px = width;
    fig.height_px = height;
    return encode(fig, format);
  }
  throw std::runtime_error(kind == "success-map"
                               ? "this campaign has no success map: it needs two numeric inputs"
                               : "this campaign has no " + std::string(kind) + " figure (no sample converged, or no numeric input)");
}

#else

bool figures_available() { return false; }

std::string campaign_figure_image(std::string_view, const scene::CampaignSpec&, const std::string&, double, int, int, FigureFormat) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

std::string study_figure_image(std::string_view, const std::string&, int, int, FigureFormat) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

std::string figure_image(std::string_view, std::string_view, std::optional<double>, int, int, const std::string&, FigureFormat,
                         const scene::Simulation*) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

#endif

}  // namespace moreau::server
