// The figures of a scene's results: a trajectory read back from its CSV (trajectory_csv.h) and a study's
// table (study.h) as the plain series of render/'s figure builders, drawn by kind (figure_kind.h). The one
// bridge between scene/ and render/, used by `moreau run --figure`, `moreau plot`, `moreau study` and the
// server alike; render/ itself knows nothing of scenes, integrators or studies.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "moreau/render/figures.h"
#include "moreau/scene/simulation.h"
#include "moreau/analysis/figure_kind.h"
#include "moreau/analysis/study.h"
#include "moreau/scene/trajectory_csv.h"

namespace moreau::scene {

// The columns of a trajectory as the time series of the state figures.
render::TimeSeriesData time_series(TrajectoryColumns columns);

// Titles, axes, units and derived series for the kind of system `sim` is. The units are the scene's
// /units (Simulation::units): time's, and each coordinate's by its name, its velocity's per time unit;
// render/ puts them on the axes. A Lagrangian system keeps the
// defaults (positions q, velocities v, E = 1/2 <M v, v>). A Lur'e system (x' = A x - B y_L, y = C x,
// eq. 4 of Brogliato 2003) is drawn as its state x, the state's discrete rate dx/dt (the CSV's _dot
// columns), its output y = C x (computed here from the x columns) and the storage W = 1/2 x^T P x (the
// energy column: the scene's P or the certificate of positive realness; 1/2 |x|^2 without one), and its
// phase portrait is the state plane.
void label_for_system(render::TimeSeriesData& data, const Simulation& sim);

// What a trajectory CSV holds, for figures drawn from the file alone (`moreau plot traj.csv`, no --scene):
// written beside it as `<csv>-metadata.json`, the file name the W3C's "CSV on the Web" convention looks
// for. Its tableSchema names and describes each column (time, a position, a Lur'e state, the storage W,
// ...) with its unit; "moreau:figures" holds what label_for_system derives from the scene (titles, axes,
// units, the output matrix C of a Lur'e system, its switching line, the energy column's name), and the
// run's converged time and impact times. The mechanical energy E = T + V(q) needs V, so only a plot with
// --scene draws it.
std::string trajectory_metadata(const Simulation& sim, const std::string& csv_file_name, std::optional<double> converged_time,
                                const std::vector<double>& impact_times);

// The file beside `csv_path` that trajectory_metadata's text is written to.
std::string trajectory_metadata_path(const std::string& csv_path);

// Labels `data` (read from the CSV) as its metadata document says. Throws std::runtime_error naming
// `source` and the JSON pointer of a field that is missing, of the wrong type, or does not fit the CSV's
// columns.
void label_from_metadata(render::TimeSeriesData& data, std::string_view metadata_text, const std::string& source);

// One line per scheme of the study, in the order of `result.orders`, through its completed rows whose
// max error of q is positive (a log axis cannot show 0): h, that error, and the timed run's wall time.
std::vector<render::SchemeRuns> study_scheme_runs(const StudyResult& result);

// Figure `kind` of a trajectory: render/'s state, energy, step or phase figure of `data`. The one place a
// trajectory figure's kind chooses its drawing, for the command line and the server. Throws
// std::invalid_argument (render's validation) for data the figure cannot show.
render::Figure trajectory_figure(TrajectoryFigure kind, const render::TimeSeriesData& data, const render::FigureOptions& options = {});

// The work figure (error against run time) or the order figure (error against h, with the fitted slopes).
// The title defaults to "<scene>: max error of q against <reference>".
render::Figure study_figure(StudyFigure kind, const StudyResult& result, render::FigureOptions options = {});

// A figure as the bytes of a file: PNG (rasterized through OSMesa) or SVG text.
std::string encode_figure(const render::Figure& figure, FigureFormat format);

}  // namespace moreau::scene
