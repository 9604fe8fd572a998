// The run report, as one JSON object (`moreau run --json`, the server's job report) and as readable text.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "moreau/core/run_summary.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& summary);
std::string report_text(const LagrangianScene& scene, const RunSummary& summary);

// With the contact diagnostics of a moreau-jean run (impacts, rest, smallest gap, position correction,
// the Lagrange-Dirichlet function W of Lemma 3); `contacts` may be null (then as above).
nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& summary, const ContactDiagnostics* contacts);
std::string report_text(const LagrangianScene& scene, const RunSummary& summary, const ContactDiagnostics* contacts);

// A Lur'e run: the absolute stability checks (Lemmas 1-2), W = 1/2 x^T P x, the outputs at rest.
nlohmann::json report_json(const LureScene& scene, const RunSummary& summary, const LureDiagnostics* diagnostics);
std::string report_text(const LureScene& scene, const RunSummary& summary, const LureDiagnostics* diagnostics);

// One sentence a student reads, for the top of a report (its "summary"): what happened (came to rest
// exactly at t = ..., reached the sliding band at ..., failed at ..., cancelled at ...), then whether the
// paper's result about the run's long-time behaviour (Theorem 4.3, Lemma 3, Lemma 2) covers it, and if
// not, the first hypothesis that fails in plain words ("the potential's force (gravity) is too strong for
// the controller's gain"); a result the steps rely on that fails comes first. Read off `report` (the
// report's JSON), so it says nothing its sections do not; `t_unit` is the scene's time unit ("" for none).
std::string plain_summary(const nlohmann::json& report, const std::string& t_unit);

}  // namespace moreau::scene
