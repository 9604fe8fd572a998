// Per-step cost of the ABL scheme, end to end through the integrator (model evaluation, step rule,
// one-step solver, state update, energy and convergence bookkeeping). Each benchmark runs a whole
// simulation per iteration and reports time per step (items_per_second is steps per second).
//
// The "moving" variants stop before the system reaches rest, so every step does the full work; the
// "to_rest" variants run the paper's 10 s, most of it at rest, where the y = 0 closed form makes a step
// cheaper.
#include <benchmark/benchmark.h>

#include "moreau/core/abl_integrator.h"
#include "moreau/core/models/manipulator.h"
#include "moreau/core/models/oscillator1.h"
#include "moreau/scene/scene.h"
#include "per_step.h"

namespace {

using namespace moreau;
using bench::RunScene;
using bench::SetPerStep;

scene::LagrangianScene LoadScene(const char* file, double t_end) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + file);
  doc["integrator"]["t_end"] = t_end;
  return scene::load_scene(doc);
}

void ManipulatorScene(benchmark::State& state, double t_end) {
  const scene::LagrangianScene sc = LoadScene("manipulator.json", t_end);
  RunScene(state, sc);
}
void BM_ManipulatorJsonScene_moving(benchmark::State& state) { ManipulatorScene(state, 1.0); }
void BM_ManipulatorJsonScene_to_rest(benchmark::State& state) { ManipulatorScene(state, 10.0); }

void ManipulatorCompiled(benchmark::State& state, double t_end) {
  models::Manipulator model;
  AblSettings settings;
  settings.h = 1e-3;
  settings.t_end = t_end;
  std::int64_t steps = 0;
  for (auto _ : state) {
    AblIntegrator<models::Manipulator> integrator(model, settings);
    const RunSummary s = integrator.run(Vec<2>(3.0, -1.0), Vec<2>(-1.0, 1.0));
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}
void BM_ManipulatorCompiled_moving(benchmark::State& state) { ManipulatorCompiled(state, 1.0); }
void BM_ManipulatorCompiled_to_rest(benchmark::State& state) { ManipulatorCompiled(state, 10.0); }

// The 1-DOF damped relay m x'' = -c x' - a Sign(x') (m = 2, c = 0.5, a = 1); it stops at t* = 3.665 s.
void BM_DampedRelayCompiled_moving(benchmark::State& state) {
  models::Oscillator1 model(2.0, 0.0, 0.0, 0.5, 1.0);
  AblSettings settings;
  settings.h = 1e-4;
  settings.t_end = 3.6;
  std::int64_t steps = 0;
  for (auto _ : state) {
    AblIntegrator<models::Oscillator1> integrator(model, settings);
    const RunSummary s = integrator.run(Vec<1>(0.0), Vec<1>(3.0));
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}

void BM_DampedRelayJsonScene_moving(benchmark::State& state) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json");
  doc["integrator"]["t_end"] = 3.6;
  doc["integrator"]["h"] = 1e-4;
  const scene::LagrangianScene sc = scene::load_scene(doc);
  RunScene(state, sc);
}

// n = 64: the friction bar (scenes/friction-bar.json: an elastic bar as 64 finite elements with Coulomb
// friction at every node; M constant and tridiagonal, so the step uses banded LU), until t = 0.3, before
// it comes to rest at t = 0.379.
// The dense scheme (abl_integrator.h), banded or dense LU: the scene without its large ABL system, which
// run_scene would otherwise choose (_large below).
void FrictionBar64(benchmark::State& state, bool banded) {
  scene::LagrangianScene sc = LoadScene("friction-bar.json", 0.3);
  auto compiled = std::make_shared<scene::CompiledLagrangian>(*sc.compiled);
  compiled->large_abl = nullptr;
  sc.compiled = compiled;
  if (!banded) sc.settings.bandwidth = -1;  // the dense LU every scene used before
  RunScene(state, sc);
}
void BM_FrictionBar64JsonScene_moving(benchmark::State& state) { FrictionBar64(state, true); }
void BM_FrictionBar64JsonScene_moving_dense(benchmark::State& state) { FrictionBar64(state, false); }
// The same scene as run_scene runs it: on the large ABL path (large_abl_integrator.h), the sparse
// P = M/h + W formed once, grad V from its tape, the inclusion by pivoting over a sparse LDL^T of the
// moving block.
void BM_FrictionBar64JsonScene_moving_large(benchmark::State& state) {
  const scene::LagrangianScene sc = LoadScene("friction-bar.json", 0.3);
  if (!scene::uses_large_abl_path(sc)) {
    state.SkipWithError("friction-bar.json does not run on the large ABL path");
    return;
  }
  RunScene(state, sc);
}

BENCHMARK(BM_ManipulatorJsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ManipulatorJsonScene_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ManipulatorCompiled_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ManipulatorCompiled_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DampedRelayCompiled_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DampedRelayJsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrictionBar64JsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrictionBar64JsonScene_moving_dense)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrictionBar64JsonScene_moving_large)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
