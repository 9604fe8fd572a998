// POST /v1/campaigns over HTTP, in-process: the records and the summary equal scene::run_campaign on the
// same spec (sample for sample), progress arrives over SSE, the figures are images, bad campaigns and
// campaigns over this server's limits get their pointer, a cancelled campaign keeps the records of the
// samples that finished, and one a stop interrupted goes on from them when the server restarts.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "moreau/analysis/campaign.h"
#include "server_fixture.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::read_json_file;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::test_support::TempDir;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

httplib::Result post_campaign(httplib::Client& c, const json& body) { return c.Post("/v1/campaigns", body.dump(), "application/json"); }

// Waits (polling its state, never a fixed sleep) until the campaign has finished `samples` samples.
void wait_for_samples(httplib::Client& c, const std::string& id, std::int64_t samples) {
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (true) {
    auto r = c.Get("/v1/campaigns/" + id);
    ASSERT_TRUE(r);
    const json j = json::parse(r->body);
    ASSERT_NE(j["state"], "done") << "the campaign ended before it could be interrupted: make it longer";
    if (j["progress"]["samples"].get<std::int64_t>() >= samples) return;
    ASSERT_LT(Clock::now(), deadline) << j.dump();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// The shipped campaign's inputs (masses, inertia, initial positions) over the shipped scene, shortened.
json campaign_fields(std::int64_t samples, bool full_report) {
  json spec = read_json_file("campaigns/manipulator-robust.json");
  spec.erase("scene");
  spec["samples"] = samples;
  spec["full_report"] = full_report;
  return spec;
}

json body_of(std::int64_t samples, bool full_report, double t_end) {
  return {{"scene", "manipulator-fig6.4"},
          {"overrides", {"integrator.t_end=" + std::to_string(t_end)}},
          {"campaign", campaign_fields(samples, full_report)}};
}

// The records of a JSON Lines text by index, without the wall times (the fields that differ between two
// runs of the same sample: the record's, and the run report's own and per phase).
std::map<std::int64_t, json> records_by_index(const std::string& jsonl) {
  std::map<std::int64_t, json> out;
  std::istringstream in(jsonl);
  for (std::string line; std::getline(in, line);) {
    json r = json::parse(line);
    r.erase("wall_seconds");
    if (r.contains("report")) {
      r["report"].erase("wall_seconds");
      r["report"].erase("phase_seconds");
    }
    const auto i = r["index"].get<std::int64_t>();
    EXPECT_TRUE(out.emplace(i, std::move(r)).second) << "sample " << i << " is present twice";
  }
  return out;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

TEST(ServerCampaign, RecordsAndSummaryEqualTheLocalCampaignAndFiguresAreDrawn) {
  TestServer ts;
  auto c = ts.client();
  const json body = body_of(24, true, 3.0);
  auto r = post_campaign(*c, body);
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const json accepted = json::parse(r->body);
  const std::string id = accepted["id"];
  EXPECT_EQ(accepted["kind"], "campaign");
  EXPECT_EQ(r->get_header_value("Location"), "/v1/campaigns/" + id);
  EXPECT_EQ(accepted["progress"]["samples_total"], 24);

  const json final = wait_final(*c, id, 120, "/v1/campaigns/");
  ASSERT_EQ(final["state"], "done") << final.dump();
  EXPECT_EQ(final["progress"]["samples"], 24);
  EXPECT_EQ(final["links"]["summary"], "/v1/campaigns/" + id + "/summary");
  EXPECT_EQ(final["links"]["samples"], "/v1/campaigns/" + id + "/samples?format=csv");

  // The same campaign in-process, in a directory of its own: every record (inputs, outcomes, final
  // state, the run's report) and the summary are identical.
  json spec_doc = body["campaign"];
  json scene = read_json_file("scenes/manipulator-fig6.4.json");
  scene["integrator"]["t_end"] = 3.0;
  spec_doc["scene"] = scene;
  const auto spec = moreau::scene::CampaignSpec::from_json(spec_doc, "");
  const TempDir local_dir("campaign-local");
  const fs::path& local = local_dir.path();
  moreau::scene::CampaignRunOptions options;
  options.workers = 2;
  const auto result = moreau::scene::run_campaign(spec, local.string(), options);
  ASSERT_TRUE(result.summarized);

  auto jsonl = c->Get("/v1/campaigns/" + id + "/samples?format=jsonl");
  ASSERT_EQ(jsonl->status, 200);
  EXPECT_EQ(jsonl->get_header_value("Content-Type"), "application/jsonl");
  const auto served = records_by_index(jsonl->body);
  const auto want = records_by_index(read_text(local / "samples.jsonl"));
  ASSERT_EQ(served.size(), 24u);
  ASSERT_EQ(want.size(), 24u);
  for (const auto& [i, record] : want) {
    ASSERT_TRUE(served.count(i)) << i;
    EXPECT_EQ(served.at(i), record) << "sample " << i;
    EXPECT_TRUE(record.contains("report"));
  }
  std::int64_t successes = 0, steps = 0;
  for (const auto& [i, record] : want) {
    successes += record["success"].get<bool>();
    steps += record["steps"].get<std::int64_t>();
  }
  EXPECT_EQ(result.steps, steps);
  // The campaign's steps count in /metrics (the only work this server did).
  EXPECT_THAT(c->Get("/metrics")->body, ::testing::HasSubstr("\nmoreau_steps_total " + std::to_string(steps) + "\n"));
  EXPECT_GT(successes, 0);  // the comparison covers converged samples too

  auto summary = c->Get("/v1/campaigns/" + id + "/summary");
  ASSERT_EQ(summary->status, 200);
  EXPECT_EQ(json::parse(summary->body), json::parse(read_text(local / "summary.json")));
  EXPECT_EQ(final["summary"], json::parse(summary->body));
  EXPECT_EQ(json::parse(summary->body)["successes"], successes);
  auto text = c->Get("/v1/campaigns/" + id + "/summary?format=text");
  ASSERT_EQ(text->status, 200);
  EXPECT_EQ(text->body, read_text(local / "summary.txt"));
  auto csv = c->Get("/v1/campaigns/" + id + "/samples");
  ASSERT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Content-Type"), "text/csv");
  EXPECT_THAT(csv->body, ::testing::StartsWith("index,\"/parameters/m1\""));
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 25);

  // Progress went out over the event stream, then the final state.
  auto events = c->Get("/v1/campaigns/" + id + "/events");
  ASSERT_EQ(events->status, 200);
  EXPECT_THAT(events->body, ::testing::HasSubstr("event: progress\ndata: {\"samples\":24,\"samples_total\":24}"));
  EXPECT_THAT(events->body, ::testing::HasSubstr("\"state\":\"done\""));
  EXPECT_LT(events->body.find("\"samples\":24"), events->body.find("\"state\":\"done\""));

  for (const char* kind : {"convergence-cdf", "inputs", "success-map"}) {
    auto fig = c->Get("/v1/campaigns/" + id + "/figure?kind=" + kind);
    ASSERT_EQ(fig->status, 200) << kind << ": " << fig->body;
    EXPECT_EQ(fig->get_header_value("Content-Type"), "image/png");
    EXPECT_EQ(fig->body.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  }
  auto svg = c->Get("/v1/campaigns/" + id + "/figure?kind=success-map&format=svg&width=640&height=400");
  ASSERT_EQ(svg->status, 200) << svg->body;
  EXPECT_THAT(svg->body, ::testing::HasSubstr("<svg"));
  EXPECT_EQ(c->Get("/v1/campaigns/" + id + "/figure?kind=state")->status, 400);

  // Campaigns, studies and jobs are listed apart; a campaign id is not a job.
  const json campaigns = json::parse(c->Get("/v1/campaigns")->body);
  EXPECT_EQ(campaigns["count"], 1);
  EXPECT_EQ(campaigns["campaigns"][0]["id"], id);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["count"], 0);
  EXPECT_EQ(c->Get("/v1/jobs/" + id)->status, 404);
  EXPECT_EQ(c->Delete("/v1/campaigns/" + id)->status, 409);
}

struct BadCampaign {
  const char* name;
  json body;
  int status;
  const char* pointer;
  const char* where;
  const char* reason;
};

TEST(ServerCampaign, BadCampaignsNameTheField) {
  auto with = [](const std::string& pointer, const json& value) {
    json b = body_of(8, false, 1.0);
    b[json::json_pointer(pointer)] = value;
    return b;
  };
  json no_campaign = body_of(8, false, 1.0);
  no_campaign.erase("campaign");
  // One more input, after the shipped campaign's five (/campaign/inputs/5).
  auto with_input = [](const json& input) {
    json b = body_of(8, false, 1.0);
    b["campaign"]["inputs"].push_back(input);
    return b;
  };
  const BadCampaign cases[] = {
      {"no_campaign", no_campaign, 400, "/campaign", "request", "missing required field 'campaign'"},
      {"campaign_type", with("/campaign", "fast"), 400, "/campaign", "request", "expected an object"},
      {"scene_in_campaign", with("/campaign/scene", "/etc/passwd"), 400, "/campaign/scene", "request", "the request's 'scene'"},
      {"unknown_path", with("/campaign/inputs/0/path", "/parameters/m9"), 400, "/campaign/inputs/0/path", "request", "nothing at"},
      {"inverted_bounds", with("/campaign/inputs/0/distribution", {{"type", "uniform"}, {"low", 2}, {"high", 1}}), 400,
       "/campaign/inputs/0/distribution/high", "request", "inverted"},
      {"zero_samples", with("/campaign/samples", 0), 400, "/campaign/samples", "request", ">= 1"},
      {"unknown_field", with("/campaign/workers", 4), 400, "/campaign/workers", "request", "unknown field"},
      {"over_the_sample_limit", with("/campaign/samples", 1001), 400, "/campaign/samples", "request", "at most 1000 per campaign"},
      // This server's limit, not the command line's (10,000,000), whatever the number's form.
      {"samples_1e12", with("/campaign/samples", 1e12), 400, "/campaign/samples", "request", "at most 1000 per campaign"},
      {"samples_10_to_the_12", with("/campaign/samples", std::int64_t{1'000'000'000'000}), 400, "/campaign/samples", "request",
       "at most 1000 per campaign"},
      // Names are data: a newline would have put a command into a Slurm script.
      {"name_with_a_newline", with("/campaign/name", "x\ntouch FILE\n#"), 400, "/campaign/name", "request", "is not a campaign name"},
      // Inputs that raise each sample's steps count: t_end = 2000 (2,000,000 steps, held to --max-steps'
      // 1,000,000), h = 1e-5 (100,000 each), against 160,000 per campaign.
      {"t_end_raised_by_an_input",
       with_input({{"path", "/integrator/t_end"}, {"distribution", {{"type", "discrete"}, {"values", {2000.0}}}}}), 400,
       "/campaign/inputs/5", "request", "/integrator/t_end = 2000.0, needs 1000000;"},
      {"h_lowered_by_an_input", with_input({{"path", "/integrator/h"}, {"distribution", {{"type", "discrete"}, {"values", {1e-5}}}}}), 400,
       "/campaign/inputs/5", "request", "needs 100000;"},
      {"over_the_step_limit", with("/overrides", {"integrator.h=1e-7"}), 400, "/integrator/h", "scene", "steps per sample"},
      {"over_the_campaign_step_limit", with("/overrides", {"integrator.t_end=30"}), 400, "/campaign/samples", "request",
       "steps per campaign"},
      {"over_the_byte_limit", with("/campaign/full_report", true), 422, "/campaign/full_report", "request", "set full_report to false"},
      {"bad_scene", with("/overrides", {"integrator.h=-1"}), 400, "/integrator/h", "scene", ""},
      {"unknown_shipped_scene", with("/scene", "no-such-scene"), 400, "/scene", "request", "no shipped scene"},
      {"unknown_body_field", with("/study", json::object()), 400, "/study", "request", "expected scene, overrides, campaign"},
  };
  ServerConfig cfg;
  cfg.max_campaign_samples = 1000;
  cfg.max_steps = 1'000'000;
  cfg.max_campaign_steps = 8 * 20'000;  // 8 samples of 1 s at h = 1e-3, not of 30 s
  cfg.max_result_bytes = 8 * 12'000;    // 8 outcome records, not 8 full reports
  TestServer ts(cfg);
  auto c = ts.client();
  for (const auto& k : cases) {
    SCOPED_TRACE(k.name);
    auto r = post_campaign(*c, k.body);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, k.status) << r->body;
    const json e = json::parse(r->body);
    EXPECT_EQ(e["pointer"], k.pointer) << e.dump();
    EXPECT_EQ(e["where"], k.where) << e.dump();
    EXPECT_THAT(e["reason"].get<std::string>(), ::testing::HasSubstr(k.reason));
  }
  // Nothing was accepted.
  EXPECT_EQ(json::parse(c->Get("/v1/campaigns")->body)["count"], 0);
  // Within every limit, the same request is accepted.
  auto ok = post_campaign(*c, body_of(8, false, 1.0));
  ASSERT_EQ(ok->status, 202) << ok->body;
  EXPECT_EQ(wait_final(*c, json::parse(ok->body)["id"], 120, "/v1/campaigns/")["state"], "done");
}

// The issue's case: a 50-step scene whose inputs set t_end = 2000 in each of 8 samples would run
// 16,000,000 steps under a budget of 100,000; it is refused at its input. Inputs that keep every sample
// within the budget are taken, and each sample's record has the steps its own t_end makes,
// ceil(t_end / h), all of them within the budget.
TEST(ServerCampaign, InputsThatChangeEachSamplesStepsCountAgainstTheBudget) {
  ServerConfig cfg;
  cfg.max_campaign_steps = 100'000;
  TestServer ts(cfg);
  auto c = ts.client();
  auto body = [](const json& t_end) {
    json b = body_of(8, false, 0.05);  // h = 1e-3: 50 steps
    b["campaign"]["inputs"].push_back({{"path", "/integrator/t_end"}, {"distribution", t_end}});
    return b;
  };
  auto r = post_campaign(*c, body({{"type", "discrete"}, {"values", {2000.0}}}));
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 400) << r->body;
  const json e = json::parse(r->body);
  EXPECT_EQ(e["pointer"], "/campaign/inputs/5") << e.dump();
  EXPECT_THAT(e["reason"].get<std::string>(), ::testing::HasSubstr("/integrator/t_end = 2000.0, needs 2000000;")) << e.dump();
  EXPECT_THAT(e["reason"].get<std::string>(), ::testing::HasSubstr("at most 100000 steps per campaign")) << e.dump();
  EXPECT_EQ(json::parse(c->Get("/v1/campaigns")->body)["count"], 0);

  auto ok = post_campaign(*c, body({{"type", "discrete"}, {"values", {0.05, 0.1, 0.25}}}));
  ASSERT_EQ(ok->status, 202) << ok->body;
  const std::string id = json::parse(ok->body)["id"];
  ASSERT_EQ(wait_final(*c, id, 120, "/v1/campaigns/")["state"], "done");
  const auto records = records_by_index(c->Get("/v1/campaigns/" + id + "/samples?format=jsonl")->body);
  ASSERT_EQ(records.size(), 8u);
  std::int64_t total = 0;
  for (const auto& [i, record] : records) {
    const double t_end = record["inputs"]["/integrator/t_end"].get<double>();
    const std::int64_t expected = t_end == 0.05 ? 50 : t_end == 0.1 ? 100 : 250;
    EXPECT_EQ(record["steps"].get<std::int64_t>(), expected) << "sample " << i << " at t_end = " << t_end;
    total += record["steps"].get<std::int64_t>();
  }
  EXPECT_LE(total, 100'000);
}

// The records of a campaign that ended early: every sample once, at least the `at_least` the campaign
// had reported, and each equal to the sample run alone.
void expect_kept_records(httplib::Client& c, const std::string& id, std::int64_t at_least) {
  auto r = c.Get("/v1/campaigns/" + id + "/samples?format=jsonl");
  ASSERT_EQ(r->status, 200) << r->body;
  const auto records = records_by_index(r->body);
  EXPECT_GE(static_cast<std::int64_t>(records.size()), at_least);
  EXPECT_LT(records.size(), 20'000u);
  json spec_doc = campaign_fields(20'000, false);
  json scene = read_json_file("scenes/manipulator-fig6.4.json");
  scene["integrator"]["t_end"] = 3.0;
  spec_doc["scene"] = scene;
  const auto spec = moreau::scene::CampaignSpec::from_json(spec_doc, "");
  const moreau::scene::CampaignDesign design(spec);
  json alone = moreau::scene::CampaignSampleRunner(spec, design).run(records.begin()->first);
  alone.erase("wall_seconds");
  EXPECT_EQ(records.begin()->second, alone) << "sample " << records.begin()->first;
}

TEST(ServerCampaign, CancelledCampaignKeepsItsFinishedSamples) {
  TestServer ts;
  auto c = ts.client();
  auto r = post_campaign(*c, body_of(20'000, false, 3.0));
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  wait_for_samples(*c, id, 2);
  auto d = c->Delete("/v1/campaigns/" + id);
  ASSERT_TRUE(d->status == 200 || d->status == 202) << d->body;
  const json final = wait_final(*c, id, 120, "/v1/campaigns/");
  ASSERT_EQ(final["state"], "cancelled") << final.dump();
  EXPECT_THAT(final["reason"].get<std::string>(), ::testing::HasSubstr("their records are kept"));
  EXPECT_FALSE(final["links"].contains("summary"));
  EXPECT_EQ(c->Get("/v1/campaigns/" + id + "/summary")->status, 409);
  expect_kept_records(*c, id, 2);
}

// A clean stop interrupts a campaign: it is queued again with the records of its finished samples, and
// the restarted server goes on from them (each sample once, equal to the sample run alone).
TEST(ServerCampaign, InterruptedCampaignGoesOnFromItsSamplesAfterARestart) {
  TempDir data;
  std::string id;
  {
    TestServer first;
    auto c = first.client();
    auto r = post_campaign(*c, body_of(20'000, false, 3.0));
    ASSERT_EQ(r->status, 202) << r->body;
    id = json::parse(r->body)["id"];
    wait_for_samples(*c, id, 2);
    data = first.release_data();
  }  // the server stops while the campaign runs
  const json record = read_json_file((data / "jobs" / id / "job.json").string());
  EXPECT_EQ(record["state"], "queued") << record.dump();
  EXPECT_THAT(record["reason"].get<std::string>(), ::testing::HasSubstr("their records are kept): it goes on from them"));
  const std::int64_t kept = static_cast<std::int64_t>(records_by_index(read_text(data / "jobs" / id / "samples.jsonl")).size());
  ASSERT_GE(kept, 2);
  TestServer second(ServerConfig{}, data.path());
  auto c = second.client();
  wait_for_samples(*c, id, kept + 2);  // the progress counts the kept samples: it goes on from them
  auto d = c->Delete("/v1/campaigns/" + id);
  ASSERT_TRUE(d->status == 200 || d->status == 202) << d->body;
  const json final = wait_final(*c, id, 120, "/v1/campaigns/");
  ASSERT_EQ(final["state"], "cancelled") << final.dump();
  expect_kept_records(*c, id, kept + 2);
}

}  // namespace
