// Scenes on the large ABL path (large_abl_integrator.h): the friction bar and a Frenkel-Kontorova chain
// compiled from the scene format, beyond the dense limits and within them. Checked against the dense
// scheme (abl_integrator.h, an independent implementation of (0.2)) step by step, against M and grad V
// written in closed form, against Theorem 4.3 (rest exactly 0.0), and every requirement of the path
// refused with the field named.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "moreau/core/large_abl_integrator.h"
#include "moreau/scene/report.h"
#include "moreau/scene/scene.h"
#include "support/friction_bar_scene.h"

namespace moreau::scene {
namespace {

using nlohmann::json;
using test_support::friction_bar_scene;

struct Trajectory : RunObserver {
  std::vector<std::vector<double>> q, v;
  void on_sample(const Sample& s) override {
    q.emplace_back(s.q, s.q + s.n);
    v.emplace_back(s.v, s.v + s.n);
  }
};

// d/du_i of k/2 sum (u_i - u_{i-1})^2 + c0 sum (1 - cos u_i), u_0 = 0: the chain's gradient by hand.
double ChainGradient(const std::vector<double>& u, int i, double k, double c0) {
  const int n = static_cast<int>(u.size());
  double g = k * (u[static_cast<std::size_t>(i)] - (i > 0 ? u[static_cast<std::size_t>(i - 1)] : 0.0)) +
             c0 * std::sin(u[static_cast<std::size_t>(i)]);
  if (i + 1 < n) g -= k * (u[static_cast<std::size_t>(i + 1)] - u[static_cast<std::size_t>(i)]);
  return g;
}

TEST(LargeAblScene, WithinTheDenseLimitsItAgreesWithTheDenseSchemeStepByStep) {
  // The chain of 48 nodes with pendulums compiles for both: the dense scheme (run_scene on this size) and
  // the large ABL system (CompiledLagrangian::large_abl, built from the dense M and g). Both run to rest.
  for (double pendulum : {0.0, 0.05}) {
    const LagrangianScene sc = load_scene(friction_bar_scene(48, 4.0, pendulum));
    ASSERT_TRUE(sc.compiled->dense);
    ASSERT_TRUE(sc.compiled->large_abl);
    auto dense_compiled = std::make_shared<CompiledLagrangian>(*sc.compiled);
    dense_compiled->large_abl = nullptr;
    LagrangianScene dense = sc;
    dense.compiled = dense_compiled;
    ASSERT_FALSE(uses_large_abl_path(dense));
    Trajectory a, b;
    LargeAblIntegrator large(*sc.compiled->large_abl, sc.settings.grid());
    const RunSummary ls =
        large.run(Eigen::Map<const Eigen::VectorXd>(sc.q0.data(), sc.n), Eigen::Map<const Eigen::VectorXd>(sc.v0.data(), sc.n), &a);
    const RunSummary ds = run_scene(dense, &b);
    ASSERT_EQ(ls.status, RunStatus::kCompleted) << ls.message;
    ASSERT_EQ(ds.status, RunStatus::kCompleted) << ds.message;
    ASSERT_EQ(a.q.size(), b.q.size());
    double dq = 0.0, dv = 0.0;
    for (std::size_t k = 0; k < a.q.size(); ++k)
      for (std::size_t j = 0; j < a.q[k].size(); ++j) {
        dq = std::max(dq, std::abs(a.q[k][j] - b.q[k][j]));
        dv = std::max(dv, std::abs(a.v[k][j] - b.v[k][j]));
      }
    EXPECT_LE(dq, 1e-12) << "pendulum " << pendulum;
    EXPECT_LE(dv, 1e-10) << "pendulum " << pendulum;
    ASSERT_TRUE(ls.rest_step.has_value()) << "pendulum " << pendulum;
    EXPECT_EQ(ls.rest_step, ds.rest_step) << "pendulum " << pendulum;
    for (double v : ls.v_final) EXPECT_EQ(v, 0.0);
  }
}

TEST(LargeAblScene, AChainOfTwoThousandFromTheSceneFormatRestsExactly) {
  const int n = 2000;
  const double pendulum = 0.05;
  const LagrangianScene sc = load_scene(friction_bar_scene(n, 4.0, pendulum));
  ASSERT_FALSE(sc.compiled->dense);
  ASSERT_TRUE(uses_large_abl_path(sc));
  const LargeAblSystem& sys = *sc.compiled->large_abl;
  // M from its bands: rhoA l / 6 tridiag(1, 4, 1), 2 on the free end, l = 1/64; k = EA / l.
  const double m6 = 1.0 / (6.0 * 64), k = 64.0;
  ASSERT_EQ(sys.mass.nonZeros(), 3 * n - 2);
  for (int i = 0; i < n; ++i) {
    EXPECT_DOUBLE_EQ(sys.mass.coeff(i, i), (i == n - 1 ? 2.0 : 4.0) * m6);
    if (i + 1 < n) EXPECT_DOUBLE_EQ(sys.mass.coeff(i, i + 1), m6);
    if (i + 1 < n) EXPECT_DOUBLE_EQ(sys.mass.coeff(i + 1, i), m6);
  }
  EXPECT_EQ(sys.bandwidth(), 1);
  // grad V from its terms against the closed form, at random positions.
  ASSERT_TRUE(sys.gradient);
  std::mt19937 rng(53);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<double> scratch = sys.gradient->make_scratch();
  for (int trial = 0; trial < 5; ++trial) {
    std::vector<double> q(static_cast<std::size_t>(n));
    for (double& x : q) x = u(rng);
    Eigen::VectorXd g;
    sys.evaluate(Eigen::Map<const Eigen::VectorXd>(q.data(), n), g, scratch);
    for (int i = 0; i < n; ++i) ASSERT_NEAR(g(i), ChainGradient(q, i, k, pendulum), 1e-10 * k) << i;
  }
  // The run: the bar slides, sticks node by node and rests exactly (Theorem 4.3's interior condition
  // holds at the end: every spring force below its node's friction).
  const RunSummary s = run_scene(sc, nullptr, nullptr);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.rest_step.has_value());
  for (double v : s.v_final) ASSERT_EQ(v, 0.0);
  EXPECT_EQ(s.equilibrium.residual, 0.0);
  EXPECT_TRUE(s.equilibrium.interior);
  EXPECT_EQ(s.mass.checked, s.steps);  // the per-step checks, at every step
  EXPECT_GT(s.mass.lambda_min, 0.0);
  EXPECT_GT(s.solver.rest_steps, 0);
  // The report: written, with the hypotheses ledger's verdicts for this run.
  const json report = report_json(sc, s, nullptr);
  EXPECT_TRUE(report.contains("guarantees"));
}

std::string Error(const json& doc) {
  try {
    load_scene(doc);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(LargeAblScene, RefusesWhatThePathDoesNotTakeAtItsField) {
  const int n = 100;
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["controller"].push_back({{"type", "norm"}, {"gain", 1}});
    EXPECT_NE(Error(doc).find("/system/controller/2: the norm term"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["integrator"]["k1"] = 1.0;
    EXPECT_NE(Error(doc).find("/integrator/k1: k1 and k3 are not taken"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    std::string all = "0";
    for (int i = 1; i <= 65; ++i) all += " + u" + std::to_string(i);
    doc["system"]["potential"].push_back("(" + all + ")^2");
    EXPECT_NE(Error(doc).find("/system/potential: a term of its sum reads 65 coordinates"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["mass"]["bands"][1][7] = "m6*(1 + u3^2)";
    EXPECT_NE(Error(doc).find("/system/mass/bands/1/7: is not a constant"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["mass"]["bands"][1] = std::vector<std::string>(n - 1, "3*m6");  // tridiag(3, 4, 3): indefinite
    EXPECT_NE(Error(doc).find("/system/mass/bands: M is not positive definite"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["mass"]["bands"].push_back(std::vector<int>(n - 3, 0));  // band 2 needs n - 2 entries
    EXPECT_NE(Error(doc).find("/system/mass/bands/2"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["force"] = std::vector<std::string>(n, "0");
    doc["system"]["force"][5] = "u5_dot";
    EXPECT_NE(Error(doc).find("/system/force/5: is not a constant"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["constraints"] = {{{"gap", "u1 + 1"}}};
    EXPECT_NE(Error(doc).find("/integrator/scheme"), std::string::npos) << Error(doc);
  }
  {
    // A study's other schemes on a scene at scale: the explicit peer and moreau-jean have no path for it.
    const LagrangianScene sc = load_scene(friction_bar_scene(n, 0.1));
    EXPECT_THROW(scene_variant(sc, Scheme::kExplicit, 1e-3), std::invalid_argument);
    EXPECT_THROW(scene_variant(sc, Scheme::kMoreauJean, 1e-3), std::invalid_argument);
    EXPECT_TRUE(uses_large_abl_path(scene_variant(sc, Scheme::kAbl, 5e-4)));
  }
  {
    json doc = friction_bar_scene(10001, 0.1);
    EXPECT_NE(Error(doc).find("/system/coordinates: more than 10000 degrees of freedom"), std::string::npos) << Error(doc);
  }
  {
    json doc = friction_bar_scene(n, 0.1);
    doc["system"]["potential"].push_back("sqrt(u4 - 1)");
    EXPECT_NE(Error(doc).find("/system/potential: the generalized force grad V + F is not finite at the initial state"), std::string::npos)
        << Error(doc);
  }
}

}  // namespace
}  // namespace moreau::scene
