// Robustness campaigns: the cost of one sample of the paper's manipulator (t_end = 3, h = 1e-3) against
// the integration alone, so that the per-sample overhead (applying the sample's values, compiling the
// scene, the report and the record) can be read off: docs/campaigns.md, "Speed".
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>
#include <vector>

#include "moreau/analysis/campaign.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"

namespace {

using json = nlohmann::json;

// The samples every benchmark below cycles through (each sample's integration costs differently: the
// overhead is a difference over the same samples).
constexpr std::int64_t kSamples = 1024;

moreau::scene::CampaignSpec manipulator_spec(bool full_report = true) {
  json spec = moreau::scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/campaigns/manipulator-robust.json");
  json scene = moreau::scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator-fig6.4.json");
  scene["integrator"]["t_end"] = 3.0;
  spec["scene"] = scene;
  spec["samples"] = 1 << 20;
  spec["full_report"] = full_report;
  return moreau::scene::CampaignSpec::from_json(spec, "");
}

// The first kSamples samples of `spec`, each compiled in full from its document, observed at every step
// as a campaign observes them.
std::vector<moreau::scene::Simulation> compiled_samples(const moreau::scene::CampaignSpec& spec) {
  const moreau::scene::CampaignDesign design(spec);
  std::vector<moreau::scene::Simulation> sims;
  for (std::int64_t i = 0; i < kSamples; ++i) {
    json doc = spec.scene;
    const auto values = design.values(i);
    for (std::size_t k = 0; k < values.size(); ++k) doc[json::json_pointer(spec.inputs[k].path)] = values[k];
    sims.push_back(moreau::scene::Simulation::from_json(doc).with_limits(moreau::scene::RunLimits{std::nullopt, 1}));
  }
  return sims;
}

// One whole sample: its values, the scene compiled with them, the run, the report and the record.
void BM_CampaignSample_manipulator_T3(benchmark::State& state) {
  const auto spec = manipulator_spec();
  const moreau::scene::CampaignDesign design(spec);
  std::int64_t i = 0;
  moreau::scene::CampaignSampleRunner runner(spec, design);
  for (auto _ : state) benchmark::DoNotOptimize(runner.run(i++ % kSamples).dump());
  state.counters["samples_per_second"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CampaignSample_manipulator_T3)->Unit(benchmark::kMicrosecond);

// The same with records of the outcomes alone (full_report false): what campaigns of millions write.
void BM_CampaignSampleOutcomes_manipulator_T3(benchmark::State& state) {
  const auto spec = manipulator_spec(false);
  const moreau::scene::CampaignDesign design(spec);
  std::int64_t i = 0;
  moreau::scene::CampaignSampleRunner runner(spec, design);
  for (auto _ : state) benchmark::DoNotOptimize(runner.run(i++ % kSamples).dump());
  state.counters["samples_per_second"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CampaignSampleOutcomes_manipulator_T3)->Unit(benchmark::kMicrosecond);

// The integration alone (the scene compiled once, outside the loop, every state seen as in a sample).
void BM_CampaignIntegrationOnly_manipulator_T3(benchmark::State& state) {
  const auto spec = manipulator_spec();
  const auto sim = moreau::scene::Simulation::from_json(spec.scene).with_limits(moreau::scene::RunLimits{std::nullopt, 1});
  struct Nothing : moreau::RunObserver {
    void on_sample(const moreau::Sample&) override {}
  } observer;
  moreau::scene::RunDiagnostics diagnostics;
  for (auto _ : state) benchmark::DoNotOptimize(sim.run(&observer, &diagnostics).steps);
}
BENCHMARK(BM_CampaignIntegrationOnly_manipulator_T3)->Unit(benchmark::kMicrosecond);

// The integration alone over the same samples as BM_CampaignSample (each sample's scene compiled before
// the loop): the sample's time less this one is the per-sample overhead.
void BM_CampaignIntegrationOfTheSamples_manipulator_T3(benchmark::State& state) {
  const auto spec = manipulator_spec();
  const std::vector<moreau::scene::Simulation> sims = compiled_samples(spec);
  struct Nothing : moreau::RunObserver {
    void on_sample(const moreau::Sample&) override {}
  } observer;
  moreau::scene::RunDiagnostics diagnostics;
  std::size_t i = 0;
  for (auto _ : state) benchmark::DoNotOptimize(sims[i++ % sims.size()].run(&observer, &diagnostics).steps);
}
BENCHMARK(BM_CampaignIntegrationOfTheSamples_manipulator_T3)->Unit(benchmark::kMicrosecond);

// The per-sample overhead as a fraction of the integration, measured in one loop: each iteration runs
// sample i through the runner (outcome records, as BM_CampaignSampleOutcomes) and the integration alone
// of the same sample compiled before the loop, alternating which goes first, and times both. The two
// share the machine's state from one iteration to the next, so the ratio does not move with the load of
// a shared machine the way the difference of two separate benchmarks does.
void BM_CampaignSampleOverhead_manipulator_T3(benchmark::State& state) {
  const auto spec = manipulator_spec(false);
  const moreau::scene::CampaignDesign design(spec);
  moreau::scene::CampaignSampleRunner runner(spec, design);
  const std::vector<moreau::scene::Simulation> sims = compiled_samples(spec);
  struct Nothing : moreau::RunObserver {
    void on_sample(const moreau::Sample&) override {}
  } observer;
  moreau::scene::RunDiagnostics diagnostics;
  using Clock = std::chrono::steady_clock;
  double sample_seconds = 0.0, integration_seconds = 0.0;
  std::int64_t i = 0;
  for (auto _ : state) {
    const std::int64_t k = i % kSamples;
    auto run_sample = [&] {
      const auto t0 = Clock::now();
      benchmark::DoNotOptimize(runner.run(k).dump());
      sample_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    auto run_integration = [&] {
      const auto t0 = Clock::now();
      benchmark::DoNotOptimize(sims[static_cast<std::size_t>(k)].run(&observer, &diagnostics).steps);
      integration_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
    };
    if (i++ % 2 == 0) {
      run_sample();
      run_integration();
    } else {
      run_integration();
      run_sample();
    }
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["sample_us"] = 1e6 * sample_seconds / n;
  state.counters["integration_us"] = 1e6 * integration_seconds / n;
  state.counters["overhead_percent"] = 100.0 * (sample_seconds - integration_seconds) / integration_seconds;
}
BENCHMARK(BM_CampaignSampleOverhead_manipulator_T3)->Unit(benchmark::kMicrosecond);

// Compiling the scene alone (what each sample does before it runs).
void BM_CampaignCompileOnly_manipulator(benchmark::State& state) {
  const auto spec = manipulator_spec();
  for (auto _ : state) benchmark::DoNotOptimize(moreau::scene::Simulation::from_json(spec.scene).dof());
}
BENCHMARK(BM_CampaignCompileOnly_manipulator)->Unit(benchmark::kMicrosecond);

}  // namespace
BENCHMARK_MAIN();
