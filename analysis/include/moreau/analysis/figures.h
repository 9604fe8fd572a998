// The figures of a scene's results: a trajectory read back from its CSV (trajectory_csv.h) and a study's
// table (study.h) as the plain series of render/'s figure builders. The one bridge between scene/ and
// render/, used by `moreau plot`, `moreau study` and the server alike; render/ itself knows nothing of
// scenes, integrators or studies.
#pragma once

#include <string>
#include <vector>

#include "moreau/render/figures.h"
#include "moreau/scene/simulation.h"
#include "moreau/analysis/study.h"
#include "moreau/scene/trajectory_csv.h"

namespace moreau::scene {

// The columns of a trajectory as the time series of the state figures.
render::TimeSeriesData time_series(TrajectoryColumns columns);

// Titles, axes and derived series for the kind of system `sim` is. A Lagrangian system keeps the
// defaults (positions q, velocities v, E = 1/2 <M v, v>). A Lur'e system (x' = A x - B y_L, y = C x,
// eq. 4 of Brogliato 2003) is drawn as its state x, the state's discrete rate dx/dt (the CSV's _dot
// columns), its output y = C x (computed here from the x columns) and the storage W = 1/2 x^T P x (the
// energy column: the scene's P or the certificate of positive realness; 1/2 |x|^2 without one), and its
// phase portrait is the state plane.
void label_for_system(render::TimeSeriesData& data, const Simulation& sim);

// One line per scheme of the study, in the order of `result.orders`, through its completed rows whose
// max error of q is positive (a log axis cannot show 0): h, that error, and the timed run's wall time.
std::vector<render::SchemeRuns> study_scheme_runs(const StudyResult& result);

// "work" (error against run time) or "order" (error against h, with the fitted slopes). The title
// defaults to "<scene>: max error of q against <reference>". Throws std::invalid_argument for another
// kind.
render::Figure study_figure(const std::string& kind, const StudyResult& result, render::FigureOptions options = {});

}  // namespace moreau::scene
