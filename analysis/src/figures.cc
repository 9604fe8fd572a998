#include "moreau/analysis/figures.h"

#include "moreau/render/render.h"
#include "moreau/scene/scene.h"

#include <utility>

namespace moreau::scene {

render::TimeSeriesData time_series(TrajectoryColumns columns) {
  render::TimeSeriesData data;
  data.t = std::move(columns.t);
  data.h = std::move(columns.h);
  data.q_names = std::move(columns.q_names);
  data.v_names = std::move(columns.v_names);
  data.q = std::move(columns.q);
  data.v = std::move(columns.v);
  data.energy = std::move(columns.energy);
  data.energy_label = "E = 1/2 <M v, v>";
  data.signal_names = std::move(columns.signal_names);
  data.signals = std::move(columns.signals);
  return data;
}

void label_for_system(render::TimeSeriesData& data, const Simulation& sim) {
  // Units: time's ("s" unless /units/t says otherwise, once the scene gives any), each position's by its
  // name, and its rate's as that unit per time unit.
  const auto& units = sim.units();
  if (!units.empty()) {
    const auto t = units.find("t");
    data.t_unit = t != units.end() ? t->second : "s";
    data.q_units.clear();
    data.v_units.clear();
    for (const std::string& name : sim.position_names()) {
      const auto u = units.find(name);
      data.q_units.push_back(u != units.end() ? u->second : "");
      data.v_units.push_back(u != units.end() && !u->second.empty() ? u->second + "/" + data.t_unit : "");
    }
  }
  // The mechanical energy at each sample, 1/2 <M v, v> (the energy column) + V(q), where the scene has a
  // potential: the energy balance's quantity (and Lemma 3's W for an impacting system).
  const LagrangianScene* lagrangian = sim.lagrangian();
  if (lagrangian && lagrangian->compiled && lagrangian->compiled->has_potential && static_cast<int>(data.q.size()) == lagrangian->n &&
      data.energy.size() == data.t.size()) {
    ForceTerms terms(*lagrangian->compiled);
    std::vector<double> q(static_cast<std::size_t>(lagrangian->n));
    data.mechanical_energy.resize(data.t.size());
    for (std::size_t k = 0; k < data.t.size(); ++k) {
      for (std::size_t i = 0; i < q.size(); ++i) q[i] = k < data.q[i].size() ? data.q[i][k] : 0.0;
      data.mechanical_energy[k] = data.energy[k] + terms.potential(q.data());
    }
    data.energy_label = "T = 1/2 <M v, v>";  // beside E, the kinetic part by its own name
  }
  const LureScene* lure = sim.lure();
  if (!lure) return;
  data.q_title = "State x";
  data.q_axis = "x";
  data.v_title = "State rate dx/dt";
  data.v_axis = "dx/dt";
  data.state_space = true;
  std::string energy = "1/2 |x|^2 (no storage matrix)";
  if (lure->storage) {
    energy = "W = 1/2 x^T P x (storage, P from the ";
    energy += lure->storage_source == "scene" ? "scene)" : "positive realness test)";
  }
  data.energy_label = energy;
  // y = C x, row by row, from the state columns.
  const Eigen::Index m = lure->C.rows(), n = lure->C.cols();
  if (static_cast<Eigen::Index>(data.q.size()) != n) return;  // a trajectory of another scene: no outputs
  data.y.assign(static_cast<std::size_t>(m), std::vector<double>(data.t.size(), 0.0));
  for (Eigen::Index i = 0; i < m; ++i)
    for (Eigen::Index j = 0; j < n; ++j) {
      const double c = lure->C(i, j);
      if (c == 0.0) continue;
      const auto& x = data.q[static_cast<std::size_t>(j)];
      auto& y = data.y[static_cast<std::size_t>(i)];
      for (std::size_t k = 0; k < y.size() && k < x.size(); ++k) y[k] += c * x[k];
    }
  data.y_names.clear();
  for (Eigen::Index i = 0; i < m; ++i) data.y_names.push_back(m == 1 ? "y" : "y" + std::to_string(i + 1));
  data.y_title = "Output y = C x";
  // Two states, one output: the state plane is split by the line C x = 0, where the feedback switches.
  if (n == 2 && m == 1) data.switching_line = {lure->C(0, 0), lure->C(0, 1)};
  data.y_axis = "y";
}

std::vector<render::SchemeRuns> study_scheme_runs(const StudyResult& result) {
  std::vector<render::SchemeRuns> runs;
  for (const auto& order : result.orders) {
    render::SchemeRuns r;
    r.scheme = scheme_name(order.scheme);
    for (const auto& row : result.rows) {
      if (row.scheme != order.scheme || row.status != "completed" || !(row.q_max_error > 0.0)) continue;
      r.h.push_back(row.h);
      r.error.push_back(row.q_max_error);
      r.run_time_s.push_back(row.wall_seconds);
    }
    if (!r.h.empty()) runs.push_back(std::move(r));
  }
  return runs;
}

render::Figure trajectory_figure(TrajectoryFigure kind, const render::TimeSeriesData& data, const render::FigureOptions& options) {
  switch (kind) {
    case TrajectoryFigure::kState: return render::state_figure(data, options);
    case TrajectoryFigure::kEnergy: return render::energy_figure(data, options);
    case TrajectoryFigure::kStep: return render::step_figure(data, options);
    case TrajectoryFigure::kPhase: return render::phase_figure(data, options);
    case TrajectoryFigure::kTracking: return render::tracking_figure(data, options);
  }
  return render::state_figure(data, options);  // not reached: the switch covers every kind
}

render::Figure study_figure(StudyFigure kind, const StudyResult& result, render::FigureOptions options) {
  if (options.title.empty()) options.title = result.scene + ": max error of q against " + result.reference;
  // The quantity on the y axis, as the study computes it (the largest Euclidean error at the common times).
  if (options.y_label.empty()) options.y_label = "max over t of ||q(t) - q_ref(t)||";
  const auto runs = study_scheme_runs(result);
  return kind == StudyFigure::kWork ? render::work_figure(runs, options) : render::order_figure(runs, options);
}

std::string encode_figure(const render::Figure& figure, FigureFormat format) {
  if (format == FigureFormat::kSvg) return render::render_svg(figure);
  const std::vector<std::uint8_t> png = render::render_png_bytes(figure);
  return std::string(png.begin(), png.end());
}

}  // namespace moreau::scene
