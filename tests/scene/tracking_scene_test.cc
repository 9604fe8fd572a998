// Tracking scenes (/system/tracking) run through Simulation, against closed forms of the 1-DOF plant
// m q'' = u + d (the scene's F = -d on the left of ABL (0.1)), derived in docs/tracking.md:
//   - continuous loop, |d| <= D < a: m |s0| / (a + D) <= t_r <= m |s0| / (a - D), sigma == 0.0 exactly after
//     t_r, then e(t) = e(t_r) exp(-Lambda (t - t_r));
//   - implicit digital controller, constant d = D0, q_d'' = 0: the fixed point u = -D0, sigma = D0 T_s / m,
//     e = D0 T_s / (m Lambda), with u of one sign once e's transient has passed;
//   - explicit digital controller: u switches sign at a rate of order 1 / T_s after reaching.
#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "moreau/platform/number_text.h"
#include "moreau/scene/simulation.h"
#include "support/one_dof_tracking.h"
#include "support/scratch_dir.h"

namespace {

using moreau::RunObserver;
using moreau::RunSummary;
using moreau::Sample;
using moreau::scene::Simulation;

// Every sample: t, q, v and the signals (qd, e, sigma, u for the one coordinate).
struct Recorder : RunObserver {
  std::vector<double> t, q, v, qd, e, sigma, u;
  void on_sample(const Sample& s) override {
    t.push_back(s.t);
    q.push_back(s.q[0]);
    v.push_back(s.v[0]);
    EXPECT_EQ(s.m, 4);
    qd.push_back(s.signals[0]);
    e.push_back(s.signals[1]);
    sigma.push_back(s.signals[2]);
    u.push_back(s.signals[3]);
  }
};

nlohmann::json one_dof(const std::string& force, const std::string& reference, const nlohmann::json& tracking_extra, double h, double t_end,
                       double q0, double v0) {
  return moreau::test_support::one_dof_tracking(force, reference, tracking_extra, h, t_end, q0, v0);
}

// The digital controller `law` at T_s on m = 2 under the constant d = D0 = 1 (F = -1), tracking
// q_d = 0.5 t (q_d'' = 0) from x = 0.2 at rest for 10 s, the plant at h = T_s / 10.
RunSummary constant_perturbation_run(const std::string& law, double Ts, Recorder& r) {
  return Simulation::from_json(one_dof("-1", "0.5*t", {{"law", law}, {"period", Ts}}, Ts / 10, 10.0, 0.2, 0.0)).run(&r);
}

TEST(TrackingScene, ContinuousLoopReachesWithinTheClosedFormBoundsAndStaysExactlyOnTheSurface) {
  // d = 1.5 sin(5 t) (F = -d), D = 1.5 < a = 4, m = 2; q_d = sin(t); sigma(0) = v0 - 1 + 3 (q0 - 0) = 2.
  const double m = 2.0, a = 4.0, D = 1.5, lambda = 3.0, h = 1e-4;
  const Simulation sim = Simulation::from_json(one_dof("-1.5*sin(5*t)", "sin(t)", nlohmann::json::object(), h, 4.0, 0.5, 1.5));
  Recorder r;
  const RunSummary s = sim.run(&r);
  ASSERT_EQ(s.status, moreau::RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.tracking && s.tracking->reached);
  const double s0 = 1.5 - 1.0 + lambda * 0.5;
  EXPECT_DOUBLE_EQ(r.sigma.front(), s0);
  const double tr = s.tracking->reaching_time;
  EXPECT_GE(tr, m * s0 / (a + D) - h);
  EXPECT_LE(tr, m * s0 / (a - D) + h);
  // After t_r, sigma is 0.0 in every sample (the state's own sigma, recomputed: v - q_d' + Lambda (q - q_d)).
  std::size_t first = 0;
  while (r.t[first] < tr) ++first;
  for (std::size_t k = first; k < r.t.size(); ++k) ASSERT_EQ(r.sigma[k], 0.0) << "t = " << r.t[k];
  // Not before: the sample just before t_r is off the surface.
  ASSERT_GT(first, 0u);
  EXPECT_NE(r.sigma[first - 1], 0.0);
  // On the surface V^k = v_{r,k} and Q^{k+1} = Q^k + h V^k give e_{k+1} = (1 - h Lambda) e_k + h q_d'(t_k) -
  // (q_d(t_{k+1}) - q_d(t_k)), with q_d = sin: the recurrence, from the closed-form reference.
  double e = r.e[first];
  for (std::size_t k = first; k + 1 < r.t.size(); ++k) {
    const double tk = r.t[k], tn = r.t[k + 1];
    e = (1.0 - (tn - tk) * lambda) * e + (tn - tk) * std::cos(tk) - (std::sin(tn) - std::sin(tk));
    ASSERT_NEAR(r.e[k + 1], e, 1e-12) << "t = " << tn;
  }
  // And the continuous e(t_r) exp(-Lambda (t - t_r)) within O(h): the recurrence's own error and its
  // offset h |q_d''| / (2 Lambda).
  const double span = r.t.back() - r.t[first];
  EXPECT_NEAR(r.e.back(), r.e[first] * std::exp(-lambda * span), lambda * span * h * std::abs(r.e[first]) + h / lambda);
  // rho = F with an exact model: |rho| <= D, reached near the maximum of |sin|.
  EXPECT_LE(s.tracking->perturbation_max, D * (1.0 + 1e-12));
  EXPECT_GT(s.tracking->perturbation_max, 0.99 * D);
  EXPECT_DOUBLE_EQ(s.tracking->alpha, a);
  // On the surface q'' = a_r, so u is the equivalent control m a_r - d = m (-sin t + Lambda^2 e) - d(t)
  // (e' = -Lambda e there), within O(h): it follows the perturbation smoothly, no switching.
  for (std::size_t k = first; k + 1 < r.t.size(); ++k) {
    const double tk = r.t[k];
    const double equivalent = m * (-std::sin(tk) + lambda * lambda * r.e[k]) - D * std::sin(5.0 * tk);
    ASSERT_NEAR(r.u[k], equivalent, 2e-3) << "t = " << tk;
  }
}

TEST(TrackingScene, ImplicitDigitalControllerSettlesAtTheClosedFormFixedPointWithoutChattering) {
  const double m = 2.0, D0 = 1.0, lambda = 3.0, Ts = 1e-3;
  Recorder r;
  const RunSummary s = constant_perturbation_run("implicit", Ts, r);
  ASSERT_EQ(s.status, moreau::RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.tracking && s.tracking->reached);
  // e's transient decays as exp(-Lambda t): 0.2 exp(-30) at t = 10 is far below the tolerances.
  EXPECT_NEAR(r.u.back(), -D0, 1e-9);
  // sigma and e at the last sample instant (the last state is one: 10 / 1e-3 samples).
  EXPECT_NEAR(r.sigma.back(), D0 * Ts / m, 1e-9);
  EXPECT_NEAR(r.e.back(), D0 * Ts / (m * lambda), 1e-9);
  // No chattering: once the transient of e has passed (u = m Lambda^2 e - D0 on the surface, one sign
  // change while e decays), u keeps one sign at every sample to the end.
  std::size_t from = 0;
  while (r.t[from] < 2.0) ++from;
  for (std::size_t k = from; k < r.u.size(); ++k) ASSERT_LT(r.u[k], 0.0) << "t = " << r.t[k];
  // After reaching the band, two sign changes in all: at arrival (the last reaching control is -a, the
  // first on the surface m Lambda^2 e - D0 > 0) and the one as e decays; the explicit law's are thousands.
  EXPECT_LE(s.tracking->sign_changes, 2);
  EXPECT_TRUE(s.tracking->predicted_on_surface_time.has_value());
  // The default band 2 a T_s / m holds sigma = D0 T_s / m.
  EXPECT_DOUBLE_EQ(s.tracking->band, 2.0 * 4.0 * Ts / m);
}

TEST(TrackingScene, ExplicitDigitalControllerChattersAtARateOfOrderOneOverTs) {
  const double m = 2.0, a = 4.0, D0 = 1.0, Ts = 1e-3;
  Recorder r;
  const RunSummary s = constant_perturbation_run("explicit", Ts, r);
  ASSERT_EQ(s.status, moreau::RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.tracking && s.tracking->reached);
  // Steps of (a + D0) T_s / m one way and (a - D0) T_s / m the other: a run of one sign lasts at most
  // ceil of their ratio samples, so the sign of u changes between 2 / ((ceil(A/B) + ceil(B/A)) T_s) and 1 / T_s
  // times a second (docs/tracking.md, "Explicit").
  const double A = a + D0, B = a - D0;
  EXPECT_GE(s.tracking->sign_changes_per_second, 2.0 / ((std::ceil(A / B) + std::ceil(B / A)) * Ts) * 0.99);
  EXPECT_LE(s.tracking->sign_changes_per_second, 1.0 / Ts * 1.01);
  // u = -xi switches between about -a and +a (its model part is 0 at rest on the reference): each change
  // moves it by about 2 a.
  EXPECT_GT(s.tracking->total_variation, 1.5 * a * s.tracking->sign_changes);
  // The orbit of sigma stays within the explicit law's peak-to-peak bound 2 a T_s / m.
  EXPECT_LE(s.tracking->sigma_max, 2.0 * a * Ts / m * (1.0 + 1e-9));
}

// The boundary layer of width phi >= a T_s / m is linear inside: under d = D0 it settles at sigma = phi D0 /
// a with u = -D0 (docs/tracking.md, "Boundary layer"), an offset proportional to phi, without chattering.
TEST(TrackingScene, BoundaryLayerSettlesAtSigmaPhiD0OverA) {
  const double m = 2.0, a = 4.0, D0 = 1.0, Ts = 1e-3, phi = 4.0 * a * Ts / m;
  Recorder r;
  const RunSummary s = Simulation::from_json(
                           one_dof("-1", "0.5*t", {{"law", "saturated"}, {"period", Ts}, {"boundary_layer", phi}}, Ts / 10, 10.0, 0.2, 0.0))
                           .run(&r);
  ASSERT_EQ(s.status, moreau::RunStatus::kCompleted) << s.message;
  EXPECT_NEAR(r.sigma.back(), phi * D0 / a, 1e-9);
  EXPECT_NEAR(r.u.back(), -D0, 1e-9);
  std::size_t from = 0;
  while (r.t[from] < 2.0) ++from;
  for (std::size_t k = from; k < r.u.size(); ++k) ASSERT_LT(r.u[k], 0.0) << "t = " << r.t[k];
}

// Measurement noise is drawn from its seed: the same seed gives the same run bit for bit, another seed
// another run; quantisation alone is deterministic and moves the run off the exact measurement's.
TEST(TrackingScene, MeasurementNoiseIsSeededAndQuantisationIsApplied) {
  auto final_q = [](const nlohmann::json& measurement) {
    return Simulation::from_json(
               one_dof("-1", "0.5*t", {{"law", "implicit"}, {"period", 1e-3}, {"measurement", measurement}}, 1e-4, 1.0, 0.2, 0.0))
        .run(nullptr)
        .q_final.at(0);
  };
  const double exact = final_q(nlohmann::json::object());
  const double seven = final_q({{"noise", 1e-4}, {"seed", 7}});
  EXPECT_EQ(final_q({{"noise", 1e-4}, {"seed", 7}}), seven);
  EXPECT_NE(final_q({{"noise", 1e-4}, {"seed", 8}}), seven);
  EXPECT_NE(seven, exact);
  EXPECT_NE(final_q({{"quantum", 1e-3}}), exact);
  EXPECT_EQ(final_q({{"quantum", 1e-3}}), final_q({{"quantum", 1e-3}}));
}

// Way points: the natural cubic spline of a line is the line, so a run tracking way points of
// q_d = 0.5 t is the run tracking the expression 0.5*t, to round-off; from a CSV file (with a header)
// read with the scene, the same. Bad files and intervals the points do not cover are named.
TEST(TrackingScene, WayPointsFromTheSceneOrACsvFile) {
  auto scene = [](const nlohmann::json& reference) {
    nlohmann::json doc = one_dof("-1", "0.5*t", {{"law", "implicit"}, {"period", 1e-3}}, 1e-4, 2.0, 0.2, 0.0);
    doc["system"]["tracking"]["reference"] = reference;
    return doc;
  };
  nlohmann::json points = nlohmann::json::array();
  std::string csv = "t,x\n";
  for (int j = 0; j <= 4; ++j) {
    points.push_back({0.5 * j, 0.25 * j});
    csv += moreau::platform::shortest(0.5 * j) + "," + moreau::platform::shortest(0.25 * j) + "\n";
  }
  const double expression = Simulation::from_json(scene({"0.5*t"})).run(nullptr).q_final.at(0);
  const nlohmann::json inline_points = {{"points", points}, {"interpolation", "natural-cubic"}};
  EXPECT_NEAR(Simulation::from_json(scene(inline_points)).run(nullptr).q_final.at(0), expression, 1e-12);

  const std::string dir = moreau::test_support::scratch_dir();
  const auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + "/" + name) << text;
    return dir + "/" + name;
  };
  write("way.csv", csv);
  const std::string path = write("way-scene.json", scene({{"csv", "way.csv"}}).dump());
  EXPECT_NEAR(Simulation::from_file(path).run(nullptr).q_final.at(0), expression, 1e-12);

  auto error_of = [](auto&& load) -> std::string {
    try {
      load();
    } catch (const moreau::scene::SceneError& e) {
      return e.what();
    }
    return "no error";
  };
  write("bad.csv", "t,x\n0,0\n1,zero\n");
  const std::string bad = write("bad-scene.json", scene({{"csv", "bad.csv"}}).dump());
  EXPECT_NE(error_of([&] { Simulation::from_file(bad); }).find("/system/tracking/reference/csv: '"), std::string::npos)
      << error_of([&] { Simulation::from_file(bad); });
  EXPECT_NE(error_of([&] { Simulation::from_file(bad); }).find("line 3"), std::string::npos);
  nlohmann::json short_points = {{"points", {{0.0, 0.0}, {1.0, 0.5}}}};
  EXPECT_NE(error_of([&] { Simulation::from_json(scene(short_points)); }).find("/system/tracking/reference/points"), std::string::npos);
  nlohmann::json unordered = {{"points", {{0.0, 0.0}, {3.0, 0.5}, {2.0, 1.0}}}};
  EXPECT_NE(error_of([&] { Simulation::from_json(scene(unordered)); }).find("increase strictly"), std::string::npos);
  EXPECT_NE(error_of([&] {
              Simulation::from_json(scene({{"points", points}, {"interpolation", "linear"}}));
            }).find("/system/tracking/reference/interpolation"),
            std::string::npos);
}

TEST(TrackingScene, SignalsAreNamedPerCoordinate) {
  const Simulation sim = Simulation::from_json(one_dof("0", "sin(t)", nlohmann::json::object(), 1e-3, 0.01, 0.0, 0.0));
  EXPECT_EQ(sim.signal_names(), (std::vector<std::string>{"qd_x", "e_x", "sigma_x", "u_x"}));
}

TEST(TrackingScene, BadFieldsAreNamedByPointer) {
  auto error_at = [](nlohmann::json doc) {
    try {
      Simulation::from_json(doc);
    } catch (const moreau::scene::SceneError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  nlohmann::json doc = one_dof("0", "sin(t)", nlohmann::json::object(), 1e-3, 1.0, 0.0, 0.0);
  doc["system"]["tracking"]["lambda"] = {-1.0};
  EXPECT_NE(error_at(doc).find("/system/tracking/lambda/0"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(t)", {{"law", "implicit"}}, 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("period"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(q)", nlohmann::json::object(), 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("/system/tracking/reference/0"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(t)", {{"nominal", {{"parameters", {{"mass", 1.0}}}}}}, 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("/system/tracking/nominal/parameters/mass"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(t)", {{"law", "sampled"}}, 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("/system/tracking/law"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(t)", nlohmann::json::object(), 1e-3, 1.0, 0.0, 0.0);
  doc["integrator"]["scheme"] = "abl";
  EXPECT_NE(error_at(doc).find("/integrator/scheme"), std::string::npos) << error_at(doc);
  // A period longer than the run (its steps per sample would be unbounded), or not a whole number of h.
  doc = one_dof("0", "sin(t)", {{"law", "implicit"}, {"period", 1e300}}, 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("/system/tracking/period"), std::string::npos) << error_at(doc);
  doc = one_dof("0", "sin(t)", {{"law", "implicit"}, {"period", 2.5e-3}}, 1e-3, 1.0, 0.0, 0.0);
  EXPECT_NE(error_at(doc).find("/system/tracking/period"), std::string::npos) << error_at(doc);
}

}  // namespace
