// The figures of a study (scene/study.h), shared by `moreau study` and POST /v1/studies: the bridge
// between the study's table and render/'s plain-data figure builders.
#pragma once

#include <string>
#include <vector>

#include "moreau/render/figures.h"
#include "moreau/scene/study.h"

namespace moreau::render {

// One line per scheme of the study, in the order of `result.orders`, through its completed rows whose
// max error of q is positive (a log axis cannot show 0): h, that error, and the timed run's wall time.
std::vector<SchemeRuns> study_scheme_runs(const scene::StudyResult& result);

// "work" (error against run time) or "order" (error against h, with the fitted slopes). The title
// defaults to "<scene>: max error of q against <reference>". Throws std::invalid_argument for another
// kind.
Figure study_figure(const std::string& kind, const scene::StudyResult& result, FigureOptions options = {});

}  // namespace moreau::render
