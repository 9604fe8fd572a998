// Live state over LCM: a job's stream on memq:// (in-process), decoded and checked; the same written
// to a file:// log and read back with lcm::LogFile; realtime pacing and its cancellation; and one
// udpm:// test between processes inside a private network namespace.
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server_fixture.h"

#include "moreau/core/models/manipulator.h"
#include "moreau/core/run_summary.h"

#include <lcm/lcm-cpp.hpp>
#include <moreau/description_t.hpp>
#include <moreau/job_event_t.hpp>
#include <moreau/lcm_url.h>
#include <moreau/state_t.hpp>

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::manipulator;
using moreau::server::testing::read_json_file;
using moreau::server::testing::submit;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_running;
using moreau::server::testing::wait_step;
using moreau::test_support::TempDir;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// Everything received on the MOREAU_* channels, decoded.
struct Received {
  std::vector<moreau::state_t> states;
  std::vector<moreau::job_event_t> events;
  std::vector<moreau::description_t> descriptions;
  std::vector<std::string> state_channels, event_channels, description_channels;
  std::string order;  // 'd', 's', 'e' per message, as received
  std::size_t undecodable = 0;

  void add(const std::string& channel, const void* data, int size) {
    moreau::state_t s;
    moreau::job_event_t e;
    moreau::description_t d;
    if (s.decode(data, 0, size) == size) {
      states.push_back(s);
      state_channels.push_back(channel);
      order += 's';
    } else if (e.decode(data, 0, size) == size) {
      events.push_back(e);
      event_channels.push_back(channel);
      order += 'e';
    } else if (d.decode(data, 0, size) == size) {
      descriptions.push_back(d);
      description_channels.push_back(channel);
      order += 'd';
    } else {
      ++undecodable;
    }
  }
  bool finished() const {
    return std::any_of(events.begin(), events.end(),
                       [](const auto& e) { return e.kind == "finished" || e.kind == "failed" || e.kind == "cancelled"; });
  }
};

// Checks a whole stream of the manipulator (t in [0, t_end], h = 1e-3) published every `period`.
void check_stream(const Received& got, const std::string& id, const json& report, double period, double t_end) {
  ASSERT_EQ(got.undecodable, 0u);
  ASSERT_FALSE(got.states.empty());
  for (const auto& ch : got.state_channels) EXPECT_EQ(ch, "MOREAU_STATE_" + upper(id));
  for (const auto& ch : got.event_channels) EXPECT_EQ(ch, "MOREAU_EVENT_" + upper(id));
  for (const auto& ch : got.description_channels) EXPECT_EQ(ch, "MOREAU_DESC_" + upper(id));
  // The description comes first: a viewer can label the first state it gets.
  ASSERT_FALSE(got.descriptions.empty());
  EXPECT_EQ(got.order.front(), 'd') << got.order.substr(0, 10);
  const auto& d = got.descriptions.front();
  EXPECT_EQ(d.job_id, id);
  EXPECT_EQ(d.scene, "manipulator");
  EXPECT_EQ(d.system, "lagrangian");
  EXPECT_EQ(d.n, 2);
  EXPECT_EQ(d.q_names, (std::vector<std::string>{"x1", "th2"}));
  EXPECT_EQ(d.v_names, (std::vector<std::string>{"x1_dot", "th2_dot"}));
  EXPECT_EQ(d.energy, "E = 1/2 <M(q) v, v> (kinetic energy)");
  EXPECT_DOUBLE_EQ(d.period, period);
  EXPECT_DOUBLE_EQ(d.t_end, t_end);
  EXPECT_EQ(d.state_channel, "MOREAU_STATE_" + upper(id));
  EXPECT_EQ(d.event_channel, "MOREAU_EVENT_" + upper(id));
  EXPECT_EQ(d.m, 0);  // a scene without signals
  // One state per period from t0, and the last state.
  const auto expected = static_cast<std::size_t>(std::llround(t_end / period)) + 1;
  EXPECT_EQ(got.states.size(), expected);
  EXPECT_EQ(got.states.front().step, 0);
  EXPECT_DOUBLE_EQ(got.states.front().t, 0.0);
  EXPECT_DOUBLE_EQ(got.states.front().q[0], 3.0);
  for (std::size_t i = 1; i < got.states.size(); ++i) {
    const auto& a = got.states[i - 1];
    const auto& b = got.states[i];
    ASSERT_GT(b.step, a.step) << i;
    ASSERT_GT(b.t, a.t) << i;
    ASSERT_GE(b.utime, a.utime) << i;
    EXPECT_LE(b.t - a.t, period + 1.5e-3) << i;
  }
  // Each state's energy against 1/2 <M(q) v, v> of its own q and v, with the paper's M(q) written apart
  // from the scene's expressions (models::Manipulator, whose defaults are the scene's parameters).
  const moreau::models::Manipulator model;
  for (const auto& s : got.states) {
    EXPECT_EQ(s.job_id, id);
    EXPECT_EQ(s.n, 2);
    ASSERT_EQ(s.q.size(), 2u);
    ASSERT_EQ(s.v.size(), 2u);
    EXPECT_DOUBLE_EQ(s.h, 1e-3);
    moreau::Mat<2> M;
    model.mass(moreau::Vec<2>(s.q[0], s.q[1]), M);
    const moreau::Vec<2> v(s.v[0], s.v[1]);
    const double kinetic = 0.5 * v.dot(M * v);
    EXPECT_NEAR(s.energy, kinetic, 1e-12 * (1.0 + kinetic)) << "step " << s.step;
  }
  const auto& last = got.states.back();
  EXPECT_EQ(last.step, report["steps"]);
  EXPECT_DOUBLE_EQ(last.t, t_end);
  EXPECT_EQ(json(last.q), report["final"]["q"]);
  EXPECT_EQ(json(last.v), report["final"]["v"]);

  // Events: started, converged (the report's step), finished last.
  ASSERT_GE(got.events.size(), 3u);
  EXPECT_EQ(got.events.front().kind, "started");
  EXPECT_EQ(got.events.back().kind, "finished");
  EXPECT_EQ(got.events.back().step, report["steps"]);
  EXPECT_EQ(std::count_if(got.events.begin(), got.events.end(), [](const auto& e) { return e.kind == "converged"; }), 1);
  EXPECT_EQ(std::count_if(got.events.begin(), got.events.end(), [](const auto& e) { return e.kind == "convergence_withdrawn"; }), 0);
  auto conv = std::find_if(got.events.begin(), got.events.end(), [](const auto& e) { return e.kind == "converged"; });
  ASSERT_NE(conv, got.events.end());
  EXPECT_EQ(conv->step, report["converged_step"]);
  EXPECT_DOUBLE_EQ(conv->t, report["converged_time"].get<double>());
  // Sent when detected (the report's window of rest reached, at step converged_step + kMinRestSteps),
  // not when the run ended: after the states before that step and before every state from it on.
  const auto detected_at = conv->step + moreau::RunSummary::kMinRestSteps;
  std::int64_t last_state_step = -1;
  std::size_t states_before = 0, next_state = 0, next_event = 0;
  for (const char kind : got.order) {
    if (kind == 's') last_state_step = got.states[next_state++].step;
    if (kind != 'e') continue;
    if (got.events[next_event++].kind != "converged") continue;
    states_before = next_state;
    EXPECT_LT(last_state_step, detected_at);
  }
  // Exactly the states before the detection step came before it (the event goes out just before the
  // state of the step that detected it, or of the first step after it that is published).
  EXPECT_EQ(states_before, static_cast<std::size_t>(
                               std::count_if(got.states.begin(), got.states.end(), [&](const auto& s) { return s.step < detected_at; })));
  EXPECT_LT(states_before, got.states.size()) << "the manipulator rests from t = 1.135, before t_end";
  EXPECT_THAT(conv->text, ::testing::HasSubstr("detected at step " + std::to_string(detected_at)));
  for (const auto& e : got.events) EXPECT_EQ(e.job_id, id);
}

struct Collector {
  // A free function with a context pointer: LCM 1.3.1's member-function subscribe() crashes under
  // GCC 12's UndefinedBehaviorSanitizer (MOREAU_SANITIZE=ON); subscribeFunction() does not.
  static void handle(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Collector* self) {
    self->got.add(channel, rbuf->data, static_cast<int>(rbuf->data_size));
  }
  Received got;
};

ServerConfig memq_config() {
  ServerConfig cfg;
  cfg.lcm_url = "memq://";
  return cfg;
}

// An in-process server streaming to memq://, and everything it publishes on MOREAU_*, collected.
struct MemqServer {
  TestServer ts{memq_config()};
  lcm::LCM* lcm = ts.server().lcm();
  Collector col;
  MemqServer() {
    if (lcm) lcm->subscribeFunction("MOREAU_.*", &Collector::handle, &col);
  }
  // Takes the messages published so far, waiting (at most 5 s) for a job's final event first: the hub
  // publishes within about a millisecond of the job's end.
  void drain() {
    const auto deadline = Clock::now() + std::chrono::seconds(5);
    while (!col.got.finished() && Clock::now() < deadline) lcm->handleTimeout(10);
    while (lcm->handleTimeout(0) > 0) {
    }
  }
};

TEST(LcmStream, MemqStreamDecodesInOrderWithTheFinalEvent) {
  MemqServer m;
  ASSERT_NE(m.lcm, nullptr);
  TestServer& ts = m.ts;
  Collector& col = m.col;

  auto c = ts.client();
  auto r = submit(*c, {{"scene", manipulator()}, {"stream", {{"period", 1.0 / 64}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const json accepted = json::parse(r->body);
  const std::string id = accepted["id"];
  EXPECT_EQ(accepted["stream"]["state_channel"], "MOREAU_STATE_" + upper(id));
  EXPECT_EQ(accepted["stream"]["event_channel"], "MOREAU_EVENT_" + upper(id));
  EXPECT_EQ(accepted["stream"]["description_channel"], "MOREAU_DESC_" + upper(id));
  const json job = wait_final(*c, id);
  ASSERT_EQ(job["state"], "done");

  m.drain();
  check_stream(col.got, id, job["report"], 1.0 / 64, 10.0);

  // Streaming does not change the trajectory: every step recorded as without it.
  const std::string csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->body;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 10002);
  EXPECT_THAT(c->Get("/metrics")->body, ::testing::HasSubstr("moreau_lcm_dropped_total 0\n"));
}

// A tracking scene's states carry its signals (q_d, e, sigma, u per coordinate) and the description
// names them: q_d against the reference the scene gives, sin(t) and 0.5 sin(2 t), and e against q - q_d.
TEST(LcmStream, ATrackingJobStreamsItsSignalsWithTheirNames) {
  MemqServer m;
  ASSERT_NE(m.lcm, nullptr);
  auto c = m.ts.client();
  json scene = moreau::server::testing::read_json_file("scenes/manipulator-tracking.json");
  scene["integrator"]["t_end"] = 1.0;
  auto r = submit(*c, {{"scene", scene}, {"stream", {{"period", 1.0 / 8}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const json job = wait_final(*c, id);
  ASSERT_EQ(job["state"], "done");
  // Over HTTP the same job's report has its tracking results and its figure is drawn from its trajectory.
  EXPECT_EQ(job["report"]["tracking"]["law"], "continuous");
  EXPECT_EQ(job["report"]["tracking"]["reached"], true);
  const auto figure = c->Get("/v1/jobs/" + id + "/figure?kind=tracking&format=svg");
  ASSERT_EQ(figure->status, 200) << figure->body;
  EXPECT_THAT(figure->body, ::testing::HasSubstr("Sliding variable"));
  m.drain();
  const Received& got = m.col.got;
  ASSERT_FALSE(got.descriptions.empty());
  EXPECT_EQ(got.descriptions.front().m, 8);
  EXPECT_EQ(got.descriptions.front().signal_names,
            (std::vector<std::string>{"qd_x1", "e_x1", "sigma_x1", "u_x1", "qd_th2", "e_th2", "sigma_th2", "u_th2"}));
  ASSERT_EQ(got.states.size(), 9u);
  for (const auto& s : got.states) {
    ASSERT_EQ(s.m, 8);
    ASSERT_EQ(s.signals.size(), 8u);
    EXPECT_NEAR(s.signals[0], std::sin(s.t), 1e-15) << s.t;
    EXPECT_NEAR(s.signals[4], 0.5 * std::sin(2.0 * s.t), 1e-15) << s.t;
    EXPECT_NEAR(s.signals[1], s.q[0] - std::sin(s.t), 1e-15) << s.t;
    EXPECT_NEAR(s.signals[5], s.q[1] - 0.5 * std::sin(2.0 * s.t), 1e-15) << s.t;
  }
}

TEST(LcmStream, CoarseTrajectoryDecimationStillStreamsEveryPeriod) {
  MemqServer m;
  ASSERT_NE(m.lcm, nullptr);
  TestServer& ts = m.ts;
  Collector& col = m.col;
  auto c = ts.client();

  // Without streaming, for reference.
  json scene = manipulator();
  scene["output"]["every"] = 100;
  auto r = submit(*c, {{"scene", scene}});
  const std::string plain = json::parse(r->body)["id"];
  wait_final(*c, plain);
  const std::string plain_csv = c->Get("/v1/jobs/" + plain + "/trajectory?format=csv")->body;
  EXPECT_EQ(std::count(plain_csv.begin(), plain_csv.end(), '\n'), 102);  // header + 101 rows

  r = submit(*c, {{"scene", scene}, {"stream", {{"period", 0.05}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const json job = wait_final(*c, id);
  m.drain();
  check_stream(col.got, id, job["report"], 0.05, 10.0);
  EXPECT_EQ(c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->body, plain_csv);
  // The scene as stored keeps its own decimation.
  const json stored = json::parse(std::ifstream(ts.data() / "jobs" / id / "scene.json"));
  EXPECT_EQ(stored["output"]["every"], 100);
}

TEST(LcmStream, FileLogIsWrittenAndReadBack) {
  const TempDir dir("lcmlog");
  const fs::path log = dir / "stream.log";
  std::string id;
  json report;
  {
    ServerConfig cfg;
    cfg.lcm_url = "file://" + log.string() + "?mode=w";
    TestServer ts(cfg);
    auto c = ts.client();
    auto r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=4"}}, {"stream", true}});
    ASSERT_EQ(r->status, 202) << r->body;
    id = json::parse(r->body)["id"];
    const json job = wait_final(*c, id);
    report = job["report"];
    c.reset();
  }  // stopping the server publishes what is left and closes the log

  lcm::LogFile file(log.string(), "r");
  ASSERT_TRUE(file.good());
  Received got;
  std::int64_t last_timestamp = 0;
  while (const lcm::LogEvent* e = file.readNextEvent()) {
    EXPECT_GE(e->timestamp, last_timestamp);
    last_timestamp = e->timestamp;
    got.add(e->channel, e->data, e->datalen);
  }
  check_stream(got, id, report, 1.0 / 64, 4.0);
}

// `moreau watch --figure` marks impacts from the impact events (at their own step's time), not from the
// states, which come every 1/64 s: replayed from a log of a bouncing ball, the live figure lists them.
TEST(LcmStream, WatchFigureMarksImpactsFromTheirEvents) {
#ifndef MOREAU_CLIENT_BINARY
  GTEST_SKIP() << "the moreau client is not part of this build";
#else
  const TempDir dir("watch-impacts");
  const fs::path log = dir / "stream.log";
  std::vector<double> impacts;
  {
    ServerConfig cfg;
    cfg.lcm_url = "file://" + log.string() + "?mode=w";
    TestServer ts(cfg);
    auto c = ts.client();
    auto r = submit(*c, {{"scene", read_json_file("scenes/bouncing-ball-e0.5.json")}, {"stream", true}});
    ASSERT_EQ(r->status, 202) << r->body;
    ASSERT_EQ(wait_final(*c, json::parse(r->body)["id"])["state"], "done");
    c.reset();
  }
  {
    lcm::LogFile file(log.string(), "r");
    Received got;
    while (const lcm::LogEvent* e = file.readNextEvent()) got.add(e->channel, e->data, e->datalen);
    for (const auto& e : got.events)
      if (e.kind == "impact") impacts.push_back(e.t);
  }
  ASSERT_GE(impacts.size(), 3u);
  const fs::path figure = dir / "live.svg";
  const std::string out_file = (dir / "out").string();
  const int rc = std::system((std::string(MOREAU_CLIENT_BINARY) + " watch --plain --until-finished --timeout 60 --lcm-url 'file://" +
                              log.string() + "?speed=0' --figure " + figure.string() + " > " + out_file + " 2>&1")
                                 .c_str());
  std::ifstream f(out_file);
  const std::string out((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_EQ(WEXITSTATUS(rc), 0) << out;
  std::ifstream svg_file(figure);
  const std::string svg((std::istreambuf_iterator<char>(svg_file)), std::istreambuf_iterator<char>());
  EXPECT_THAT(svg, ::testing::HasSubstr(">impacts<")) << "the live figure has no impact marks";
#endif
}

// A stream whose run a clean stop interrupts ends with a "stopped" event saying so; the restarted server
// runs the job again, from the start, on the same channels: "started", then its states from t = 0, then
// "finished". Each server writes its own file:// log, so that nothing published is missed.
TEST(LcmStream, AStopEndsTheStreamWithStoppedAndTheRestartStreamsTheJobAgain) {
  const TempDir dir("lcmlog-restart");
  const auto read_log = [](const fs::path& log) {
    Received got;
    lcm::LogFile file(log.string(), "r");
    EXPECT_TRUE(file.good());
    while (const lcm::LogEvent* e = file.readNextEvent()) got.add(e->channel, e->data, e->datalen);
    return got;
  };
  TempDir data;
  std::string id;
  ServerConfig cfg;
  cfg.workers = 1;
  cfg.max_steps = 2'000'000'000;
  {
    cfg.lcm_url = "file://" + (dir / "first.log").string() + "?mode=w";
    TestServer first(cfg);
    auto c = first.client();
    // About 2e7 steps (a second or two), a state every 100 s of simulated time.
    auto r = submit(
        *c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=2e4", "output.every=100000"}}, {"stream", {{"period", 100}}}});
    ASSERT_EQ(r->status, 202) << r->body;
    id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_running(*c, id), "running");
    c.reset();
    first.stop();
    data = first.release_data();
  }
  const Received before = read_log(dir / "first.log");
  ASSERT_FALSE(before.events.empty());
  EXPECT_EQ(before.events.front().kind, "started");
  const auto& last = before.events.back();
  EXPECT_EQ(last.job_id, id);
  ASSERT_EQ(last.kind, "stopped") << "the job ended before the stop: make it longer";
  EXPECT_EQ(last.text, "the server stopped while the job was running: it runs again from the start when the server restarts");
  EXPECT_FALSE(before.finished());
  {
    cfg.lcm_url = "file://" + (dir / "second.log").string() + "?mode=w";
    TestServer again(cfg, data.path());
    auto c = again.client();
    EXPECT_EQ(wait_final(*c, id, 120)["state"], "done");
    c.reset();
  }
  const Received after = read_log(dir / "second.log");
  ASSERT_FALSE(after.events.empty());
  EXPECT_EQ(after.events.front().kind, "started");
  EXPECT_EQ(after.events.back().kind, "finished");
  for (const auto& ch : after.event_channels) EXPECT_EQ(ch, "MOREAU_EVENT_" + upper(id));
  ASSERT_FALSE(after.states.empty());
  EXPECT_EQ(after.states.front().step, 0);
  EXPECT_EQ(after.states.back().t, 2e4);
  EXPECT_EQ(after.states.size(), 201u);  // t = 0, 100, ..., 2e4
}

// A file:// log in a directory that does not exist, or a log to read that does not exist: the server
// refuses to start and `moreau watch` exits 2, each saying which, not only LCM's "Failed to open".
TEST(LcmStream, AFileUrlWithoutItsDirectoryOrFileSaysWhich) {
  EXPECT_EQ(moreau::lcm_url_problem("file:///nonexistent-moreau-dir/x.log?mode=w"), "the directory /nonexistent-moreau-dir does not exist");
  EXPECT_EQ(moreau::lcm_url_problem("file:///nonexistent-moreau-dir/x.log"), "the log file /nonexistent-moreau-dir/x.log does not exist");
  EXPECT_EQ(moreau::lcm_url_problem("file:///tmp/x.log?speed=2&mode=a"), "");
  EXPECT_EQ(moreau::lcm_url_problem("memq://"), "");
  EXPECT_EQ(moreau::lcm_url_problem("udpm://239.255.76.67:7667?ttl=0"), "");
  EXPECT_EQ(moreau::lcm_url_problem(""), "");

  ServerConfig cfg;
  cfg.lcm_url = "file:///nonexistent-moreau-dir/stream.log?mode=w";
  try {
    TestServer ts(cfg);
    ADD_FAILURE() << "the server started with an LCM log it cannot write";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("cannot open LCM URL 'file:///nonexistent-moreau-dir/stream.log?mode=w': the directory "
                                               "/nonexistent-moreau-dir does not exist"));
  }
#ifdef MOREAU_CLIENT_BINARY
  const TempDir dir("watch-url");
  const std::string out_file = (dir / "out").string();
  const int rc = std::system(
      (std::string(MOREAU_CLIENT_BINARY) + " watch --lcm-url 'file:///nonexistent-moreau-dir/x.log' > " + out_file + " 2>&1").c_str());
  std::ifstream f(out_file);
  const std::string out((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(WEXITSTATUS(rc), 2) << out;
  EXPECT_THAT(out, ::testing::HasSubstr("the log file /nonexistent-moreau-dir/x.log does not exist"));
#endif
}

TEST(LcmStream, RealtimeIsPacedAndStillCancelsQuickly) {
  ServerConfig cfg;
  cfg.lcm_url = "memq://";
  TestServer ts(cfg);
  auto c = ts.client();
  lcm::LCM* l = ts.server().lcm();
  ASSERT_NE(l, nullptr);
  Collector col;
  l->subscribeFunction("MOREAU_DESC_.*", &Collector::handle, &col);
  // 0.3 s of simulated time takes 0.3 s of wall-clock time.
  auto t0 = Clock::now();
  auto r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=0.3"}}, {"stream", {{"realtime", true}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  EXPECT_EQ(wait_final(*c, json::parse(r->body)["id"])["state"], "done");
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_GE(took, 0.28);
  EXPECT_LT(took, 2.0);
  while (l->handleTimeout(0) > 0) {
  }
  ASSERT_GE(col.got.descriptions.size(), 1u) << "a description when the stream starts";
  const std::size_t first_job_descriptions = col.got.descriptions.size();

  // A paced job sleeps until each sample's time; cancelling it wakes it. With a stream period of 60 s and
  // a trajectory row every 60,000 steps of 1e-3 s, the run's samples are 60,000 steps apart (a stream
  // samples the run at least once per period), and its second is due 60 s of wall-clock time after its
  // start. Once its progress shows its last cancellation check before that sample (step 59,904 =
  // 234 x 256), it is asleep or about to be: woken, it stops at its next check (step 60,160); not woken,
  // it would sleep until the 60 s are up. The 20 s given to wait_final tell the two apart with a wide
  // margin (nothing is timed).
  json paced = manipulator();
  paced["integrator"]["t_end"] = 100.0;
  paced["output"]["every"] = 60000;
  r = submit(*c, {{"scene", paced}, {"stream", {{"realtime", true}, {"period", 60.0}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, id), "running");
  constexpr std::int64_t kInterval = moreau::RunObserver::kControlInterval;
  constexpr std::int64_t kLastCheckBefore = 60000 / kInterval * kInterval;
  ASSERT_GE(wait_step(*c, id, kLastCheckBefore), kLastCheckBefore);
  auto d = c->Delete("/v1/jobs/" + id);
  ASSERT_EQ(d->status, 202) << d->body;
  EXPECT_EQ(json::parse(d->body)["state"], "cancelling");
  const json job = wait_final(*c, id, 20);
  EXPECT_EQ(job["state"], "cancelled") << "the paced run was not woken by its cancellation: " << job.dump();
  EXPECT_EQ(job["report"]["steps"].get<std::int64_t>(), kLastCheckBefore + kInterval);

  // A long paced stream repeats its description about once a second of wall-clock time, for viewers
  // that join late: wait (on the messages, not a clock) until a second one comes, and check the spacing.
  r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=100"}}, {"stream", {{"realtime", true}}}});
  const std::string late = json::parse(r->body)["id"];
  auto of_late = [&] {
    std::vector<moreau::description_t> out;
    for (const auto& d : col.got.descriptions)
      if (d.job_id == late) out.push_back(d);
    return out;
  };
  const auto deadline = Clock::now() + std::chrono::seconds(20);
  while (of_late().size() < 3 && Clock::now() < deadline) l->handleTimeout(50);
  c->Delete("/v1/jobs/" + late);
  const auto repeated = of_late();
  ASSERT_GE(repeated.size(), 3u);
  for (std::size_t i = 1; i < repeated.size(); ++i) {
    EXPECT_GE(repeated[i].utime - repeated[i - 1].utime, 990000) << i;  // at most one per second
  }
  EXPECT_GE(col.got.descriptions.size(), first_job_descriptions + 3);
}

// Impacts go out as they happen: one "impact" event per impacting contact, before the first state after
// it, with the numbers the report records for it; and they agree with the closed form of a falling ball
// and with Newton's law.
TEST(LcmStream, ImpactEventsAreStreamedAsTheyHappen) {
  MemqServer m;
  ASSERT_NE(m.lcm, nullptr);
  TestServer& ts = m.ts;
  Collector& col = m.col;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", read_json_file("scenes/bouncing-ball-e0.8.json")}, {"stream", true}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const json job = wait_final(*c, id);
  ASSERT_EQ(job["state"], "done");
  m.drain();
  ASSERT_EQ(col.got.undecodable, 0u);
  const json& contacts = job["report"]["contacts"];
  const json& recorded = contacts["impacts"];
  ASSERT_FALSE(contacts["impacts_truncated"].get<bool>());

  // The impact events, their fields parsed from the key=value text.
  struct Impact {
    std::int64_t step;
    double t, pre, post, restitution, impulse;
    int contact;
  };
  std::vector<Impact> impacts;
  for (const auto& e : col.got.events) {
    if (e.kind != "impact") continue;
    Impact i{e.step, e.t, 0, 0, 0, 0, -1};
    ASSERT_EQ(std::sscanf(e.text.c_str(), "contact=%d pre=%lf post=%lf restitution=%lf impulse=%lf", &i.contact, &i.pre, &i.post,
                          &i.restitution, &i.impulse),
              5)
        << e.text;
    impacts.push_back(i);
  }
  ASSERT_EQ(static_cast<std::int64_t>(impacts.size()), contacts["impact_count"].get<std::int64_t>());
  ASSERT_EQ(impacts.size(), recorded.size());
  ASSERT_GE(impacts.size(), 5u);
  for (std::size_t k = 0; k < impacts.size(); ++k) {
    SCOPED_TRACE(k);
    const Impact& i = impacts[k];
    EXPECT_EQ(i.step, recorded[k]["step"]);
    EXPECT_EQ(i.t, recorded[k]["t"].get<double>());
    EXPECT_EQ(i.pre, recorded[k]["pre_velocity"].get<double>());
    EXPECT_EQ(i.post, recorded[k]["post_velocity"].get<double>());
    EXPECT_EQ(i.impulse, recorded[k]["impulse"].get<double>());
    EXPECT_EQ(i.contact, 0);
    EXPECT_EQ(i.restitution, 0.8);
    EXPECT_LT(i.pre, 0.0);
    EXPECT_NEAR(i.post, -0.8 * i.pre, 1e-12 * std::abs(i.pre)) << "Newton's law at an impulse: U+ = -e U-";
  }
  // The first impact: the ball dropped from y0 = 1 m reaches the ground at t1 = sqrt(2 y0 / g) with speed
  // g t1 (the scene's description), to within a step (h = 1e-3).
  const double g = 9.81, t1 = std::sqrt(2.0 / g), h = 1e-3;
  EXPECT_NEAR(impacts[0].t, t1, h);
  EXPECT_NEAR(impacts[0].pre, -g * t1, g * h);
  // As they happen: each impact event comes before the first state of its step or later, after the
  // states before it.
  std::int64_t last_state_step = -1;
  std::size_t next_state = 0, next_event = 0;
  for (const char kind : col.got.order) {
    if (kind == 's') last_state_step = col.got.states[next_state++].step;
    if (kind != 'e') continue;
    const auto& e = col.got.events[next_event++];
    if (e.kind == "impact") {
      EXPECT_LT(last_state_step, e.step) << e.text;
    }
  }
}

// A rest that ends: the forced relay of scenes/forced-relay.json sticks at t* = m v0 / (a - f) = 1.2,
// and from t = 1.5 a force of 3.5 > a breaks the stiction. The stream says "converged" when the rest
// reaches the report's window, "convergence_withdrawn" at the step the velocity leaves 0.0, and nothing
// more: the report does not count the run as converged.
TEST(LcmStream, ConvergenceIsWithdrawnWhenTheRestEnds) {
  MemqServer m;
  ASSERT_NE(m.lcm, nullptr);
  auto c = m.ts.client();
  json scene = read_json_file("scenes/forced-relay.json");
  scene.erase("exact");
  scene["system"]["force"][0] = "-f - 3*min(1, max(0, 1e6*(t - 1.5)))";  // a step at t = 1.5 (within 1 us)
  scene["integrator"]["t_end"] = 2.0;
  auto r = submit(*c, {{"scene", scene}, {"stream", true}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const json job = wait_final(*c, id);
  ASSERT_EQ(job["state"], "done");
  m.drain();
  ASSERT_EQ(m.col.got.undecodable, 0u);
  EXPECT_EQ(job["report"]["converged_step"], nullptr);

  std::vector<moreau::job_event_t> rest;
  for (const auto& e : m.col.got.events)
    if (e.kind == "converged" || e.kind == "convergence_withdrawn") rest.push_back(e);
  ASSERT_EQ(rest.size(), 2u);
  const double h = 1e-3, t_stop = 1.5 * 1.2 / (2.0 - 0.5);
  EXPECT_EQ(rest[0].kind, "converged");
  EXPECT_NEAR(rest[0].t, t_stop, 2 * h);
  EXPECT_EQ(rest[1].kind, "convergence_withdrawn");
  EXPECT_GE(rest[1].t, 1.5);
  EXPECT_LE(rest[1].t, 1.5 + 2 * h);
  EXPECT_THAT(rest[1].text, ::testing::HasSubstr("the rest from step " + std::to_string(rest[0].step) + " ended"));
  EXPECT_EQ(m.col.got.events.back().kind, "finished");
}

// ---- udpm:// between processes, inside a private network namespace ----

int run_shell(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(LcmStream, UdpmBetweenProcessesInAPrivateNetworkNamespace) {
#ifndef MOREAU_CLIENT_BINARY
  GTEST_SKIP() << "the moreau client is not part of this build";
#else
  // Multicast is only ever sent inside a network namespace of our own, never on the real network.
  if (run_shell("unshare -rn true >/dev/null 2>&1") != 0) {
    GTEST_SKIP() << "network namespaces are not available here (unshare -rn failed): the udpm:// test needs one "
                    "so that no multicast reaches the real network";
  }
  const TempDir dir("udpm");
  const std::string cmd = std::string("sh ") + MOREAU_NETNS_SCRIPT + " " + MOREAU_SERVER_BINARY + " " + MOREAU_CLIENT_BINARY + " " +
                          dir.path().string() + " > " + (dir / "script.out").string() + " 2>&1";
  const int rc = run_shell(cmd);
  std::ifstream out_file(dir / "script.out");
  const std::string out((std::istreambuf_iterator<char>(out_file)), std::istreambuf_iterator<char>());
  ASSERT_EQ(rc, 0) << out;

  const json report = json::parse(std::ifstream(dir / "report.json"));
  const std::string id = report.at("id");
  lcm::LogFile file((dir / "watch.log").string(), "r");
  ASSERT_TRUE(file.good()) << out;
  Received got;
  while (const lcm::LogEvent* e = file.readNextEvent()) got.add(e->channel, e->data, e->datalen);
  // Paced at 64 states per second, nothing is lost on the loopback interface.
  check_stream(got, id, report.at("report"), 1.0 / 64, 1.5);
  // The first watch ended when the job finished and said so; the second, interrupted by SIGINT (Ctrl-C),
  // exits 0 with its one-line summary instead of a receive error.
  const auto read = [&](const char* name) {
    std::ifstream f(dir / name);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  };
  EXPECT_THAT(read("watch.out"), ::testing::HasSubstr("moreau watch: a job finished; received ")) << out;
  EXPECT_EQ(read("interrupt.rc"), "0\n") << out;
  const std::string interrupted = read("interrupt.out");
  EXPECT_THAT(interrupted, ::testing::HasSubstr("moreau watch: interrupted; received 0 states and 0 events of 0 jobs (0 ended)"));
  EXPECT_THAT(interrupted, ::testing::Not(::testing::HasSubstr("receive failed")));
#endif
}

}  // namespace
