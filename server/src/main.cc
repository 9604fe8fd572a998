// moreau-server: serves the job API (docs/api.md) and streams live state over LCM (docs/streaming.md).
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <stdexcept>
#include <thread>

#include <CLI/CLI.hpp>

#include "moreau/server/server.h"
#include "storage.h"

namespace {

sigset_t termination_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

}  // namespace

int main(int argc, char** argv) {
  moreau::server::ServerConfig cfg;
  cfg.data_dir = "moreau-data";
  if (const char* t = std::getenv("MOREAU_TOKEN"); t && *t) cfg.token = t;

  CLI::App app{"moreau-server: the Moreau job API over HTTP/JSON, with live state over LCM"};
  app.set_version_flag("--version", "moreau-server 0.1.0");
  app.add_option("--host", cfg.host, "Address to bind (a non-loopback one needs --token)")->capture_default_str();
  app.add_option("--port", cfg.port, "TCP port (0: any free port, printed at start)")->capture_default_str();
  app.add_option("--data", cfg.data_dir, "Directory for job records and results")->capture_default_str();
  app.add_option("--scenes", cfg.scenes_dir, "Directory served by /v1/scenes (default: " + moreau::server::default_scenes_dir() + ")");
  app.add_option("--workers", cfg.workers, "Jobs integrated at once (0: one per core)")->capture_default_str();
  app.add_option("--io-threads", cfg.io_threads, "Threads that make finished jobs' results durable (fsync, rename)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--queue", cfg.queue, "Queued jobs beyond which submissions get 429")
      ->capture_default_str()
      ->check(CLI::Range(0, 1000000));
  app.add_option("--max-connections", cfg.max_connections, "Open connections at most (more: 503 at once)")
      ->capture_default_str()
      ->check(CLI::Range(2, 900));
  app.add_option("--max-connections-per-client", cfg.max_connections_per_client,
                 "Open connections from one client address at most (more: 503 at once)")
      ->capture_default_str()
      ->check(CLI::Range(1, 900));
  app.add_option("--header-timeout-ms", cfg.header_timeout_ms, "Time a request's line and headers may take to arrive")
      ->capture_default_str()
      ->check(CLI::Range(10, 600'000));
  app.add_option("--body-timeout-ms", cfg.body_timeout_ms, "Time a request's body may take to arrive")
      ->capture_default_str()
      ->check(CLI::Range(10, 3'600'000));
  app.add_option("--max-waiting", cfg.max_waiting, "Long polls (?wait) and event streams open at once (more: 429)")
      ->capture_default_str()
      ->check(CLI::Range(0, 900));
  app.add_option("--max-result-bytes", cfg.max_result_bytes, "Largest trajectory a job may write, bytes (more: 422 at submission)")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{4096}, std::int64_t{1} << 50));
  app.add_option("--max-figure-pixels", cfg.max_figure_pixels, "Pixels of one figure at most (width times height)")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{4096}, std::int64_t{16'777'216}));
  app.add_option("--max-figure-source-bytes", cfg.max_figure_source_bytes,
                 "Largest stored trajectory a figure is drawn from, bytes (more: 422)")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{4096}, std::int64_t{1} << 40));
  app.add_option("--figures-at-once", cfg.figures_at_once, "Figures drawn at once (more wait for a turn)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  app.add_option("--lcm-url", cfg.lcm_url, "LCM URL for live state (default: LCM_DEFAULT_URL, else LCM's default)");
  app.add_option("--token", cfg.token, "Require 'Authorization: Bearer TOKEN' (default: MOREAU_TOKEN)");
  app.add_option("--cors-origin", cfg.cors_origin,
                 "Answer cross-origin requests from this browser origin (scheme://host[:port], or *); default: none")
      ->check([](const std::string& v) -> std::string {
        if (v == "*") return "";
        const auto sep = v.find("://");
        const std::string scheme = sep == std::string::npos ? "" : v.substr(0, sep);
        const std::string host = sep == std::string::npos ? "" : v.substr(sep + 3);
        const bool ok = (scheme == "http" || scheme == "https") && !host.empty() && host.size() <= 253 &&
                        host.find_first_of("/?# \t") == std::string::npos;
        return ok ? "" : "expected * or an origin scheme://host[:port] with no path, e.g. https://lab.example:8443";
      });
  app.add_flag("--allow-unauthenticated-remote", cfg.allow_unauthenticated_remote, "Allow a non-loopback --host without a token");
  app.add_option("--max-body", cfg.max_body_bytes, "Largest request body, bytes (larger: 413)")->capture_default_str();
  app.add_option("--max-steps", cfg.max_steps, "Integration steps per job at most")->capture_default_str()->check(CLI::PositiveNumber);
  app.add_option(
         "--max-job-seconds", cfg.max_job_seconds,
         "Wall-clock seconds one job (run, study or campaign) may run; past it, it ends failed, keeping what it wrote (0: no limit)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e7));
  app.add_option("--max-campaign-samples", cfg.max_campaign_samples, "Samples of one campaign at most (POST /v1/campaigns)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--max-campaign-steps", cfg.max_campaign_steps, "Integration steps of all of one campaign's samples at most")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--campaign-threads", cfg.campaign_threads, "Threads one campaign runs its samples on (0: as many as --workers)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--max-samples", cfg.max_samples, "Trajectory rows per job at most")
      ->capture_default_str()
      ->check(CLI::Range(std::int64_t{3}, std::int64_t{1} << 40));
  app.add_option("--keep-alive", cfg.keep_alive_seconds, "Seconds an idle keep-alive connection stays open")->capture_default_str();
  app.add_option("--keep-alive-requests", cfg.keep_alive_requests,
                 "Requests served on one connection before it is closed (lets waiting connections in)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  app.add_flag("--log-requests", cfg.log_requests, "One line per request on stderr");
  app.add_option("--keep-jobs", cfg.keep_jobs,
                 "Finished jobs and studies kept (memory and disk); the oldest beyond it are deleted (0: all)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  // Block SIGINT and SIGTERM in every thread; one thread waits for them and stops the server.
  sigset_t signals = termination_signals();
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  try {
    moreau::server::Server server(cfg);
    // A data directory the server cannot write in (a read-only mount, say) would fail every job while
    // /healthz says ok: refuse to start instead, naming it.
    try {
      moreau::server::check_writable_directory(std::filesystem::path(cfg.data_dir) / "jobs");
    } catch (const std::exception& e) {
      throw std::runtime_error("cannot use data directory '" + cfg.data_dir + "': " + e.what());
    }
    const int port = server.start();
    std::cout << "moreau-server: listening on http://" << (cfg.host.find(':') != std::string::npos ? "[" + cfg.host + "]" : cfg.host) << ":"
              << port << " (data " << cfg.data_dir << (cfg.token.empty() ? ", no token" : ", token required") << ")" << std::endl;
    std::thread([&server, signals] {
      int sig = 0;
      sigwait(&signals, &sig);
      std::cerr << "moreau-server: signal " << sig << ", stopping\n";
      server.stop();
    }).detach();
    server.wait();
  } catch (const std::exception& e) {
    std::cerr << "moreau-server: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
