// The HTTP layer: routes, authentication, validation and limits, over the JobRunner.
#include "moreau/server/server.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <numeric>
#include <sstream>
#include <string_view>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "figures.h"
#include "job_runner.h"
#include "lcm_stream.h"
#include "moreau/analysis/campaign.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "conditional.h"
#include "embedded_files.h"
#include "storage.h"
#include "trajectory.h"

// After Eigen (through the scene headers): httplib.h pulls in <resolv.h>, whose `_res` macro breaks
// Eigen's product kernels if it comes first.
#include "http_transport.h"

namespace moreau::server {
namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;
using Clock = std::chrono::steady_clock;

std::string default_scenes_dir() {
#ifdef MOREAU_SOURCE_DIR
  const fs::path source = fs::path(MOREAU_SOURCE_DIR) / "scenes";
  std::error_code ec;
  if (fs::is_directory(source, ec)) return source.string();
#endif
  return "/usr/share/moreau/scenes";
}

namespace {

constexpr int kMaxWaitSeconds = 60;
constexpr int kDefaultFigureWidth = 1200, kDefaultFigureHeight = 800;

// Invalid UTF-8 (quoted from a request into an error message) is replaced by U+FFFD rather than making
// dump() throw.
void send_json(Response& res, int status, const json& j) {
  res.status = status;
  res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n", "application/json");
}

// Error bodies: {"error": what went wrong, "pointer": the JSON pointer of the field at fault,
// "where": "scene" (pointer into the scene) or "request" (pointer into the request body), "reason"}.
// A queued job's place in the queue (1: the next to run), added to its JSON.
json with_queue_position(json j, const std::map<std::string, int>& positions) {
  if (auto it = positions.find(j.value("id", "")); it != positions.end()) j["queue_position"] = it->second;
  return j;
}

// Sets the ETag of a finished result, figure or static file, and answers 304 Not Modified (no body)
// when the request's If-None-Match already holds it.
bool not_modified(const Request& req, Response& res, const std::string& etag) {
  res.set_header("ETag", etag);
  if (!req.has_header("If-None-Match") || !if_none_match(req.get_header_value("If-None-Match"), etag)) return false;
  res.status = 304;
  return true;
}

void send_error(Response& res, int status, const std::string& error, const std::string& pointer = "", const std::string& reason = "",
                const std::string& where = "") {
  json j = {{"error", error}};
  if (!pointer.empty()) j["pointer"] = pointer;
  if (!where.empty()) j["where"] = where;
  if (!reason.empty()) j["reason"] = reason;
  send_json(res, status, j);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// Compares in time that depends on the secret's length only, not on where the strings differ.
bool constant_time_equal(const std::string& given, const std::string& secret) {
  volatile unsigned char diff = given.size() != secret.size() ? 1 : 0;
  for (std::size_t i = 0; i < secret.size(); ++i) {
    const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
    diff = static_cast<unsigned char>(diff | (g ^ static_cast<unsigned char>(secret[i])));
  }
  return diff == 0;
}

// Every path the API serves, the methods it takes and the query parameters its GET reads (docs/api.md,
// server/openapi.json, the routes registered in Impl::setup_routes()): the Allow header of a 405 and of an OPTIONS answer, and the
// 400 for a query parameter the path does not read. HEAD is served wherever GET is.
// ServerApi.WrongMethodIs405WithAllowAndOptionsAnswers checks this table against the routes.
struct RouteInfo {
  const char* pattern;  // segments; "*" is any one non-empty segment, "a|b" either name
  const char* allow;
  std::vector<std::string> params;              // of GET (and HEAD)
  std::vector<std::string> delete_params = {};  // of DELETE; POST reads none
};

// Whether `path` matches `pattern` segment by segment (no regular expressions: this runs for every
// request, before routing).
bool path_matches(std::string_view path, std::string_view pattern) {
  if (path == pattern) return true;  // "/" included, whose one segment is empty
  while (!path.empty() || !pattern.empty()) {
    if (path.empty() || pattern.empty() || path[0] != '/' || pattern[0] != '/') return false;
    path.remove_prefix(1);
    pattern.remove_prefix(1);
    const std::string_view seg = path.substr(0, path.find('/')), want = pattern.substr(0, pattern.find('/'));
    path.remove_prefix(seg.size());
    pattern.remove_prefix(want.size());
    if (seg.empty()) return false;
    if (want == "*") continue;
    bool any = false;
    for (std::string_view alts = want; !alts.empty() && !any;) {
      const std::string_view alt = alts.substr(0, alts.find('|'));
      any = alt == seg;
      alts.remove_prefix(std::min(alts.size(), alt.size() + 1));
    }
    if (!any) return false;
  }
  return true;
}

const RouteInfo* route_for(const std::string& path) {
  static const std::vector<std::string> kNone, kList = {"state", "scene", "limit", "before"}, kWait = {"wait"},
                                               kFigure = {"kind", "width", "height", "format"}, kPurge = {"purge"};
  static const RouteInfo routes[] = {
      {"/", "GET, HEAD, OPTIONS", kNone},
      {"/ui/app.js|style.css", "GET, HEAD, OPTIONS", kNone},
      {"/healthz", "GET, HEAD, OPTIONS", kNone},
      {"/metrics", "GET, HEAD, OPTIONS", kNone},
      {"/v1/openapi.json", "GET, HEAD, OPTIONS", kNone},
      {"/v1/scenes", "GET, HEAD, OPTIONS", kNone},
      {"/v1/scenes/*", "GET, HEAD, OPTIONS", kNone},
      {"/v1/jobs", "GET, HEAD, POST, OPTIONS", kList},
      {"/v1/jobs/*", "GET, HEAD, DELETE, OPTIONS", kWait, kPurge},
      {"/v1/jobs/*/events|report", "GET, HEAD, OPTIONS", kNone},
      {"/v1/jobs/*/trajectory", "GET, HEAD, OPTIONS", {"format", "from", "to", "every"}},
      {"/v1/jobs/*/figure", "GET, HEAD, OPTIONS", kFigure},
      {"/v1/studies", "GET, HEAD, POST, OPTIONS", kList},
      {"/v1/studies/*", "GET, HEAD, DELETE, OPTIONS", kWait, kPurge},
      {"/v1/studies/*/events", "GET, HEAD, OPTIONS", kNone},
      {"/v1/studies/*/table", "GET, HEAD, OPTIONS", {"format"}},
      {"/v1/studies/*/figure", "GET, HEAD, OPTIONS", kFigure},
      {"/v1/campaigns", "GET, HEAD, POST, OPTIONS", kList},
      {"/v1/campaigns/*", "GET, HEAD, DELETE, OPTIONS", kWait, kPurge},
      {"/v1/campaigns/*/events", "GET, HEAD, OPTIONS", kNone},
      {"/v1/campaigns/*/summary|samples", "GET, HEAD, OPTIONS", {"format"}},
      {"/v1/campaigns/*/figure", "GET, HEAD, OPTIONS", kFigure},
  };
  for (const RouteInfo& r : routes)
    if (path_matches(path, r.pattern)) return &r;
  return nullptr;
}

const char* allowed_methods(const std::string& path) {
  const RouteInfo* r = route_for(path);
  return r ? r->allow : nullptr;
}

// The first query parameter of the request that its path does not read, with why, or "" if none.
std::string unknown_query_parameter(const Request& req) {
  const RouteInfo* r = route_for(req.path);
  if (!r) return "";
  // Each method reads its own: DELETE /v1/jobs/ID?wait=5 would otherwise be accepted and the wait
  // ignored. POST reads none.
  static const std::vector<std::string> kNone;
  const std::vector<std::string>& params = req.method == "GET" || req.method == "HEAD" ? r->params
                                           : req.method == "DELETE"                    ? r->delete_params
                                                                                       : kNone;
  for (const auto& [name, value] : req.params) {
    if (std::find(params.begin(), params.end(), name) != params.end()) continue;
    std::string takes;
    for (const std::string& p : params) takes += (takes.empty() ? "" : ", ") + p;
    return "unknown query parameter '" + name.substr(0, 64) + "' on " + req.method.substr(0, 16) + " " + req.path.substr(0, 256) +
           (takes.empty() ? " (it takes none)" : " (it takes " + takes + ")");
  }
  return "";
}

// 405 for a path that exists under other methods, with the Allow header (RFC 9110 15.5.6).
void send_method_not_allowed(Response& res, const std::string& method, const std::string& path, const char* allow) {
  res.set_header("Allow", allow);
  send_error(res, 405, "method not allowed", "", method + " is not allowed on " + path + "; allowed: " + allow);
}

// The reason of a 404 for a path no endpoint serves: the method and path asked for (bounded).
std::string no_endpoint(const Request& req) {
  return "no endpoint " + req.method.substr(0, 16) + " " + req.path.substr(0, 256) + "; see docs/api.md for the endpoints";
}

bool is_loopback(const std::string& host) { return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0; }

std::string fmt_g(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.10g", v);
  return buf;
}

// A query parameter as a number in [lo, hi], or nullopt (absent); throws std::invalid_argument.
std::optional<double> number_param(const Request& req, const char* name, double lo, double hi) {
  if (!req.has_param(name)) return std::nullopt;
  const std::string v = req.get_param_value(name);
  char* end = nullptr;
  const double d = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !std::isfinite(d) || d < lo || d > hi)
    throw std::invalid_argument(std::string("query parameter '") + name + "' must be a number in [" + fmt_g(lo) + ", " + fmt_g(hi) + "]");
  return d;
}

struct BadRequest {
  int status;
  std::string error, pointer, reason, where;
};

// Thrown while drawing a figure when a stored file of a finished job cannot be read: a 500, not a 422.
struct StoredFileUnreadable {
  std::string error;
};
// ... or when the job was deleted (pruned) meanwhile: a 404.
struct JobDeleted {};

bool valid_channel_prefix(const std::string& s) {
  if (s.empty() || s.size() > 64 || !(s[0] >= 'A' && s[0] <= 'Z')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; });
}

// Ends the connection after this response: its request was answered without reading all of its body,
// so the bytes left on it cannot be read as a next request.
void close_connection_after(Response& res) {
  if (auto* c = current_connection()) c->close_after = true;
  res.set_header("Connection", "close");
}

TransportLimits transport_limits(const ServerConfig& cfg) {
  TransportLimits l;
  l.max_connections = std::max(2, cfg.max_connections);
  l.max_connections_per_client = std::max(1, cfg.max_connections_per_client);
  l.header_timeout = std::chrono::milliseconds(std::max(1, cfg.header_timeout_ms));
  l.body_timeout = std::chrono::milliseconds(std::max(1, cfg.body_timeout_ms));
  l.keep_alive_timeout = std::chrono::seconds(std::max(1, cfg.keep_alive_seconds));
  l.keep_alive_requests = std::max(1, cfg.keep_alive_requests);
  // As sent, a body may be larger than decoded only by its chunked framing: a few bytes per chunk.
  l.max_raw_body_bytes = cfg.max_body_bytes + cfg.max_body_bytes / 8 + (64 << 10);
  return l;
}

// A request path or header as the request log shows it: control bytes, CR, LF and non-ASCII escaped as
// \xHH, so that a request cannot write lines of its own into the log.
std::string log_escaped(const std::string& s, std::size_t max = 512) {
  std::string out;
  for (std::size_t i = 0; i < s.size() && out.size() < max; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c >= 0x7f || c == '\\') {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (out.size() >= max) out += "...";
  return out;
}

// Counts the holders of a bounded resource (waiting connections, figures being drawn).
class Budget {
 public:
  explicit Budget(int capacity) : capacity_(capacity) {}
  // Takes a place, or returns false at once when all are taken.
  bool try_take() {
    std::lock_guard lock(mu_);
    if (taken_ >= capacity_) return false;
    ++taken_;
    return true;
  }
  // Takes a place, waiting up to `timeout` for one.
  bool take(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mu_);
    if (!cv_.wait_for(lock, timeout, [&] { return taken_ < capacity_; })) return false;
    ++taken_;
    return true;
  }
  void give_back() {
    {
      std::lock_guard lock(mu_);
      --taken_;
    }
    cv_.notify_one();
  }
  int taken() const {
    std::lock_guard lock(mu_);
    return taken_;
  }

 private:
  const int capacity_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  int taken_ = 0;
};

// The study settings of a request or of a stored study.json, its errors at /study.
scene::StudySettings study_settings_at(const json& fields) {
  try {
    return scene::study_settings_from_json(fields, "/study");
  } catch (const scene::SceneError& e) {
    throw BadRequest{400, "invalid request", e.pointer(), e.reason(), "request"};
  }
}

}  // namespace

class Server::Impl {
 public:
  explicit Impl(ServerConfig config) : cfg_(std::move(config)), hub_(cfg_.lcm_url), jobs_(cfg_, hub_), http_(transport_limits(cfg_)) {
    if (cfg_.scenes_dir.empty()) cfg_.scenes_dir = default_scenes_dir();
    if (!cfg_.lcm_url.empty()) hub_.open();
    requeue_recovered(jobs_.recover());
    setup_routes();
  }

  ~Impl() { stop(); }

  // The jobs a previous server accepted and did not finish run again, compiled from the documents they
  // stored, within this server's limits (which may have changed since: a job they now refuse fails,
  // saying why), in the order they were submitted and ahead of new ones.
  void requeue_recovered(const std::vector<std::shared_ptr<Job>>& pending) {
    for (const auto& job : pending) {
      const auto t_load = Clock::now();
      std::string refused;
      try {
        const auto stored = [&job](const char* name) {
          json doc = json::parse(read_file(job->dir / name).value_or(""), nullptr, false);
          if (!doc.is_object()) throw std::runtime_error(std::string("its ") + name + " is missing or unreadable");
          return doc;
        };
        switch (job->kind) {
          case JobKind::kRun: prepare_run(*job, stored("scene.json"), job->stream); break;
          case JobKind::kStudy: prepare_study(*job, stored("scene.json"), study_settings_at(stored("study.json"))); break;
          case JobKind::kCampaign: prepare_campaign(*job, stored("campaign.json")); break;
        }
      } catch (const BadRequest& e) {
        refused = (e.pointer.empty() ? "" : e.pointer + ": ") + e.reason;
      } catch (const scene::SceneError& e) {
        refused = e.pointer() + ": " + e.reason();
      } catch (const std::exception& e) {
        refused = e.what();
      }
      job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();
      jobs_.requeue(job, refused);
    }
  }

  int start() {
    if (cfg_.token.empty() && !is_loopback(cfg_.host) && !cfg_.allow_unauthenticated_remote) {
      throw std::runtime_error("refusing to serve " + cfg_.host +
                               " without a token: give --token (or MOREAU_TOKEN), or --allow-unauthenticated-remote");
    }
    // Any web page the user visits could otherwise read, submit and delete jobs through the browser.
    if (cfg_.cors_origin == "*" && cfg_.token.empty()) {
      throw std::runtime_error(
          "refusing --cors-origin '*' without a token: any web page could use this server; give --token "
          "(or MOREAU_TOKEN), or name the one origin to answer");
    }
    jobs_.start();
    int port = cfg_.port;
    if (port == 0) {
      port = http_.bind_to_any_port(cfg_.host);
      if (port < 0) throw std::runtime_error("cannot bind " + cfg_.host + " (any port)");
    } else if (!http_.bind_to_port(cfg_.host, port)) {
      throw std::runtime_error("cannot bind " + cfg_.host + ":" + std::to_string(port));
    }
    port_ = port;
    // libcpp-httplib listens with a backlog of 5 (compiled in): a burst of new connections beyond it
    // waits for SYN retransmissions (1 s, 3 s, ...) or is reset. Listening again raises it.
    if (listen_socket_ >= 0) ::listen(listen_socket_, SOMAXCONN);
    listener_ = std::thread([this] { http_.listen_after_bind(); });
    housekeeper_ = std::thread([this] { housekeeping(); });
    while (!http_.is_running()) std::this_thread::sleep_for(std::chrono::microseconds(200));
    return port_;
  }

  void stop() {
    {
      std::lock_guard lock(stop_mu_);
      if (stopped_) return;
      stopped_ = true;
    }
    stop_cv_.notify_all();  // the housekeeper
    jobs_.stop();           // ends event streams, long polls and running jobs first
    http_.stop();
    http_.shut_down_connections();  // idle keep-alive and slow connections end now, not at their deadlines
    if (listener_.joinable()) listener_.join();
    if (housekeeper_.joinable()) housekeeper_.join();
    hub_.stop();
    {
      std::lock_guard lock(stop_mu_);
      stop_done_ = true;
    }
    stop_cv_.notify_all();
  }

  void wait() {
    std::unique_lock lock(stop_mu_);
    stop_cv_.wait(lock, [&] { return stop_done_; });
  }

  int port() const { return port_; }
  lcm::LCM* lcm() { return hub_.get(); }

  // Every 5 s while the server is idle (no queued or running job), gives the memory freed by past
  // requests back to the system: glibc keeps it in per-thread arenas otherwise, and the resident size
  // would stay at its peak after a burst of connections.
  void housekeeping() {
    std::unique_lock lock(stop_mu_);
    while (!stop_cv_.wait_for(lock, std::chrono::seconds(5), [&] { return stopped_; })) {
#ifdef __GLIBC__
      if (jobs_.idle()) malloc_trim(0);
#endif
    }
  }

 private:
  void setup_routes();
  // Answers a request whose framing, token or announced body is refused (and marks its connection to
  // be closed); false if the request may go on to its handler.
  bool screen(const Request& req, Response& res);
  void body_too_large(Response& res) const {
    close_connection_after(res);
    send_error(res, 413, "request body too large", "",
               "this server accepts bodies of at most " + std::to_string(cfg_.max_body_bytes) +
                   " bytes (counted after Content-Encoding is decoded)");
  }
  // The body of a POST, decoded, or nullopt after answering 413 (over the limit as decoded), 408 (too
  // slow) or 400 (broken framing or encoding).
  std::optional<std::string> read_body(const Request& req, Response& res, const httplib::ContentReader& reader);
  void post_job(const Request& req, Response& res, const std::string& body);
  void post_study(const Request& req, Response& res, const std::string& body);
  void post_campaign(const Request& req, Response& res, const std::string& body);
  // A job's compiled contents and fields from its documents, within this server's limits: at submission,
  // and again for a job a restarted server runs (requeue_recovered). Throw BadRequest or scene::SceneError.
  void prepare_run(Job& job, const json& doc, const StreamSettings& stream);
  void prepare_study(Job& job, const json& doc, scene::StudySettings st);
  void prepare_campaign(Job& job, const json& spec_doc);
  void get_job(const Request& req, Response& res, JobKind kind);
  void list_jobs(const Request& req, Response& res, JobKind kind);
  void delete_job(const Request& req, Response& res, JobKind kind);
  void job_events(const Request& req, Response& res, JobKind kind);
  void study_table(const Request& req, Response& res);
  void study_figure(const Request& req, Response& res);
  void campaign_summary(const Request& req, Response& res);
  void campaign_samples(const Request& req, Response& res);
  void campaign_figure(const Request& req, Response& res);
  // The scene document of a request body: "scene" (an object, or the name of a shipped scene) with
  // "overrides" applied. Throws BadRequest or scene::SceneError.
  json request_scene(const json& body) const;
  void job_report(const Request& req, Response& res);
  void job_trajectory(const Request& req, Response& res);
  void job_figure(const Request& req, Response& res);
  void list_scenes(const Request& req, Response& res);
  void get_scene(const Request& req, Response& res);
  void metrics(const Request& req, Response& res);

  // The job (or study) named by the first capture, or nullptr after answering 404. The id is checked
  // against [0-9a-f]{32} and looked up in memory: request data never reaches a path.
  std::shared_ptr<Job> job_for(const Request& req, Response& res, JobKind kind = JobKind::kRun) {
    const std::string id = req.matches.size() > 1 ? req.matches[1].str() : std::string();
    std::shared_ptr<Job> job = is_job_id(id) ? jobs_.find(id) : nullptr;
    if (job && job->kind != kind) job = nullptr;
    if (job && is_deleted(*job)) job = nullptr;
    if (!job) {
      // Says which id was not found, or why it cannot be an id (quoted, bounded; JSON escapes it).
      const std::string what = kind == JobKind::kRun ? "job" : kind_name(kind);
      const std::string post = "POST " + kind_url(kind).substr(0, kind_url(kind).size() - 1);
      send_error(res, 404, std::string("no such ") + what, "",
                 is_job_id(id) ? std::string("no ") + what + " " + id +
                                     " on this server (finished ones are deleted when purged, or beyond --keep-jobs)"
                               : "'" + id.substr(0, 64) + "' is not a " + what + " id: " + what + " ids are 32 lowercase hex digits, as " +
                                     post + " returns them");
    }
    return job;
  }
  static bool is_deleted(const Job& job) {
    std::shared_lock files(job.files_mu);
    return job.deleted;
  }
  // A file of a finished job, read under its files lock: nullopt if the job has no such result yet, or
  // was deleted (pruned by --keep-jobs) meanwhile; then *deleted says which.
  static std::optional<std::string> job_file(const Job& job, bool Job::*has, const char* name, bool* deleted = nullptr) {
    std::shared_lock files(job.files_mu);
    if (deleted) *deleted = job.deleted;
    if (job.deleted || !final_with(job, has)) return std::nullopt;
    return read_file(job.dir / name);
  }
  // A stored result of a finished job (its report, a study's table, a campaign's summary), whole, with
  // its strong ETag; 409 `not_yet` (the job's state and when it comes) until the job has it, 404 once the
  // job is deleted. `attachment`: a download's file name, or "".
  static void send_result_file(const Request& req, Response& res, const Job& job, const char* name, const char* content_type,
                               const char* not_yet, const std::string& when, const std::string& attachment = "") {
    bool deleted = false;
    auto text = job_file(job, &Job::has_report, name, &deleted);
    if (deleted) return send_deleted(res);
    if (!text)
      return send_error(
          res, 409, not_yet, "",
          std::string("the ") + (job.kind == JobKind::kRun ? "job" : kind_name(job.kind)) + " is " + to_string(state_of(job)) + when);
    if (not_modified(req, res, strong_etag(*text))) return;
    res.status = 200;
    if (!attachment.empty()) res.set_header("Content-Disposition", "attachment; filename=\"" + attachment + "\"");
    res.set_content(std::move(*text), content_type);
  }
  void too_many_waiting(Response& res) const {
    res.set_header("Retry-After", "1");
    send_error(res, 429, "too many waiting requests", "",
               "this server holds at most " + std::to_string(cfg_.max_waiting) +
                   " long polls (?wait) and event streams open at once; retry, or poll without wait");
  }
  static void send_deleted(Response& res) {
    send_error(res, 404, "no such job", "",
               "the job was deleted (purged, or beyond the most recent finished jobs this server keeps: --keep-jobs)");
  }
  // The job's state, report presence and trajectory presence, under its lock.
  static JobState state_of(const Job& job) {
    std::lock_guard lock(job.mu);
    return job.state;
  }
  // Queues a validated job or study and answers: 202 with it and its Location, 429 with Retry-After when
  // the queue is full, 503 while stopping, 507 if its records cannot be written (a full disk, say).
  void queue_and_answer(const std::shared_ptr<Job>& job, const json& scene_doc, const json* study_doc, Response& res) {
    int retry_after = 1;
    JobRunner::Submit outcome;
    try {
      outcome = jobs_.submit(job, scene_doc, &retry_after, study_doc);
    } catch (const std::exception& e) {
      return send_error(res, 507, "cannot store the job", "", e.what());
    }
    switch (outcome) {
      case JobRunner::Submit::kQueued: break;
      case JobRunner::Submit::kQueueFull:
        res.set_header("Retry-After", std::to_string(retry_after));
        return send_error(
            res, 429, "queue full", "",
            "the server holds " + std::to_string(cfg_.queue) + " queued jobs at most; retry in " + std::to_string(retry_after) + " s");
      case JobRunner::Submit::kStopping: return send_error(res, 503, "server stopping");
    }
    const json j = with_queue_position(job_json(*job, nullptr), jobs_.queue_positions());
    res.set_header("Location", j["url"].get<std::string>());
    send_json(res, 202, j);
  }
  // Whether the job is final and has the results `what` points to (has_report or has_trajectory).
  static bool final_with(const Job& job, bool Job::*what) {
    std::lock_guard lock(job.mu);
    return job.*what && is_final(job.state);
  }
  struct FigureRequest {
    std::pair<int, int> size{kDefaultFigureWidth, kDefaultFigureHeight};
    FigureFormat format = FigureFormat::kPng;
  };
  // The requested figure: size (width, height: 64 to 4096, default 1200x800, at most --max-figure-pixels
  // in all) and format (png, the default, or svg), or nullopt after answering 501 (no render/ in this
  // build) or 400.
  std::optional<FigureRequest> figure_request(const Request& req, Response& res) const {
    if (!figures_available()) {
      send_error(res, 501, "figures not available", "", "this server was built without render/ (no OSMesa)");
      return std::nullopt;
    }
    FigureRequest f;
    try {
      if (auto w = number_param(req, "width", 64, 4096)) f.size.first = static_cast<int>(*w);
      if (auto h = number_param(req, "height", 64, 4096)) f.size.second = static_cast<int>(*h);
    } catch (const std::exception& e) {
      send_error(res, 400, "bad query", "", e.what());
      return std::nullopt;
    }
    if (static_cast<std::int64_t>(f.size.first) * f.size.second > cfg_.max_figure_pixels) {
      send_error(res, 400, "bad query", "",
                 "a figure has at most " + std::to_string(cfg_.max_figure_pixels) + " pixels (width times height); asked for " +
                     std::to_string(static_cast<std::int64_t>(f.size.first) * f.size.second));
      return std::nullopt;
    }
    const std::string format = req.has_param("format") ? req.get_param_value("format") : "png";
    if (format != "png" && format != "svg") {
      send_error(res, 400, "bad query", "", "query parameter 'format' must be png or svg");
      return std::nullopt;
    }
    f.format = format == "svg" ? FigureFormat::kSvg : FigureFormat::kPng;
    return f;
  }
  // Answers with the figure `draw` makes (422 if it throws, 500 if a stored file is unreadable). At the
  // default size it is read from, or written to, `cache_stem` + ".png" or ".svg": a name from a fixed
  // list, never from the request.
  template <class Draw>
  void send_figure(const Request& req, Response& res, const Job& job, const fs::path& cache_stem, const FigureRequest& f, Draw&& draw) {
    const bool svg = f.format == FigureFormat::kSvg;
    const char* content_type = svg ? "image/svg+xml" : "image/png";
    const fs::path cache = cache_stem.string() + (svg ? ".svg" : ".png");
    const bool default_size = f.size == std::pair<int, int>{kDefaultFigureWidth, kDefaultFigureHeight};
    if (default_size) {
      std::shared_lock files(job.files_mu);  // the cache is the job's file: never read one being deleted
      if (job.deleted) return send_deleted(res);
      if (auto bytes = read_file(cache)) {
        if (not_modified(req, res, strong_etag(*bytes))) return;
        res.status = 200;
        return res.set_content(std::move(*bytes), content_type);
      }
    }
    // At most --figures-at-once are drawn at once (each holds its trajectory and a frame buffer).
    if (!drawing_.take(std::chrono::seconds(30))) {
      res.set_header("Retry-After", "1");
      return send_error(res, 503, "figures busy", "", "every figure slot stayed busy for 30 s; retry");
    }
    std::string bytes;
    try {
      bytes = draw();
    } catch (const StoredFileUnreadable& e) {
      drawing_.give_back();
      return send_error(res, 500, e.error);
    } catch (const JobDeleted&) {
      drawing_.give_back();
      return send_deleted(res);
    } catch (const std::exception& e) {
      drawing_.give_back();
      return send_error(res, 422, "cannot draw this figure", "", e.what());
    }
    drawing_.give_back();
    if (default_size) {
      // Not into a job deleted (purged, pruned) while it was drawn: its directory is going.
      std::shared_lock files(job.files_mu);
      if (job.deleted) return send_deleted(res);
      try {
        write_file_atomic(cache, bytes, Durability::kFsync);
      } catch (const std::exception& e) {
        std::cerr << "moreau-server: " << e.what() << "\n";
      }
    }
    if (not_modified(req, res, strong_etag(bytes))) return;
    res.status = 200;
    res.set_content(std::move(bytes), content_type);
  }

  // The committed report of a run (report.json) or result of a study (result.json).
  std::optional<json> read_report(const Job& job) {
    auto text = job_file(job, &Job::has_report,
                         job.kind == JobKind::kStudy      ? "result.json"
                         : job.kind == JobKind::kCampaign ? "summary.json"
                                                          : "report.json");
    if (!text) return std::nullopt;
    json j = json::parse(*text, nullptr, false);
    if (j.is_discarded()) return std::nullopt;
    return j;
  }
  // Files of the scenes directory: name (file stem) -> path. Names come from the listing, never from
  // the request.
  std::map<std::string, fs::path> scene_files() const {
    std::map<std::string, fs::path> out;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(cfg_.scenes_dir, ec)) {
      if (e.is_regular_file(ec) && e.path().extension() == ".json") out.emplace(e.path().stem().string(), e.path());
    }
    return out;
  }

  ServerConfig cfg_;
  LcmHub hub_;
  JobRunner jobs_;
  GuardedHttpServer http_;
  Budget waiting_{cfg_.max_waiting};      // long polls and event streams open now
  Budget drawing_{cfg_.figures_at_once};  // figures being drawn now
  std::thread listener_;
  std::thread housekeeper_;
  int port_ = -1;
  int listen_socket_ = -1;  // the bound socket (set by the socket options callback)
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stopped_ = false;    // stop() has begun
  bool stop_done_ = false;  // stop() has finished
  mutable std::mutex stats_mu_;
  std::map<int, std::int64_t> responses_;
};

void Server::Impl::setup_routes() {
  http_.set_tcp_nodelay(true);
  // cpp-httplib's default socket options set SO_REUSEPORT, with which a second server binds the same
  // port and silently takes part of the connections. SO_REUSEADDR alone still allows a restart while
  // old connections are in TIME_WAIT, and a port in use is an error ("cannot bind").
  http_.set_socket_options([this](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listen_socket_ = sock;
  });
  // Bodies are read by BodyReader (decoded size) and the transport (size as sent); this only keeps
  // httplib from reading a body it would not pass to a handler.
  http_.set_payload_max_length(cfg_.max_body_bytes);
  http_.set_keep_alive_timeout(cfg_.keep_alive_seconds);
  http_.set_keep_alive_max_count(static_cast<std::size_t>(std::max(1, cfg_.keep_alive_requests)));
  http_.on_refused = [this](int status) {
    std::lock_guard lock(stats_mu_);
    ++responses_[status];
  };

  // Every request passes here once its headers are read, before any of its body is: the framing, the
  // token, and whether a body may come at all (only POST takes one, as application/json, announced
  // within the limit). Answered requests close their connection: their body is never read.
  http_.set_pre_routing_handler([this](const Request& req, Response& res) {
    return screen(req, res) ? httplib::Server::HandlerResponse::Handled : httplib::Server::HandlerResponse::Unhandled;
  });
  // "Expect: 100-continue" is answered before routing: the client sends its body only after a 100, so
  // a request refused here never sends it.
  http_.set_expect_100_continue_handler([this](const Request& req, Response& res) { return screen(req, res) ? res.status : 100; });
  http_.set_error_handler([this](const Request& req, Response& res) {
    if (!res.body.empty()) return;
    const ConnectionContext* conn = current_connection();
    if (conn && conn->timed_out) return send_error(res, 408, "request timeout", "", "the request did not arrive in time");
    if (conn && conn->headers_too_large) {
      close_connection_after(res);
      return send_error(res, 431, "request headers too large", "",
                        "the request line and headers may take at most " + std::to_string(http_.limits().max_header_bytes) + " bytes");
    }
    if (conn && conn->too_large) return body_too_large(res);
    if (res.status == 404) {
      if (const char* allow = allowed_methods(req.path)) return send_method_not_allowed(res, req.method, req.path, allow);
    }
    switch (res.status) {
      case 404: send_error(res, 404, "not found", "", no_endpoint(req)); break;
      case 414:  // httplib's own answer to a request line over its limit; its headers were skipped, not read
        close_connection_after(res);
        send_error(res, 414, "URI too long", "", "the request line may take at most " + std::to_string(kMaxRequestLineBytes) + " bytes");
        break;
      case 413: body_too_large(res); break;
      case 400: send_error(res, 400, "bad request"); break;
      default: send_error(res, res.status, "error " + std::to_string(res.status)); break;
    }
  });
  http_.set_exception_handler([](const Request&, Response& res, std::exception_ptr ep) {
    std::string what = "unknown error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    std::cerr << "moreau-server: internal error: " << log_escaped(what) << "\n";
    send_error(res, 500, "internal error", "", what);
  });
  // Every answer (routed, refused while screening, errors, streams): no content sniffing, and unless the
  // answer carries a policy of its own (the web page's files, page_file below) one under which nothing it
  // holds (a figure, a CSV, a report, an error quoting a client's text) loads or runs anything, or is
  // framed, when a browser opens it. The answers the transport writes itself carry the same
  // (http_transport.cc). httplib calls this as it writes each response, after the error handler.
  http_.set_post_routing_handler([](const Request&, Response& res) {
    if (!res.has_header("X-Content-Type-Options")) res.set_header("X-Content-Type-Options", "nosniff");
    if (!res.has_header("Content-Security-Policy")) res.set_header("Content-Security-Policy", kApiContentSecurityPolicy);
  });
  http_.set_logger([this](const Request& req, const Response& res) {
    {
      std::lock_guard lock(stats_mu_);
      ++responses_[res.status];
    }
    if (cfg_.log_requests) {
      std::fprintf(stderr, "moreau-server: %s %s %d %zu\n", log_escaped(req.method, 16).c_str(), log_escaped(req.path).c_str(), res.status,
                   res.body.size());
    }
  });

  http_.Get("/healthz", [this](const Request&, Response& res) {
    if (jobs_.stopping()) return send_json(res, 503, {{"status", "stopping"}});
    send_json(res, 200, {{"status", "ok"}});
  });
  http_.Get("/metrics", [this](const Request& req, Response& res) { metrics(req, res); });
  // The web page (server/web/): static, and open without the token (the page asks for it). Its policy
  // lets it load only its own script and style, and images it made from fetched figures (blob:) or its
  // empty icon (data:, which spares the browser a /favicon.ico request).
  auto page_file = [](std::string_view text, const char* type) {
    return [text, type, etag = strong_etag(text)](const Request& req, Response& res) {
      // Before the conditional answer: a 304 carries the page's policy too (a cache may update the stored
      // answer's headers from it), never the API's, which would forbid the page its own script.
      res.set_header("Content-Security-Policy",
                     "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; connect-src 'self'; "
                     "base-uri 'none'; form-action 'none'; frame-ancestors 'none'");
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_header("Referrer-Policy", "no-referrer");
      res.set_header("Cache-Control", "no-cache");
      if (not_modified(req, res, etag)) return;
      res.status = 200;
      res.set_content(std::string(text), type);
    };
  };
  http_.Get("/", page_file(web_index_html(), "text/html; charset=utf-8"));
  http_.Get("/ui/app.js", page_file(web_app_js(), "text/javascript; charset=utf-8"));
  http_.Get("/ui/style.css", page_file(web_style_css(), "text/css; charset=utf-8"));
  http_.Get("/v1/openapi.json", [etag = strong_etag(openapi_document())](const Request& req, Response& res) {
    if (not_modified(req, res, etag)) return;
    res.status = 200;
    res.set_content(std::string(openapi_document()), "application/json");
  });
  http_.Get("/v1/scenes", [this](const Request& req, Response& res) { list_scenes(req, res); });
  http_.Get(R"(/v1/scenes/([^/]+))", [this](const Request& req, Response& res) { get_scene(req, res); });
  http_.Post("/v1/jobs", [this](const Request& req, Response& res, const httplib::ContentReader& reader) {
    if (auto body = read_body(req, res, reader)) post_job(req, res, *body);
  });
  http_.Get("/v1/jobs", [this](const Request& req, Response& res) { list_jobs(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+))", [this](const Request& req, Response& res) { get_job(req, res, JobKind::kRun); });
  http_.Delete(R"(/v1/jobs/([^/]+))", [this](const Request& req, Response& res) { delete_job(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+)/events)", [this](const Request& req, Response& res) { job_events(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+)/report)", [this](const Request& req, Response& res) { job_report(req, res); });
  http_.Get(R"(/v1/jobs/([^/]+)/trajectory)", [this](const Request& req, Response& res) { job_trajectory(req, res); });
  http_.Get(R"(/v1/jobs/([^/]+)/figure)", [this](const Request& req, Response& res) { job_figure(req, res); });
  http_.Post("/v1/studies", [this](const Request& req, Response& res, const httplib::ContentReader& reader) {
    if (auto body = read_body(req, res, reader)) post_study(req, res, *body);
  });
  http_.Post("/v1/campaigns", [this](const Request& req, Response& res, const httplib::ContentReader& reader) {
    if (auto body = read_body(req, res, reader)) post_campaign(req, res, *body);
  });
  // Any other POST: answered without reading its body (the connection then closes).
  http_.Post(".*", [this](const Request& req, Response& res, const httplib::ContentReader&) {
    close_connection_after(res);
    if (const char* allow = allowed_methods(req.path)) return send_method_not_allowed(res, req.method, req.path, allow);
    send_error(res, 404, "not found", "", no_endpoint(req));
  });
  http_.Get("/v1/studies", [this](const Request& req, Response& res) { list_jobs(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+))", [this](const Request& req, Response& res) { get_job(req, res, JobKind::kStudy); });
  http_.Delete(R"(/v1/studies/([^/]+))", [this](const Request& req, Response& res) { delete_job(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+)/events)", [this](const Request& req, Response& res) { job_events(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+)/table)", [this](const Request& req, Response& res) { study_table(req, res); });
  http_.Get(R"(/v1/studies/([^/]+)/figure)", [this](const Request& req, Response& res) { study_figure(req, res); });
  http_.Get("/v1/campaigns", [this](const Request& req, Response& res) { list_jobs(req, res, JobKind::kCampaign); });
  http_.Get(R"(/v1/campaigns/([^/]+))", [this](const Request& req, Response& res) { get_job(req, res, JobKind::kCampaign); });
  http_.Delete(R"(/v1/campaigns/([^/]+))", [this](const Request& req, Response& res) { delete_job(req, res, JobKind::kCampaign); });
  http_.Get(R"(/v1/campaigns/([^/]+)/events)", [this](const Request& req, Response& res) { job_events(req, res, JobKind::kCampaign); });
  http_.Get(R"(/v1/campaigns/([^/]+)/summary)", [this](const Request& req, Response& res) { campaign_summary(req, res); });
  http_.Get(R"(/v1/campaigns/([^/]+)/samples)", [this](const Request& req, Response& res) { campaign_samples(req, res); });
  http_.Get(R"(/v1/campaigns/([^/]+)/figure)", [this](const Request& req, Response& res) { campaign_figure(req, res); });
}

namespace {

// The JSON object body of a POST: checks the content type (415) and the syntax (400), and that it is an
// object whose fields are among `fields` (given as "scene, overrides?, stream?"), with "scene".
json post_body(const std::string& text, const std::vector<std::string>& fields, const std::string& shape) {
  // JSON text never holds a raw NUL (RFC 8259 escapes control characters): a NUL is a sign of a binary or
  // truncated upload, and would cut C strings made from the scene.
  if (const auto nul = text.find('\0'); nul != std::string::npos)
    throw BadRequest{400, "malformed JSON", "", "the body holds a NUL byte at offset " + std::to_string(nul), "request"};
  // Bounded nesting before parsing: the JSON library copies and prints recursively.
  if (const auto at = scene::json_depth_exceeded(text)) {
    throw BadRequest{400, "malformed JSON", "",
                     "nested deeper than " + std::to_string(scene::kMaxJsonDepth) + " levels at byte " + std::to_string(*at), "request"};
  }
  json body = json::parse(text, nullptr, false);
  if (body.is_discarded()) {
    std::string why = "the body is not valid JSON";
    try {
      const json ignored = json::parse(text);
    } catch (const json::exception& e) {  // parse_error, and out_of_range for a number such as 1e999
      why = e.what();
    }
    throw BadRequest{400, "malformed JSON", "", why, "request"};
  }
  if (!body.is_object()) throw BadRequest{400, "invalid request", "", "the body must be an object " + shape, "request"};
  std::string expected;
  for (const auto& f : fields) expected += (expected.empty() ? "" : ", ") + f;
  for (const auto& [key, value] : body.items()) {
    if (std::find(fields.begin(), fields.end(), key) == fields.end())
      throw BadRequest{400, "invalid request", "/" + key, "unknown field (expected " + expected + ")", "request"};
  }
  if (!body.contains("scene")) throw BadRequest{400, "invalid request", "/scene", "missing required field 'scene'", "request"};
  return body;
}

}  // namespace

namespace {

// scene::apply_override, with an error about the override itself (not of the form PATH=VALUE, a path too
// deep: pointer "/") reported at `pointer` in the request; errors about the scene path keep theirs.
void apply_request_override(json& doc, const std::string& assignment, const std::string& pointer) {
  try {
    scene::apply_override(doc, assignment);
  } catch (const scene::SceneError& e) {
    if (e.pointer() == "/") throw BadRequest{400, "invalid request", pointer, e.reason(), "request"};
    throw;
  }
}

}  // namespace

namespace {

// Runs a POST handler, answering what it throws: BadRequest as itself, SceneError as 400 "invalid scene"
// with the pointer into the scene.
template <class Handler>
void answer_bad_requests(Response& res, Handler&& handle) {
  try {
    handle();
  } catch (const BadRequest& e) {
    send_error(res, e.status, e.error, e.pointer, e.reason, e.where);
  } catch (const scene::SceneError& e) {
    send_error(res, 400, "invalid scene", e.pointer(), e.reason(), "scene");
  }
}

}  // namespace

json Server::Impl::request_scene(const json& body) const {
  // The scene: a document, or the name of a shipped scene.
  json doc;
  const json& scene = body["scene"];
  if (scene.is_object()) {
    doc = scene;
  } else if (scene.is_string()) {
    const auto files = scene_files();
    auto it = files.find(scene.get<std::string>());
    if (it == files.end())
      throw BadRequest{400, "invalid request", "/scene", "no shipped scene by that name (GET /v1/scenes lists them)", "request"};
    doc = scene::read_scene_file(it->second.string());
  } else {
    throw BadRequest{400, "invalid request", "/scene", "expected a scene object or the name of a shipped scene", "request"};
  }

  // Overrides, as `moreau run --set`: ["integrator.h=1e-4", ...] or {"integrator.h": 1e-4, ...}.
  if (body.contains("overrides")) {
    const json& o = body["overrides"];
    if (o.is_array()) {
      for (std::size_t i = 0; i < o.size(); ++i) {
        if (!o[i].is_string())
          throw BadRequest{400, "invalid request", "/overrides/" + std::to_string(i), "expected a string PATH=VALUE", "request"};
        apply_request_override(doc, o[i].get<std::string>(), "/overrides/" + std::to_string(i));
      }
    } else if (o.is_object()) {
      for (const auto& [path, value] : o.items())
        apply_request_override(doc, path + "=" + value.dump(), "/overrides/" + scene::json_pointer_token(path));
    } else {
      throw BadRequest{400, "invalid request", "/overrides", "expected an array of \"PATH=VALUE\" or an object {PATH: VALUE}", "request"};
    }
  }
  return doc;
}

bool Server::Impl::screen(const Request& req, Response& res) {
  auto refuse = [&](int status, const std::string& error, const std::string& reason) {
    close_connection_after(res);
    send_error(res, status, error, "", reason);
    return true;
  };
  // Framing (RFC 9112 section 6): a request with both, or with two lengths, can be read two ways by two
  // servers in a row (request smuggling), so it is refused, not interpreted.
  const std::size_t te = req.headers.count("Transfer-Encoding"), cl = req.headers.count("Content-Length");
  if (te > 0 && cl > 0) return refuse(400, "bad request framing", "both Transfer-Encoding and Content-Length are given");
  if (cl > 1) return refuse(400, "bad request framing", "Content-Length is given more than once");
  if (te > 1 || (te == 1 && lower(trim(req.get_header_value("Transfer-Encoding"))) != "chunked"))
    return refuse(400, "bad request framing", "the only Transfer-Encoding accepted is chunked");
  std::optional<std::uint64_t> length;
  if (cl == 1) {
    const std::string v = trim(req.get_header_value("Content-Length"));
    if (v.empty() || v.size() > 19 || !std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return refuse(400, "bad request framing", "Content-Length is not a decimal number");
    length = std::stoull(v);
  }

  // CORS (--cors-origin): a request from the configured origin gets its answer marked readable by that
  // origin, errors included (a page must be able to read why); a preflight is answered here, before the
  // token, since browsers send preflights without credentials. Off by default: no header at all.
  // Origins compare without case (browsers send scheme and host in lower case). An answer that depends on
  // the Origin says so (Vary) to every client, so that a cache never serves one origin's answer to another.
  const std::string origin = req.get_header_value("Origin");
  const bool cors = !cfg_.cors_origin.empty() && !origin.empty() && (cfg_.cors_origin == "*" || lower(origin) == lower(cfg_.cors_origin));
  if (!cfg_.cors_origin.empty() && cfg_.cors_origin != "*") res.set_header("Vary", "Origin");
  if (cors) {
    res.set_header("Access-Control-Allow-Origin", cfg_.cors_origin == "*" ? std::string("*") : origin);
    res.set_header("Access-Control-Expose-Headers", "Location, Retry-After, ETag, WWW-Authenticate");
    if (req.method == "OPTIONS" && req.has_header("Access-Control-Request-Method")) {
      const char* allow = allowed_methods(req.path);
      if (!allow) return refuse(404, "not found", no_endpoint(req));
      res.status = 204;
      res.set_header("Allow", allow);
      res.set_header("Access-Control-Allow-Methods", allow);
      res.set_header("Access-Control-Allow-Headers", "Authorization, Content-Type, Content-Encoding, Last-Event-ID, If-None-Match");
      res.set_header("Access-Control-Max-Age", "600");
      return true;
    }
  }

  // Open without the token: the health check, and the web page's static files (they hold no data; the
  // page asks for the token and sends it with every API request).
  const bool open_path = req.path == "/healthz" || req.path == "/" || req.path == "/ui/app.js" || req.path == "/ui/style.css";
  if (!cfg_.token.empty() && !open_path) {
    const std::string auth = req.get_header_value("Authorization");
    const std::string prefix = "Bearer ";
    const bool ok = auth.size() > prefix.size() && lower(auth.substr(0, prefix.size())) == "bearer " &&
                    constant_time_equal(trim(auth.substr(prefix.size())), cfg_.token);
    if (!ok) {
      res.set_header("WWW-Authenticate", "Bearer realm=\"moreau\"");
      return refuse(401, auth.empty() ? "authentication required" : "invalid token", "send the header 'Authorization: Bearer TOKEN'");
    }
  }

  const bool has_body = te == 1 || (length && *length > 0);
  // No route takes PUT or PATCH: answered before any body is read.
  if (req.method == "PUT" || req.method == "PATCH") {
    if (const char* allow = allowed_methods(req.path)) {
      close_connection_after(res);
      send_method_not_allowed(res, req.method, req.path, allow);
      return true;
    }
    return refuse(404, "not found", no_endpoint(req));
  }
  // A query parameter the path does not read is refused, not ignored (format=svg on a server that only
  // drew PNG returned a PNG).
  if (const std::string why = unknown_query_parameter(req); !why.empty()) {
    if (has_body) close_connection_after(res);
    send_error(res, 400, "bad query", "", why);
    return true;
  }
  // OPTIONS: which methods a path takes, without a body.
  if (req.method == "OPTIONS") {
    if (has_body) return refuse(400, "unexpected body", "OPTIONS requests take no body");
    const char* allow = allowed_methods(req.path);
    if (!allow) return refuse(404, "not found", no_endpoint(req));
    res.status = 204;
    res.set_header("Allow", allow);
    return true;
  }
  if (req.method != "POST") {
    if (has_body) return refuse(400, "unexpected body", req.method + " requests take no body");
    // No body, and httplib reads one for some methods unless told its length: it is 0 (RFC 9112 6.3).
    if (cl == 0) const_cast<Request&>(req).headers.emplace("Content-Length", "0");
    return false;
  }
  if (te == 0 && cl == 0) return refuse(411, "length required", "send the body with Content-Length or Transfer-Encoding: chunked");
  const std::string type_header = req.get_header_value("Content-Type");
  const std::string content_type = lower(trim(type_header.substr(0, type_header.find(';'))));
  if (content_type != "application/json")
    return refuse(415, "unsupported content type", "POST " + req.path + " takes application/json, got '" + type_header + "'");
  const std::string encoding = lower(trim(req.get_header_value("Content-Encoding")));
  if (!encoding.empty() && encoding != "identity" && encoding != "gzip" && encoding != "deflate")
    return refuse(415, "unsupported content encoding", "Content-Encoding may be gzip, deflate or identity, got '" + encoding + "'");
  if (length && *length > cfg_.max_body_bytes) {
    body_too_large(res);
    return true;
  }
  return false;
}

std::optional<std::string> Server::Impl::read_body(const Request&, Response& res, const httplib::ContentReader& reader) {
  std::string body;
  bool over = false;
  // Decoded bytes are counted as they come: a compressed body stops expanding at the limit.
  const bool ok = reader([&](const char* data, std::size_t n) {
    if (body.size() + n > cfg_.max_body_bytes) {
      over = true;
      return false;
    }
    body.append(data, n);
    return true;
  });
  if (ok) return body;
  ConnectionContext* conn = current_connection();
  close_connection_after(res);
  if (over || (conn && conn->too_large)) {
    body_too_large(res);
  } else if (conn && conn->timed_out) {
    send_error(res, 408, "request timeout", "", "the body did not arrive within " + std::to_string(cfg_.body_timeout_ms) + " ms");
  } else {
    send_error(res, 400, "bad request body", "", "the body could not be read (broken chunked framing or content encoding)");
  }
  return std::nullopt;
}

// What a run needs, from its scene (the request's, or the one a job stored): compiled once, within this
// server's limits. Throws BadRequest or scene::SceneError.
void Server::Impl::prepare_run(Job& job, const json& doc, const StreamSettings& stream) {
  // The scene is compiled once; this server's limits then apply to the compiled simulation
  // (Simulation::with_limits), never by rewriting the scene.
  const scene::Simulation sim = scene::Simulation::from_json(doc);

  // Limits. Fixed steps are known now; for the adaptive rules (h their largest step) the count is a
  // lower bound, and the run gets this server's step limit as its max_steps.
  const auto* lag = sim.lagrangian();
  const bool fixed = !lag || lag->settings.step_rule == StepRule::kFixed;
  const std::int64_t planned = sim.planned_steps();
  scene::RunLimits limits;
  if (planned > cfg_.max_steps) {
    throw BadRequest{400, "invalid scene", "/integrator/h",
                     "h = " + fmt_g(sim.h()) + " over [" + fmt_g(sim.t0()) + ", " + fmt_g(sim.t_end()) + "] needs " +
                         (fixed ? "" : "at least ") + std::to_string(planned) + " steps; this server runs at most " +
                         std::to_string(cfg_.max_steps) + " steps per job",
                     "scene"};
  }
  if (sim.max_steps() > cfg_.max_steps) limits.max_steps = cfg_.max_steps;
  const std::int64_t every = sim.output_every();
  const std::int64_t rows = planned / every + 2;
  if (rows > cfg_.max_samples) {
    const std::int64_t need = (planned + cfg_.max_samples - 3) / std::max<std::int64_t>(1, cfg_.max_samples - 2);
    throw BadRequest{400, "invalid scene", "/output/every",
                     "the trajectory would have about " + std::to_string(rows) + " rows (" + std::to_string(planned) +
                         " steps, one row every " + std::to_string(every) + "); this server keeps at most " +
                         std::to_string(cfg_.max_samples) + ": set /output/every to at least " + std::to_string(need),
                     "scene"};
  }
  // Bytes: rows times the widest row bounds the file.
  const std::int64_t row_bytes = max_trajectory_row_bytes(sim);
  if (rows > cfg_.max_result_bytes / row_bytes) {
    const std::int64_t max_rows = std::max<std::int64_t>(3, cfg_.max_result_bytes / row_bytes);
    const std::int64_t need = (planned + max_rows - 3) / std::max<std::int64_t>(1, max_rows - 2);
    throw BadRequest{422, "result too large", "/output/every",
                     "the trajectory could take about " + std::to_string(rows) + " rows of up to " + std::to_string(row_bytes) +
                         " bytes (" + std::to_string(rows / 1'000'000 * row_bytes) + " MB); this server stores at most " +
                         std::to_string(cfg_.max_result_bytes) + " bytes per job: set /output/every to at least " + std::to_string(need),
                     "scene"};
  }
  // Streaming needs a sample at least once per period: sample the run more finely than the
  // trajectory's decimation if needed (the trajectory keeps the scene's own rows).
  std::int64_t engine_every = every;
  if (stream.enabled) {
    const std::int64_t per_period = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(stream.period / sim.h() + 1e-9)));
    if (every > per_period) {
      engine_every = std::gcd(every, per_period);
      limits.output_every = engine_every;
    }
  }

  if (stream.enabled) {
    try {
      hub_.open();
    } catch (const std::exception& e) {
      throw BadRequest{503, "streaming is not available", "/stream", e.what(), "request"};
    }
  }

  job.scene_name = sim.name().empty() ? "scene" : sim.name();
  job.t0 = sim.t0();
  job.t_end = sim.t_end();
  job.t_now = sim.t0();
  job.planned_steps = planned;
  job.record_every = every;
  job.stream = stream;
  if (stream.enabled) set_channels(job.stream, job.id);
  job.sim.emplace(sim.with_limits(limits));
}

void Server::Impl::post_job(const Request&, Response& res, const std::string& text) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "stream", "strict"}, "{scene, overrides?, stream?, strict?}");
    const json doc = request_scene(body);
    if (body.contains("strict") && !body["strict"].is_boolean())
      throw BadRequest{400, "invalid request", "/strict", "expected true or false", "request"};

    // Streaming: true, or {"channel": PREFIX, "period": seconds, "realtime": bool}.
    StreamSettings stream;
    if (body.contains("stream")) {
      const json& s = body["stream"];
      if (s.is_boolean()) {
        stream.enabled = s.get<bool>();
      } else if (s.is_object()) {
        stream.enabled = true;
        for (const auto& [key, value] : s.items()) {
          const std::string ptr = "/stream/" + key;
          if (key == "channel") {
            if (!value.is_string() || !valid_channel_prefix(value.get<std::string>()))
              throw BadRequest{400, "invalid request", ptr,
                               "expected an UPPER_SNAKE channel prefix such as \"MOREAU\" ([A-Z][A-Z0-9_]*, at most 64)", "request"};
            stream.prefix = value.get<std::string>();
          } else if (key == "period") {
            if (!value.is_number() || !(value.get<double>() > 0) || !std::isfinite(value.get<double>()))
              throw BadRequest{400, "invalid request", ptr, "expected a positive number of simulation seconds", "request"};
            stream.period = value.get<double>();
          } else if (key == "realtime") {
            if (!value.is_boolean()) throw BadRequest{400, "invalid request", ptr, "expected true or false", "request"};
            stream.realtime = value.get<bool>();
          } else {
            throw BadRequest{400, "invalid request", ptr, "unknown field (expected channel, period, realtime)", "request"};
          }
        }
      } else {
        throw BadRequest{400, "invalid request", "/stream", "expected true or an object {channel?, period?, realtime?}", "request"};
      }
    }

    auto job = jobs_.make_job();
    job->strict = body.contains("strict") && body["strict"].get<bool>();
    prepare_run(*job, doc, stream);
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    queue_and_answer(job, doc, nullptr, res);
  });
}

// What a study needs, from its scene and settings (the request's, or those a job stored), within this
// server's limits. Throws BadRequest or scene::SceneError.
void Server::Impl::prepare_study(Job& job, const json& doc, scene::StudySettings st) {
  // A Lur'e scene is refused here at /system/type, a constrained one by the check below.
  scene::LagrangianScene sc = scene::load_scene(doc);
  if (!sc.constraint_names.empty()) {
    throw BadRequest{400, "invalid scene", "/system/constraints",
                     "studies compare abl, explicit and regularized, which do not integrate unilateral constraints", "scene"};
  }
  const std::int64_t planned = scene::study_planned_steps(sc, st);
  if (planned > cfg_.max_steps) {
    throw BadRequest{400, "invalid request", "/study/h",
                     "this study takes about " + std::to_string(planned) + " integration steps over all its runs (" +
                         std::to_string(st.schemes.size()) + " schemes, " + std::to_string(st.h.size()) + " step sizes, 1 + " +
                         std::to_string(st.repeats) + " runs each); this server runs at most " + std::to_string(cfg_.max_steps) +
                         " steps per job: use larger step sizes, fewer schemes or fewer repeats",
                     "request"};
  }
  // The study's own checks (every h and the reference h positive, finite, within the interval and the
  // scene's step limit; an exact solution finite on the grid), at submission rather than in the run:
  // their option names (--reference-h) become pointers into the request (/study/reference_h).
  try {
    scene::check_study_settings(sc, st);
  } catch (const scene::SceneError& e) {
    std::string pointer = e.pointer();
    if (pointer.rfind("--", 0) != 0) throw;
    pointer = "/study/" + pointer.substr(2);
    std::replace(pointer.begin(), pointer.end(), '-', '_');
    throw BadRequest{400, "invalid request", pointer, e.reason(), "request"};
  }
  // Adaptive step rules may take more steps than planned: each run gets this server's limit.
  sc.settings.max_steps = std::min<std::int64_t>(sc.settings.max_steps, cfg_.max_steps);

  job.kind = JobKind::kStudy;
  job.scene_name = sc.name.empty() ? "scene" : sc.name;
  job.t0 = sc.settings.t0;
  job.t_end = sc.settings.t_end;
  job.planned_steps = planned;
  job.rows_total = static_cast<std::int64_t>(st.schemes.size() * st.h.size());
  job.study = std::move(st);
  job.study_scene.emplace(std::move(sc));
}

void Server::Impl::post_study(const Request&, Response& res, const std::string& text) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "study"}, "{scene, overrides?, study?}");
    const json doc = request_scene(body);
    auto job = jobs_.make_job();
    prepare_study(*job, doc, study_settings_at(body.contains("study") ? body["study"] : json()));
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    const json settings = scene::study_settings_to_json(job->study);
    queue_and_answer(job, doc, &settings, res);
  });
}

// A campaign's records on disk, at most: a bound on one record (its inputs, outcomes and final state;
// with full_report, the run's report too) times the samples, for the refusal at submission.
// run_campaign holds the run to the limit itself (CampaignRunOptions::max_bytes), whatever a record takes.
std::int64_t campaign_bytes_bound(const scene::CampaignSpec& spec, int dof) {
  std::int64_t per_record = 1024 + 64 * (2 * dof + static_cast<std::int64_t>(spec.inputs.size()));
  for (const auto& in : spec.inputs) per_record += 2 * static_cast<std::int64_t>(in.path.size());
  if (spec.full_report) per_record += 16384 + 1024 * dof;
  return per_record * spec.samples;
}

// What a campaign needs, from its spec with the scene inlined (the request's, or a stored campaign.json),
// within this server's limits. Throws BadRequest or scene::SceneError.
void Server::Impl::prepare_campaign(Job& job, const json& spec_doc) {
  const scene::Simulation sim = scene::Simulation::from_json(spec_doc.at("scene"));  // its errors: 400 invalid scene, at the scene's field
  // This server's sample limit first, whatever the number's form (1e12 is a float in JSON): the spec
  // reader's own limit is the command line's, far above it.
  if (spec_doc.contains("samples") && spec_doc["samples"].is_number() &&
      spec_doc["samples"].get<double>() > static_cast<double>(cfg_.max_campaign_samples))
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     (spec_doc["samples"].is_number_float() ? fmt_g(spec_doc["samples"].get<double>()) : spec_doc["samples"].dump()) +
                         " samples; this server runs at most " + std::to_string(cfg_.max_campaign_samples) +
                         " per campaign (run larger ones with moreau campaign, on one machine or a Slurm cluster)",
                     "request"};
  scene::CampaignSpec spec;
  try {
    spec = scene::CampaignSpec::from_json(spec_doc, "");
  } catch (const scene::SceneError& e) {
    throw BadRequest{400, "invalid request", "/campaign" + (e.pointer() == "/" ? std::string() : e.pointer()), e.reason(), "request"};
  }
  // Limits: the samples, the steps of each (a job's limit) and of all, the bytes of the records.
  if (spec.samples > cfg_.max_campaign_samples)
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     std::to_string(spec.samples) + " samples; this server runs at most " + std::to_string(cfg_.max_campaign_samples) +
                         " per campaign (run larger ones with moreau campaign, on one machine or a Slurm cluster)",
                     "request"};
  const std::int64_t planned = sim.planned_steps();
  if (planned > cfg_.max_steps)
    throw BadRequest{400, "invalid scene", "/integrator/h",
                     "h = " + fmt_g(sim.h()) + " over [" + fmt_g(sim.t0()) + ", " + fmt_g(sim.t_end()) + "] needs " +
                         std::to_string(planned) + " steps per sample; this server runs at most " + std::to_string(cfg_.max_steps) +
                         " steps per run",
                     "scene"};
  if (planned > cfg_.max_campaign_steps / spec.samples)
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     std::to_string(spec.samples) + " samples of " + std::to_string(planned) + " steps each; this server runs at most " +
                         std::to_string(cfg_.max_campaign_steps) + " steps per campaign",
                     "request"};
  // Each sample by its own settings: an input may be t_end, h or a parameter they use. Sample i's bound is
  // ceil((t_end - t0) / h) of its scene, capped by --max-steps (the runner stops a sample there); the
  // run itself stops at --max-campaign-steps whatever the samples take (job_runner).
  const scene::CampaignStepBound steps = scene::campaign_step_bound(spec, cfg_.max_steps, cfg_.max_campaign_steps);
  if (steps.total > cfg_.max_campaign_steps) {
    const std::string pointer = steps.input >= 0 ? "/campaign/inputs/" + std::to_string(steps.input) : std::string("/campaign/samples");
    std::string values;
    if (steps.input >= 0) {
      const std::vector<json> drawn = scene::CampaignDesign(spec).values(steps.largest_sample);
      const std::string shown = drawn[static_cast<std::size_t>(steps.input)].dump();
      values = ", with " + spec.inputs[static_cast<std::size_t>(steps.input)].path + " = " +
               (shown.size() > 40 ? shown.substr(0, 37) + "..." : shown);
    }
    throw BadRequest{400, "invalid request", pointer,
                     "with their inputs applied, the samples need " + std::string(steps.stopped ? "more than " : "") +
                         std::to_string(steps.total) + " steps in all (sample " + std::to_string(steps.largest_sample) + values +
                         ", needs " + std::to_string(steps.largest) + "; the scene alone " + std::to_string(planned) +
                         " per sample); this server runs at most " + std::to_string(cfg_.max_campaign_steps) + " steps per campaign",
                     "request"};
  }
  const std::int64_t bytes = campaign_bytes_bound(spec, sim.dof());
  if (bytes > cfg_.max_result_bytes)
    throw BadRequest{422, "result too large", spec.full_report ? "/campaign/full_report" : "/campaign/samples",
                     "the records could take about " + std::to_string(bytes) + " bytes; this server stores at most " +
                         std::to_string(cfg_.max_result_bytes) + " per campaign" +
                         (spec.full_report ? ": set full_report to false (each record then holds the outcomes without the run's report)"
                                           : ": run fewer samples"),
                     "request"};

  job.kind = JobKind::kCampaign;
  job.scene_name = sim.name().empty() ? "scene" : sim.name();
  job.t0 = sim.t0();
  job.t_end = sim.t_end();
  job.planned_steps = steps.total;
  job.rows_total = spec.samples;
  job.campaign.emplace(std::move(spec));
}

void Server::Impl::post_campaign(const Request&, Response& res, const std::string& text) {
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "campaign"}, "{scene, overrides?, campaign}");
    const json doc = request_scene(body);
    if (!body.contains("campaign"))
      throw BadRequest{400, "invalid request", "/campaign",
                       "missing required field 'campaign' (the uncertain inputs, the sampler and the samples: docs/campaigns.md)",
                       "request"};
    const json& fields = body["campaign"];
    if (!fields.is_object())
      throw BadRequest{400, "invalid request", "/campaign",
                       "expected an object {inputs, samples, sampler?, seed?, target?, map?, full_report?}", "request"};
    // The scene is the request's own (an object, or a shipped scene's name, with overrides): a path in the
    // spec would be a file on this machine.
    if (fields.contains("scene"))
      throw BadRequest{400, "invalid request", "/campaign/scene",
                       "the scene is the request's 'scene' (an object, or the name of a shipped scene), not a field of 'campaign'",
                       "request"};
    json spec_doc = fields;
    spec_doc["scene"] = doc;
    auto job = jobs_.make_job();
    prepare_campaign(*job, spec_doc);
    const json stored = job->campaign->document;
    queue_and_answer(job, doc, &stored, res);
  });
}

void Server::Impl::campaign_summary(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kCampaign);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "text") return send_error(res, 400, "bad query", "", "format must be json or text");
  send_result_file(req, res, *job, format == "text" ? "summary.txt" : "summary.json",
                   format == "text" ? "text/plain; charset=utf-8" : "application/json", "no summary yet",
                   "; the summary is served once every sample is done");
}

void Server::Impl::campaign_samples(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kCampaign);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "csv";
  if (format != "csv" && format != "jsonl") return send_error(res, 400, "bad query", "", "format must be csv or jsonl");
  // Opened under the files lock, then sent piece by piece as the client takes it (bounded memory for
  // any size), from the open file even if the campaign is deleted meanwhile.
  auto in = std::make_shared<std::ifstream>();
  {
    std::shared_lock files(job->files_mu);
    if (job->deleted) return send_deleted(res);
    if (!final_with(*job, &Job::has_trajectory))
      return send_error(res, 409, "no samples yet", "",
                        std::string("the campaign is ") + to_string(state_of(*job)) +
                            "; its records are served once it has ended (GET it for its progress, or follow /events)");
    in->open(job->dir / (format == "csv" ? "samples.csv" : "samples.jsonl"), std::ios::binary);
    if (!*in) return send_error(res, 500, "stored samples unreadable");
  }
  res.status = 200;
  res.set_header("Content-Disposition", "attachment; filename=\"campaign-" + job->id + (format == "csv" ? ".csv\"" : ".jsonl\""));
  res.set_chunked_content_provider(format == "csv" ? "text/csv" : "application/jsonl", [in](std::size_t, httplib::DataSink& sink) {
    char buffer[1 << 16];
    in->read(buffer, sizeof buffer);
    const auto n = static_cast<std::size_t>(in->gcount());
    if (n > 0 && !sink.write(buffer, n)) return false;
    if (!*in) sink.done();
    return true;
  });
}

void Server::Impl::campaign_figure(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kCampaign);
  if (!job) return;
  const std::string kind = req.has_param("kind") ? req.get_param_value("kind") : "convergence-cdf";
  if (kind != "convergence-cdf" && kind != "inputs" && kind != "success-map")
    return send_error(res, 400, "bad query", "", "kind must be convergence-cdf, inputs or success-map");
  const auto figure = figure_request(req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_report)) {
    return send_error(res, 409, "no summary yet", "",
                      std::string("the campaign is ") + to_string(state_of(*job)) + "; figures are drawn once every sample is done");
  }
  send_figure(req, res, *job, job->dir / ("figure-" + kind), *figure, [&] {
    bool deleted = false;
    auto spec_text = job_file(*job, &Job::has_report, "campaign.json", &deleted);
    if (deleted) throw JobDeleted{};
    if (!spec_text) throw StoredFileUnreadable{"stored campaign spec unreadable"};
    const json spec_doc = json::parse(*spec_text, nullptr, false);
    if (!spec_doc.is_object() || !spec_doc.contains("scene") || !spec_doc["scene"].is_object())
      throw StoredFileUnreadable{"stored campaign spec unreadable"};
    // Read under the files lock: the records are read whole (a few numbers per sample are kept).
    std::shared_lock files(job->files_mu);
    if (job->deleted) throw JobDeleted{};
    return campaign_figure_image(kind, scene::CampaignSpec::from_json(spec_doc, ""), job->dir.string(), job->t_end, figure->size.first,
                                 figure->size.second, figure->format);
  });
}

void Server::Impl::get_job(const Request& req, Response& res, JobKind kind) {
  auto job = job_for(req, res, kind);
  if (!job) return;
  std::optional<double> wait;
  try {
    wait = number_param(req, "wait", 0, kMaxWaitSeconds);
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  if (wait && *wait > 0) {
    if (!waiting_.try_take()) return too_many_waiting(res);
    jobs_.wait_final(*job, std::chrono::milliseconds(static_cast<std::int64_t>(*wait * 1000)));
    waiting_.give_back();
  }
  const auto report = read_report(*job);
  if (is_deleted(*job)) return send_deleted(res);  // purged (or pruned) while it waited
  send_json(res, 200, with_queue_position(job_json(*job, report ? &*report : nullptr), jobs_.queue_positions()));
}

void Server::Impl::list_jobs(const Request& req, Response& res, JobKind kind) {
  const std::string state = req.has_param("state") ? req.get_param_value("state") : "";
  if (!state.empty() && state != "queued" && state != "running" && state != "cancelling" && state != "done" && state != "failed" &&
      state != "cancelled")
    return send_error(res, 400, "bad query", "", "state must be queued, running, cancelling, done, failed or cancelled");
  const std::string scene = req.has_param("scene") ? req.get_param_value("scene") : "";
  std::optional<double> limit;
  try {
    limit = number_param(req, "limit", 1, 1e9);
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  const char* plural = kind == JobKind::kStudy ? "studies" : kind == JobKind::kCampaign ? "campaigns" : "jobs";
  // The cursor: only jobs created before this one (the "next" link of a page names the oldest of it).
  const std::string before = req.has_param("before") ? req.get_param_value("before") : "";
  const auto all = jobs_.list();  // by creation
  auto end = all.end();
  if (!before.empty()) {
    end = std::find_if(all.begin(), all.end(), [&](const auto& job) { return job->id == before && job->kind == kind; });
    if (end == all.end() || is_deleted(**end))
      return send_error(res, 400, "bad query", "",
                        "query parameter 'before' names no " + std::string(kind == JobKind::kRun ? "job" : kind_name(kind)) +
                            " on this server (a cursor is the id of a listed one; it may have been deleted since: list again)");
  }
  std::vector<std::shared_ptr<Job>> picked;
  std::size_t total = 0;
  for (auto it = all.begin(); it != end; ++it) {
    const auto& job = *it;
    if (job->kind != kind) continue;
    ++total;
    if (!state.empty() && to_string(state_of(*job)) != state) continue;
    if (!scene.empty() && job->scene_name != scene) continue;
    picked.push_back(job);
  }
  std::size_t from = 0;
  if (limit && picked.size() > static_cast<std::size_t>(*limit)) from = picked.size() - static_cast<std::size_t>(*limit);
  const auto positions = jobs_.queue_positions();
  json list = json::array();
  for (std::size_t i = from; i < picked.size(); ++i) list.push_back(with_queue_position(job_json(*picked[i], nullptr), positions));
  json body = {{plural, list}, {"count", list.size()}, {"total", total}};
  // The page of older ones, with the same filters.
  if (from > 0) {
    std::string next =
        std::string("/v1/") + plural + "?limit=" + std::to_string(static_cast<std::int64_t>(*limit)) + "&before=" + picked[from]->id;
    if (!state.empty()) next += "&state=" + state;
    if (!scene.empty()) next += "&scene=" + httplib::detail::encode_query_param(scene);
    body["next"] = next;
  }
  send_json(res, 200, body);
}

void Server::Impl::delete_job(const Request& req, Response& res, JobKind kind) {
  auto job = job_for(req, res, kind);
  if (!job) return;
  const char* what = kind == JobKind::kRun ? "job" : kind_name(kind);
  // ?purge=true deletes a final job with its records and results; without it DELETE cancels, and never
  // deletes results (a cancel that races the run's end must not lose them).
  if (req.has_param("purge")) {
    const std::string v = req.get_param_value("purge");
    if (v != "true" && v != "1") return send_error(res, 400, "bad query", "", "query parameter 'purge' must be true or 1");
    if (!jobs_.remove(job)) {
      if (is_deleted(*job)) return send_deleted(res);
      return send_error(res, 409, std::string(what) + " not finished", "",
                        std::string("the ") + what + " is " + to_string(state_of(*job)) +
                            "; cancel it (DELETE without purge), then purge it once it is final");
    }
    return send_json(res, 200, {{"id", job->id}, {"deleted", true}});
  }
  const auto outcome = jobs_.cancel(job);
  // The status is read off the same snapshot as the body: a run can stop between the cancel and the
  // snapshot, and a 202 must never carry a final state. A run that ended done or failed before it saw
  // the request (its last steps raced the DELETE) was not cancelled: the job is finished (409).
  const json body = job_json(*job, nullptr);
  const std::string state = body.value("state", "");
  if (outcome == JobRunner::Cancel::kAlreadyFinished || state == "done" || state == "failed") {
    return send_error(res, 409, std::string(what) + " already finished", "",
                      std::string("the ") + what + " is " + state + " (DELETE ?purge=true deletes it with its results)");
  }
  // 200: cancelled (it was queued, or its run has already stopped); 202: cancelling, and cancelled once
  // its run stops.
  send_json(res, state == "cancelling" ? 202 : 200, body);
}

void Server::Impl::job_events(const Request& req, Response& res, JobKind kind) {
  auto job = job_for(req, res, kind);
  if (!job) return;
  auto last = std::make_shared<std::uint64_t>(0);
  if (req.has_header("Last-Event-ID")) {
    // An id this job has issued: decimal digits, at most the last id so far. Anything else would be
    // read as some other position (a negative number wraps around to a huge one).
    const std::string v = trim(req.get_header_value("Last-Event-ID"));
    std::uint64_t issued = 0;
    {
      std::lock_guard lock(job->mu);
      issued = job->next_event_id - 1;
    }
    const bool digits = !v.empty() && v.size() <= 19 && std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (!digits || std::stoull(v) > issued) {
      return send_error(
          res, 400, "bad Last-Event-ID", "",
          "Last-Event-ID must be an event id this job has sent (0 to " + std::to_string(issued) + "), got '" + v.substr(0, 40) + "'");
    }
    *last = std::stoull(v);
  }
  if (!waiting_.try_take()) return too_many_waiting(res);
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Accel-Buffering", "no");
  res.set_chunked_content_provider(
      "text/event-stream",
      [this, job, last](std::size_t, httplib::DataSink& sink) {
        bool done = false;
        const auto events = jobs_.events_after(*job, *last, std::chrono::seconds(15), done);
        std::string out;
        for (const auto& e : events) {
          out += "id: " + std::to_string(e.id) + "\nevent: " + e.name + "\ndata: " + e.data + "\n\n";
          *last = e.id;
        }
        if (out.empty() && !done) out = ": keep-alive\n\n";
        if (!out.empty() && !sink.write(out.data(), out.size())) return false;
        if (done) sink.done();
        return true;
      },
      [this](bool) { waiting_.give_back(); });
}

void Server::Impl::job_report(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  send_result_file(req, res, *job, "report.json", "application/json", "no report yet", "");
}

void Server::Impl::job_trajectory(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv") return send_error(res, 400, "bad query", "", "format must be json or csv");
  RowWindow window;
  try {
    if (auto from = number_param(req, "from", -1e300, 1e300)) window.from = *from;
    if (auto to = number_param(req, "to", -1e300, 1e300)) window.to = *to;
    if (auto every = number_param(req, "every", 1, 1e15)) {
      if (*every != std::floor(*every)) throw std::invalid_argument("query parameter 'every' must be a whole number of rows");
      window.every = static_cast<std::int64_t>(*every);
    }
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  if (window.from > window.to) return send_error(res, 400, "bad query", "", "query parameter 'from' is after 'to'");
  // Opened under the files lock; read piece by piece as the client takes it (bounded memory for any
  // length), from the open file even if the job is deleted meanwhile.
  auto reader = std::make_shared<TrajectoryReader>();
  std::string error;
  std::string identity;  // of the stored file and of the window asked for: the weak ETag's source
  {
    std::shared_lock files(job->files_mu);
    if (job->deleted) return send_deleted(res);
    if (!final_with(*job, &Job::has_trajectory)) {
      return send_error(res, 409, "no trajectory yet", "",
                        std::string("the job is ") + to_string(state_of(*job)) + "; the trajectory is served once it has finished");
    }
    if (!reader->open((job->dir / "trajectory.csv").string(), window,
                      format == "csv" ? TrajectoryReader::Format::kCsv : TrajectoryReader::Format::kJson, &error))
      return send_error(res, 500, "stored trajectory unreadable", "", error);
    std::error_code ec;
    const auto size = fs::file_size(job->dir / "trajectory.csv", ec);
    const auto mtime = fs::last_write_time(job->dir / "trajectory.csv", ec);
    char window_text[96];
    std::snprintf(window_text, sizeof window_text, "|%.17g|%.17g|%lld", window.from, window.to, static_cast<long long>(window.every));
    identity = job->id + "|" + std::to_string(size) + "|" + std::to_string(mtime.time_since_epoch().count()) + "|" + format + window_text;
  }
  if (not_modified(req, res, weak_etag(identity))) return;
  res.status = 200;
  if (format == "csv") res.set_header("Content-Disposition", "attachment; filename=\"" + job->id + ".csv\"");
  res.set_chunked_content_provider(format == "csv" ? "text/csv" : "application/json", [reader](std::size_t, httplib::DataSink& sink) {
    std::string part;
    const bool more = reader->next(part);
    if (!part.empty() && !sink.write(part.data(), part.size())) return false;
    if (!more) sink.done();
    return true;
  });
}

void Server::Impl::job_figure(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  const std::string kind = req.has_param("kind") ? req.get_param_value("kind") : "state";
  if (!is_figure_kind(kind)) return send_error(res, 400, "bad query", "", "kind must be state, energy, step or phase");
  const auto figure = figure_request(req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_trajectory)) {
    return send_error(res, 409, "no trajectory yet", "",
                      std::string("the job is ") + to_string(state_of(*job)) + "; figures are drawn once it has finished");
  }
  if (is_deleted(*job)) return send_deleted(res);
  static const std::map<std::string, std::string> kFiles = {
      {"state", "figure-state"}, {"energy", "figure-energy"}, {"step", "figure-step"}, {"phase", "figure-phase"}};
  send_figure(req, res, *job, job->dir / kFiles.at(kind), *figure, [&] {
    std::error_code size_ec;
    const auto bytes = fs::file_size(job->dir / "trajectory.csv", size_ec);
    if (!size_ec && static_cast<std::int64_t>(bytes) > cfg_.max_figure_source_bytes) {
      throw std::invalid_argument("the trajectory has " + std::to_string(bytes) + " bytes; this server draws figures from at most " +
                                  std::to_string(cfg_.max_figure_source_bytes) +
                                  ": fetch a window (/trajectory?format=csv&from=&to=&every=) and draw it with moreau plot");
    }
    bool deleted = false;
    auto csv = job_file(*job, &Job::has_trajectory, "trajectory.csv", &deleted);
    if (deleted) throw JobDeleted{};
    if (!csv) throw StoredFileUnreadable{"stored trajectory unreadable"};
    std::optional<double> converged;
    if (auto report = read_report(*job)) {
      if (report->contains("converged_time") && (*report)["converged_time"].is_number())
        converged = (*report)["converged_time"].get<double>();
    }
    // A Lur'e job's figures are labelled as such (state x, output y, storage W): its stored scene says so.
    std::optional<scene::Simulation> system;
    if (auto text = job_file(*job, &Job::has_trajectory, "scene.json")) {
      const json doc = json::parse(*text, nullptr, false);
      if (!doc.is_discarded() && scene::system_type(doc) == "lure") {
        try {
          system.emplace(scene::Simulation::from_json(doc));
        } catch (const std::exception&) {
          // A scene this build no longer compiles: the figure keeps the default labels.
        }
      }
    }
    return figure_image(kind, *csv, converged, figure->size.first, figure->size.second, job->scene_name + " (" + job->id.substr(0, 8) + ")",
                        figure->format, system ? &*system : nullptr);
  });
}

void Server::Impl::study_table(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kStudy);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv") return send_error(res, 400, "bad query", "", "format must be json or csv");
  send_result_file(req, res, *job, format == "csv" ? "table.csv" : "result.json", format == "csv" ? "text/csv" : "application/json",
                   "no table yet", "; the table is served once it is done", format == "csv" ? "study-" + job->id + ".csv" : "");
}

void Server::Impl::study_figure(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kStudy);
  if (!job) return;
  const std::string kind = req.has_param("kind") ? req.get_param_value("kind") : "work";
  if (kind != "work" && kind != "order") return send_error(res, 400, "bad query", "", "kind must be work or order");
  const auto figure = figure_request(req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_report)) {
    return send_error(res, 409, "no table yet", "",
                      std::string("the study is ") + to_string(state_of(*job)) + "; figures are drawn once it is done");
  }
  send_figure(req, res, *job, job->dir / (kind == "work" ? "figure-work" : "figure-order"), *figure, [&] {
    bool deleted = false;
    auto result = job_file(*job, &Job::has_report, "result.json", &deleted);
    if (deleted) throw JobDeleted{};
    if (!result) throw StoredFileUnreadable{"stored study result unreadable"};
    return study_figure_image(kind, *result, figure->size.first, figure->size.second, figure->format);
  });
}

void Server::Impl::list_scenes(const Request&, Response& res) {
  json list = json::array();
  for (const auto& [name, path] : scene_files()) {
    json entry = {{"name", name}, {"url", "/v1/scenes/" + name}};
    if (auto text = read_file(path)) {
      json doc = json::parse(*text, nullptr, false);
      if (doc.is_object()) {
        if (doc.contains("name") && doc["name"].is_string()) entry["title"] = doc["name"];
        if (doc.contains("description") && doc["description"].is_string()) entry["description"] = doc["description"];
      }
    }
    list.push_back(entry);
  }
  send_json(res, 200, {{"scenes", list}, {"count", list.size()}});
}

void Server::Impl::get_scene(const Request& req, Response& res) {
  const auto files = scene_files();
  auto it = files.find(req.matches[1].str());
  if (it == files.end())
    return send_error(res, 404, "no such scene", "",
                      "no shipped scene '" + req.matches[1].str().substr(0, 64) + "'; GET /v1/scenes lists them");
  auto text = read_file(it->second);
  if (!text) return send_error(res, 500, "scene unreadable");
  res.status = 200;
  res.set_content(std::move(*text), "application/json");
}

void Server::Impl::metrics(const Request&, Response& res) {
  const Metrics m = jobs_.metrics();
  std::ostringstream os;
  os.precision(17);
  os << "# HELP moreau_jobs Jobs known to the server, by state.\n# TYPE moreau_jobs gauge\n";
  for (const auto& [state, count] : m.jobs_by_state) os << "moreau_jobs{state=\"" << state << "\"} " << count << "\n";
  os << "# HELP moreau_queue_length Jobs waiting for a worker.\n# TYPE moreau_queue_length gauge\n"
     << "moreau_queue_length " << m.queue_length << "\n";
  os << "# HELP moreau_queue_capacity Queued jobs beyond which submissions get 429.\n# TYPE moreau_queue_capacity gauge\n"
     << "moreau_queue_capacity " << m.queue_capacity << "\n";
  os << "# HELP moreau_workers Integrating threads.\n# TYPE moreau_workers gauge\nmoreau_workers " << m.workers << "\n";
  os << "# HELP moreau_workers_busy Threads running a job now.\n# TYPE moreau_workers_busy gauge\n"
     << "moreau_workers_busy " << m.workers_busy << "\n";
  os << "# HELP moreau_jobs_submitted_total Jobs accepted.\n# TYPE moreau_jobs_submitted_total counter\n"
     << "moreau_jobs_submitted_total " << m.submitted << "\n";
  os << "# HELP moreau_jobs_rejected_total Jobs refused because the queue was full.\n# TYPE moreau_jobs_rejected_total counter\n"
     << "moreau_jobs_rejected_total{reason=\"queue_full\"} " << m.rejected_queue_full << "\n";
  os << "# HELP moreau_steps_total Integration steps of finished jobs.\n# TYPE moreau_steps_total counter\n"
     << "moreau_steps_total " << m.steps_total << "\n";
  os << "# HELP moreau_integrate_seconds_total Time spent integrating.\n# TYPE moreau_integrate_seconds_total counter\n"
     << "moreau_integrate_seconds_total " << m.integrate_seconds_total << "\n";
  os << "# HELP moreau_steps_per_second Steps of the jobs finished in the last 10 s, per second.\n"
     << "# TYPE moreau_steps_per_second gauge\nmoreau_steps_per_second " << m.steps_per_second << "\n";
  os << "# HELP moreau_lcm_messages_total LCM messages published.\n# TYPE moreau_lcm_messages_total counter\n"
     << "moreau_lcm_messages_total " << m.lcm_published << "\n";
  os << "# HELP moreau_lcm_dropped_total States not published because a stream fell too far behind.\n"
     << "# TYPE moreau_lcm_dropped_total counter\nmoreau_lcm_dropped_total " << m.lcm_dropped << "\n";
  const TransportStats t = http_.stats();
  os << "# HELP moreau_http_connections Open HTTP connections.\n# TYPE moreau_http_connections gauge\n"
     << "moreau_http_connections " << t.open << "\n";
  os << "# HELP moreau_http_connections_refused_total Connections refused over --max-connections or "
        "--max-connections-per-client.\n# TYPE moreau_http_connections_refused_total counter\n"
     << "moreau_http_connections_refused_total " << t.refused_total << "\n";
  os << "# HELP moreau_http_timeouts_total Requests whose headers or body missed their deadline.\n"
     << "# TYPE moreau_http_timeouts_total counter\nmoreau_http_timeouts_total " << t.timed_out_total << "\n";
  os << "# HELP moreau_http_responses_total HTTP responses, by status code.\n# TYPE moreau_http_responses_total counter\n";
  {
    std::lock_guard lock(stats_mu_);
    for (const auto& [code, count] : responses_) os << "moreau_http_responses_total{code=\"" << code << "\"} " << count << "\n";
  }
  res.status = 200;
  res.set_content(os.str(), "text/plain; version=0.0.4");
}

// ---- Server ----

Server::Server(ServerConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {}
Server::~Server() = default;
int Server::start() { return impl_->start(); }
void Server::stop() { impl_->stop(); }
void Server::wait() { impl_->wait(); }
int Server::port() const { return impl_->port(); }
lcm::LCM* Server::lcm() { return impl_->lcm(); }

}  // namespace moreau::server
