#include "moreau/render/study_figures.h"

#include <stdexcept>

namespace moreau::render {

std::vector<SchemeRuns> study_scheme_runs(const scene::StudyResult& result) {
  std::vector<SchemeRuns> runs;
  for (const auto& order : result.orders) {
    SchemeRuns r;
    r.scheme = scene::scheme_name(order.scheme);
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

Figure study_figure(const std::string& kind, const scene::StudyResult& result, FigureOptions options) {
  if (options.title.empty()) options.title = result.scene + ": max error of q against " + result.reference;
  const auto runs = study_scheme_runs(result);
  if (kind == "work") return work_figure(runs, options);
  if (kind == "order") return order_figure(runs, options);
  throw std::invalid_argument("unknown study figure '" + kind + "' (expected work or order)");
}

}  // namespace moreau::render
