// load_test: drives a running moreau-server with many concurrent HTTP connections for a fixed time,
// submitting small jobs, and checks every answer; then waits for the queue to drain and checks that
// every accepted job finished "done" with its report stored. Run by scripts/load-test.sh, which starts
// the server and records its memory; the numbers are in docs/reliability.md ("Load").
//
//   load_test --port 8080 --connections 256 --duration 20 [--no-keep-alive] [--scene damped-relay]
//             [--set integrator.t_end=1 --set output.every=100] [--timeout 30]
//
// Every connection is one thread with one httplib::Client (keep-alive unless --no-keep-alive) that
// POSTs /v1/jobs again and again. Answers: 202 accepted (must carry a job id and Location), 429 refused
// (must carry Retry-After), anything else an error; no answer at all (connect, read or write failure)
// is a connection error, counted by kind. The last line of the output is machine-readable:
//   RESULT key=value ...
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <httplib.h>
#include <nlohmann/json.hpp>

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

struct Counts {
  std::int64_t requests = 0, accepted = 0, refused = 0, other = 0, conn_errors = 0;
  std::int64_t bad_accept = 0, refused_without_retry_after = 0;
  std::map<int, std::int64_t> other_by_status;
  std::map<std::string, std::int64_t> errors_by_kind;
  std::vector<float> latency_ms;  // every answered request
  std::vector<std::string> ids;   // accepted jobs
  std::string first_other;        // the first unexpected answer, for the log

  void merge(Counts& o) {
    requests += o.requests;
    accepted += o.accepted;
    refused += o.refused;
    other += o.other;
    conn_errors += o.conn_errors;
    bad_accept += o.bad_accept;
    refused_without_retry_after += o.refused_without_retry_after;
    for (auto& [k, v] : o.other_by_status) other_by_status[k] += v;
    for (auto& [k, v] : o.errors_by_kind) errors_by_kind[k] += v;
    latency_ms.insert(latency_ms.end(), o.latency_ms.begin(), o.latency_ms.end());
    ids.insert(ids.end(), o.ids.begin(), o.ids.end());
    if (first_other.empty()) first_other = o.first_other;
  }
};

double percentile(std::vector<float>& v, double p) {
  if (v.empty()) return 0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

double metric(const std::string& text, const std::string& name) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(name + " ", 0) == 0) return std::stod(line.substr(name.size() + 1));
  return -1;
}

}  // namespace

int main(int argc, char** argv) {
  std::string host = "127.0.0.1", scene = "damped-relay";
  int port = 8080, connections = 256, timeout = 30, verify_threads = 8;
  double duration = 20, drain_timeout = 120;
  bool no_keep_alive = false, no_verify = false;
  std::vector<std::string> overrides = {"integrator.t_end=1", "output.every=100"};

  CLI::App app{"load_test: many concurrent connections submitting jobs to a moreau-server, every answer checked"};
  app.add_option("--host", host, "Server address")->capture_default_str();
  app.add_option("--port", port, "Server port")->required();
  app.add_option("--connections,-c", connections, "Concurrent connections (one thread each)")->capture_default_str();
  app.add_option("--duration,-d", duration, "Seconds of load")->capture_default_str();
  app.add_option("--scene", scene, "Shipped scene to submit")->capture_default_str();
  app.add_option("--set", overrides, "Overrides (PATH=VALUE), replacing the defaults")->capture_default_str();
  app.add_option("--timeout", timeout, "Connect and read timeout of a request, seconds")->capture_default_str();
  app.add_flag("--no-keep-alive", no_keep_alive, "A new connection for every request");
  app.add_flag("--no-verify", no_verify, "Do not check the accepted jobs afterwards");
  app.add_option("--drain-timeout", drain_timeout, "Seconds to wait for the queue to drain")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const std::string body = json({{"scene", scene}, {"overrides", overrides}}).dump();
  auto make_client = [&](bool keep_alive) {
    auto c = std::make_unique<httplib::Client>(host, port);
    c->set_keep_alive(keep_alive);
    c->set_tcp_nodelay(true);
    c->set_connection_timeout(timeout, 0);
    c->set_read_timeout(timeout, 0);
    c->set_write_timeout(timeout, 0);
    return c;
  };

  // ---- load ----
  std::vector<Counts> counts(static_cast<std::size_t>(connections));
  std::vector<std::thread> threads;
  std::atomic<bool> go{false};
  std::atomic<int> ready{0};
  const auto t_begin = Clock::now();
  Clock::time_point t_end;
  for (int i = 0; i < connections; ++i) {
    threads.emplace_back([&, i] {
      Counts& k = counts[static_cast<std::size_t>(i)];
      auto c = make_client(!no_keep_alive);
      ++ready;
      while (!go.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      while (Clock::now() < t_end) {
        const auto t0 = Clock::now();
        auto r = c->Post("/v1/jobs", body, "application/json");
        ++k.requests;
        if (!r) {
          ++k.conn_errors;
          ++k.errors_by_kind[httplib::to_string(r.error())];
          continue;
        }
        k.latency_ms.push_back(std::chrono::duration<float, std::milli>(Clock::now() - t0).count());
        if (r->status == 202) {
          ++k.accepted;
          const json j = json::parse(r->body, nullptr, false);
          if (j.is_object() && j.contains("id") && j["id"].is_string() && r->has_header("Location")) {
            k.ids.push_back(j["id"].get<std::string>());
          } else {
            ++k.bad_accept;
          }
        } else if (r->status == 429) {
          ++k.refused;
          if (!r->has_header("Retry-After")) ++k.refused_without_retry_after;
        } else {
          ++k.other;
          ++k.other_by_status[r->status];
          if (k.first_other.empty()) k.first_other = std::to_string(r->status) + " " + r->body;
        }
      }
    });
  }
  while (ready.load() < connections) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const double setup_seconds = std::chrono::duration<double>(Clock::now() - t_begin).count();
  const auto t_start = Clock::now();
  t_end = t_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration));
  go = true;
  for (auto& t : threads) t.join();
  const double load_seconds = std::chrono::duration<double>(Clock::now() - t_start).count();
  Counts all;
  for (auto& k : counts) all.merge(k);

  std::printf("load: %d connections (%s), %.1f s (threads ready in %.2f s), %lld requests, %.0f requests/s\n", connections,
              no_keep_alive ? "a new connection per request" : "keep-alive", load_seconds, setup_seconds,
              static_cast<long long>(all.requests), static_cast<double>(all.requests) / load_seconds);
  std::printf("  202 accepted %lld (%.0f/s), 429 refused %lld, other statuses %lld, connection errors %lld\n",
              static_cast<long long>(all.accepted), static_cast<double>(all.accepted) / load_seconds, static_cast<long long>(all.refused),
              static_cast<long long>(all.other), static_cast<long long>(all.conn_errors));
  for (const auto& [s, n] : all.other_by_status) std::printf("  status %d: %lld\n", s, static_cast<long long>(n));
  for (const auto& [e, n] : all.errors_by_kind) std::printf("  connection error %s: %lld\n", e.c_str(), static_cast<long long>(n));
  if (!all.first_other.empty()) std::printf("  first unexpected answer: %s\n", all.first_other.c_str());
  const double p50 = percentile(all.latency_ms, 0.50), p99 = percentile(all.latency_ms, 0.99),
               pmax = all.latency_ms.empty() ? 0 : *std::max_element(all.latency_ms.begin(), all.latency_ms.end());
  std::printf("  latency of answered requests: p50 %.2f ms, p99 %.2f ms, max %.1f ms\n", p50, p99, pmax);
  if (all.bad_accept || all.refused_without_retry_after)
    std::printf("  malformed: %lld 202 without id/Location, %lld 429 without Retry-After\n", static_cast<long long>(all.bad_accept),
                static_cast<long long>(all.refused_without_retry_after));

  // ---- drain ----
  auto c = make_client(true);
  const auto t_drain = Clock::now();
  double queue = -1, busy = -1, submitted = -1, rejected = -1;
  bool drained = false;
  while (std::chrono::duration<double>(Clock::now() - t_drain).count() < drain_timeout) {
    auto m = c->Get("/metrics");
    if (m && m->status == 200) {
      queue = metric(m->body, "moreau_queue_length");
      busy = metric(m->body, "moreau_workers_busy");
      submitted = metric(m->body, "moreau_jobs_submitted_total");
      rejected = metric(m->body, "moreau_jobs_rejected_total{reason=\"queue_full\"}");
      const double running = metric(m->body, "moreau_jobs{state=\"running\"}");
      const double queued = metric(m->body, "moreau_jobs{state=\"queued\"}");
      if (queue == 0 && busy == 0 && running == 0 && queued == 0) {
        drained = true;
        break;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  const double drain_seconds = std::chrono::duration<double>(Clock::now() - t_drain).count();
  std::printf("drain: %s in %.2f s; server counted %.0f submitted, %.0f refused (queue full)\n",
              drained ? "queue empty, workers idle" : "NOT DRAINED", drain_seconds, submitted, rejected);

  // ---- verify ----
  std::atomic<std::int64_t> done{0}, not_done{0}, no_report{0}, verify_errors{0};
  std::mutex mu;
  std::map<std::string, std::int64_t> states;
  if (!no_verify) {
    std::atomic<std::size_t> next{0};
    std::vector<std::thread> vt;
    for (int t = 0; t < verify_threads; ++t) {
      vt.emplace_back([&] {
        auto vc = make_client(true);
        for (std::size_t i = next++; i < all.ids.size(); i = next++) {
          const std::string& id = all.ids[i];
          auto r = vc->Get("/v1/jobs/" + id);
          if (!r || r->status != 200) {
            ++verify_errors;
            continue;
          }
          const json j = json::parse(r->body, nullptr, false);
          const std::string state = j.is_object() ? j.value("state", "?") : "?";
          {
            std::lock_guard l(mu);
            ++states[state];
          }
          if (state != "done") {
            ++not_done;
            continue;
          }
          auto rep = vc->Get("/v1/jobs/" + id + "/report");
          if (!rep || rep->status != 200 || json::parse(rep->body, nullptr, false).value("status", "") != "completed" ||
              !j.contains("report")) {
            ++no_report;
            continue;
          }
          ++done;
        }
      });
    }
    for (auto& t : vt) t.join();
    std::printf(
        "verify: %zu accepted jobs: %lld done with their report stored, %lld not done, %lld done without a readable "
        "report, %lld lookups failed\n",
        all.ids.size(), static_cast<long long>(done.load()), static_cast<long long>(not_done.load()),
        static_cast<long long>(no_report.load()), static_cast<long long>(verify_errors.load()));
    for (const auto& [s, n] : states) std::printf("  state %s: %lld\n", s.c_str(), static_cast<long long>(n));
  }

  const bool ok = drained && all.other == 0 && all.bad_accept == 0 && all.refused_without_retry_after == 0 &&
                  (no_verify || (done.load() == static_cast<std::int64_t>(all.ids.size()) && verify_errors == 0));
  std::printf(
      "RESULT connections=%d keep_alive=%d seconds=%.1f requests=%lld rps=%.0f accepted=%lld accepted_per_s=%.0f refused=%lld "
      "other=%lld conn_errors=%lld p50_ms=%.2f p99_ms=%.2f max_ms=%.1f drained=%d drain_s=%.2f verified_done=%lld "
      "not_done=%lld no_report=%lld server_submitted=%.0f server_rejected=%.0f ok=%d\n",
      connections, no_keep_alive ? 0 : 1, load_seconds, static_cast<long long>(all.requests),
      static_cast<double>(all.requests) / load_seconds, static_cast<long long>(all.accepted),
      static_cast<double>(all.accepted) / load_seconds, static_cast<long long>(all.refused), static_cast<long long>(all.other),
      static_cast<long long>(all.conn_errors), p50, p99, pmax, drained ? 1 : 0, drain_seconds, static_cast<long long>(done.load()),
      static_cast<long long>(not_done.load()), static_cast<long long>(no_report.load()), submitted, rejected, ok ? 1 : 0);
  return ok ? 0 : 1;
}
