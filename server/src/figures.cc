#include "figures.h"

#include <stdexcept>

#include <nlohmann/json.hpp>

#include "moreau/scene/study.h"

#include "trajectory.h"

#ifdef MOREAU_SERVER_HAVE_RENDER
#include "moreau/render/figures.h"
#include "moreau/render/render.h"
#include "moreau/render/study_figures.h"
#endif

namespace moreau::server {

bool is_figure_kind(std::string_view kind) {
  return kind == "state" || kind == "energy" || kind == "step" || kind == "phase";
}

#ifdef MOREAU_SERVER_HAVE_RENDER

bool figures_available() { return true; }

std::vector<std::uint8_t> figure_png(std::string_view kind, std::string_view csv, std::optional<double> converged_time,
                                     int width, int height, const std::string& title) {
  std::string error;
  auto cols = trajectory_columns(csv, &error);
  if (!cols) throw std::runtime_error(error);
  const std::size_t c = cols->names.size();
  if (c < 5 || cols->names[0] != "t" || cols->names[1] != "h" || cols->names[c - 1] != "energy" || (c - 3) % 2 != 0)
    throw std::runtime_error("the trajectory does not have the columns t, h, q..., v..., energy");
  if (cols->values[0].empty()) throw std::runtime_error("the trajectory has no rows");
  const std::size_t n = (c - 3) / 2;
  render::TimeSeriesData data;
  data.t = std::move(cols->values[0]);
  data.h = std::move(cols->values[1]);
  for (std::size_t i = 0; i < n; ++i) {
    data.q_names.push_back(cols->names[2 + i]);
    data.v_names.push_back(cols->names[2 + n + i]);
    data.q.push_back(std::move(cols->values[2 + i]));
    data.v.push_back(std::move(cols->values[2 + n + i]));
  }
  data.energy = std::move(cols->values[c - 1]);
  data.energy_label = "E = 1/2 <M v, v>";
  data.converged_time = converged_time;
  render::FigureOptions opt;
  opt.width_px = width;
  opt.height_px = height;
  opt.title = title;
  render::Figure fig;
  if (kind == "state") fig = render::state_figure(data, opt);
  else if (kind == "energy") fig = render::energy_figure(data, opt);
  else if (kind == "step") fig = render::step_figure(data, opt);
  else if (kind == "phase") fig = render::phase_figure(data, opt);
  else throw std::runtime_error("unknown figure kind (expected state, energy, step or phase)");
  return render::render_png_bytes(fig);
}

std::vector<std::uint8_t> study_figure_png(std::string_view kind, const std::string& result_json, int width, int height) {
  const nlohmann::json j = nlohmann::json::parse(result_json, nullptr, false);
  if (j.is_discarded()) throw std::runtime_error("the stored study result is not valid JSON");
  const scene::StudyResult result = scene::StudyResult::from_json(j);
  render::FigureOptions opt;
  opt.width_px = width;
  opt.height_px = height;
  return render::render_png_bytes(render::study_figure(std::string(kind), result, opt));
}

#else

bool figures_available() { return false; }

std::vector<std::uint8_t> study_figure_png(std::string_view, const std::string&, int, int) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

std::vector<std::uint8_t> figure_png(std::string_view, std::string_view, std::optional<double>, int, int,
                                     const std::string&) {
  throw std::runtime_error("this server was built without render/: figures are not available");
}

#endif

}  // namespace moreau::server
