// Robots from URDF: the per-step cost of scheme (0.2) on the 7-joint KUKA iiwa with the paper's
// controller on every joint (scenes/iiwa14-controller.json at a fixed h = 1e-3) and of the Moreau-Jean
// scheme on the same arm with joint limits and friction (scenes/iiwa14-joint-limit.json), on n-link planar chains
// (scripts/make-chain-urdf.py, n = 2 .. 64) and the rigid-body terms alone (M, C, G: rigid_body.h), and
// the time to load and compile a 64-link URDF scene. docs/robots.md has the figures and the command.
#include <benchmark/benchmark.h>

#include <fstream>
#include <sstream>

#include "moreau/core/rigid_body.h"
#include "moreau/scene/scene.h"
#include "per_step.h"
#include "moreau/scene/urdf.h"
#include "support/chain_scene.h"

namespace {

using namespace moreau;
using bench::RunScene;
using test_support::chain_scene;
using test_support::chain_urdf_text;

// The arm of iiwa14-controller.json at a fixed h = 1e-3 until t = 0.15, before it comes to rest (0.19 s).
void BM_Iiwa14Controller_moving(benchmark::State& state) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-controller.json");
  doc["integrator"]["step_rule"] = "fixed";
  doc["integrator"]["t_end"] = 0.15;
  RunScene(state, scene::load_scene(doc));
}

// The same arm under the Moreau-Jean scheme (scenes/iiwa14-joint-limit.json: 14 joint limits with
// Newton impacts, viscous and Coulomb joint friction): its first 0.6 s, the fall, the impacts on joint 2's
// and joint 4's limits and the closing contact. The one-step problem has a row per friction term and per
// limit, most of them inactive or sliding on every step.
void BM_Iiwa14JointLimit_impacts(benchmark::State& state) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-joint-limit.json");
  doc["integrator"]["t_end"] = 0.6;
  RunScene(state, scene::load_scene(doc));
}

// scenes/iiwa14-tracking.json: the arm tracking its joint-space reference with the implicit digital
// controller at 1 kHz, the plant by (0.2) at h = 1e-4 (10 plant steps per controller sample), 10% model
// error, over its first second (10^4 plant steps, 10^3 samples): ns_per_step is per plant step, and a
// controller sample costs its step plus the nominal model and the one-step inclusion in sigma.
void BM_Iiwa14Tracking_1kHz(benchmark::State& state) {
  nlohmann::json doc = scene::read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-tracking.json");
  doc["integrator"]["t_end"] = 1.0;
  RunScene(state, scene::load_scene(doc));
}

void BM_ChainStep(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  RunScene(state, scene::load_scene(chain_scene(n, 0.1)));
}

// M, C and G alone (rigid_body_terms), the model part of a step.
void BM_RigidBodyTerms(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  scene::UrdfRobot robot = n == 7 ? scene::read_urdf([] {
    std::ifstream in(std::string(MOREAU_SOURCE_DIR) + "/scenes/robots/kuka-iiwa14.urdf");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }())
                                  : scene::read_urdf(chain_urdf_text(n));
  RigidBodyData data(robot.model);
  Eigen::VectorXd q = Eigen::VectorXd::LinSpaced(n, -1.0, 1.0), v = Eigen::VectorXd::LinSpaced(n, 0.5, -0.5), G(n);
  Eigen::MatrixXd M(n, n), C(n, n);
  for (auto _ : state) {
    rigid_body_terms(robot.model, data, q.data(), v.data(), M, C, G);
    benchmark::DoNotOptimize(M.data());
    benchmark::DoNotOptimize(C.data());
    q(0) += 1e-9;
  }
}

// Parse the 64-link URDF (in the module) and compile the scene: what `moreau run` does before stepping.
void BM_LoadChain64Scene(benchmark::State& state) {
  const nlohmann::json doc = chain_scene(64, 0.1);
  for (auto _ : state) {
    const scene::LagrangianScene sc = scene::load_scene(doc);
    benchmark::DoNotOptimize(sc.n);
  }
}

BENCHMARK(BM_Iiwa14Controller_moving)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Iiwa14JointLimit_impacts)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Iiwa14Tracking_1kHz)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ChainStep)->Arg(2)->Arg(7)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_RigidBodyTerms)->Arg(2)->Arg(7)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kNanosecond);
BENCHMARK(BM_LoadChain64Scene)->Unit(benchmark::kMillisecond);

}  // namespace
BENCHMARK_MAIN();
