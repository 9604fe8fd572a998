// The run report, as one JSON object (`moreau run --json`, the server's job report) and as readable text.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "moreau/core/run_summary.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& summary);
std::string report_text(const LagrangianScene& scene, const RunSummary& summary);

}  // namespace moreau::scene
