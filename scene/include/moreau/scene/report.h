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

}  // namespace moreau::scene
