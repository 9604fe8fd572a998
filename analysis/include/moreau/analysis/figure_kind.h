// The figures Moreau draws, as types, and their names. A figure is named by a string only at the edges:
// the command line (`moreau run --figure KIND=FILE`, `moreau plot --kind`, `moreau figure --kind`), the
// server's query parameters (?kind=, ?format=), the links of a job and the file names of its figures. Each
// of them reads the names from the tables below and turns them into these enums at once (figure_from_name);
// the drawing (figures.h, campaign_figures.h) takes the enums. As Ceres's types.h does for its options:
// one table per enum, read both ways.
//
// Header only, with no library behind it (CMake target moreau_figure_kinds): the server names figures,
// and checks the names asked for, also when it is built without render/ and cannot draw them.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace moreau::scene {

// The figures of one run, drawn from its trajectory by render/'s figure builders (render/figures.h).
enum class TrajectoryFigure {
  kState,     // positions and velocities against time (state_figure)
  kEnergy,    // the energy against time, log y axis (energy_figure)
  kStep,      // the step size h_k against t_k, log y axis (step_figure)
  kPhase,     // the phase portrait (phase_figure)
  kTracking,  // q with q_d, e, |sigma| (log) and u of a tracking run (tracking_figure)
};

// The figures of a study, drawn from its table (study_figure, figures.h).
enum class StudyFigure {
  kWork,   // error against run time
  kOrder,  // error against h, with the fitted orders
};

// The figures of a robustness campaign, drawn from its records (campaign_figures.h).
enum class CampaignFigure {
  kConvergenceCdf,  // the fraction of the samples converged by time t
  kInputs,          // each numeric input against the convergence time
  kSuccessMap,      // the plane of the two map inputs, successes apart
};

// How a figure is written: PNG (rasterized through OSMesa) or SVG (text, no GL).
enum class FigureFormat { kPng, kSvg };

// The name table of each enum, in the order listings and messages give them; the first is the default
// (of `moreau plot --kind`, of the server's ?kind= and ?format=).
template <class Kind>
struct FigureNames;
template <>
struct FigureNames<TrajectoryFigure> {
  static constexpr std::pair<TrajectoryFigure, const char*> kTable[] = {
      {TrajectoryFigure::kState, "state"}, {TrajectoryFigure::kEnergy, "energy"},     {TrajectoryFigure::kStep, "step"},
      {TrajectoryFigure::kPhase, "phase"}, {TrajectoryFigure::kTracking, "tracking"},
  };
};
template <>
struct FigureNames<StudyFigure> {
  static constexpr std::pair<StudyFigure, const char*> kTable[] = {{StudyFigure::kWork, "work"}, {StudyFigure::kOrder, "order"}};
};
template <>
struct FigureNames<CampaignFigure> {
  static constexpr std::pair<CampaignFigure, const char*> kTable[] = {
      {CampaignFigure::kConvergenceCdf, "convergence-cdf"},
      {CampaignFigure::kInputs, "inputs"},
      {CampaignFigure::kSuccessMap, "success-map"},
  };
};
template <>
struct FigureNames<FigureFormat> {
  static constexpr std::pair<FigureFormat, const char*> kTable[] = {{FigureFormat::kPng, "png"}, {FigureFormat::kSvg, "svg"}};
};

// The name of a kind: "state", "convergence-cdf", "svg".
template <class Kind>
constexpr const char* figure_name(Kind kind) {
  for (const auto& [k, name] : FigureNames<Kind>::kTable)
    if (k == kind) return name;
  return "";  // not reached: every enumerator is in its table (tests/analysis/scene_figures_test.cc)
}

// The kind a name denotes, or nullopt for a name that is none (names are compared exactly).
template <class Kind>
constexpr std::optional<Kind> figure_from_name(std::string_view name) {
  for (const auto& [k, known] : FigureNames<Kind>::kTable)
    if (name == known) return k;
  return std::nullopt;
}

// The default kind: the first of the table.
template <class Kind>
constexpr Kind default_figure() {
  return FigureNames<Kind>::kTable[0].first;
}

// Every name, in the table's order (for a command line option's allowed values).
template <class Kind>
std::vector<std::string> figure_names() {
  std::vector<std::string> out;
  for (const auto& entry : FigureNames<Kind>::kTable) out.emplace_back(entry.second);
  return out;
}

// Every name as a message lists them: "state, energy, step or phase", "work or order".
template <class Kind>
std::string figure_name_list() {
  const std::vector<std::string> names = figure_names<Kind>();
  std::string out;
  for (std::size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

}  // namespace moreau::scene
