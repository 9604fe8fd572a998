#include "moreau/analysis/campaign_figures.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "moreau/render/render.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {
namespace {

constexpr int kBlue = 0, kVermillion = 1, kGreen = 2;

std::string count_text(std::size_t k, std::size_t n) { return std::to_string(k) + " of " + std::to_string(n); }

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
    cdf.color = kBlue;
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
    p.x_label = "convergence time t (s)";
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

  // Each numeric input against the convergence time; the samples that did not succeed apart, at t_end.
  render::Figure inputs;
  inputs.title = spec.name + ": each input against the convergence time";
  int panels = 0;
  for (std::size_t d = 0; d < spec.inputs.size() && panels < 8; ++d) {
    if (!spec.inputs[d].distribution.numeric()) continue;
    render::Series ok, bad;
    ok.label = "succeeded: convergence time";
    ok.style = bad.style = render::SeriesStyle::points;
    ok.color = kBlue;
    bad.label = "did not succeed (drawn at t_end)";
    bad.color = kVermillion;
    for (const auto& o : outcomes) {
      const double x = d < o.inputs.size() ? o.inputs[d] : std::nan("");
      if (!std::isfinite(x)) continue;
      if (o.success && std::isfinite(o.converged_time)) {
        ok.x.push_back(x);
        ok.y.push_back(o.converged_time);
      } else {
        bad.x.push_back(x);
        bad.y.push_back(t_end);
      }
    }
    render::Panel p;
    p.x_label = spec.inputs[d].path;
    p.y_label = "t (s)";
    if (!ok.x.empty()) p.series.push_back(std::move(ok));
    if (!bad.x.empty()) p.series.push_back(std::move(bad));
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
    ok.color = kGreen;
    bad.color = kVermillion;
    for (const auto& o : outcomes) {
      if (a >= o.inputs.size() || b >= o.inputs.size() || !std::isfinite(o.inputs[a]) || !std::isfinite(o.inputs[b])) continue;
      render::Series& s = o.success ? ok : bad;
      s.x.push_back(o.inputs[a]);
      s.y.push_back(o.inputs[b]);
    }
    ok.label = "succeeded (" + std::to_string(ok.x.size()) + ")";
    bad.label = "did not succeed (" + std::to_string(bad.x.size()) + ")";
    render::Panel p;
    p.x_label = spec.inputs[a].path;
    p.y_label = spec.inputs[b].path;
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
