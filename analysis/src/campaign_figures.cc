#include "moreau/analysis/campaign_figures.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "moreau/render/render.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {
namespace {

// One colour per outcome in every figure: success blue, converged but off the target reddish purple, no
// convergence (or a failed run) vermillion.
constexpr int kSucceeded = 0, kFailed = 1, kMissed = 3;

std::string count_text(std::size_t k, std::size_t n) { return std::to_string(k) + " of " + std::to_string(n); }

std::string with_unit(const std::string& quantity, const std::string& unit) {
  return unit.empty() ? quantity : quantity + " [" + unit + "]";
}

// The scene's /units/<name> ("" when not given).
std::string unit_of(const nlohmann::json& scene, const std::string& name) {
  if (!scene.is_object() || !scene.contains("units") || !scene["units"].is_object()) return "";
  const nlohmann::json& u = scene["units"];
  return u.contains(name) && u[name].is_string() ? u[name].get<std::string>() : "";
}

// Time's unit: the scene's, "s" by default.
std::string time_unit(const nlohmann::json& scene) {
  const std::string t = unit_of(scene, "t");
  return t.empty() ? "s" : t;
}

// An input's axis label in words, with its unit where the scene gives one: /parameters/m1 -> "m1",
// /initial/q/0 -> "initial x1 [m]" (the coordinate's name from /system/coordinates), /initial/v/0 ->
// "initial x1_dot [m/s]"; any other pointer as it is.
std::string input_label(const CampaignSpec& spec, std::size_t d) {
  const std::string& path = spec.inputs[d].path;
  const nlohmann::json& scene = spec.scene;
  const std::string parameters = "/parameters/";
  if (path.rfind(parameters, 0) == 0 && path.find('/', parameters.size()) == std::string::npos) {
    const std::string name = path.substr(parameters.size());
    return with_unit(name, unit_of(scene, name));
  }
  for (const char* which : {"q", "v"}) {
    const std::string prefix = std::string("/initial/") + which + "/";
    if (path.rfind(prefix, 0) != 0) continue;
    const std::string index = path.substr(prefix.size());
    if (index.empty() || index.find_first_not_of("0123456789") != std::string::npos || index.size() > 4) return path;
    const std::size_t i = std::stoul(index);
    std::string name = "q" + std::to_string(i + 1);
    if (scene.contains("system") && scene["system"].is_object() && scene["system"].contains("coordinates") &&
        scene["system"]["coordinates"].is_array() && i < scene["system"]["coordinates"].size() &&
        scene["system"]["coordinates"][i].is_string())
      name = scene["system"]["coordinates"][i].get<std::string>();
    const std::string unit = unit_of(scene, name);
    if (std::string(which) == "q") return with_unit("initial " + name, unit);
    return with_unit("initial " + name + "_dot", unit.empty() ? "" : unit + "/" + time_unit(scene));
  }
  return path;
}

}  // namespace

std::vector<std::pair<CampaignFigure, render::Figure>> campaign_figures(const CampaignSpec& spec,
                                                                        const std::vector<CampaignOutcome>& outcomes, double t_end) {
  std::vector<std::pair<CampaignFigure, render::Figure>> figures;
  const std::size_t n = outcomes.size();
  std::size_t successes = 0;
  for (const auto& o : outcomes) successes += o.success;

  // The empirical CDF of the convergence time, over all samples (those that never converged keep it
  // below 1): a staircase, each step 1/n at a convergence time.
  std::vector<double> times;
  for (const auto& o : outcomes)
    if (o.converged && std::isfinite(o.converged_time)) times.push_back(o.converged_time);
  std::sort(times.begin(), times.end());
  if (!times.empty()) {
    render::Series cdf;
    cdf.label = "converged by t (" + count_text(times.size(), n) + " samples)";
    cdf.color = kSucceeded;
    double level = 0.0;
    for (double t : times) {
      cdf.x.push_back(t);
      cdf.y.push_back(level);
      level += 1.0 / static_cast<double>(n);
      cdf.x.push_back(t);
      cdf.y.push_back(level);
    }
    cdf.x.push_back(std::max(t_end, times.back()));
    cdf.y.push_back(level);
    render::Panel p;
    p.title = "fraction of the samples at rest (converged) by time t";
    p.x_label = with_unit("convergence time t", time_unit(spec.scene));
    p.y_label = "fraction of samples";
    p.y_axis.min = 0.0;
    p.y_axis.max = 1.0;
    p.series.push_back(std::move(cdf));
    p.legend_place = render::LegendPlace::lower_right;
    render::Figure f;
    f.title = spec.name + ": convergence time, " + count_text(successes, n) + " samples succeeded";
    f.panels.push_back(std::move(p));
    figures.emplace_back(CampaignFigure::kConvergenceCdf, std::move(f));
  }

  // Each numeric input against the convergence time: the samples that succeeded, those that converged
  // but did not meet the target (at their convergence time too), and those that never converged (at
  // t_end), each in its colour.
  render::Figure inputs;
  inputs.title = spec.name + ": each input against the convergence time";
  int panels = 0;
  for (std::size_t d = 0; d < spec.inputs.size() && panels < 8; ++d) {
    if (!spec.inputs[d].distribution.numeric()) continue;
    render::Series ok, missed, bad;
    ok.label = "succeeded: convergence time";
    missed.label = "converged off the target: convergence time";
    ok.style = missed.style = bad.style = render::SeriesStyle::points;
    ok.color = kSucceeded;
    missed.color = kMissed;
    bad.label = "did not converge (drawn at t_end)";
    bad.color = kFailed;
    for (const auto& o : outcomes) {
      const double x = d < o.inputs.size() ? o.inputs[d] : std::nan("");
      if (!std::isfinite(x)) continue;
      const bool at_rest = o.converged && std::isfinite(o.converged_time);
      render::Series& s = o.success && at_rest ? ok : at_rest ? missed : bad;
      s.x.push_back(x);
      s.y.push_back(at_rest ? o.converged_time : t_end);
    }
    render::Panel p;
    p.x_label = input_label(spec, d);
    p.y_label = with_unit("t", time_unit(spec.scene));
    for (render::Series* s : {&ok, &missed, &bad})
      if (!s->x.empty()) p.series.push_back(std::move(*s));
    if (p.series.empty()) continue;
    p.legend = panels == 0;
    inputs.panels.push_back(std::move(p));
    ++panels;
  }
  if (!inputs.panels.empty()) {
    inputs.height_px = std::clamp(260 * panels + 80, 400, 2400);
    figures.emplace_back(CampaignFigure::kInputs, std::move(inputs));
  }

  // The success region in the plane of two inputs.
  if (spec.map_inputs[0] >= 0 && spec.map_inputs[1] >= 0) {
    const auto a = static_cast<std::size_t>(spec.map_inputs[0]), b = static_cast<std::size_t>(spec.map_inputs[1]);
    render::Series ok, bad;
    ok.style = bad.style = render::SeriesStyle::points;
    ok.color = kSucceeded;
    bad.color = kFailed;
    for (const auto& o : outcomes) {
      if (a >= o.inputs.size() || b >= o.inputs.size() || !std::isfinite(o.inputs[a]) || !std::isfinite(o.inputs[b])) continue;
      render::Series& s = o.success ? ok : bad;
      s.x.push_back(o.inputs[a]);
      s.y.push_back(o.inputs[b]);
    }
    ok.label = "succeeded (" + std::to_string(ok.x.size()) + ")";
    bad.label = "did not succeed (" + std::to_string(bad.x.size()) + ")";
    render::Panel p;
    p.x_label = input_label(spec, a);
    p.y_label = input_label(spec, b);
    // Every sample on one side: the map has no boundary to show in the range sampled, and says so.
    if (bad.x.empty() && !ok.x.empty()) p.title = "every sample succeeded: no boundary of the success region in the range sampled";
    if (ok.x.empty() && !bad.x.empty()) p.title = "no sample succeeded: no success region in the range sampled";
    if (!ok.x.empty()) p.series.push_back(std::move(ok));
    if (!bad.x.empty()) p.series.push_back(std::move(bad));
    if (!p.series.empty()) {
      render::Figure f;
      f.title = spec.name + ": success region, " + count_text(successes, n) + " samples succeeded";
      f.panels.push_back(std::move(p));
      figures.emplace_back(CampaignFigure::kSuccessMap, std::move(f));
    }
  }
  return figures;
}

std::vector<std::string> write_campaign_figures(const std::string& dir_name) {
  namespace fs = std::filesystem;
  const fs::path dir = dir_name;
  const CampaignSpec spec = CampaignSpec::from_json(read_scene_file((dir / "campaign.json").string()), dir.string());
  const auto outcomes = read_campaign_outcomes(spec, dir.string());
  const double t_end = Simulation::from_json(spec.scene).t_end();
  fs::create_directories(dir / "figures");
  std::vector<std::string> paths;
  for (const auto& [kind, figure] : campaign_figures(spec, outcomes, t_end)) {
    const fs::path path = dir / "figures" / (std::string(figure_name(kind)) + ".png");
    render::render_png(figure, path.string());
    paths.push_back(path.string());
  }
  return paths;
}

}  // namespace moreau::scene
