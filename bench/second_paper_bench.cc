// Per-step cost of the second paper's schemes (Brogliato 2003), end to end through the integrators:
// moreau-jean on the bouncing ball (model and gap evaluation, prediction of the active set, the exact
// one-step complementarity problem, impacts and the W bookkeeping), moreau-jean on the first paper's
// manipulator (its controller rows in the one-step generalized equation) and the theta-method on a two-state
// relay Lur'e system (the one-step generalized equation, exact zeros, the storage function W). Each
// benchmark runs a whole simulation per iteration and reports ns_per_step (items_per_second is steps
// per second).
//
// "moving" variants stop before the system rests or slides, so every step does the full work (for the
// ball: free flight and the first impacts); the others run the scene's horizon, through the Zeno
// accumulation and the resting contact, or the sliding mode y == 0.
#include <benchmark/benchmark.h>

#include <optional>

#include "moreau/core/lure_integrator.h"
#include "moreau/core/moreau_jean_integrator.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "per_step.h"

namespace {

using namespace moreau;
using bench::RunScene;
using bench::SetPerStep;

nlohmann::json Doc(const char* file, double t_end) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/" + file);
  doc["integrator"]["t_end"] = t_end;
  return doc;
}

// ---- the bouncing ball (e = 0.5; impacts accumulate at t_inf = 1.355 s) ---------------------------------
void BallScene(benchmark::State& state, double t_end) {
  const scene::LagrangianScene sc = scene::load_scene(Doc("bouncing-ball-e0.5.json", t_end));
  std::int64_t steps = 0;
  for (auto _ : state) {
    const RunSummary s = scene::run_scene(sc, nullptr);
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}
void BM_BouncingBallJsonScene_moving(benchmark::State& state) { BallScene(state, 1.3); }
void BM_BouncingBallJsonScene_to_rest(benchmark::State& state) { BallScene(state, 3.0); }

// The same ball as a compiled C++ model.
struct Ball {
  static constexpr int kDof = 1;
  double m = 1.0, g = 9.81, e = 0.5;
  Controller<1> phi = Controller<1>::zero(1);
  int dof() const { return 1; }
  const Controller<1>& controller() const { return phi; }
  bool constant_mass() const { return true; }
  bool constant_terms() const { return true; }
  void mass(const Vec<1>&, Mat<1>& M) const { M(0, 0) = m; }
  void evaluate(double, const Vec<1>&, const Vec<1>&, LagrangianTerms<1>& out) const {
    out.M(0, 0) = m;
    out.C(0, 0) = 0.0;
    out.g(0) = m * g;
  }
  int num_constraints() const { return 1; }
  double restitution(int) const { return e; }
  template <class Rows>
  void constraints(const Vec<1>& q, Eigen::VectorXd& gap, Rows& H) const {
    gap(0) = q(0);
    H(0, 0) = 1.0;
  }
  bool has_potential() const { return true; }
  double potential(const Vec<1>& q) const { return m * g * q(0); }
  double evaluate_with_potential(double t, const Vec<1>& q, const Vec<1>& v, LagrangianTerms<1>& out) const {
    evaluate(t, q, v, out);
    return potential(q);
  }
};

void BallCompiled(benchmark::State& state, double t_end) {
  Ball model;
  MoreauJeanSettings settings;
  settings.h = 1e-3;
  settings.t_end = t_end;
  std::int64_t steps = 0;
  for (auto _ : state) {
    MoreauJeanIntegrator<Ball> integrator(model, settings);
    const RunSummary s = integrator.run(Vec<1>(1.0), Vec<1>(0.0));
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}
void BM_BouncingBallCompiled_moving(benchmark::State& state) { BallCompiled(state, 1.3); }
void BM_BouncingBallCompiled_to_rest(benchmark::State& state) { BallCompiled(state, 3.0); }

// ---- the manipulator of Adly, Brogliato and Le (2016), section 6, under moreau-jean --------------------
// scenes/manipulator.json with the Moreau-Jean scheme instead of (0.2). Without constraints every step's
// one-step problem is the controller's rows alone, solved as (6.5) by the sign patterns of (0.2)
// (moreau_jean_integrator.h); the position moves with V^{k+1}. position_update "standard"
// (q_{k+1} = q_k + h v_{k+1}, the update of Siconos' MoreauJeanOSI; without impacts "mdi" is the same).
// Moving: its first second, before it rests at t = 1.135; to rest: the 10 s of the scene.
void ManipulatorMoreauJean(benchmark::State& state, double t_end) {
  nlohmann::json doc = Doc("manipulator.json", t_end);
  doc["integrator"]["scheme"] = "moreau-jean";
  doc["integrator"]["position_update"] = "standard";
  RunScene(state, scene::load_scene(doc));
}
void BM_ManipulatorMoreauJeanJsonScene_moving(benchmark::State& state) { ManipulatorMoreauJean(state, 1.0); }
void BM_ManipulatorMoreauJeanJsonScene_to_rest(benchmark::State& state) { ManipulatorMoreauJean(state, 10.0); }

// ---- the damped relay (scenes/damped-relay.json) under moreau-jean: the discrete scheme of Siconos'
// MoreauJeanOSI for this system (docs/siconos-comparison.md). h = 1e-3 over the scene's 6 s (rest at
// 3.665), and h = 1e-4 over its first 3.6 s (moving).
void DampedRelayMoreauJean(benchmark::State& state, double h, double t_end) {
  nlohmann::json doc = Doc("damped-relay.json", t_end);
  doc["integrator"]["scheme"] = "moreau-jean";
  doc["integrator"]["h"] = h;
  RunScene(state, scene::load_scene(doc));
}
void BM_DampedRelayMoreauJeanJsonScene_to_rest(benchmark::State& state) { DampedRelayMoreauJean(state, 1e-3, 6.0); }
void BM_DampedRelayMoreauJeanJsonScene_moving(benchmark::State& state) { DampedRelayMoreauJean(state, 1e-4, 3.6); }

// ---- the two-state relay Lur'e system (y = x1 + 2 x2 slides from t = 0.218 s) ---------------------------
void RelayScene(benchmark::State& state, double t_end) {
  const scene::LureScene sc = scene::load_lure_scene(Doc("lure-relay-2state.json", t_end));
  std::int64_t steps = 0;
  for (auto _ : state) {
    const RunSummary s = scene::run_lure_scene(sc, nullptr, nullptr);
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}
void BM_RelayLure2JsonScene_moving(benchmark::State& state) { RelayScene(state, 0.2); }
void BM_RelayLure2JsonScene_sliding(benchmark::State& state) { RelayScene(state, 10.0); }

void RelayCompiled(benchmark::State& state, double t_end) {
  Mat<2> A;
  A << 0, 1, -2, -3;
  const Eigen::Matrix<double, 2, 1> B(0, 1);
  Eigen::Matrix<double, 1, 2> C;
  C << 1, 2;
  Mat<2> P;
  P << 7, 1, 1, 2;
  const std::vector<MonotoneGraph> graphs = {MonotoneGraph::relay(1.0)};
  LureSettings settings;
  settings.h = 1e-3;
  settings.t_end = t_end;
  std::int64_t steps = 0;
  for (auto _ : state) {
    LureIntegrator<2, 1> integrator(A, B, C, graphs, settings, P);
    const RunSummary s = integrator.run(Vec<2>(1.0, 0.0));
    steps = s.steps;
    benchmark::DoNotOptimize(s.q_final.data());
  }
  SetPerStep(state, steps);
}
void BM_RelayLure2Compiled_moving(benchmark::State& state) { RelayCompiled(state, 0.2); }
void BM_RelayLure2Compiled_sliding(benchmark::State& state) { RelayCompiled(state, 10.0); }

BENCHMARK(BM_BouncingBallJsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BouncingBallJsonScene_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BouncingBallCompiled_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BouncingBallCompiled_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ManipulatorMoreauJeanJsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_ManipulatorMoreauJeanJsonScene_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DampedRelayMoreauJeanJsonScene_to_rest)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DampedRelayMoreauJeanJsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RelayLure2JsonScene_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RelayLure2JsonScene_sliding)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RelayLure2Compiled_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RelayLure2Compiled_sliding)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
