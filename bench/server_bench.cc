// moreau-server benchmarks, against an in-process server on 127.0.0.1 with keep-alive clients:
//   BM_SmallJobs       jobs per second: the manipulator with t_end = 1 (1000 steps), each client
//                      submitting a job and waiting for its result, again and again; and the submit
//                      latency (POST to 202) of all clients pooled, p50 and p99 in ms
//   BM_SubmitToResult  latency from POST /v1/jobs to the finished job (p50, p90, p99 in ms)
//   BM_StreamingOverhead  a job's integration time (1e5 steps, every state recorded) without and with
//                      LCM streaming at the default period: the cost streaming adds to the integrator
// Numbers and the command: docs/api.md and docs/streaming.md.
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <time.h>

#include "job_observer.h"
#include "job.h"
#include "lcm_stream.h"
#include "server_fixture.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::TestServer;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

TestServer& shared_server() {
  static TestServer ts([] {
    ServerConfig cfg;
    cfg.workers = std::getenv("MOREAU_BENCH_WORKERS") ? std::atoi(std::getenv("MOREAU_BENCH_WORKERS")) : 0;
    cfg.queue = 100000;
    cfg.max_connections = 512;
    cfg.lcm_url = "file:///dev/null?mode=w";
    return cfg;
  }());
  return ts;
}

std::string small_job_body() {
  json scene = moreau::server::testing::manipulator();
  scene["integrator"]["t_end"] = 1;
  return json({{"scene", scene}}).dump();
}

// Submits and waits; returns false on any error.
// `submit_ms`, if given, gets the time from the POST to its 202.
bool one_job(httplib::Client& c, const std::string& body, json* report = nullptr, std::vector<float>* submit_ms = nullptr) {
  const auto t0 = Clock::now();
  auto r = c.Post("/v1/jobs", body, "application/json");
  if (!r || r->status != 202) return false;
  if (submit_ms) submit_ms->push_back(std::chrono::duration<float, std::milli>(Clock::now() - t0).count());
  const std::string id = json::parse(r->body)["id"];
  while (true) {
    auto g = c.Get("/v1/jobs/" + id + "?wait=10");
    if (!g || g->status != 200) return false;
    json j = json::parse(g->body);
    const std::string state = j["state"];
    if (state == "done") {
      if (report) *report = std::move(j["report"]);
      return true;
    }
    if (state == "failed" || state == "cancelled") return false;
  }
}

// The submit latency (POST to 202) of every client of a run, pooled: the last client out reports the
// percentiles (counters are summed over the clients, the others report 0).
struct SubmitLatencies {
  std::mutex mu;
  std::vector<float> ms;
  int finished = 0;
};

void BM_SmallJobs(benchmark::State& state) {
  static SubmitLatencies pooled;
  TestServer& ts = shared_server();
  auto c = ts.client();
  const std::string body = small_job_body();
  std::int64_t jobs = 0;
  std::vector<float> submit_ms;
  for (auto _ : state) {
    if (!one_job(*c, body, nullptr, &submit_ms)) {
      state.SkipWithError("a job failed");
      break;
    }
    ++jobs;
  }
  state.SetItemsProcessed(jobs);
  state.counters["jobs_per_s"] = benchmark::Counter(static_cast<double>(jobs), benchmark::Counter::kIsRate);
  std::lock_guard lock(pooled.mu);
  pooled.ms.insert(pooled.ms.end(), submit_ms.begin(), submit_ms.end());
  double p50 = 0, p99 = 0;
  if (++pooled.finished == state.threads() && !pooled.ms.empty()) {
    std::sort(pooled.ms.begin(), pooled.ms.end());
    auto pct = [&](double p) {
      return pooled.ms[std::min(pooled.ms.size() - 1, static_cast<std::size_t>(p * static_cast<double>(pooled.ms.size())))];
    };
    p50 = pct(0.50);
    p99 = pct(0.99);
    pooled.ms.clear();
    pooled.finished = 0;
  }
  state.counters["submit_p50_ms"] = p50;
  state.counters["submit_p99_ms"] = p99;
}
BENCHMARK(BM_SmallJobs)->ThreadRange(1, 8)->UseRealTime()->MinTime(2.0);

void BM_SubmitToResult(benchmark::State& state) {
  TestServer& ts = shared_server();
  auto c = ts.client();
  const std::string body = small_job_body();
  std::vector<double> ms;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    if (!one_job(*c, body)) {
      state.SkipWithError("a job failed");
      break;
    }
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  if (ms.empty()) return;
  std::sort(ms.begin(), ms.end());
  auto pct = [&](double p) { return ms[std::min(ms.size() - 1, static_cast<std::size_t>(p * static_cast<double>(ms.size())))]; };
  state.counters["p50_ms"] = pct(0.50);
  state.counters["p90_ms"] = pct(0.90);
  state.counters["p99_ms"] = pct(0.99);
}
BENCHMARK(BM_SubmitToResult)->UseRealTime()->MinTime(2.0);

// A job's "integrate" phase (the run loop and its observers; CSV formatting excluded), 1e5 steps with
// every state recorded, without and with LCM streaming at the default period (6401 states). The two
// kinds alternate so that both see the same machine load; the overhead compares the fastest runs
// (least disturbed by other processes) and the medians.
void BM_StreamingOverhead(benchmark::State& state) {
  TestServer& ts = shared_server();
  auto c = ts.client();
  json scene = moreau::server::testing::manipulator();
  scene["integrator"]["t_end"] = 100;
  const std::string plain = json({{"scene", scene}}).dump();
  const std::string streamed = json({{"scene", scene}, {"stream", true}}).dump();
  std::vector<double> a, b;
  for (auto _ : state) {
    json report;
    if (!one_job(*c, plain, &report)) {
      state.SkipWithError("a job failed");
      break;
    }
    a.push_back(report["phase_seconds"]["integrate"].get<double>() * 1e3);
    if (!one_job(*c, streamed, &report)) {
      state.SkipWithError("a job failed");
      break;
    }
    b.push_back(report["phase_seconds"]["integrate"].get<double>() * 1e3);
  }
  if (a.empty()) return;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  state.counters["plain_min_ms"] = a.front();
  state.counters["stream_min_ms"] = b.front();
  state.counters["plain_median_ms"] = a[a.size() / 2];
  state.counters["stream_median_ms"] = b[b.size() / 2];
  state.counters["overhead_min_pct"] = 100.0 * (b.front() / a.front() - 1.0);
  state.counters["overhead_median_pct"] = 100.0 * (b[b.size() / 2] / a[a.size() / 2] - 1.0);
}
BENCHMARK(BM_StreamingOverhead)->Iterations(60)->UseRealTime()->Unit(benchmark::kMillisecond);

// The same comparison without HTTP and disk: the worker's own observer (trajectory rows to /dev/null,
// progress, cancellation) without and with the stream observer, on this thread, timed by this
// thread's CPU clock so that other processes do not count. The hub publishes to file:///dev/null on
// its own thread. Alternating runs; the fastest of each kind and the medians are compared.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

void BM_ObserverCost(benchmark::State& state) {
  using namespace moreau::server;
  json scene = moreau::server::testing::manipulator();
  scene["integrator"]["t_end"] = 100;  // 1e5 steps, every one recorded
  const auto sim = moreau::scene::Simulation::from_json(scene);
  LcmHub hub("file:///dev/null?mode=w");
  std::vector<double> a, b;
  auto one = [&](bool stream) {
    Job job;
    job.id = "0123456789abcdef0123456789abcdef";
    moreau::scene::TrajectoryCsvWriter csv("/dev/null", sim.position_names(), sim.velocity_names());
    std::shared_ptr<JobStream> js;
    std::optional<StreamObserver> so;
    if (stream) {
      StreamSettings ss;
      ss.enabled = true;
      set_channels(ss, job.id);
      js = std::make_shared<JobStream>(job.id, ss, sim.dof());
      hub.add(js);
      so.emplace(js, sim.t0(), &job.cancel);
    }
    JobObserver obs(job, csv, 1, 1, 1 << 30, so ? &*so : nullptr, [] {});
    const double t0 = thread_cpu_ms();
    const auto summary = sim.run(&obs);
    obs.finish();
    if (so) so->flush_last(summary);
    const double ms = thread_cpu_ms() - t0;
    if (js) js->close();
    csv.close();
    return ms;
  };
  for (auto _ : state) {
    a.push_back(one(false));
    b.push_back(one(true));
  }
  hub.stop();
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  state.counters["plain_min_ms"] = a.front();
  state.counters["stream_min_ms"] = b.front();
  state.counters["plain_median_ms"] = a[a.size() / 2];
  state.counters["stream_median_ms"] = b[b.size() / 2];
  state.counters["overhead_min_pct"] = 100.0 * (b.front() / a.front() - 1.0);
  state.counters["overhead_median_pct"] = 100.0 * (b[b.size() / 2] / a[a.size() / 2] - 1.0);
}
BENCHMARK(BM_ObserverCost)->Iterations(40)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
