// Studies against a scene's exact solution: the ABL scheme's measured order on constant M is 1 and it
// never chatters; the explicit peer chatters; the timing protocol and the table's shape.
#include "moreau/analysis/study.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <functional>
#include <limits>

#include <Eigen/Dense>

#include "moreau/core/models/manipulator.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {
namespace {

TEST(Study, LadderParsing) {
  const auto h = parse_ladder("1e-1:1e-5:9");
  ASSERT_EQ(h.size(), 9u);
  EXPECT_DOUBLE_EQ(h.front(), 1e-1);
  EXPECT_NEAR(h.back(), 1e-5, 1e-20);
  EXPECT_NEAR(h[4], 1e-3, 1e-18);
  EXPECT_EQ(parse_ladder("1e-2,5e-3").size(), 2u);
  EXPECT_THROW(parse_ladder("1e-2:0:3"), SceneError);
  EXPECT_THROW(parse_ladder("1e-2:1e-3:1"), SceneError);
  EXPECT_THROW(parse_ladder("abc"), SceneError);
}

TEST(Study, DampedRelayAgainstItsExactSolution) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  StudySettings st;
  st.h = parse_ladder("1e-2:1e-4:3");
  st.repeats = 2;
  const StudyResult r = run_study(sc, st);
  EXPECT_EQ(r.reference, "exact solution");
  ASSERT_EQ(r.rows.size(), 9u);
  for (const auto& row : r.rows) {
    EXPECT_EQ(row.status, "completed") << scheme_name(row.scheme) << " " << row.h << " " << row.message;
    EXPECT_GT(row.q_max_error, 0.0);
    // The row's time is the minimum over `repeats` timed runs (one only when a run is longer than
    // single_run_seconds, which then is the row's time).
    if (row.wall_seconds <= st.single_run_seconds) {
      EXPECT_EQ(row.timed_runs, st.repeats) << scheme_name(row.scheme) << " " << row.h;
    } else {
      EXPECT_EQ(row.timed_runs, 1);
    }
    if (row.scheme == Scheme::kAbl) {
      EXPECT_EQ(row.chatter_sign_changes, 0) << "the implicit scheme rests exactly";
      EXPECT_EQ(row.chatter_amplitude, 0.0);
      ASSERT_TRUE(row.converged_time_error.has_value());
      EXPECT_LE(*row.converged_time_error, 2 * row.h);
    }
    if (row.scheme == Scheme::kExplicit) {
      EXPECT_GT(row.chatter_sign_changes, 0) << row.h;
    }
  }
  // Each row's time is one of its timed runs, all of which ran inside the study's own wall time.
  double rows_seconds = 0.0;
  for (const auto& row : r.rows) rows_seconds += row.wall_seconds;
  EXPECT_LE(rows_seconds, r.wall_seconds);
  ASSERT_EQ(r.orders.size(), 3u);
  EXPECT_EQ(r.orders[0].scheme, Scheme::kAbl);
  EXPECT_NEAR(r.orders[0].q_max, 1.0, 0.1);  // Remark 5.1: order 1 for constant M
  EXPECT_NEAR(r.orders[0].v_max, 1.0, 0.1);
  // The summary cites Remark 5.1 (M is constant here) and nothing for the other schemes.
  EXPECT_EQ(r.orders[0].theory, "Remark 5.1");
  ASSERT_TRUE(r.orders[0].theory_order.has_value());
  EXPECT_EQ(*r.orders[0].theory_order, 1.0);
  EXPECT_EQ(r.orders[1].theory, "none");
  EXPECT_FALSE(r.orders[1].theory_order.has_value());
  EXPECT_NE(r.to_text().find("theory: Remark 5.1, order 1.000"), std::string::npos) << r.to_text();
  const std::string csv = r.to_csv();
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 10);
  EXPECT_EQ(r.to_json()["rows"].size(), 9u);
}

// The manipulator's M depends on q: Theorem 5.2 would need Assumption 5.2, which the paper says fails for
// this robot and which is not checked, so no order is promised (never "Theorem 5.2, order 1/2").
TEST(Study, ManipulatorOrderIsAttributedToNoTheorem) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json"));
  const StudyResult::Order o = order_theory(sc, Scheme::kAbl);
  EXPECT_EQ(o.theory, "none");
  EXPECT_FALSE(o.theory_order.has_value());
  EXPECT_NE(o.theory_note.find("Assumption 5.2"), std::string::npos);
  StudyResult r;
  r.orders.push_back(o);
  const StudyResult back = StudyResult::from_json(r.to_json());
  EXPECT_EQ(back.orders[0].theory, "none");
  EXPECT_EQ(back.orders[0].theory_note, o.theory_note);
  const LagrangianScene relay = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  EXPECT_EQ(order_theory(relay, Scheme::kAbl).theory, "Remark 5.1");
  EXPECT_EQ(order_theory(relay, Scheme::kRegularized).theory, "none");
}

// A study's summary has the guarantees section of each of its runs, as `moreau run` has it.
// References: for the damped relay C = 0, so r_k of Theorem 4.1's (4.2) is 0 at every step and every h,
// and M = m > 0 (Assumption 3.1, for the explicit peer too); no theorem covers the regularized peer. For
// the manipulator at h = 1 with v0 = (10, 10), r_0 = 2 h ||C(q0, v0)||_2 / lambda_min(M(q0)) > 1 from the
// paper's closed-form M and C (models::Manipulator): the row fails from its first step, while a row at
// a step 1000 times smaller holds there; each row's section is the one `moreau run` computes for the same
// scene and h.
TEST(Study, EveryRowCarriesItsRunsGuarantees) {
  const LagrangianScene relay = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  StudySettings st;
  st.h = {1e-2, 1e-3};
  st.repeats = 1;
  const StudyResult r = run_study(relay, st);
  ASSERT_EQ(r.rows.size(), 6u);
  EXPECT_TRUE(r.reference_guarantees.is_null());  // the exact solution is the reference
  for (const StudyRow& row : r.rows) {
    if (row.scheme == Scheme::kRegularized) {
      EXPECT_TRUE(row.guarantees.empty());
      continue;
    }
    const std::string relied_on = row.scheme == Scheme::kAbl ? "Theorem 4.1" : "Assumption 3.1";
    bool found = false;
    for (const auto& g : row.guarantees) {
      if (g["result"] != relied_on) continue;
      found = true;
      EXPECT_TRUE(g["relied_on"].get<bool>());
      EXPECT_EQ(g["verdict"], "holds") << g.dump();
    }
    EXPECT_TRUE(found) << scheme_name(row.scheme) << " " << row.h;
  }
  const std::string text = r.to_text();
  EXPECT_NE(text.find("    abl: Theorem 4.1 (relied on): holds at h = 0.01, 0.001\n"), std::string::npos) << text;
  EXPECT_NE(text.find("    explicit: Assumption 3.1 (relied on): holds at h = 0.01, 0.001\n"), std::string::npos) << text;
  EXPECT_NE(text.find("    regularized: no theorem of the papers covers this scheme\n"), std::string::npos) << text;

  const std::vector<std::string> overrides = {"initial.v=[10,10]", "integrator.t_end=3"};
  const Simulation manipulator = Simulation::from_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json", overrides);
  models::Manipulator model;
  LagrangianTerms<2> terms;
  model.evaluate(0.0, Vec<2>(3.0, -1.0), Vec<2>(10.0, 10.0), terms);
  const double r0 =
      2.0 * 1.0 * Eigen::JacobiSVD<Mat<2>>(terms.C).singularValues()(0) / Eigen::SelfAdjointEigenSolver<Mat<2>>(terms.M).eigenvalues()(0);
  ASSERT_GT(r0, 1.0);
  StudySettings ms;
  ms.h = {1.0, 1e-3};
  ms.schemes = {Scheme::kAbl};
  ms.repeats = 1;
  ms.reference_h = 1e-4;
  const StudyResult mr = run_study(*manipulator.lagrangian(), ms);
  ASSERT_EQ(mr.rows.size(), 2u);
  ASSERT_TRUE(mr.reference_guarantees.is_array());
  for (const StudyRow& row : mr.rows) {
    const Simulation same = Simulation::from_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json",
                                                  {overrides[0], overrides[1], "integrator.h=" + std::to_string(row.h)});
    const RunSummary s = same.run(nullptr);
    EXPECT_EQ(row.guarantees, same.report_json(s)["guarantees"]) << row.h;
  }
  EXPECT_EQ(mr.rows[0].guarantees[0]["result"], "Theorem 4.1");
  EXPECT_EQ(mr.rows[0].guarantees[0]["verdict"], "fails");
  EXPECT_EQ(mr.rows[1].guarantees[0]["verdict"], "holds");
  const std::string mtext = mr.to_text();
  EXPECT_NE(mtext.find("    abl: Theorem 4.1 (relied on): fails at h = 1; holds at h = 0.001\n"), std::string::npos) << mtext;
  EXPECT_NE(mtext.find("        first at h = 1, fails: (4.2)"), std::string::npos) << mtext;
  EXPECT_NE(mtext.find("    reference (abl at h = 0.0001): Theorem 4.1 holds"), std::string::npos) << mtext;
}

TEST(Study, ScenesWithConstraintsAreRefused) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/bouncing-ball-e0.5.json"));
  StudySettings st;
  st.h = {1e-2};
  try {
    run_study(sc, st);
    FAIL() << "a study would ignore the ground";
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/system/constraints");
  }
}

TEST(Study, BadSettingsNameTheOption) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  StudySettings st;
  st.h = {1e-2};
  st.schemes = {};
  try {
    run_study(sc, st);
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "--schemes");
  }
  // Names are read once, by the parser: an unknown or repeated one never reaches the settings.
  for (const char* list : {"abl,rk4", "abl,abl", ","}) {
    try {
      parse_study_schemes(list);
      ADD_FAILURE() << list;
    } catch (const SceneError& e) {
      EXPECT_EQ(e.pointer(), "--schemes") << list;
    }
  }
  EXPECT_EQ(parse_study_schemes("regularized,abl"), (std::vector<Scheme>{Scheme::kRegularized, Scheme::kAbl}));
}

TEST(Study, SettingsFromJson) {
  const auto st = study_settings_from_json(nlohmann::json{{"h", {1e-2, 1e-3}},
                                                          {"schemes", "abl,regularized"},
                                                          {"epsilon", 1e-4},
                                                          {"repeats", 2},
                                                          {"eval_points", 50},
                                                          {"regularization", "saturation"},
                                                          {"reference_h", 1e-5}},
                                           "/study");
  EXPECT_EQ(st.h, (std::vector<double>{1e-2, 1e-3}));
  EXPECT_EQ(st.schemes, (std::vector<Scheme>{Scheme::kAbl, Scheme::kRegularized}));
  EXPECT_EQ(st.epsilon, 1e-4);
  EXPECT_EQ(st.repeats, 2);
  EXPECT_EQ(st.eval_points, 50);
  EXPECT_EQ(st.regularization, Regularization::kSaturation);
  EXPECT_EQ(st.reference_h, 1e-5);
  const auto back = study_settings_from_json(study_settings_to_json(st), "/study");
  EXPECT_EQ(back.h, st.h);
  EXPECT_EQ(back.schemes, st.schemes);
  EXPECT_EQ(back.reference_h, st.reference_h);
  EXPECT_EQ(study_settings_to_json(back), study_settings_to_json(st));
  const auto defaults = study_settings_from_json(nlohmann::json(), "/study");
  EXPECT_EQ(defaults.h.size(), 9u) << "the default ladder is 1e-1:1e-5:9";
  EXPECT_EQ(defaults.schemes.size(), 3u);
  try {
    study_settings_from_json(nlohmann::json{{"schemes", {"abl", 3}}}, "/study");
    FAIL();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), "/study/schemes/1");
  }
}

TEST(Study, PlannedStepsCountEveryRun) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  StudySettings st;
  st.h = {1e-2, 1e-3};
  st.schemes = {Scheme::kAbl, Scheme::kExplicit};
  st.repeats = 3;
  const double span = sc.settings.t_end - sc.settings.t0;
  // The scene has an exact solution: no reference run.
  const double want = 2 * 4 * (std::ceil(span / 1e-2) + std::ceil(span / 1e-3));
  EXPECT_EQ(study_planned_steps(sc, st), static_cast<std::int64_t>(want));
  st.reference_h = 1e-4;
  EXPECT_EQ(study_planned_steps(sc, st), static_cast<std::int64_t>(want + std::ceil(span / 1e-4)));
}

TEST(Study, ResultSurvivesJson) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  StudySettings st;
  st.h = {1e-2, 1e-3};
  st.schemes = {Scheme::kAbl, Scheme::kExplicit};
  st.repeats = 1;
  const StudyResult r = run_study(sc, st);
  const StudyResult back = StudyResult::from_json(r.to_json());
  EXPECT_EQ(back.to_json(), r.to_json());
  EXPECT_EQ(back.to_csv(), r.to_csv());
  EXPECT_THROW(StudyResult::from_json(nlohmann::json{{"rows", 1}}), std::invalid_argument);
}

TEST(Study, CancelStopsTheStudyBetweenAndInsideRuns) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json"));
  std::atomic<bool> cancel{false};
  StudySettings st;
  st.h = {1e-2, 1e-3, 1e-4};
  st.schemes = {Scheme::kAbl};
  st.repeats = 1;
  st.cancel = &cancel;
  std::vector<std::size_t> seen;
  st.on_row = [&](std::size_t done, std::size_t total) {
    EXPECT_EQ(total, 3u);
    seen.push_back(done);
    if (done == 1) cancel = true;
  };
  EXPECT_THROW(run_study(sc, st), StudyCancelled);
  EXPECT_EQ(seen, (std::vector<std::size_t>{1}));
  // Inside a run: one long run (6e8 steps), cancelled once it has started, after the check between rows.
  // Without the check inside the run, the study would end normally (there is no row after it).
  cancel = false;
  StudySettings st2 = st;
  st2.on_row = nullptr;
  st2.h = {1e-8};
  bool started = false;
  st2.on_row_start = [&](Scheme, double) {
    started = true;
    cancel = true;
  };
  EXPECT_THROW(run_study(sc, st2), StudyCancelled);
  EXPECT_TRUE(started);
}

// Settings that would put NaN into the table (or overflow a step count) are refused before any run, with
// the option (or the scene field) named. Each case starts from the damped relay with h = {1e-2}.
struct BadStudyCase {
  std::string name;
  std::function<void(StudySettings&, nlohmann::json&)> mutate;
  std::string pointer;
  std::string reason_part;
};

class BadStudy : public ::testing::TestWithParam<BadStudyCase> {};

TEST_P(BadStudy, ErrorNamesTheOption) {
  nlohmann::json doc = read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json");
  StudySettings st;
  st.h = {1e-2};
  st.repeats = 1;
  st.eval_points = 50;
  GetParam().mutate(st, doc);
  const LagrangianScene sc = load_scene(doc);
  try {
    const StudyResult r = run_study(sc, st);
    FAIL() << "ran the study:\n" << r.to_text();
  } catch (const SceneError& e) {
    EXPECT_EQ(e.pointer(), GetParam().pointer) << e.what();
    EXPECT_NE(std::string(e.what()).find(GetParam().reason_part), std::string::npos) << e.what();
  }
}

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

INSTANTIATE_TEST_SUITE_P(
    Study, BadStudy,
    ::testing::Values(
        BadStudyCase{"NaNStep",
                     [](StudySettings& st, nlohmann::json&) {
                       st.h = {1e-2, kNaN};
                     },
                     "--h", "not a positive finite step size"},
        BadStudyCase{"InfiniteStep", [](StudySettings& st, nlohmann::json&) { st.h = {kInf}; }, "--h", "not a positive finite step size"},
        BadStudyCase{"ZeroStep",
                     [](StudySettings& st, nlohmann::json&) {
                       st.h = {1e-2, 0.0};
                     },
                     "--h", "not a positive finite step size"},
        BadStudyCase{"NegativeStep", [](StudySettings& st, nlohmann::json&) { st.h = {-1e-2}; }, "--h", "not a positive finite step size"},
        BadStudyCase{"EmptyLadder", [](StudySettings& st, nlohmann::json&) { st.h.clear(); }, "--h", "empty"},
        BadStudyCase{"StepLongerThanTheInterval",
                     [](StudySettings& st, nlohmann::json&) {
                       st.h = {1e-2, 100.0};
                     },
                     "--h", "longer than the interval"},
        BadStudyCase{"StepCountOverflows", [](StudySettings& st, nlohmann::json&) { st.h = {1e-300}; }, "--h",
                     "steps, more than the limit"},
        BadStudyCase{"StepCountAboveTheScenesLimit",
                     [](StudySettings& st, nlohmann::json& d) {
                       d["integrator"]["max_steps"] = 1000;
                       d["integrator"]["h"] = 1e-2;
                       st.h = {1e-2, 1e-3};
                     },
                     "--h", "more than the limit of 1000"},
        BadStudyCase{"ZeroReferenceStep", [](StudySettings& st, nlohmann::json&) { st.reference_h = 0.0; }, "--reference-h",
                     "not a positive finite step size"},
        BadStudyCase{"NegativeReferenceStep", [](StudySettings& st, nlohmann::json&) { st.reference_h = -1e-4; }, "--reference-h",
                     "not a positive finite step size"},
        BadStudyCase{"NaNReferenceStep", [](StudySettings& st, nlohmann::json&) { st.reference_h = kNaN; }, "--reference-h",
                     "not a positive finite step size"},
        BadStudyCase{"ReferenceStepCountOverflows", [](StudySettings& st, nlohmann::json&) { st.reference_h = 1e-300; }, "--reference-h",
                     "steps, more than the limit"},
        BadStudyCase{"DefaultReferenceStepCountTooLarge",
                     [](StudySettings& st, nlohmann::json& d) {
                       d.erase("exact");
                       st.h = {1e-8};
                     },
                     "--reference-h", "min h / 10"},
        BadStudyCase{"InfiniteEpsilon", [](StudySettings& st, nlohmann::json&) { st.epsilon = kInf; }, "--epsilon", "positive finite"},
        BadStudyCase{"TooManyEvalPoints", [](StudySettings& st, nlohmann::json&) { st.eval_points = 1000000000; }, "--eval-points",
                     "100000"},
        BadStudyCase{"TooManyRepeats", [](StudySettings& st, nlohmann::json&) { st.repeats = 1000; }, "--repeats", "20"},
        // The reference is the scene's closed form: it must be a number at every common time.
        BadStudyCase{"ExactPositionNotFiniteOnTheGrid", [](StudySettings&, nlohmann::json& d) { d["exact"]["q"][0] = "sqrt(3 - t)"; },
                     "/exact/q/0", "not finite at t = "},
        BadStudyCase{"ExactVelocityNotFiniteOnTheGrid", [](StudySettings&, nlohmann::json& d) { d["exact"]["v"][0] = "1/(t - 6)"; },
                     "/exact/v/0", "not finite at t = 6"}),
    [](const auto& info) { return info.param.name; });

// A failed row has no errors: the table shows none (JSON null, an empty CSV cell, "-" in text), never
// "nan", and neither do orders fitted from fewer than two points.
TEST(Study, TablesShowNoNaNForAFailedRow) {
  StudyResult r;
  r.scene = "x";
  r.reference = "exact solution";
  StudyRow row;
  row.scheme = Scheme::kExplicit;
  row.h = 0.1;
  row.status = "failed";
  row.message = "diverged at step 3";
  row.q_max_error = row.q_l2_error = row.v_max_error = row.v_l2_error = row.final_error = kNaN;
  row.chatter_amplitude = kInf;
  r.rows.push_back(row);
  StudyResult::Order order;
  order.scheme = Scheme::kExplicit;
  order.q_max = order.v_max = kNaN;
  r.orders.push_back(order);
  for (const std::string& table : {r.to_csv(), r.to_text(), r.to_json().dump()}) {
    std::string lower = table;
    std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
    EXPECT_EQ(lower.find("nan"), std::string::npos) << table;
    EXPECT_EQ(lower.find("inf"), std::string::npos) << table;
  }
  // h in shortest round-trip form: "0.1" reads back as the double 0.1 (not 17 digits, 0.10000000000000001).
  EXPECT_NE(r.to_csv().find("explicit,0.1,failed,0,0,,,,,,,,0,\n"), std::string::npos) << r.to_csv();
}

}  // namespace
}  // namespace moreau::scene
