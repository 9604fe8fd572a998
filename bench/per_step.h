// Per-step timing for the benchmarks that run whole simulations (core_bench, robot_bench): each
// iteration is one run, and the reported rate is steps per second, with ns_per_step beside it.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdint>

#include "moreau/scene/scene.h"

namespace moreau::bench {

inline void SetPerStep(benchmark::State& state, std::int64_t steps_per_run) {
  state.SetItemsProcessed(state.iterations() * steps_per_run);
  state.counters["ns_per_step"] =
      benchmark::Counter(static_cast<double>(state.iterations() * steps_per_run), benchmark::Counter::kIsRate | benchmark::Counter::kInvert,
                         benchmark::Counter::kIs1000);
}

// Runs a compiled scene once per iteration and reports time per step; a run that does not complete
// marks the benchmark as an error instead of timing a failure.
inline void RunScene(benchmark::State& state, const scene::LagrangianScene& sc) {
  std::int64_t steps = 0;
  for (auto _ : state) {
    const RunSummary s = scene::run_scene(sc, nullptr);
    steps = s.steps;
    if (s.status != RunStatus::kCompleted) state.SkipWithError(s.message.c_str());
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}

}  // namespace moreau::bench
