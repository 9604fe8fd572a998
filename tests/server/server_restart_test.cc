// A restarted moreau-server with the same data directory serves every finished job again (the same
// report bytes) and runs the jobs it had accepted and not finished: queued ones, ones a clean stop
// interrupted, and ones a dead server was running (once: the second death fails them). Nothing accepted
// is lost.
#include <chrono>
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server_fixture.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::manipulator;
using moreau::server::testing::submit;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_final_study;
using moreau::server::testing::wait_running;
using moreau::test_support::TempDir;
using json = nlohmann::json;
namespace fs = std::filesystem;

struct Saved {
  std::string id, report, csv, job;
};

// Writes a job directory as a server leaves it: `record` (job.json, with `id`) and the scene it ran.
void plant_job(const fs::path& data, const std::string& id, json record, const json* scene) {
  fs::create_directories(data / "jobs" / id);
  record["id"] = id;
  std::ofstream(data / "jobs" / id / "job.json") << record.dump(2);
  if (scene) std::ofstream(data / "jobs" / id / "scene.json") << scene->dump(2);
}

TEST(ServerRestart, FinishedJobsAreServedAgainAndUnfinishedOnesRunAgain) {
  TempDir data;  // the servers' data directory, moved here from the first server
  Saved done, cancelled, study;
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  json done_scene;
  {
    TestServer first(cfg);
    auto c = first.client();
    auto r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=2"}}});
    ASSERT_EQ(r->status, 202);
    done.id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_final(*c, done.id)["state"], "done");
    done.report = c->Get("/v1/jobs/" + done.id + "/report")->body;
    done.csv = c->Get("/v1/jobs/" + done.id + "/trajectory?format=csv")->body;

    json long_scene = manipulator();
    long_scene["integrator"]["t_end"] = 1e6;
    long_scene["output"]["every"] = 100000;
    r = submit(*c, {{"scene", long_scene}});
    ASSERT_EQ(r->status, 202);
    cancelled.id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_running(*c, cancelled.id), "running");
    ASSERT_EQ(c->Delete("/v1/jobs/" + cancelled.id)->status, 202);
    ASSERT_EQ(wait_final(*c, cancelled.id)["state"], "cancelled");
    cancelled.report = c->Get("/v1/jobs/" + cancelled.id + "/report")->body;

    const json settings = {{"h", "1e-2:1e-3:3"}, {"schemes", {"abl", "explicit"}}, {"repeats", 1}, {"eval_points", 200}};
    r = c->Post("/v1/studies", json({{"scene", "damped-relay"}, {"study", settings}}).dump(), "application/json");
    ASSERT_EQ(r->status, 202) << r->body;
    study.id = json::parse(r->body)["id"];
    const json final = wait_final_study(*c, study.id, 60);
    ASSERT_EQ(final["state"], "done") << final.dump();
    study.report = final["result"].dump();
    c.reset();
    data = first.release_data();
  }
  const json done_record = json::parse(std::ifstream(data / "jobs" / done.id / "job.json"));
  done_scene = json::parse(std::ifstream(data / "jobs" / done.id / "scene.json"));
  json unfinished = done_record;
  unfinished["finished"] = 0;
  unfinished.erase("progress");

  // A job the server was running when it died: its record says "running", there is no report, and an
  // interrupted write is left. It runs again, from the start.
  const std::string crashed_id = "00112233445566778899aabbccddeeff";
  unfinished["state"] = "running";
  plant_job(data.path(), crashed_id, unfinished, &done_scene);
  std::ofstream(data / "jobs" / crashed_id / "trajectory.csv.tmp") << "t,h\n";
  // The same, for the second time (the server died under it before): it fails.
  const std::string crashed_twice_id = "00112233445566778899aabbccddee00";
  unfinished["crashes"] = 1;
  plant_job(data.path(), crashed_twice_id, unfinished, &done_scene);
  unfinished.erase("crashes");
  // Queued jobs: one whose scene is gone, one that the restarted server's limits refuse (2e8 steps where
  // it now runs at most 1e8 per job).
  unfinished["state"] = "queued";
  const std::string no_scene_id = "00112233445566778899aabbccddee01", too_long_id = "00112233445566778899aabbccddee02";
  plant_job(data.path(), no_scene_id, unfinished, nullptr);
  json too_long = done_scene;
  too_long["integrator"]["t_end"] = 2e5;
  plant_job(data.path(), too_long_id, unfinished, &too_long);
  // A study a clean stop left queued: its scene and settings as the finished study stored them.
  const std::string queued_study_id = "00112233445566778899aabbccddee03";
  {
    json record = json::parse(std::ifstream(data / "jobs" / study.id / "job.json"));
    record["state"] = "queued";
    record["finished"] = 0;
    record.erase("progress");
    const json study_scene = json::parse(std::ifstream(data / "jobs" / study.id / "scene.json"));
    plant_job(data.path(), queued_study_id, record, &study_scene);
    fs::copy_file(data / "jobs" / study.id / "study.json", data / "jobs" / queued_study_id / "study.json");
  }
  // Not a job directory: ignored.
  fs::create_directories(data / "jobs" / "not-a-job");

  ServerConfig restarted = cfg;
  restarted.max_steps = 100'000'000;
  {
    TestServer second(restarted, data.path());
    auto c = second.client();
    const json list = json::parse(c->Get("/v1/jobs")->body);
    EXPECT_EQ(list["count"], 6) << list.dump(2);  // the runs (a study is listed under /v1/studies)

    json job = json::parse(c->Get("/v1/jobs/" + done.id)->body);
    EXPECT_EQ(job["state"], "done");
    EXPECT_EQ(job["report"], json::parse(done.report));
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/report")->body, done.report);
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/trajectory?format=csv")->body, done.csv);
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/trajectory")->status, 200);

    job = json::parse(c->Get("/v1/jobs/" + cancelled.id)->body);
    EXPECT_EQ(job["state"], "cancelled");
    EXPECT_EQ(c->Get("/v1/jobs/" + cancelled.id + "/report")->body, cancelled.report);

    // Run again: the trajectory is the one the same scene gave the first server, byte for byte (the
    // reference: the done job, run by the first server from the same scene.json).
    job = wait_final(*c, crashed_id);
    EXPECT_EQ(job["state"], "done") << job.dump(2);
    EXPECT_EQ(c->Get("/v1/jobs/" + crashed_id + "/trajectory?format=csv")->body, done.csv);
    EXPECT_EQ(json::parse(c->Get("/v1/jobs/" + crashed_id + "/report")->body)["status"], "completed");
    EXPECT_FALSE(fs::exists(data / "jobs" / crashed_id / "trajectory.csv.tmp"));
    // Its events: queued again (saying why), running, done.
    const std::string events = c->Get("/v1/jobs/" + crashed_id + "/events")->body;
    EXPECT_THAT(events, ::testing::HasSubstr("\"state\":\"done\""));

    job = json::parse(c->Get("/v1/jobs/" + crashed_twice_id)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"], "the server died twice while the job was running: it is not run again (it may be what stops the server)");
    EXPECT_FALSE(job.contains("report"));
    EXPECT_EQ(c->Get("/v1/jobs/" + crashed_twice_id + "/report")->status, 409);
    // The events stream of a finished job gives its final state and ends.
    auto ev = c->Get("/v1/jobs/" + crashed_twice_id + "/events");
    ASSERT_EQ(ev->status, 200);
    EXPECT_THAT(ev->body, ::testing::HasSubstr("\"state\":\"failed\""));

    // The study runs too: the same rows (errors, steps, orders) as the study it was copied from; only wall
    // times differ.
    const json study_final = wait_final_study(*c, queued_study_id, 60);
    ASSERT_EQ(study_final["state"], "done") << study_final.dump(2);
    const json first_result = json::parse(study.report);
    ASSERT_EQ(first_result["rows"].size(), 6u);  // 2 schemes, 3 step sizes
    ASSERT_EQ(study_final["result"]["rows"].size(), first_result["rows"].size());
    for (std::size_t i = 0; i < first_result["rows"].size(); ++i) {
      json a = study_final["result"]["rows"][i], b = first_result["rows"][i];
      for (json* row : {&a, &b})
        for (const char* timing : {"ns_per_step", "wall_seconds", "seconds"}) row->erase(timing);
      EXPECT_EQ(a, b) << "row " << i;
    }

    job = json::parse(c->Get("/v1/jobs/" + no_scene_id)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"], "the restarted server cannot run the job again: its scene.json is missing or unreadable");
    job = json::parse(c->Get("/v1/jobs/" + too_long_id)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"],
              "the restarted server cannot run the job again: /integrator/h: h = 0.001 over [0, 200000] needs 200000000 steps; this "
              "server runs at most 100000000 steps per job");

    // The server goes on taking jobs.
    auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1"}}});
    ASSERT_EQ(r->status, 202);
    EXPECT_EQ(wait_final(*c, json::parse(r->body)["id"])["state"], "done");
    c.reset();
  }
  // The records on disk say how each ended, for the next restart too; the job run again counts the death.
  json record = json::parse(std::ifstream(data / "jobs" / crashed_id / "job.json"));
  EXPECT_EQ(record["state"], "done");
  EXPECT_EQ(record["crashes"], 1);
  record = json::parse(std::ifstream(data / "jobs" / crashed_twice_id / "job.json"));
  EXPECT_EQ(record["state"], "failed");
  EXPECT_EQ(record["crashes"], 2);
}

// A clean stop (SIGTERM, or Server::stop) loses nothing: the running job is stopped and queued again, the
// queued one stays queued, and the restarted server runs both to the end.
TEST(ServerRestart, StoppingTheServerKeepsRunningAndQueuedJobs) {
  TempDir data;  // the servers' data directory, moved here from the first server
  std::string running, queued;
  ServerConfig cfg;
  cfg.workers = 1;
  cfg.max_steps = 2'000'000'000;
  // About 2e7 steps (a second or two): long enough to be running when the stop comes.
  json long_scene = manipulator();
  long_scene["integrator"]["t_end"] = 2e4;
  long_scene["output"]["every"] = 100000;
  {
    TestServer ts(cfg);
    auto c = ts.client();
    auto r = submit(*c, {{"scene", long_scene}});
    running = json::parse(r->body)["id"];
    ASSERT_EQ(wait_running(*c, running), "running");
    r = submit(*c, {{"scene", "damped-relay"}});
    queued = json::parse(r->body)["id"];
    c.reset();
    const auto t0 = std::chrono::steady_clock::now();
    ts.stop();
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3.0);
    data = ts.release_data();
  }
  // On disk: both queued, the interrupted one saying why, no partial results.
  json record = json::parse(std::ifstream(data / "jobs" / running / "job.json"));
  ASSERT_EQ(record["state"], "queued") << "the job ended before the stop: make it longer";
  EXPECT_EQ(record["reason"], "the server stopped while the job was running: it runs again from the start when the server restarts");
  EXPECT_FALSE(record.contains("crashes"));
  for (const char* name : {"trajectory.csv.tmp", "report.json.tmp", "trajectory.csv", "report.json"})
    EXPECT_FALSE(fs::exists(data / "jobs" / running / name)) << name;
  record = json::parse(std::ifstream(data / "jobs" / queued / "job.json"));
  EXPECT_EQ(record["state"], "queued");
  EXPECT_FALSE(record.contains("reason"));
  {
    TestServer again(cfg, data.path());
    auto c = again.client();
    // Whole runs: every step to t_end, one row per 100000 steps and the first and last states.
    json job = wait_final(*c, running, 120);
    ASSERT_EQ(job["state"], "done") << job.dump(2);
    const json report = json::parse(c->Get("/v1/jobs/" + running + "/report")->body);
    EXPECT_EQ(report["status"], "completed");
    EXPECT_EQ(report["steps"], 20'000'000);
    EXPECT_EQ(report["t_final"], 2e4);
    const std::string csv = c->Get("/v1/jobs/" + running + "/trajectory?format=csv")->body;
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 201);  // the header, rows at steps 0, 1e5, ..., 2e7
    job = wait_final(*c, queued, 60);
    EXPECT_EQ(job["state"], "done") << job.dump(2);
    c.reset();
  }
}

}  // namespace
