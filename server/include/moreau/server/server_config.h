// moreau-server's configuration: every limit and setting an operator chooses (docs/api.md,
// docs/reliability.md), in one struct that main.cc fills from the command line and the server's parts
// (HTTP transport, job store and runner, streaming) read.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace moreau::server {

struct ServerConfig {
  std::string host = "127.0.0.1";
  int port = 8080;         // 0: any free port (see Server::port())
  std::string data_dir;    // results and job records; created if missing
  std::string scenes_dir;  // served by /v1/scenes; empty: default_scenes_dir()
  int workers = 0;         // integrating threads; 0: one per core
  int io_threads = 4;      // threads that fsync and rename finished jobs' results
  int queue = 64;          // queued jobs beyond which POST /v1/jobs answers 429
  // Connections: each open one is served by its own thread, so a slow or waiting client holds only its
  // own. Beyond either limit a new connection is answered 503 at once and closed.
  int max_connections = 512;            // open connections in all
  int max_connections_per_client = 64;  // open connections from one client address
  int header_timeout_ms = 10'000;       // a request's line and headers must arrive within this
  int body_timeout_ms = 60'000;         // ... and its body within this after the headers
  // Long polls (?wait) and event streams open at once; beyond it they are answered 429 at once, so
  // that waiting clients cannot take every connection slot.
  int max_waiting = 256;
  std::string lcm_url;                        // empty: LCM_DEFAULT_URL, else LCM's default, opened at the first stream
  std::string token;                          // non-empty: every endpoint but /healthz needs "Authorization: Bearer TOKEN"
  bool allow_unauthenticated_remote = false;  // start() refuses a non-loopback host without a token unless set
  // Cross-origin requests (CORS) from a browser page served elsewhere: empty (the default) answers none,
  // "*" any origin, else exactly this origin ("https://lab.example:8443"). Preflights are answered
  // without the token (browsers never send one with them); every other request still needs it.
  std::string cors_origin;
  // The largest request body, counted after decoding (Content-Encoding) and whatever the framing
  // (Content-Length, chunked, or read to the end): larger gets 413.
  std::size_t max_body_bytes = 4u << 20;
  // The largest result a job may write (its trajectory CSV, bounded above by rows times the widest
  // row): a scene that could write more is refused at submission with 422.
  std::int64_t max_result_bytes = std::int64_t{1} << 30;
  // Figures: pixels of one figure at most (the renderer holds about 20 bytes per pixel while drawing),
  // and figures drawn at once (more wait for a turn).
  std::int64_t max_figure_pixels = 4'194'304;
  int figures_at_once = 2;
  // The largest stored trajectory a figure is drawn from (it is read whole, and held as numbers while
  // drawn: about 1.4 times its size); larger gets 422, with the window parameters to use instead.
  std::int64_t max_figure_source_bytes = std::int64_t{256} << 20;
  // Wall-clock seconds one job (a run, a study or a campaign) may hold its worker: past it the job stops at
  // its next check and ends failed, keeping what it wrote. Steps are not cost (a 64-joint arm's step costs
  // about 400 times a ball's), so this is the bound on the work a job can take. 0: no limit.
  double max_job_seconds = 3600;
  std::int64_t max_steps = 100'000'000;  // integration steps per job
  std::int64_t max_samples = 2'000'000;  // trajectory rows per job
  // Campaigns (POST /v1/campaigns): samples of one campaign at most, integration steps of all its samples
  // at most (each sample is also held to max_steps), and the threads one campaign runs its samples on
  // (0: as many as workers). A campaign is one job of the queue: it takes one worker's place and runs its
  // samples on its own threads.
  std::int64_t max_campaign_samples = 100'000;
  std::int64_t max_campaign_steps = 10'000'000'000;
  int campaign_threads = 0;
  int keep_alive_seconds = 5;  // idle keep-alive connections are closed after this
  // Requests served on one connection before it is closed: a busy keep-alive connection then goes back
  // behind the connections waiting for a thread, so that more clients than threads all get served.
  int keep_alive_requests = 100;
  bool log_requests = false;  // one line per request on stderr
  // Finished jobs and studies kept, in memory and on disk; beyond it the oldest finished ones are deleted
  // (pruned in batches of a tenth of it). 0: keep all, until an operator deletes them.
  std::int64_t keep_jobs = 0;
};

}  // namespace moreau::server
