#include "moreau/analysis/figures.h"

#include "moreau/render/render.h"
#include "moreau/scene/scene.h"

#include <cmath>
#include <stdexcept>
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

namespace {

// A Lur'e system's output y = C x, row by row from the state columns, and the line C x = 0 across a
// two-state plane with one output, where the feedback switches. A trajectory of another scene (other
// than n state columns) gets no outputs.
void add_outputs(render::TimeSeriesData& data, const std::vector<std::vector<double>>& C) {
  const std::size_t m = C.size(), n = m ? C[0].size() : 0;
  if (data.q.size() != n) return;
  data.y.assign(m, std::vector<double>(data.t.size(), 0.0));
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t j = 0; j < n; ++j) {
      const double c = C[i][j];
      if (c == 0.0) continue;
      const auto& x = data.q[j];
      auto& y = data.y[i];
      for (std::size_t k = 0; k < y.size() && k < x.size(); ++k) y[k] += c * x[k];
    }
  data.y_names.clear();
  for (std::size_t i = 0; i < m; ++i) data.y_names.push_back(m == 1 ? "y" : "y" + std::to_string(i + 1));
  data.y_title = "Output y = C x";
  data.y_axis = "y";
  if (n == 2 && m == 1) data.switching_line = {C[0][0], C[0][1]};
}

}  // namespace

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
  std::vector<std::vector<double>> C(static_cast<std::size_t>(lure->C.rows()));
  for (Eigen::Index i = 0; i < lure->C.rows(); ++i)
    for (Eigen::Index j = 0; j < lure->C.cols(); ++j) C[static_cast<std::size_t>(i)].push_back(lure->C(i, j));
  add_outputs(data, C);
}

std::string trajectory_metadata_path(const std::string& csv_path) { return csv_path + "-metadata.json"; }

std::string trajectory_metadata(const Simulation& sim, const std::string& csv_file_name, std::optional<double> converged_time,
                                const std::vector<double>& impact_times) {
  using nlohmann::json;
  // The labels of an empty trajectory with the scene's columns: what label_for_system gives any run of it.
  render::TimeSeriesData labels;
  labels.q.assign(sim.position_names().size(), {});
  labels.v.assign(sim.velocity_names().size(), {});
  labels.energy_label = "E = 1/2 <M v, v>";
  label_for_system(labels, sim);
  const bool lure = sim.lure() != nullptr;
  auto unit_of = [](const std::vector<std::string>& units, std::size_t i) { return i < units.size() ? units[i] : std::string(); };
  json columns = json::array();
  auto column = [&](const std::string& name, const std::string& what, const std::string& unit) {
    json c = {{"name", name}, {"titles", name}, {"datatype", "double"}, {"dc:description", what}};
    if (!unit.empty()) c["moreau:unit"] = unit;
    columns.push_back(std::move(c));
  };
  column("t", "time", labels.t_unit);
  column("h", "the step that led to this sample, t_k - t_(k-1) (the first row: the nominal step)", labels.t_unit);
  const auto& q = sim.position_names();
  const auto& v = sim.velocity_names();
  for (std::size_t i = 0; i < q.size(); ++i) column(q[i], (lure ? "state " : "position ") + q[i], unit_of(labels.q_units, i));
  for (std::size_t i = 0; i < v.size(); ++i) column(v[i], (lure ? "rate of the state " : "velocity ") + q[i], unit_of(labels.v_units, i));
  column("energy", labels.energy_label.empty() ? "E = 1/2 <M v, v>" : labels.energy_label, "");
  for (const std::string& name : sim.signal_names()) column(name, "signal " + name, "");

  json C = json::array();
  if (const LureScene* l = sim.lure()) {
    for (Eigen::Index i = 0; i < l->C.rows(); ++i) {
      json row = json::array();
      for (Eigen::Index j = 0; j < l->C.cols(); ++j) row.push_back(l->C(i, j));
      C.push_back(std::move(row));
    }
  }
  json figures = {{"system", lure ? "lure" : "lagrangian"},
                  {"q_title", labels.q_title},
                  {"q_axis", labels.q_axis},
                  {"v_title", labels.v_title},
                  {"v_axis", labels.v_axis},
                  {"state_space", labels.state_space},
                  {"energy_label", labels.energy_label},
                  {"t_unit", labels.t_unit},
                  {"q_units", labels.q_units},
                  {"v_units", labels.v_units},
                  {"output_matrix", C},
                  {"impact_times", impact_times}};
  figures["converged_time"] = converged_time ? json(*converged_time) : json(nullptr);
  json doc = {{"@context", "http://www.w3.org/ns/csvw"},
              {"url", csv_file_name},
              {"dc:title", "trajectory of the scene '" + sim.name() + "'"},
              {"dc:creator", "moreau"},
              {"tableSchema", {{"columns", columns}}},
              {"moreau:figures", figures}};
  return doc.dump(2) + "\n";
}

void label_from_metadata(render::TimeSeriesData& data, std::string_view metadata_text, const std::string& source) {
  using nlohmann::json;
  json doc;
  try {
    doc = parse_json_text(metadata_text, source);
  } catch (const SceneError& e) {
    throw std::runtime_error(e.what());
  }
  auto fail = [&](const std::string& pointer, const std::string& why) { throw std::runtime_error(source + " at " + pointer + ": " + why); };
  if (!doc.is_object() || !doc.contains("moreau:figures") || !doc["moreau:figures"].is_object())
    fail("/moreau:figures", "missing (not a trajectory's metadata from moreau)");
  const json& f = doc["moreau:figures"];
  const std::string at = "/moreau:figures/";
  auto text = [&](const char* key, std::string& out) {
    if (!f.contains(key)) return;
    if (!f[key].is_string()) fail(at + key, "expected a string");
    out = f[key].get<std::string>();
  };
  auto texts = [&](const char* key, std::vector<std::string>& out, std::size_t size) {
    if (!f.contains(key)) return;
    const json& a = f[key];
    if (!a.is_array() || !std::all_of(a.begin(), a.end(), [](const json& e) { return e.is_string(); }))
      fail(at + key, "expected an array of strings");
    if (!a.empty() && a.size() != size)
      fail(at + key, std::to_string(a.size()) + " units for the CSV's " + std::to_string(size) + " columns");
    out = a.get<std::vector<std::string>>();
  };
  auto numbers = [&](const json& a, const std::string& pointer) {
    if (!a.is_array() || !std::all_of(a.begin(), a.end(), [](const json& e) { return e.is_number(); }))
      fail(pointer, "expected an array of numbers");
    return a.get<std::vector<double>>();
  };
  text("q_title", data.q_title);
  text("q_axis", data.q_axis);
  text("v_title", data.v_title);
  text("v_axis", data.v_axis);
  text("energy_label", data.energy_label);
  text("t_unit", data.t_unit);
  texts("q_units", data.q_units, data.q.size());
  texts("v_units", data.v_units, data.v.size());
  if (f.contains("state_space")) {
    if (!f["state_space"].is_boolean()) fail(at + "state_space", "expected true or false");
    data.state_space = f["state_space"].get<bool>();
  }
  if (f.contains("impact_times")) data.impact_times = numbers(f["impact_times"], at + "impact_times");
  if (f.contains("converged_time") && !f["converged_time"].is_null()) {
    if (!f["converged_time"].is_number()) fail(at + "converged_time", "expected a number or null");
    data.converged_time = f["converged_time"].get<double>();
  }
  if (f.contains("output_matrix")) {
    const json& C = f["output_matrix"];
    if (!C.is_array()) fail(at + "output_matrix", "expected an array of rows");
    std::vector<std::vector<double>> rows;
    for (std::size_t i = 0; i < C.size(); ++i) {
      rows.push_back(numbers(C[i], at + "output_matrix/" + std::to_string(i)));
      if (rows.back().size() != data.q.size())
        fail(at + "output_matrix/" + std::to_string(i),
             std::to_string(rows.back().size()) + " entries for the CSV's " + std::to_string(data.q.size()) + " state columns");
    }
    if (!rows.empty()) add_outputs(data, rows);
  }
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
