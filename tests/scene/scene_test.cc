// The scene format: the shipped scenes against their closed forms and against the compiled C++ model,
// the Christoffel C against (1.3), the measured order, overrides, and the errors bad scenes get.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <vector>

#include "moreau/core/models/manipulator.h"
#include "moreau/scene/json_number.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/scene_model.h"
#include "moreau/scene/simulation.h"

#include "support/scene_run.h"
#include "support/scratch_dir.h"

namespace moreau::scene {
namespace {

using nlohmann::json;

json Scene(const std::string& name) { return test_support::shipped_scene(name); }
using Recorder = test_support::SampleRecorder;

// The checks at recorded states (RecordedStateChecks: Assumption 4.1 at every 16th, E at every 64th) find
// the same maxima, times and sample counts whether the run hands them every recorded state (an observer
// after them needs all) or only those they check (nothing after them: sample_stride() = 16), for
// several output.every, on scenes where Assumption 4.1 holds for a while and where it fails.
// The scheme table (scheme.h) against what docs/scene-format.md and docs/studies.md promise: the names a
// scene may give per system type, the peers a study compares, and the rows in the enum's order.
TEST(SchemeTable, NamesAndRolesAreTheDocumentedOnes) {
  const std::vector<std::string> expected = {"abl", "explicit", "regularized", "moreau-jean", "implicit-euler", "tracking"};
  ASSERT_EQ(all_schemes().size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const SchemeTraits& row = all_schemes()[i];
    EXPECT_EQ(static_cast<std::size_t>(row.scheme), i) << "row " << i << " is out of the enum's order";
    EXPECT_EQ(row.name, expected[i]);
    EXPECT_EQ(scheme_from_name(expected[i]), row.scheme);
    EXPECT_EQ(&traits(row.scheme), &row);
  }
  EXPECT_EQ(scheme_from_name("Abl"), std::nullopt);
  EXPECT_EQ(scheme_names_for_scenes(SystemType::kLagrangian), "abl, moreau-jean or tracking");
  EXPECT_EQ(scheme_names_for_scenes(SystemType::kLure), "implicit-euler");
  EXPECT_EQ(scheme_names_for_studies(), "abl, explicit or regularized");
  // Only the scheme (0.2) itself is covered by Theorems 4.1-4.3; only Moreau-Jean integrates contacts.
  for (const SchemeTraits& row : all_schemes()) {
    EXPECT_EQ(row.theorems_4_1_to_4_3, row.scheme == Scheme::kAbl) << row.name;
    EXPECT_EQ(row.contacts, row.scheme == Scheme::kMoreauJean) << row.name;
  }
}

// A study's variant of a scene is the scene with the scheme's implied settings: the explicit peer on a
// fixed step with the explicit velocity update, whatever the scene's rule; abl keeps the scene's rule.
TEST(SchemeTable, StudyVariantsCarryTheSchemesSettings) {
  json doc = Scene("damped-relay.json");
  doc["integrator"]["step_rule"] = "theorem-4.1";
  const LagrangianScene sc = load_scene(doc);
  const LagrangianScene explicit_peer = scene_variant(sc, Scheme::kExplicit, 0.25);
  EXPECT_EQ(explicit_peer.scheme, Scheme::kExplicit);
  EXPECT_EQ(explicit_peer.settings.h, 0.25);
  EXPECT_EQ(explicit_peer.settings.step_rule, StepRule::kFixed);
  EXPECT_EQ(explicit_peer.settings.velocity_update, VelocityUpdate::kExplicit);
  const LagrangianScene abl = scene_variant(explicit_peer, Scheme::kAbl, 0.5);
  EXPECT_EQ(abl.settings.velocity_update, VelocityUpdate::kImplicit);
  EXPECT_EQ(scene_variant(sc, Scheme::kAbl, 0.5).settings.step_rule, StepRule::kTheorem41);
  EXPECT_THROW(scene_variant(sc, Scheme::kImplicitEuler, 0.5), std::invalid_argument);
}

TEST(RecordedStateChecks, SeeTheSameStatesWithOrWithoutAnObserverAfterThem) {
  int force_samples = 0, energy_samples = 0;
  for (const char* file : {"damped-relay.json", "coulomb-oscillator.json", "manipulator.json"}) {
    for (int every : {1, 3, 7}) {
      json doc = Scene(file);
      doc["output"]["every"] = every;
      const LagrangianScene sc = load_scene(doc);
      Recorder after;
      EXPECT_EQ(RecordedStateChecks(sc, nullptr).sample_stride(), RecordedStateChecks::kStride);
      EXPECT_EQ(RecordedStateChecks(sc, &after).sample_stride(), 1);
      const RunSummary alone = run_scene(sc, nullptr);
      const RunSummary chained = run_scene(sc, &after);
      const std::string where = std::string(file) + ", every " + std::to_string(every);
      EXPECT_EQ(alone.force_bounds.samples, chained.force_bounds.samples) << where;
      EXPECT_EQ(alone.force_bounds.failed, chained.force_bounds.failed) << where;
      EXPECT_EQ(alone.force_bounds.max_force, chained.force_bounds.max_force) << where;
      EXPECT_EQ(alone.force_bounds.max_force_time, chained.force_bounds.max_force_time) << where;
      EXPECT_EQ(alone.force_bounds.max_gradient, chained.force_bounds.max_gradient) << where;
      EXPECT_EQ(alone.force_bounds.max_gradient_time, chained.force_bounds.max_gradient_time) << where;
      EXPECT_EQ(alone.mechanical.samples, chained.mechanical.samples) << where;
      EXPECT_EQ(alone.mechanical.initial, chained.mechanical.initial) << where;
      EXPECT_EQ(alone.mechanical.max_rise, chained.mechanical.max_rise) << where;
      EXPECT_EQ(alone.mechanical.max_rise_time, chained.mechanical.max_rise_time) << where;
      EXPECT_EQ(alone.mechanical.max_balance, chained.mechanical.max_balance) << where;
      EXPECT_EQ(alone.mechanical.max_balance_time, chained.mechanical.max_balance_time) << where;
      // By definition: the recorded states numbered 0, 16, 32, ... up to the last (and 64 for E).
      const std::int64_t recorded = static_cast<std::int64_t>(after.t.size());
      if (!chained.force_bounds.failed) {
        EXPECT_EQ(chained.force_bounds.samples, (recorded + 15) / 16) << where;
      }
      if (sc.compiled->has_potential) {
        EXPECT_EQ(chained.mechanical.samples, (recorded + 63) / 64) << where;
      }
      force_samples += static_cast<int>(alone.force_bounds.samples);
      energy_samples += static_cast<int>(alone.mechanical.samples);
    }
  }
  EXPECT_GT(force_samples, 100) << "Assumption 4.1 must be sampled at many states, not only the first";
  EXPECT_GT(energy_samples, 100);
}

std::vector<double> Exact(const LagrangianScene& sc, double t) {
  std::vector<double> slots(1 + 2 * sc.n, 0.0), out(2 * sc.n), scratch(sc.exact_tape->scratch_size());
  slots[0] = t;
  sc.exact_tape->eval(slots.data(), out.data(), scratch.data());
  return out;
}

TEST(Scene, ManipulatorSceneMatchesTheCompiledModel) {
  const LagrangianScene sc = load_scene(Scene("manipulator.json"));
  ASSERT_EQ(sc.n, 2);
  Recorder from_json;
  const RunSummary a = run_scene(sc, &from_json);

  models::Manipulator model;  // same parameters as the scene
  Recorder from_cpp;
  AblSettings settings = sc.settings;
  AblIntegrator<models::Manipulator> integrator(model, settings);
  const RunSummary b = integrator.run(Vec<2>(3.0, -1.0), Vec<2>(-1.0, 1.0), &from_cpp);

  ASSERT_EQ(a.status, RunStatus::kCompleted) << a.message;
  ASSERT_EQ(from_json.q.size(), from_cpp.q.size());
  double max_diff = 0.0;
  for (std::size_t i = 0; i < from_json.q.size(); ++i) {
    max_diff = std::max(max_diff, std::abs(from_json.q[i] - from_cpp.q[i]));
    max_diff = std::max(max_diff, std::abs(from_json.v[i] - from_cpp.v[i]));
  }
  EXPECT_LT(max_diff, 1e-12);
  ASSERT_TRUE(a.converged_step && b.converged_step);
  EXPECT_EQ(*a.converged_step, *b.converged_step);
}

// The Christoffel C of the scene is the paper's C for the manipulator, entry by entry.
TEST(Scene, ChristoffelMatrixOfTheManipulatorIsThePapers) {
  const LagrangianScene sc = load_scene(Scene("manipulator.json"));
  SceneModel<2> from_scene(sc);
  models::Manipulator model;
  LagrangianTerms<2> a, b;
  a.resize(2);
  b.resize(2);
  for (double th : {-2.0, -0.3, 0.0, 0.7, 2.5}) {
    const Vec<2> q(0.4, th), v(-1.3, 2.2);
    from_scene.evaluate(0.0, q, v, a);
    model.evaluate(0.0, q, v, b);
    EXPECT_LT((a.M - b.M).norm(), 1e-15);
    EXPECT_LT((a.C - b.C).norm(), 1e-15) << a.C << "\n vs \n" << b.C;
    EXPECT_LT((a.g - b.g).norm(), 1e-14);
  }
}

// evaluate_with_potential() (one tape for M, C, g and V: the Moreau-Jean step at every state) against
// evaluate() and potential() (their own tapes) bit for bit, and V against the scenes' closed forms.
TEST(Scene, TermsAndPotentialFromOneTapeAreThoseOfTheirOwnTapes) {
  const LagrangianScene arm = load_scene(Scene("manipulator.json"));
  EXPECT_EQ(arm.compiled->step_potential_tape.num_outputs(), arm.compiled->step_tape.num_outputs() + 1);
  SceneModel<2> model(arm);
  LagrangianTerms<2> both, terms;
  both.resize(2);
  terms.resize(2);
  for (double th : {-2.0, -0.3, 0.0, 0.7, 2.5}) {
    const Vec<2> q(0.4, th), v(-1.3, 2.2);
    const double V = model.evaluate_with_potential(0.0, q, v, both);
    model.evaluate(0.0, q, v, terms);
    EXPECT_TRUE((both.M.array() == terms.M.array()).all()) << both.M << "\n vs \n" << terms.M;
    EXPECT_TRUE((both.C.array() == terms.C.array()).all()) << both.C << "\n vs \n" << terms.C;
    EXPECT_TRUE((both.g.array() == terms.g.array()).all()) << both.g << "\n vs \n" << terms.g;
    EXPECT_EQ(V, model.potential(q)) << "th2 = " << th;
    EXPECT_NEAR(V, -0.5 * 1.0 * 9.81 * std::cos(th), 1e-14) << "th2 = " << th;  // V = -b m2 g cos(th2)
  }

  // The ball: M, C and g constant (no step tape to run), V = m g y the tape's only output.
  const LagrangianScene ball = load_scene(Scene("bouncing-ball-e0.5.json"));
  EXPECT_EQ(ball.compiled->step_tape.num_outputs(), 0u);
  EXPECT_EQ(ball.compiled->step_potential_tape.num_outputs(), 1u);
  SceneModel<1> ball_model(ball);
  LagrangianTerms<1> ball_terms;
  ball_terms.resize(1);
  for (double y : {-0.25, 0.0, 1.0, 3.5}) {
    const Vec<1> q(y), v(0.5);
    const double V = ball_model.evaluate_with_potential(0.0, q, v, ball_terms);
    EXPECT_EQ(V, ball_model.potential(q));
    EXPECT_NEAR(V, 1.0 * 9.81 * y, 1e-14) << "y = " << y;  // m = 1
    EXPECT_EQ(ball_terms.M(0, 0), 1.0);
    EXPECT_EQ(ball_terms.g(0), 9.81);
  }
}

// (1.3): dM/dt = C + C^T along any motion, for the Christoffel C of a 3-DOF arm with a coupled,
// configuration-dependent M. dM/dt is taken here by central differences (the library never does).
TEST(Scene, ChristoffelSatisfiesSkewSymmetryProperty) {
  json doc = Scene("manipulator.json");
  doc["system"]["coordinates"] = {"a", "b2", "c"};
  doc["system"]["mass"] = {{"3 + cos(b2) + cos(b2 + c)", "1 + 0.5*cos(b2) + cos(b2 + c)", "0.5*cos(b2 + c)"},
                           {"1 + 0.5*cos(b2) + cos(b2 + c)", "2 + cos(c)", "0.25 + 0.5*cos(c)"},
                           {"0.5*cos(b2 + c)", "0.25 + 0.5*cos(c)", "0.6 + 0.1*sin(a)^2"}};
  doc["system"]["potential"] = "sin(a) + cos(b2)";
  doc["system"]["controller"] = {{{"type", "quadratic"}, {"weights", {1, 1, 1}}}, {{"type", "abs"}, {"gains", {1, 1, 1}}}};
  doc["initial"] = {{"q", {0.1, 0.2, 0.3}}, {"v", {0, 0, 0}}};
  const LagrangianScene sc = load_scene(doc);
  SceneModel<3> model(sc);
  LagrangianTerms<3> terms;
  terms.resize(3);
  Mat<3> Mp, Mm;
  for (int trial = 0; trial < 20; ++trial) {
    const Vec<3> q(std::sin(trial * 1.1), std::cos(trial * 0.7) * 2, trial * 0.3 - 3);
    const Vec<3> v(std::cos(trial * 2.3), -1.0 + 0.1 * trial, std::sin(trial * 0.5) * 3);
    model.evaluate(0.0, q, v, terms);
    const double d = 1e-6;
    model.mass(q + d * v, Mp);
    model.mass(q - d * v, Mm);
    const Mat<3> dMdt = (Mp - Mm) / (2 * d);
    EXPECT_LT((dMdt - terms.C - terms.C.transpose()).norm(), 1e-8) << "trial " << trial;
    // C itself (not only C + C^T) against the Christoffel symbols of the first kind built here from central
    // differences of M: C_ij = sum_k 1/2 (dM_ij/dq_k + dM_ik/dq_j - dM_jk/dq_i) v_k.
    Mat<3> dM[3];
    for (int k = 0; k < 3; ++k) {
      const Vec<3> e = Vec<3>::Unit(k);
      model.mass(q + d * e, Mp);
      model.mass(q - d * e, Mm);
      dM[k] = (Mp - Mm) / (2 * d);
    }
    Mat<3> C_fd = Mat<3>::Zero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) C_fd(i, j) += 0.5 * (dM[k](i, j) + dM[j](i, k) - dM[i](j, k)) * v(k);
    EXPECT_LT((C_fd - terms.C).norm(), 1e-8) << "trial " << trial << "\n" << C_fd << "\n vs \n" << terms.C;
  }
}

TEST(Scene, DampedRelayMatchesItsClosedForm) {
  const LagrangianScene sc = load_scene(Scene("damped-relay.json"));
  Recorder rec;
  const RunSummary s = run_scene(sc, &rec);
  ASSERT_EQ(s.status, RunStatus::kCompleted);
  ASSERT_TRUE(s.converged_step);
  EXPECT_NEAR(*s.converged_time, *sc.exact_rest_time, 2 * sc.settings.h);
  // Explicit position update: Q^k - q(t_k) ~ (h/2)(v0 - v(t)) <= 1.5 h, plus the O(h) velocity lag.
  EXPECT_NEAR(s.q_final[0], sc.exact_rest_q[0], 3 * sc.settings.h);
  for (std::size_t k = 0; k < rec.t.size(); k += 97) {
    const auto ex = Exact(sc, rec.t[k]);
    EXPECT_NEAR(rec.q[k], ex[0], 3 * sc.settings.h) << rec.t[k];
    EXPECT_NEAR(rec.v[k], ex[1], 3 * sc.settings.h) << rec.t[k];
    if (rec.t[k] > *s.converged_time) {
      ASSERT_EQ(rec.v[k], 0.0);
    }
  }
}

TEST(Scene, ForcedRelaySticks) {
  const LagrangianScene sc = load_scene(Scene("forced-relay.json"));
  Recorder rec;
  const RunSummary s = run_scene(sc, &rec);
  ASSERT_TRUE(s.converged_step);
  EXPECT_NEAR(*s.converged_time, *sc.exact_rest_time, sc.settings.h);
  for (std::size_t k = 0; k < rec.t.size(); k += 31) {
    const auto ex = Exact(sc, rec.t[k]);
    EXPECT_NEAR(rec.v[k], ex[1], 1e-12 + (std::abs(rec.t[k] - *sc.exact_rest_time) < 2e-3 ? 2e-3 : 0.0));
    EXPECT_NEAR(rec.q[k], ex[0], sc.settings.h);
  }
  EXPECT_TRUE(s.equilibrium.interior);
}

// Reference: the closed form of the scene's description (turning points p_{j+1} = -(p_j - 2 a/k sign p_j),
// rest at x = 0.1 after four half periods, t = 2 pi). The scheme's explicit position update drifts the
// turning points by O(h) (docs/numerics.md, "Energy"): the rest position error must shrink tenfold with
// h (order 1) and the rest time must be within two steps of 2 pi.
TEST(Scene, CoulombOscillatorRestsWhereTheClosedFormSaysAtOrderOne) {
  auto rest = [](double h) {
    json doc = Scene("coulomb-oscillator.json");
    doc["integrator"]["h"] = h;
    const LagrangianScene sc = load_scene(doc);
    const RunSummary s = run_scene(sc, nullptr);
    EXPECT_TRUE(s.converged_step) << h;
    EXPECT_EQ(s.v_final[0], 0.0);
    EXPECT_NEAR(*s.converged_time, *sc.exact_rest_time, 2.0 * h);
    return std::abs(s.q_final[0] - sc.exact_rest_q[0]);
  };
  const double e3 = rest(1e-3), e4 = rest(1e-4);
  EXPECT_GT(e3 / e4, 9.0);
  EXPECT_LT(e3 / e4, 11.0);
  EXPECT_LT(e4, 2e-3);
}

// The manipulator's order against an independent reference. No theorem promises an order here (Theorem
// 5.2 needs Assumption 5.2, which the paper says fails for this robot). On [0, 0.6] neither velocity
// reaches zero (th2' first sticks at 0.0 near t = 0.75, x1' near t = 1.13), so (0.1) is the smooth ODE
// M(q) v' = -C(q, v) v - grad V(q) - v - sign(v0) there, integrated here by classical RK4 at h = 1e-4 on
// the paper's closed-form M, C and grad V (models::Manipulator, written by hand, not compiled from the
// scene). The scheme (0.2) is first order on such a stretch (an Euler method): the measured order between
// consecutive h of 1e-2, 1e-3, 1e-4 must be 1 within 0.1, and its error at h = 1e-4 below 1e-3.
TEST(Scene, ManipulatorIsFirstOrderOnItsSmoothStretchAgainstRK4) {
  const models::Manipulator model;
  const Vec<2> sign_v0(-1.0, 1.0);  // v0 = (-1, 1)
  auto rhs = [&](double t, const Eigen::Vector4d& x) {
    LagrangianTerms<2> terms;
    terms.resize(2);
    const Vec<2> q = x.head<2>(), v = x.tail<2>();
    model.evaluate(t, q, v, terms);
    Eigen::Vector4d dx;
    dx.head<2>() = v;
    dx.tail<2>() = terms.M.lu().solve(-terms.C * v - terms.g - v - sign_v0);
    return dx;
  };
  Eigen::Vector4d x(3.0, -1.0, -1.0, 1.0);
  const double H = 1e-4;
  for (int k = 0; k < 6000; ++k) {
    const double t = k * H;
    const Eigen::Vector4d k1 = rhs(t, x), k2 = rhs(t + H / 2, x + H / 2 * k1), k3 = rhs(t + H / 2, x + H / 2 * k2),
                          k4 = rhs(t + H, x + H * k3);
    x += H / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  ASSERT_NE(x(2), 0.0);
  ASSERT_EQ(x(2) < 0, true);  // still moving in the initial direction at t = 0.6: the ODE applied throughout
  ASSERT_EQ(x(3) > 0, true);
  std::vector<double> hs = {1e-2, 1e-3, 1e-4}, errs;
  for (double h : hs) {
    json doc = Scene("manipulator.json");
    doc["integrator"]["h"] = h;
    doc["integrator"]["t_end"] = 0.6;
    const RunSummary s = run_scene(load_scene(doc), nullptr);
    ASSERT_EQ(s.status, RunStatus::kCompleted);
    ASSERT_NE(s.v_final[1], 0.0);
    double e = 0;
    for (int i = 0; i < 2; ++i) e = std::max({e, std::abs(s.q_final[i] - x(i)), std::abs(s.v_final[i] - x(2 + i))});
    errs.push_back(e);
  }
  for (std::size_t i = 1; i < hs.size(); ++i) {
    const double order = std::log(errs[i - 1] / errs[i]) / std::log(hs[i - 1] / hs[i]);
    EXPECT_NEAR(order, 1.0, 0.1) << "between h = " << hs[i - 1] << " and " << hs[i] << " (errors " << errs[i - 1] << ", " << errs[i] << ")";
  }
  EXPECT_LT(errs.back(), 1e-3);
}

TEST(Scene, OverridesSetAnyField) {
  json doc = Scene("manipulator.json");
  apply_override(doc, "integrator.h=1e-4");
  apply_override(doc, "initial.v=[0,1]");
  apply_override(doc, "/parameters/m1=2");
  apply_override(doc, "system.mass.0.0=m1 + 2*m2");
  apply_override(doc, "integrator.step_rule=theorem-4.1");
  EXPECT_EQ(doc["integrator"]["h"], 1e-4);
  EXPECT_EQ(doc["initial"]["v"], json({0, 1}));
  EXPECT_EQ(doc["parameters"]["m1"], 2);
  EXPECT_EQ(doc["system"]["mass"][0][0], "m1 + 2*m2");
  EXPECT_EQ(doc["integrator"]["step_rule"], "theorem-4.1");
  const LagrangianScene sc = load_scene(doc);
  EXPECT_EQ(sc.settings.step_rule, StepRule::kTheorem41);
  EXPECT_THROW(apply_override(doc, "system.mass.5.0=1"), SceneError);
  EXPECT_THROW(apply_override(doc, "integrator.h"), SceneError);
}

// Limits applied to a compiled Simulation (what a server does to every job) give what the same limits
// written into the scene give: the same samples and the same summary, bit for bit, on a Lagrangian and a
// Lur'e scene; a lowered max_steps stops an adaptive run there. The scene is compiled once.
TEST(Scene, LimitsOnACompiledSimulationEqualTheSameLimitsInTheScene) {
  for (const char* file : {"manipulator.json", "lure-relay-2state.json", "bouncing-ball-e0.5.json"}) {
    SCOPED_TRACE(file);
    json doc = Scene(file);
    const Simulation compiled = Simulation::from_json(doc);
    doc["output"]["every"] = 7;
    const Simulation written = Simulation::from_json(doc);
    RunLimits limits;
    limits.output_every = 7;
    const Simulation limited = compiled.with_limits(limits);
    EXPECT_EQ(limited.output_every(), 7);
    EXPECT_NE(compiled.output_every(), 7) << "with_limits changed the simulation it copied";
    Recorder a, b;
    const RunSummary sa = written.run(&a);
    const RunSummary sb = limited.run(&b);
    EXPECT_EQ(sa.status, RunStatus::kCompleted);
    EXPECT_EQ(sa.steps, sb.steps);
    EXPECT_EQ(sa.q_final, sb.q_final);
    EXPECT_EQ(sa.v_final, sb.v_final);
    EXPECT_GT(a.t.size(), 2u);
    EXPECT_EQ(a.t, b.t);
    EXPECT_EQ(a.q, b.q);
    EXPECT_EQ(a.v, b.v);
  }
  json doc = Scene("manipulator.json");
  doc["integrator"]["step_rule"] = "theorem-4.1";
  const Simulation adaptive = Simulation::from_json(doc);
  RunLimits limits;
  limits.max_steps = 50;
  const Simulation limited = adaptive.with_limits(limits);
  EXPECT_EQ(limited.max_steps(), 50);
  EXPECT_GT(adaptive.max_steps(), 50);
  const RunSummary s = limited.run(nullptr);
  EXPECT_EQ(s.status, RunStatus::kFailed);
  EXPECT_EQ(s.steps, 50);
  EXPECT_THAT(s.message, ::testing::HasSubstr("max_steps"));
  limits.max_steps = std::int64_t{1} << 62;  // a limit above the scene's own leaves it alone
  EXPECT_EQ(adaptive.with_limits(limits).max_steps(), adaptive.max_steps());
}

// Each bad scene gets an error naming the field (a JSON pointer) and saying what is wrong.
struct BadCase {
  std::string name;
  std::function<void(json&)> mutate;
  std::string pointer;
  std::string reason_part;
};

class BadScene : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadScene, ErrorNamesTheField) {
  json doc = Scene("manipulator.json");
  GetParam().mutate(doc);
  try {
    load_scene(doc);
    FAIL() << "accepted a bad scene";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), GetParam().pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(GetParam().reason_part), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    Scene, BadScene,
    ::testing::Values(
        BadCase{"WrongRowSize", [](json& d) { d["system"]["mass"][1] = {"1"}; }, "/system/mass/1", "expected 2 entries"},
        BadCase{"UnknownName", [](json& d) { d["system"]["mass"][0][1] = "m2*b*cos(th3)"; }, "/system/mass/0/1", "unknown name 'th3'"},
        BadCase{"NotSymmetric", [](json& d) { d["system"]["mass"][1][0] = "m2*b*sin(th2)"; }, "/system/mass/1/0", "not symmetric"},
        BadCase{"NotPositiveDefinite", [](json& d) { d["system"]["mass"][0][0] = -1; }, "/system/mass", "not positive definite"},
        BadCase{"MassDependsOnVelocity", [](json& d) { d["system"]["mass"][0][0] = "1 + x1_dot^2"; }, "/system/mass/0/0", "cannot appear"},
        BadCase{"NonFiniteParameter", [](json& d) { d["parameters"]["m1"] = "1/0"; }, "/parameters/m1", "non-finite"},
        BadCase{"NaNInMass", [](json& d) { d["system"]["mass"][0][0] = "sqrt(-1)"; }, "/system/mass/0/0", "not finite"},
        BadCase{"ZeroStep", [](json& d) { d["integrator"]["h"] = 0; }, "/integrator/h", "must be > 0"},
        BadCase{"NegativeStep", [](json& d) { d["integrator"]["h"] = -1e-3; }, "/integrator/h", "must be > 0"},
        BadCase{"NonPositiveEnd", [](json& d) { d["integrator"]["t_end"] = 0; }, "/integrator/t_end", "must be > t0"},
        BadCase{"TooManySteps", [](json& d) { d["integrator"]["h"] = 1e-12; }, "/integrator/h", "steps"},
        BadCase{"UnknownScheme", [](json& d) { d["integrator"]["scheme"] = "rk4"; }, "/integrator/scheme", "unknown scheme"},
        BadCase{"UnknownRule", [](json& d) { d["integrator"]["step_rule"] = "adaptive"; }, "/integrator/step_rule", "expected"},
        BadCase{"UnknownField", [](json& d) { d["integrater"] = 1; }, "/integrater", "unknown field"},
        BadCase{"WrongType", [](json& d) { d["system"]["potential"] = json::array(); }, "/system/potential", "expected a number or an expression"},
        BadCase{"SyntaxError", [](json& d) { d["system"]["potential"] = "cos(th2"; }, "/system/potential", "character"},
        BadCase{"NegativeGain", [](json& d) { d["system"]["controller"][1]["gains"][0] = -1; }, "/system/controller/1/gains/0", ">= 0"},
        BadCase{"UnknownController", [](json& d) { d["system"]["controller"][0]["type"] = "huber"; }, "/system/controller/0/type", "unknown controller"},
        BadCase{"InitialSize", [](json& d) { d["initial"]["q"] = {1, 2, 3}; }, "/initial/q", "expected 2 entries"},
        BadCase{"InitialNotConstant", [](json& d) { d["initial"]["q"][0] = "t"; }, "/initial/q/0", "cannot appear"},
        BadCase{"ParameterCycle", [](json& d) { d["parameters"]["m1"] = "m2 + m1"; }, "/parameters/m1", "depends on itself"},
        BadCase{"MissingMass", [](json& d) { d["system"].erase("mass"); }, "/system", "mass"},
        BadCase{"MissingIntegrator", [](json& d) { d.erase("integrator"); }, "/integrator", "missing"},
        BadCase{"Theorem42WithoutEta", [](json& d) { d["system"]["controller"] = {{{"type", "abs"}, {"gains", {1, 1}}}}; d["integrator"]["step_rule"] = "theorem-4.2"; }, "/integrator/step_rule", "eta"},
        BadCase{"BadSystemType", [](json& d) { d["system"]["type"] = "hamiltonian"; }, "/system/type", "unknown system type"},
        // Coordinate names are the trajectory's column names (t, h, <q>, <q>_dot, energy) and the
        // expressions' variables: none may be one of the trajectory's own columns or another
        // coordinate's velocity, whatever the order (CSV header t,h,h,... and duplicate JSON keys before).
        BadCase{"CoordinateNamedAsTheStepColumn", [](json& d) { d["system"]["coordinates"] = {"h", "th2"}; }, "/system/coordinates/0",
                "the trajectory has its own column 'h' (the step size)"},
        BadCase{"CoordinateNamedAsTheEnergyColumn", [](json& d) { d["system"]["coordinates"] = {"x1", "energy"}; }, "/system/coordinates/1",
                "the trajectory has its own column 'energy'"},
        BadCase{"CoordinateNamedAsTheTimeColumn", [](json& d) { d["system"]["coordinates"] = {"t", "th2"}; }, "/system/coordinates/0",
                "the trajectory has its own column 't'"},
        BadCase{"CoordinateNamedAsAFunction", [](json& d) { d["system"]["coordinates"] = {"x1", "sin"}; }, "/system/coordinates/1",
                "'sin' is reserved"},
        BadCase{"CoordinateNamedAsAnotherCoordinatesVelocity", [](json& d) { d["system"]["coordinates"] = {"x1", "x1_dot"}; },
                "/system/coordinates/1", "'x1_dot' is the name of the velocity of coordinate 'x1'"},
        BadCase{"CoordinateNamedAsTheVelocityOfALaterCoordinate", [](json& d) { d["system"]["coordinates"] = {"th2_dot", "th2"}; },
                "/system/coordinates/0", "'th2_dot' is the name of the velocity of coordinate 'th2'"},
        BadCase{"DuplicateCoordinateName", [](json& d) { d["system"]["coordinates"] = {"x1", "x1"}; }, "/system/coordinates/1",
                "duplicate name 'x1'"},
        // A run must take at least one step and its step count must fit the limit, checked in double
        // before any conversion to an integer (a double beyond 2^63 converts to int64 with undefined
        // behaviour). For the adaptive rules h is the largest step, so (t_end - t0) / h bounds their count.
        BadCase{"StepLongerThanTheInterval", [](json& d) { d["integrator"]["h"] = 1e9; }, "/integrator/h", "longer than the interval"},
        BadCase{"StepSoLongTheRunTakesNoStep", [](json& d) { d["integrator"]["h"] = 1e12; }, "/integrator/h", "longer than the interval"},
        BadCase{"FixedRuleStepCountOverflowsAtAFarEnd", [](json& d) { d["integrator"]["t_end"] = 1e300; }, "/integrator/h", "steps, more than the limit"},
        BadCase{"FixedRuleStepCountOverflowsAtATinyStep", [](json& d) { d["integrator"]["h"] = 1e-300; }, "/integrator/h", "steps, more than the limit"},
        BadCase{"AdaptiveRuleStepCountOverflowsAtAFarEnd", [](json& d) { d["integrator"]["step_rule"] = "theorem-4.1"; d["integrator"]["t_end"] = 1e300; }, "/integrator/h", "needs at least"},
        BadCase{"AdaptiveRuleStepCountOverflowsAtATinyStep", [](json& d) { d["integrator"]["step_rule"] = "theorem-4.2"; d["integrator"]["h"] = 1e-300; }, "/integrator/h", "needs at least"},
        BadCase{"AdaptiveRuleStepLongerThanTheInterval", [](json& d) { d["integrator"]["step_rule"] = "theorem-4.1"; d["integrator"]["h"] = 11; }, "/integrator/h", "longer than the interval"},
        BadCase{"IntervalOverflows", [](json& d) { d["integrator"]["t0"] = -1e308; d["integrator"]["t_end"] = 1e308; }, "/integrator/t_end", "overflows"}),
    [](const auto& info) { return info.param.name; });

TEST(Scene, JsonNestingIsBoundedBeforeParsing) {
  EXPECT_FALSE(json_depth_exceeded("{\"a\": [[1, 2], {\"b\": []}]}", 4));
  EXPECT_EQ(json_depth_exceeded("{\"a\": [[1, 2], {\"b\": []}]}", 2), std::optional<std::size_t>(7));
  // Brackets inside strings, escaped quotes included, do not count.
  EXPECT_FALSE(json_depth_exceeded(R"({"a": "[[[[\"[[[[", "b": ["]]]]"]})", 2));
  EXPECT_TRUE(json_depth_exceeded(std::string(100000, '['), kMaxJsonDepth));

  const std::string path = moreau::test_support::scratch_dir() + "/deep.json";
  {
    std::ofstream out(path);
    out << "{\"name\": " << std::string(100000, '[') << std::string(100000, ']') << "}";
  }
  try {
    read_scene_file(path);
    FAIL() << "a deeply nested file was parsed";
  } catch (const SceneError& e) {
    EXPECT_THAT(e.reason(), ::testing::HasSubstr("nested deeper than 64 levels at byte 72"));
  }
  nlohmann::json doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json");
  EXPECT_THROW(apply_override(doc, "name=" + std::string(1000, '[') + std::string(1000, ']')), SceneError);
  EXPECT_THROW(apply_override(doc, "a" + std::string(1000, '.') + "=1"), SceneError);
  EXPECT_NO_THROW(apply_override(doc, "description=[[1]]"));
}

// A number literal that overflows a double ("1e999") is a SceneError at the number's JSON pointer, with
// its byte offset and line, whether it comes from a file or an override: never nlohmann::json's
// out_of_range exception escaping (which aborted `moreau run`).
TEST(Scene, NumberOutOfRangeNamesItsPointerAndByte) {
  const std::string path = moreau::test_support::scratch_dir() + "/overflow.json";
  const std::string text = "{\"name\": \"x\",\n \"integrator\": {\"t_end\": 1, \"h\": 1e999}}";
  std::ofstream(path) << text;
  try {
    read_scene_file(path);
    FAIL() << "parsed a number that overflows a double";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/integrator/h") << e.what();
    EXPECT_THAT(e.reason(), ::testing::HasSubstr("number out of range at byte " + std::to_string(text.find("1e999"))));
    EXPECT_THAT(e.reason(), ::testing::HasSubstr("line 2"));
  } catch (const std::exception& e) {
    FAIL() << "not a SceneError: " << e.what();
  }
  json doc = Scene("manipulator.json");
  for (const char* value : {"[0, -1e999]", "[0,1e400]"}) {
    try {
      apply_override(doc, std::string("initial.v=") + value);
      FAIL() << "took " << value << " for a string";
    } catch (const SceneError& e) {
      EXPECT_EQ(e.pointer(), "/initial/v/1") << e.what();
      EXPECT_THAT(e.reason(), ::testing::HasSubstr("number out of range")) << e.what();
    } catch (const std::exception& e) {
      FAIL() << "not a SceneError: " << e.what();
    }
  }
  // Text that is not JSON at all is still a string (an expression, a bare word).
  EXPECT_NO_THROW(apply_override(doc, "system.potential=1e3*cos(th2)"));
  EXPECT_EQ(doc["system"]["potential"], "1e3*cos(th2)");
}

// read_scene_file reads at most 64 MiB and one byte, whatever the file says its size is: a larger file
// is refused with the limit in the message, not read to the end (an endless device or FIFO would never
// end: Cli/BadCommandLine.* covers /dev/zero, Cli.SceneFromAnEndlessFifoIsRefusedAtTheSizeLimit a FIFO).
TEST(Scene, SceneFileLargerThan64MiBIsRefused) {
  const std::string path = moreau::test_support::scratch_dir() + "/huge.json";
  std::ofstream(path).close();
  std::filesystem::resize_file(path, (std::uintmax_t{64} << 20) + 1);  // sparse: no disk space used
  try {
    read_scene_file(path);
    FAIL() << "read a file of 64 MiB + 1 byte";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/");
    EXPECT_THAT(e.reason(), ::testing::HasSubstr("larger than 64 MiB")) << e.what();
  }
  // Exactly 64 MiB is read, and refused for what it holds (NUL bytes), not for its size.
  std::filesystem::resize_file(path, std::uintmax_t{64} << 20);
  try {
    read_scene_file(path);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_THAT(e.reason(), ::testing::HasSubstr("not valid JSON")) << e.what();
  }
  std::filesystem::remove(path);
}

TEST(Scene, MalformedJsonNamesLineAndColumn) {
  const std::string path = moreau::test_support::scratch_dir() + "/bad.json";
  FILE* f = std::fopen(path.c_str(), "w");
  std::fputs("{\n  \"name\": \"x\",\n  \"system\": {,\n}", f);
  std::fclose(f);
  try {
    read_scene_file(path);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
}

// The compiler's bandwidth: the widest |i - j| where M or C is not identically zero, C included (a
// diagonal M whose entry depends on another coordinate makes C reach it).
TEST(Scene, BandwidthCoversMassAndCoriolis) {
  EXPECT_EQ(load_scene(Scene("friction-bar.json")).compiled->bandwidth, 1);
  EXPECT_EQ(load_scene(Scene("coulomb-oscillator.json")).compiled->bandwidth, 0);
  EXPECT_EQ(load_scene(Scene("manipulator.json")).compiled->bandwidth, 1);  // full, n = 2
  json doc = Scene("coulomb-oscillator.json");
  doc["system"]["coordinates"] = {"x", "y", "z", "u", "w", "s"};
  json mass = json::array();
  for (int i = 0; i < 6; ++i) {
    json row = json::array();
    for (int j = 0; j < 6; ++j) row.push_back(i == j ? (i == 0 ? "m*(1 + z^2)" : "m") : "0");
    mass.push_back(row);
  }
  doc["system"]["mass"] = mass;
  doc["system"]["controller"][0]["gains"] = {"a", "a", "a", "a", "a", "a"};
  doc["initial"] = {{"q", {"p0", 0, 0, 0, 0, 0}}, {"v", {0, 0, 0, 0, 0, 0}}};
  doc.erase("exact");
  const LagrangianScene coupled = load_scene(doc);
  EXPECT_EQ(coupled.compiled->bandwidth, 2);  // C(0, 2) and C(2, 0) from dM_00/dz
  EXPECT_EQ(coupled.settings.bandwidth, 2);
}

// The friction bar (64 coordinates, tridiagonal M) runs on banded LU, says so, and gives what dense LU
// gives, to round-off, while it moves (until t = 0.3; it rests from 0.379).
TEST(Scene, FrictionBarRunsOnBandedLuAndMatchesDenseLu) {
  json doc = Scene("friction-bar.json");
  doc["integrator"]["t_end"] = 0.3;
  LagrangianScene banded = load_scene(doc);
  // By default the bar runs on the large ABL path (its structure, 64 >= kLargeAblFromDof; compared with the
  // dense scheme in large_abl_test.cc); here the dense scheme's two factorisations are compared.
  EXPECT_TRUE(uses_large_abl_path(banded));
  auto compiled = std::make_shared<CompiledLagrangian>(*banded.compiled);
  compiled->large_abl = nullptr;
  banded.compiled = compiled;
  ASSERT_EQ(banded.n, 64);
  ASSERT_EQ(banded.settings.bandwidth, 1);
  LagrangianScene dense = banded;
  dense.settings.bandwidth = -1;
  const RunSummary a = run_scene(banded, nullptr);
  const RunSummary b = run_scene(dense, nullptr);
  ASSERT_EQ(a.status, RunStatus::kCompleted) << a.message;
  ASSERT_EQ(b.status, RunStatus::kCompleted) << b.message;
  EXPECT_EQ(a.solver.linear_solver, "banded LU with partial pivoting, bandwidth 1");
  EXPECT_EQ(b.solver.linear_solver,
            "dense LU with partial pivoting, of a step's first pattern, updated for its later patterns");  // n = 64, separable phi
  EXPECT_EQ(a.solver.fallback_steps, 0);
  ASSERT_EQ(a.q_final.size(), 64u);
  double vmax = 0.0;
  for (int i = 0; i < 64; ++i) {
    EXPECT_NEAR(a.q_final[i], b.q_final[i], 1e-12) << i;
    EXPECT_NEAR(a.v_final[i], b.v_final[i], 1e-11) << i;
    EXPECT_EQ(a.v_final[i] == 0.0, b.v_final[i] == 0.0) << i;  // the same nodes stick
    vmax = std::max(vmax, std::abs(a.v_final[i]));
  }
  EXPECT_GT(vmax, 1e-3) << "still moving at t = 0.3: every step solved a real system";
}

// A URDF robot's joints name its coordinates, under the same rule as system.coordinates: a joint whose
// (sanitized) name is one of the trajectory's own columns, or another joint's velocity <name>_dot, is
// refused at /system/urdf/text, naming the joint and the line of its <joint> element.
std::string two_joint_urdf(const std::string& first, const std::string& second) {
  const std::string inertial =
      "<inertial><mass value=\"1\"/><inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" izz=\"0.1\"/></inertial>";
  const std::string limit = "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>";
  return "<robot name=\"two\">\n"  // line 1
         "<!-- <joint name=\"" +
         second +
         "\" type=\"revolute\"> in a comment is not the joint -->\n"  // line 2
         "<link name=\"base\"/>\n"                                    // line 3
         "<joint name=\"" +
         first +
         "\" type=\"revolute\">\n"  // line 4
         "<parent link=\"base\"/><child link=\"l1\"/><axis xyz=\"0 0 1\"/>" +
         limit +
         "\n</joint>\n"  // lines 5-6
         "<link name=\"l1\">" +
         inertial +
         "</link>\n"  // line 7
         "<joint name=\"" +
         second +
         "\" type=\"revolute\">\n"  // line 8
         "<parent link=\"l1\"/><child link=\"l2\"/><origin xyz=\"1 0 0\"/><axis xyz=\"0 0 1\"/>" +
         limit +
         "\n</joint>\n"
         "<link name=\"l2\">" +
         inertial +
         "</link>\n"
         "</robot>\n";
}

json two_joint_scene(const std::string& first, const std::string& second) {
  return {{"name", "two joints"},
          {"system", {{"type", "lagrangian"}, {"urdf", {{"text", two_joint_urdf(first, second)}}}}},
          {"initial", {{"q", {0.1, 0.2}}}},
          {"integrator", {{"h", 1e-3}, {"t_end", 0.01}}}};
}

std::string scene_error(const json& doc) {
  try {
    load_scene(doc);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Scene, UrdfJointNamesFollowTheCoordinateNameRule) {
  // Names that are free: the coordinates are the joints, their velocities <joint>_dot.
  const LagrangianScene ok = load_scene(two_joint_scene("a", "b"));
  EXPECT_EQ(ok.coordinates, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(ok.velocities, (std::vector<std::string>{"a_dot", "b_dot"}));

  EXPECT_EQ(scene_error(two_joint_scene("h", "energy")),
            "/system/urdf/text: joint 'h' (line 4): 'h' is reserved: the trajectory has its own column 'h' (the step size)");
  EXPECT_EQ(scene_error(two_joint_scene("j1", "energy")),
            "/system/urdf/text: joint 'energy' (line 8): 'energy' is reserved: the trajectory has its own column 'energy' (the energy)");
  EXPECT_EQ(scene_error(two_joint_scene("t", "j2")),
            "/system/urdf/text: joint 't' (line 4): 't' is reserved: the trajectory has its own column 't' (the time)");
  EXPECT_EQ(scene_error(two_joint_scene("a", "a_dot")),
            "/system/urdf/text: joint 'a_dot' (line 8): 'a_dot' is the name of the velocity of coordinate 'a' (its column in the "
            "trajectory and its name in expressions): give this coordinate another name");
  EXPECT_EQ(scene_error(two_joint_scene("b_dot", "b"))
                .rfind("/system/urdf/text: joint 'b_dot' (line 4): 'b_dot' is the name of the "
                       "velocity of coordinate 'b'",
                       0),
            0u)
      << scene_error(two_joint_scene("b_dot", "b"));
  // A joint name an expression cannot use is sanitized first ('-' becomes '_'); the rule holds for the
  // name it gives, and the error says both.
  EXPECT_EQ(scene_error(two_joint_scene("a", "a-dot"))
                .rfind("/system/urdf/text: joint 'a-dot' (line 8) gives the coordinate name "
                       "'a_dot': 'a_dot' is the name of the velocity of coordinate 'a'",
                       0),
            0u)
      << scene_error(two_joint_scene("a", "a-dot"));
  EXPECT_EQ(scene_error(two_joint_scene("a-b", "a_b")), "/system/urdf/text: joint 'a_b' (line 8): duplicate name 'a_b'");
}

// JSON has no NaN or infinity: a writer puts null for them (never an invalid document, never a string),
// the reader of that JSON gets NaN back, and the document read back equals the value written.
TEST(JsonNumber, NonFiniteValuesAreNullAndReadBackAsNaN) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  for (const double v : {nan, -nan, inf, -inf}) {
    const nlohmann::json j = finite_or_null(v);
    EXPECT_TRUE(j.is_null());
    EXPECT_TRUE(std::isnan(number_or_nan(j)));
  }
  EXPECT_EQ(finite_or_null(0.1).get<double>(), 0.1);
  EXPECT_TRUE(std::signbit(finite_or_null(-0.0).get<double>()));
  const nlohmann::json doc = {{"error", finite_or_null(nan)}, {"h", finite_or_null(0.1)}};
  EXPECT_EQ(doc.dump(), R"({"error":null,"h":0.1})");
  EXPECT_EQ(nlohmann::json::parse(doc.dump()), doc);
  EXPECT_EQ(number_or_nan(nlohmann::json::parse("0.1")), 0.1);
  EXPECT_EQ(number_or_nan(nlohmann::json(3)), 3.0);
  EXPECT_TRUE(std::isnan(number_or_nan(nlohmann::json("1"))));
}

}  // namespace
}  // namespace moreau::scene
