// Fuzzes the scene format: any bytes must load as a scene or fail with a SceneError naming a field,
// never crash or hang; a scene that loads and takes at most a few thousand steps is also run, and its
// report must not hold NaN unless the run says it failed.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "moreau/scene/simulation.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace moreau;
  const nlohmann::json doc = nlohmann::json::parse(data, data + size, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  try {
    const scene::Simulation sim = scene::Simulation::from_json(doc);
    if (sim.planned_steps() > 2000) return 0;
    const RunSummary s = sim.run(nullptr);
    if (s.status == RunStatus::kCompleted) {
      for (double v : s.q_final)
        if (!std::isfinite(v)) __builtin_trap();
      for (double v : s.v_final)
        if (!std::isfinite(v)) __builtin_trap();
    }
    (void)sim.report_json(s).dump();
  } catch (const scene::SceneError&) {
  }
  return 0;
}
