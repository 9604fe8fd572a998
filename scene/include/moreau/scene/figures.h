// The figures of a scene's results: a trajectory read back from its CSV (trajectory_csv.h) and a study's
// table (study.h) as the plain series of render/'s figure builders. The one bridge between scene/ and
// render/, used by `moreau plot`, `moreau study` and the server alike; render/ itself knows nothing of
// scenes, integrators or studies.
#pragma once

#include <string>
#include <vector>

#include "moreau/render/figures.h"
#include "moreau/scene/study.h"
#include "moreau/scene/trajectory_csv.h"

namespace moreau::scene {

// The columns of a trajectory as the time series of the state figures.
render::TimeSeriesData time_series(TrajectoryColumns columns);

// One line per scheme of the study, in the order of `result.orders`, through its completed rows whose
// max error of q is positive (a log axis cannot show 0): h, that error, and the timed run's wall time.
std::vector<render::SchemeRuns> study_scheme_runs(const StudyResult& result);

// "work" (error against run time) or "order" (error against h, with the fitted slopes). The title
// defaults to "<scene>: max error of q against <reference>". Throws std::invalid_argument for another
// kind.
render::Figure study_figure(const std::string& kind, const StudyResult& result, render::FigureOptions options = {});

}  // namespace moreau::scene
