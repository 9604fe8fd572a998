#include "moreau/scene/figures.h"

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
  return data;
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

render::Figure study_figure(const std::string& kind, const StudyResult& result, render::FigureOptions options) {
  if (options.title.empty()) options.title = result.scene + ": max error of q against " + result.reference;
  const auto runs = study_scheme_runs(result);
  if (kind == "work") return render::work_figure(runs, options);
  if (kind == "order") return render::order_figure(runs, options);
  throw std::invalid_argument("unknown study figure '" + kind + "' (expected work or order)");
}

}  // namespace moreau::scene
