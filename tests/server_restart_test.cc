// A restarted moreau-server with the same data directory serves every finished job again (the same
// report bytes) and marks the jobs that were running as failed, with the reason.
#include <chrono>
#include <filesystem>
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
using moreau::test_support::TempDir;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_running;
using json = nlohmann::json;
namespace fs = std::filesystem;

struct Saved {
  std::string id, report, csv, job;
};

TEST(ServerRestart, FinishedJobsAreServedAgainAndRunningOnesFail) {
  TempDir data;  // the servers' data directory, moved here from the first server
  Saved done, cancelled;
  std::string crashed_id;
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
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
    c.reset();
    data = first.release_data();
  }

  // A job the server was running when it died: its record says "running" and there is no report.
  crashed_id = "00112233445566778899aabbccddeeff";
  fs::create_directories(data / "jobs" / crashed_id);
  {
    json record = json::parse(std::ifstream(data / "jobs" / done.id / "job.json"));
    record["id"] = crashed_id;
    record["state"] = "running";
    record["finished"] = 0;
    std::ofstream(data / "jobs" / crashed_id / "job.json") << record.dump(2);
    std::ofstream(data / "jobs" / crashed_id / "trajectory.csv.tmp") << "t,h\n";  // an interrupted write
  }
  // Not a job directory: ignored.
  fs::create_directories(data / "jobs" / "not-a-job");

  {
    TestServer second(cfg, data.path());
    auto c = second.client();
    const json list = json::parse(c->Get("/v1/jobs")->body);
    EXPECT_EQ(list["count"], 3) << list.dump(2);

    json job = json::parse(c->Get("/v1/jobs/" + done.id)->body);
    EXPECT_EQ(job["state"], "done");
    EXPECT_EQ(job["report"], json::parse(done.report));
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/report")->body, done.report);
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/trajectory?format=csv")->body, done.csv);
    EXPECT_EQ(c->Get("/v1/jobs/" + done.id + "/trajectory")->status, 200);

    job = json::parse(c->Get("/v1/jobs/" + cancelled.id)->body);
    EXPECT_EQ(job["state"], "cancelled");
    EXPECT_EQ(c->Get("/v1/jobs/" + cancelled.id + "/report")->body, cancelled.report);

    job = json::parse(c->Get("/v1/jobs/" + crashed_id)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"], "server restarted while the job was running");
    EXPECT_FALSE(job.contains("report"));
    EXPECT_EQ(c->Get("/v1/jobs/" + crashed_id + "/report")->status, 409);
    EXPECT_FALSE(fs::exists(data / "jobs" / crashed_id / "trajectory.csv.tmp"));
    // The events stream of a finished job gives its final state and ends.
    auto ev = c->Get("/v1/jobs/" + crashed_id + "/events");
    ASSERT_EQ(ev->status, 200);
    EXPECT_THAT(ev->body, ::testing::HasSubstr("\"state\":\"failed\""));

    // The server goes on taking jobs.
    auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1"}}});
    ASSERT_EQ(r->status, 202);
    EXPECT_EQ(wait_final(*c, json::parse(r->body)["id"])["state"], "done");
    c.reset();
  }
  // The record on disk now says failed, for the next restart too.
  const json record = json::parse(std::ifstream(data / "jobs" / crashed_id / "job.json"));
  EXPECT_EQ(record["state"], "failed");
}

TEST(ServerRestart, StoppingTheServerFailsRunningAndQueuedJobs) {
  TempDir data;  // the servers' data directory, moved here from the first server
  std::string running, queued;
  ServerConfig cfg;
  cfg.workers = 1;
  cfg.max_steps = 2'000'000'000;
  {
    TestServer ts(cfg);
    auto c = ts.client();
    json long_scene = manipulator();
    long_scene["integrator"]["t_end"] = 1e6;
    long_scene["output"]["every"] = 100000;
    auto r = submit(*c, {{"scene", long_scene}});
    running = json::parse(r->body)["id"];
    ASSERT_EQ(wait_running(*c, running), "running");
    r = submit(*c, {{"scene", long_scene}});
    queued = json::parse(r->body)["id"];
    c.reset();
    const auto t0 = std::chrono::steady_clock::now();
    ts.stop();
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 3.0);
    data = ts.release_data();
  }
  {
    TestServer again(cfg, data.path());
    auto c = again.client();
    json job = json::parse(c->Get("/v1/jobs/" + running)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"], "server stopped while the job was running");
    job = json::parse(c->Get("/v1/jobs/" + queued)->body);
    EXPECT_EQ(job["state"], "failed");
    EXPECT_EQ(job["reason"], "server stopped before the job ran");
    c.reset();
  }
}

}  // namespace
