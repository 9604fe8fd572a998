// Figures of a finished job, drawn by render/ from its trajectory (the same figures as
// `moreau run --figure`), and of a finished study, from its table.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace moreau::scene {
class Simulation;
struct CampaignSpec;
}  // namespace moreau::scene

namespace moreau::server {

// Whether this build can draw figures (render/ was available).
bool figures_available();

// Whether `kind` is one of state, energy, step, phase.
bool is_figure_kind(std::string_view kind);

// PNG (drawn through OSMesa) or SVG (text, no GL).
enum class FigureFormat { kPng, kSvg };

// The image of figure `kind` for the trajectory CSV, as bytes, labelled for the kind of system `system`
// is (scene::label_for_system; null: a mechanical system's labels). Throws std::runtime_error (or
// render's FigureError) with a clear message.
std::string figure_image(std::string_view kind, std::string_view csv, std::optional<double> converged_time, int width, int height,
                         const std::string& title, FigureFormat format, const scene::Simulation* system = nullptr);

// The image of a study's "work" or "order" figure, from its stored result.json (as `moreau study --work`
// / `--order` draw them). Throws std::runtime_error or std::invalid_argument with a clear message.
std::string study_figure_image(std::string_view kind, const std::string& result_json, int width, int height, FigureFormat format);

// The image of a finished campaign's figure "convergence-cdf", "inputs" or "success-map"
// (campaign_figures.h), from the records in its directory. Throws std::runtime_error with a clear message,
// also when the campaign has no such figure (no sample converged; fewer than two numeric inputs).
std::string campaign_figure_image(std::string_view kind, const scene::CampaignSpec& spec, const std::string& dir, double t_end, int width,
                                  int height, FigureFormat format);

}  // namespace moreau::server
