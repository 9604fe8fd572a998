// Figures of a finished job, drawn by render/ from its trajectory (the same figures as
// `moreau run --figure`), and of a finished study, from its table.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::server {

// Whether this build can draw figures (render/ was available).
bool figures_available();

// Whether `kind` is one of state, energy, step, phase.
bool is_figure_kind(std::string_view kind);

// The PNG of figure `kind` for the trajectory CSV. Throws std::runtime_error (or render's FigureError)
// with a clear message.
std::vector<std::uint8_t> figure_png(std::string_view kind, std::string_view csv, std::optional<double> converged_time, int width,
                                     int height, const std::string& title);

// The PNG of a study's "work" or "order" figure, from its stored result.json (as `moreau study --work` /
// `--order` draw them). Throws std::runtime_error or std::invalid_argument with a clear message.
std::vector<std::uint8_t> study_figure_png(std::string_view kind, const std::string& result_json, int width, int height);

}  // namespace moreau::server
