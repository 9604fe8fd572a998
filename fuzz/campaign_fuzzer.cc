// Fuzzes campaign specs (docs/campaigns.md): any JSON must be accepted as a spec or refused with a
// SceneError naming the field, never crash or hang. A spec that is accepted has its first samples drawn
// (each value must be finite where its distribution is numeric); when its scene is small (at most 2000
// steps a run) a few samples are run through the same runner as `moreau campaign` and summarized.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "moreau/analysis/campaign.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace moreau::scene;
  const nlohmann::json doc = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) return 0;
  // A scene named by a path would be read from the file system: not what this target explores.
  if (doc.contains("scene") && doc["scene"].is_string()) return 0;
  try {
    const CampaignSpec spec = CampaignSpec::from_json(doc, "");
    const CampaignDesign design(spec);
    const std::int64_t n = std::min<std::int64_t>(spec.samples, 4);
    for (std::int64_t i = 0; i < n; ++i) {
      const std::vector<nlohmann::json> values = design.values(i);
      if (values.size() != spec.inputs.size()) __builtin_trap();
      for (std::size_t k = 0; k < values.size(); ++k)
        if (values[k].is_number() && !std::isfinite(values[k].get<double>())) __builtin_trap();
    }
    if (Simulation::from_json(spec.scene).planned_steps() > 2000) return 0;
    CampaignSampleRunner runner(spec, design, std::int64_t{2000});
    std::vector<nlohmann::json> records;
    for (std::int64_t i = 0; i < n; ++i) records.push_back(runner.run(i));
    if (n == spec.samples) (void)format_campaign_summary(summarize_campaign(spec, records));
  } catch (const SceneError&) {
  }
  return 0;
}
