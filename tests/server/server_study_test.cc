// POST /v1/studies over HTTP, in-process: the table equals scene::run_study on the same scene and
// settings, the work and order figures are PNGs, bad study settings get their pointer, a running study
// cancels, and a finished one is served again after a restart.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "moreau/analysis/study.h"
#include "server_fixture.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::read_json_file;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final_study;
using moreau::test_support::TempDir;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

httplib::Result post_study(httplib::Client& c, const json& body) { return c.Post("/v1/studies", body.dump(), "application/json"); }

// Width and height from a PNG's IHDR chunk (bytes 16..23, big-endian).
std::pair<std::uint32_t, std::uint32_t> png_size(const std::string& png) {
  EXPECT_GE(png.size(), 24u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  auto be32 = [&](std::size_t at) {
    return (std::uint32_t(std::uint8_t(png[at])) << 24) | (std::uint32_t(std::uint8_t(png[at + 1])) << 16) |
           (std::uint32_t(std::uint8_t(png[at + 2])) << 8) | std::uint32_t(std::uint8_t(png[at + 3]));
  };
  return {be32(16), be32(20)};
}

const json kSettings = {{"h", "1e-2:1e-3:3"}, {"schemes", {"abl", "explicit"}}, {"repeats", 1}, {"eval_points", 200}};

TEST(ServerStudy, TableEqualsTheLibraryStudyAndFiguresAreDrawn) {
  TestServer ts;
  auto c = ts.client();
  auto r = post_study(*c, {{"scene", "damped-relay"}, {"study", kSettings}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const json accepted = json::parse(r->body);
  const std::string id = accepted["id"];
  EXPECT_EQ(accepted["kind"], "study");
  EXPECT_EQ(r->get_header_value("Location"), "/v1/studies/" + id);
  EXPECT_EQ(accepted["progress"]["rows_total"], 6);

  const json final = wait_final_study(*c, id, 60);
  ASSERT_EQ(final["state"], "done") << final.dump();
  EXPECT_EQ(final["progress"]["rows"], 6);
  EXPECT_EQ(final["result"]["reference"], "exact solution");
  EXPECT_EQ(final["links"]["csv"], "/v1/studies/" + id + "/table?format=csv");

  // The same study in-process: every error, step count and order is identical (the runs are
  // deterministic; only wall times differ).
  const auto sc = moreau::scene::load_scene(read_json_file("scenes/damped-relay.json"));
  const auto local = moreau::scene::run_study(sc, moreau::scene::study_settings_from_json(kSettings, "/study"));
  auto table = c->Get("/v1/studies/" + id + "/table");
  ASSERT_EQ(table->status, 200);
  EXPECT_EQ(table->get_header_value("Content-Type"), "application/json");
  const json served = json::parse(table->body);
  ASSERT_EQ(served["rows"].size(), local.rows.size());
  for (std::size_t i = 0; i < local.rows.size(); ++i) {
    const json& row = served["rows"][i];
    const auto& want = local.rows[i];
    EXPECT_EQ(row["scheme"], moreau::scene::scheme_name(want.scheme));
    EXPECT_EQ(row["h"].get<double>(), want.h);
    EXPECT_EQ(row["status"], "completed");
    EXPECT_EQ(row["steps"].get<std::int64_t>(), want.steps);
    EXPECT_EQ(row["q_max_error"].get<double>(), want.q_max_error);
    EXPECT_EQ(row["v_l2_error"].get<double>(), want.v_l2_error);
    EXPECT_EQ(row["final_error"].get<double>(), want.final_error);
    EXPECT_EQ(row["chatter_sign_changes"].get<std::int64_t>(), want.chatter_sign_changes);
    EXPECT_GT(row["wall_seconds"].get<double>(), 0.0);
  }
  ASSERT_EQ(served["orders"].size(), 2u);
  EXPECT_EQ(served["orders"][0]["q_max"].get<double>(), local.orders[0].q_max);

  auto csv = c->Get("/v1/studies/" + id + "/table?format=csv");
  ASSERT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Content-Type"), "text/csv");
  EXPECT_THAT(csv->body, ::testing::StartsWith("scheme,h,status,steps,wall_seconds,q_max_error"));
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 7);

  for (const char* kind : {"work", "order"}) {
    auto fig = c->Get("/v1/studies/" + id + "/figure?kind=" + kind);
    ASSERT_EQ(fig->status, 200) << kind << ": " << fig->body;
    EXPECT_EQ(fig->get_header_value("Content-Type"), "image/png");
    EXPECT_EQ(png_size(fig->body), std::make_pair(1200u, 800u));
    EXPECT_TRUE(fs::exists(ts.data() / "jobs" / id / (std::string("figure-") + kind + ".png")));
  }
  auto small = c->Get("/v1/studies/" + id + "/figure?kind=order&width=640&height=400");
  ASSERT_EQ(small->status, 200);
  EXPECT_EQ(png_size(small->body), std::make_pair(640u, 400u));

  auto svg = c->Get("/v1/studies/" + id + "/figure?kind=work&format=svg");
  ASSERT_EQ(svg->status, 200) << svg->body;
  EXPECT_EQ(svg->get_header_value("Content-Type"), "image/svg+xml");
  EXPECT_THAT(svg->body, ::testing::HasSubstr("<svg"));

  // Every integration counts in /metrics: the study's runs are integration time (at least the sum of
  // the rows' times) and steps.
  const std::string metrics = c->Get("/metrics")->body;
  const auto metric = [&](const std::string& name) {
    const auto at = metrics.find("\n" + name + " ");
    EXPECT_NE(at, std::string::npos) << name;
    return at == std::string::npos ? -1.0 : std::stod(metrics.substr(at + name.size() + 2));
  };
  double rows_seconds = 0.0;
  std::int64_t rows_steps = 0;
  for (const json& row : served["rows"]) {
    rows_seconds += row["wall_seconds"].get<double>();
    rows_steps += row["steps"].get<std::int64_t>();
  }
  EXPECT_GE(metric("moreau_integrate_seconds_total"), rows_seconds);
  EXPECT_EQ(metric("moreau_steps_total"), static_cast<double>(rows_steps));

  // Studies and jobs are listed apart; a study id is not a job.
  const json studies = json::parse(c->Get("/v1/studies")->body);
  EXPECT_EQ(studies["count"], 1);
  EXPECT_EQ(studies["studies"][0]["id"], id);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["count"], 0);
  EXPECT_EQ(c->Get("/v1/jobs/" + id)->status, 404);
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/figure?kind=state")->status, 400);
  EXPECT_EQ(c->Delete("/v1/studies/" + id)->status, 409);
}

struct BadStudy {
  const char* name;
  json body;
  int status;
  const char* pointer;
  const char* where;
  const char* reason;
};

TEST(ServerStudy, BadStudiesNameTheField) {
  json ball = read_json_file("scenes/bouncing-ball-e0.5.json");
  const BadStudy cases[] = {
      {"ladder",
       {{"scene", "damped-relay"}, {"study", {{"h", "1e-2:0:3"}}}},
       400,
       "/study/h",
       "request",
       "not a positive finite step size"},
      {"ladder_count", {{"scene", "damped-relay"}, {"study", {{"h", "1e-2:1e-3:1"}}}}, 400, "/study/h", "request", "COUNT"},
      {"h_negative", {{"scene", "damped-relay"}, {"study", {{"h", {1e-2, -1e-3}}}}}, 400, "/study/h/1", "request", "positive"},
      {"h_type", {{"scene", "damped-relay"}, {"study", {{"h", true}}}}, 400, "/study/h", "request", "ladder"},
      {"scheme",
       {{"scene", "damped-relay"}, {"study", {{"schemes", {"abl", "rk4"}}}}},
       400,
       "/study/schemes/1",
       "request",
       "unknown scheme 'rk4'"},
      {"scheme_twice", {{"scene", "damped-relay"}, {"study", {{"schemes", "abl,abl"}}}}, 400, "/study/schemes", "request", "twice"},
      {"repeats", {{"scene", "damped-relay"}, {"study", {{"repeats", 0}}}}, 400, "/study/repeats", "request", "integer in [1, 20]"},
      {"eval_points", {{"scene", "damped-relay"}, {"study", {{"eval_points", 1.5}}}}, 400, "/study/eval_points", "request", "integer"},
      {"regularization",
       {{"scene", "damped-relay"}, {"study", {{"regularization", "atan"}}}},
       400,
       "/study/regularization",
       "request",
       "tanh"},
      {"unknown_setting", {{"scene", "damped-relay"}, {"study", {{"tolerance", 1}}}}, 400, "/study/tolerance", "request", "unknown field"},
      {"study_type", {{"scene", "damped-relay"}, {"study", "fast"}}, 400, "/study", "request", "expected an object"},
      {"unknown_field", {{"scene", "damped-relay"}, {"stream", true}}, 400, "/stream", "request", "expected scene, overrides, study"},
      {"no_scene", {{"study", json::object()}}, 400, "/scene", "request", "missing required field"},
      {"too_much_work", {{"scene", "damped-relay"}, {"study", {{"h", {1e-9}}}}}, 400, "/study/h", "request", "integration steps"},
      {"h_longer_than_the_interval",
       {{"scene", "damped-relay"}, {"study", {{"h", {1e-2, 1e9}}}}},
       400,
       "/study/h",
       "request",
       "longer than the interval"},
      // Said to a user, not to a programmer: no internal function names.
      {"lure", {{"scene", "lure-relay"}}, 400, "/system/type", "scene", "studies compare schemes for Lagrangian systems; a Lur'e system"},
      {"constraints", {{"scene", ball}}, 400, "/system/constraints", "scene", "unilateral constraints"},
      {"bad_scene", {{"scene", "damped-relay"}, {"overrides", {"integrator.h=-1"}}}, 400, "/integrator/h", "scene", ""},
  };
  TestServer ts;
  auto c = ts.client();
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    auto r = post_study(*c, k.body);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, k.status) << r->body;
    const json e = json::parse(r->body);
    EXPECT_EQ(e.value("pointer", ""), k.pointer) << r->body;
    EXPECT_EQ(e.value("where", ""), k.where) << r->body;
    EXPECT_THAT(e.value("reason", ""), ::testing::HasSubstr(k.reason)) << r->body;
    EXPECT_THAT(e.value("reason", ""), ::testing::Not(::testing::HasSubstr("()"))) << "an internal function name: " << r->body;
  }
  auto r = c->Post("/v1/studies", kSettings.dump(), "text/plain");
  EXPECT_EQ(r->status, 415);
  r = c->Post("/v1/studies", "{\"scene\": \"damped-relay\", \"study\": {", "application/json");
  EXPECT_EQ(r->status, 400);
  EXPECT_EQ(json::parse(r->body)["error"], "malformed JSON");
  EXPECT_EQ(json::parse(c->Get("/v1/studies")->body)["total"], 0) << "nothing was queued";
  EXPECT_EQ(c->Get("/v1/studies/0123456789abcdef0123456789abcdef")->status, 404);
}

TEST(ServerStudy, CancellingARunningStudyStopsIt) {
  TestServer ts;
  auto c = ts.client();
  // The manipulator over a fine ladder: seconds of work, cancelled after it starts.
  auto r = post_study(*c, {{"scene", "manipulator"},
                           {"overrides", {"integrator.t_end=50"}},
                           {"study", {{"h", "1e-3:1e-5:3"}, {"schemes", "abl"}, {"repeats", 3}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  while (json::parse(c->Get("/v1/studies/" + id)->body)["state"] == "queued" && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  auto d = c->Delete("/v1/studies/" + id);
  ASSERT_TRUE(d->status == 202 || d->status == 200) << d->body;  // 200 if it had not left the queue yet
  const json j = wait_final_study(*c, id);
  EXPECT_EQ(j["state"], "cancelled") << j.dump();
  EXPECT_THAT(j["reason"].get<std::string>(), ::testing::HasSubstr("cancelled"));
  // Stopped inside its first rows, not after them (promptness inside a run, in steps, is
  // Study.CancelStopsTheStudyBetweenAndInsideRuns).
  EXPECT_LT(j["progress"]["rows"].get<std::int64_t>(), j["progress"]["rows_total"].get<std::int64_t>());
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/table")->status, 409);
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/figure")->status, 409);
}

TEST(ServerStudy, AFinishedStudyIsServedAgainAfterARestart) {
  TempDir data;
  std::string id, table, csv;
  {
    TestServer first;
    auto c = first.client();
    auto r = post_study(*c, {{"scene", "damped-relay"}, {"study", kSettings}});
    ASSERT_EQ(r->status, 202);
    id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_final_study(*c, id, 60)["state"], "done");
    table = c->Get("/v1/studies/" + id + "/table")->body;
    csv = c->Get("/v1/studies/" + id + "/table?format=csv")->body;
    data = first.release_data();
  }
  TestServer second(ServerConfig{}, data.path());
  auto c = second.client();
  const json j = json::parse(c->Get("/v1/studies/" + id)->body);
  EXPECT_EQ(j["state"], "done");
  EXPECT_EQ(j["kind"], "study");
  EXPECT_EQ(j["progress"]["rows"], 6);
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/table")->body, table);
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/table?format=csv")->body, csv);
  EXPECT_EQ(c->Get("/v1/studies/" + id + "/figure?kind=work")->status, 200);
}

}  // namespace
