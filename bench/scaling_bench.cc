// Systems at scale (docs/scaling.md): the stack of N balls at rest and dropped, the gapped
// Newton's cradle, from N = 2 to 8192, the granular column (nonlinear gaps) from N = 4 to 3333, and the
// friction bar and chain (the abl scheme, large ABL path) from N = 65 to 10000, each a scene compiled as `moreau run`
// compiles it (the scenes of scripts/make-contact-scene.py, tests/support/contact_scenes.h) and run by run_scene. `dense` variants run the
// same scene on the dense Moreau-Jean step (N <= 64): the two sides of the crossover kLargeContactFromDof.
//
//   build/bench/scaling_bench --benchmark_filter='Stack|Cradle|Column|Friction' --benchmark_min_time=0.2
//
// Counters: ns_per_step (the run's wall time over its steps), and for the dropped stack and the column the median and
// worst single step (timed from one sample to the next, every step sampled; each step's fastest of 7
// rounds) and their ratio.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "moreau/core/large_abl_integrator.h"
#include "moreau/scene/scene.h"
#include "per_step.h"
#include "support/contact_scenes.h"
#include "support/friction_bar_scene.h"

namespace {

using moreau::RunObserver;
using moreau::RunStatus;
using moreau::RunSummary;
using moreau::Sample;
namespace scene = moreau::scene;

using moreau::test_support::column_scene;
using moreau::test_support::cradle_scene;
using moreau::test_support::stack_scene;

// The scene on the dense step: the same compile without the large-contact system.
scene::LagrangianScene dense(scene::LagrangianScene sc) {
  auto c = std::make_shared<scene::CompiledLagrangian>(*sc.compiled);
  c->large_contacts = nullptr;
  sc.compiled = c;
  return sc;
}

void BM_StackAtRest(benchmark::State& state) {
  const scene::LagrangianScene sc = scene::load_scene(stack_scene(static_cast<int>(state.range(0)), 0.0, 0.2));
  moreau::bench::RunScene(state, sc);
}
void BM_StackAtRest_dense(benchmark::State& state) {
  const scene::LagrangianScene sc = dense(scene::load_scene(stack_scene(static_cast<int>(state.range(0)), 0.0, 0.2)));
  moreau::bench::RunScene(state, sc);
}
void BM_GappedCradle(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const scene::LagrangianScene sc = scene::load_scene(cradle_scene(n, 0.01, 0.01 * (n - 1) + 0.05));
  moreau::bench::RunScene(state, sc);
}
void BM_GappedCradle_dense(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const scene::LagrangianScene sc = dense(scene::load_scene(cradle_scene(n, 0.01, 0.01 * (n - 1) + 0.05)));
  moreau::bench::RunScene(state, sc);
}

// Every step's wall time, from one sample to the next (output every step).
struct StepClock : RunObserver {
  std::vector<double> seconds;
  std::chrono::steady_clock::time_point last = std::chrono::steady_clock::now();
  void on_sample(const Sample&) override {
    const auto now = std::chrono::steady_clock::now();
    seconds.push_back(std::chrono::duration<double>(now - last).count());
    last = now;
  }
};

// Runs the scene each iteration with every step timed and sets the counters: ns_per_step, and the median
// and worst single step and their ratio. A step's time is its fastest over the rounds (the run is
// deterministic: the same step does the same work each round): the cost of the step itself, without the
// preemptions of a shared machine, which a single round's slowest step shows instead.
void RunTimingEveryStep(benchmark::State& state, const scene::LagrangianScene& sc) {
  std::int64_t steps = 0;
  std::vector<double> fastest;
  for (auto _ : state) {
    StepClock clock;
    clock.seconds.reserve(1000);
    clock.last = std::chrono::steady_clock::now();
    const RunSummary s = scene::run_scene(sc, &clock);
    steps = s.steps;
    if (s.status != RunStatus::kCompleted) state.SkipWithError(s.message.c_str());
    if (fastest.empty()) fastest.assign(clock.seconds.size(), 1e300);
    for (std::size_t k = 1; k < clock.seconds.size() && k < fastest.size(); ++k)  // the first is the initial sample
      fastest[k] = std::min(fastest[k], clock.seconds[k]);
  }
  std::vector<double> t(fastest.begin() + 1, fastest.end());
  std::sort(t.begin(), t.end());
  const double median = t[t.size() / 2], worst = t.back();
  moreau::bench::SetPerStep(state, steps);
  state.counters["median_step_us"] = median * 1e6;
  state.counters["worst_step_us"] = worst * 1e6;
  state.counters["worst_over_median"] = worst / median;
}

// A stack dropped from 1 mm gaps: impacts travel up and down it, contacts close and open, until it rests.
void BM_StackDropped(benchmark::State& state) {
  RunTimingEveryStep(state, scene::load_scene(stack_scene(static_cast<int>(state.range(0)), 1e-3, 0.5)));
}

// A granular column: N balls dropped into a tube (nonlinear gaps between balls), landing, bouncing off
// each other and the walls, settling into a zigzag over 1 s (2N coordinates, 3N contacts).
void BM_GranularColumn(benchmark::State& state) {
  RunTimingEveryStep(state, scene::load_scene(column_scene(static_cast<int>(state.range(0)), 1e-3, 1.0)));
}
void BM_GranularColumn_dense(benchmark::State& state) {
  const scene::LagrangianScene sc = dense(scene::load_scene(column_scene(static_cast<int>(state.range(0)), 1e-3, 1.0)));
  moreau::bench::RunScene(state, sc);
}

// The friction bar (tests/support/friction_bar_scene.h, scripts/make-friction-bar.py): an elastic bar of N
// finite elements with Coulomb friction at every node, M tridiagonal, on the large ABL path beyond 64
// nodes (the abl scheme). Run to t = 0.3 s, moving (the bar of 64 rests at 0.379 s), and with pendulums at
// every node (a nonlinear grad V from its terms) over 4 s: sliding, sticking node by node, resting.
void BM_FrictionBar(benchmark::State& state) {
  RunTimingEveryStep(state, scene::load_scene(moreau::test_support::friction_bar_scene(static_cast<int>(state.range(0)), 0.3)));
}
// Within the dense limits the bar compiles for both steps: the large ABL path (run directly) and the
// dense scheme (run_scene without the large system): the two sides of the crossover kLargeAblFromDof.
void BM_FrictionBarSmall(benchmark::State& state) {
  const scene::LagrangianScene sc = scene::load_scene(moreau::test_support::friction_bar_scene(static_cast<int>(state.range(0)), 0.3));
  const Eigen::Map<const Eigen::VectorXd> q0(sc.q0.data(), sc.n), v0(sc.v0.data(), sc.n);
  std::int64_t steps = 0;
  for (auto _ : state) {
    moreau::LargeAblIntegrator integrator(*sc.compiled->large_abl, sc.settings.grid());
    const RunSummary s = integrator.run(q0, v0);
    steps = s.steps;
    if (s.status != RunStatus::kCompleted) state.SkipWithError(s.message.c_str());
  }
  moreau::bench::SetPerStep(state, steps);
}
void BM_FrictionBarSmall_dense(benchmark::State& state) {
  scene::LagrangianScene sc = scene::load_scene(moreau::test_support::friction_bar_scene(static_cast<int>(state.range(0)), 0.3));
  auto c = std::make_shared<scene::CompiledLagrangian>(*sc.compiled);
  c->large_abl = nullptr;
  sc.compiled = c;
  moreau::bench::RunScene(state, sc);
}
void BM_FrictionChainToRest(benchmark::State& state) {
  RunTimingEveryStep(state, scene::load_scene(moreau::test_support::friction_bar_scene(static_cast<int>(state.range(0)), 4.0, 0.05)));
}

}  // namespace

BENCHMARK(BM_StackAtRest)->RangeMultiplier(2)->Range(2, 8192)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StackAtRest_dense)->RangeMultiplier(2)->Range(2, 64)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_StackDropped)->RangeMultiplier(4)->Range(8, 8192)->Iterations(7)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GranularColumn)
    ->Arg(4)
    ->Arg(8)
    ->Arg(16)
    ->Arg(64)
    ->Arg(256)
    ->Arg(1024)
    ->Arg(3333)
    ->Iterations(3)
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GranularColumn_dense)->Arg(4)->Arg(8)->Arg(16)->Iterations(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GappedCradle)->Arg(2)->Arg(8)->Arg(16)->Arg(64)->Arg(256)->Arg(1024)->Arg(4096)->Arg(8192)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GappedCradle_dense)->RangeMultiplier(2)->Range(2, 64)->Unit(benchmark::kMillisecond);

BENCHMARK(BM_FrictionBar)->Arg(65)->Arg(256)->Arg(1024)->Arg(4096)->Arg(10000)->Iterations(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FrictionBarSmall)->Arg(2)->Arg(4)->Arg(8)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrictionBarSmall_dense)->Arg(2)->Arg(4)->Arg(8)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FrictionChainToRest)->Arg(65)->Arg(256)->Arg(1024)->Arg(4096)->Iterations(3)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
