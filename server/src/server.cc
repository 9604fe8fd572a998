// The HTTP layer: routes, authentication, validation and limits, over the JobManager.
#include "moreau/server/server.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <numeric>
#include <sstream>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "figures.h"
#include "jobs.h"
#include "lcm_stream.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "storage.h"
#include "trajectory.h"

// After Eigen (through the scene headers): httplib.h pulls in <resolv.h>, whose `_res` macro breaks
// Eigen's product kernels if it comes first.
#include <httplib.h>

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
void send_error(Response& res, int status, const std::string& error, const std::string& pointer = "",
                const std::string& reason = "", const std::string& where = "") {
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

bool is_loopback(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

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
    throw std::invalid_argument(std::string("query parameter '") + name + "' must be a number in [" + fmt_g(lo) + ", " +
                                fmt_g(hi) + "]");
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

bool valid_channel_prefix(const std::string& s) {
  if (s.empty() || s.size() > 64 || !(s[0] >= 'A' && s[0] <= 'Z')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; });
}

}  // namespace

class Server::Impl {
 public:
  explicit Impl(ServerConfig config)
      : cfg_(std::move(config)), hub_(cfg_.lcm_url), jobs_(cfg_, hub_) {
    if (cfg_.scenes_dir.empty()) cfg_.scenes_dir = default_scenes_dir();
    if (!cfg_.lcm_url.empty()) hub_.open();
    jobs_.recover();
    setup_routes();
  }

  ~Impl() { stop(); }

  int start() {
    if (cfg_.token.empty() && !is_loopback(cfg_.host) && !cfg_.allow_unauthenticated_remote) {
      throw std::runtime_error("refusing to serve " + cfg_.host +
                               " without a token: give --token (or MOREAU_TOKEN), or --allow-unauthenticated-remote");
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
    jobs_.stop();  // ends event streams and running jobs first, so that no pool thread is held
    http_.stop();
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
  void post_job(const Request& req, Response& res);
  void post_study(const Request& req, Response& res);
  void get_job(const Request& req, Response& res, JobKind kind);
  void list_jobs(const Request& req, Response& res, JobKind kind);
  void delete_job(const Request& req, Response& res, JobKind kind);
  void job_events(const Request& req, Response& res, JobKind kind);
  void study_table(const Request& req, Response& res);
  void study_figure(const Request& req, Response& res);
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
    if (!job) {
      if (kind == JobKind::kStudy)
        send_error(res, 404, "no such study", "", "study ids are 32 lowercase hex digits, as POST /v1/studies returns them");
      else
        send_error(res, 404, "no such job", "", "job ids are 32 lowercase hex digits, as POST /v1/jobs returns them");
    }
    return job;
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
    JobManager::Submit outcome;
    try {
      outcome = jobs_.submit(job, scene_doc, &retry_after, study_doc);
    } catch (const std::exception& e) {
      return send_error(res, 507, "cannot store the job", "", e.what());
    }
    switch (outcome) {
      case JobManager::Submit::kQueued: break;
      case JobManager::Submit::kQueueFull:
        res.set_header("Retry-After", std::to_string(retry_after));
        return send_error(res, 429, "queue full", "",
                          "the server holds " + std::to_string(cfg_.queue) + " queued jobs at most; retry in " +
                              std::to_string(retry_after) + " s");
      case JobManager::Submit::kStopping: return send_error(res, 503, "server stopping");
    }
    const json j = job_json(*job, nullptr);
    res.set_header("Location", j["url"].get<std::string>());
    send_json(res, 202, j);
  }
  // Whether the job is final and has the results `what` points to (has_report or has_trajectory).
  static bool final_with(const Job& job, bool Job::*what) {
    std::lock_guard lock(job.mu);
    return job.*what && is_final(job.state);
  }
  // The requested figure size (width, height: 64 to 4096, default 1200x800), or nullopt after
  // answering 501 (no render/ in this build) or 400.
  static std::optional<std::pair<int, int>> figure_size(const Request& req, Response& res) {
    if (!figures_available()) {
      send_error(res, 501, "figures not available", "", "this server was built without render/ (no OSMesa)");
      return std::nullopt;
    }
    std::pair<int, int> size{kDefaultFigureWidth, kDefaultFigureHeight};
    try {
      if (auto w = number_param(req, "width", 64, 4096)) size.first = static_cast<int>(*w);
      if (auto h = number_param(req, "height", 64, 4096)) size.second = static_cast<int>(*h);
    } catch (const std::exception& e) {
      send_error(res, 400, "bad query", "", e.what());
      return std::nullopt;
    }
    return size;
  }
  // Answers with a PNG drawn by `draw` (422 if it throws, 500 if a stored file is unreadable). At the default size it is read from, or
  // written to, `cache`: a name from a fixed list, never from the request.
  template <class Draw>
  static void send_png(Response& res, const fs::path& cache, std::pair<int, int> size, Draw&& draw) {
    const bool default_size = size == std::pair<int, int>{kDefaultFigureWidth, kDefaultFigureHeight};
    if (default_size) {
      if (auto png = read_file(cache)) {
        res.status = 200;
        return res.set_content(std::move(*png), "image/png");
      }
    }
    std::vector<std::uint8_t> png;
    try {
      png = draw();
    } catch (const StoredFileUnreadable& e) {
      return send_error(res, 500, e.error);
    } catch (const std::exception& e) {
      return send_error(res, 422, "cannot draw this figure", "", e.what());
    }
    std::string bytes(png.begin(), png.end());
    if (default_size) {
      try {
        write_file_atomic(cache, bytes, Durability::kFsync);
      } catch (const std::exception& e) {
        std::cerr << "moreau-server: " << e.what() << "\n";
      }
    }
    res.status = 200;
    res.set_content(std::move(bytes), "image/png");
  }

  // The committed report of a run (report.json) or result of a study (result.json).
  std::optional<json> read_report(const Job& job) {
    if (!final_with(job, &Job::has_report)) return std::nullopt;
    auto text = read_file(job.dir / (job.kind == JobKind::kStudy ? "result.json" : "report.json"));
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
  JobManager jobs_;
  httplib::Server http_;
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
  http_.set_payload_max_length(cfg_.max_body_bytes);
  http_.set_keep_alive_timeout(cfg_.keep_alive_seconds);
  http_.set_keep_alive_max_count(static_cast<std::size_t>(std::max(1, cfg_.keep_alive_requests)));
  const int threads = std::max(2, cfg_.http_threads);
  http_.new_task_queue = [threads] { return new httplib::ThreadPool(static_cast<std::size_t>(threads)); };

  http_.set_pre_routing_handler([this](const Request& req, Response& res) {
    if (cfg_.token.empty() || req.path == "/healthz") return httplib::Server::HandlerResponse::Unhandled;
    const std::string auth = req.get_header_value("Authorization");
    const std::string prefix = "Bearer ";
    const bool ok = auth.size() > prefix.size() && lower(auth.substr(0, prefix.size())) == "bearer " &&
                    constant_time_equal(trim(auth.substr(prefix.size())), cfg_.token);
    if (ok) return httplib::Server::HandlerResponse::Unhandled;
    res.set_header("WWW-Authenticate", "Bearer realm=\"moreau\"");
    // The body of a refused request has not been read: the connection cannot carry another request.
    res.set_header("Connection", "close");
    send_error(res, 401, auth.empty() ? "authentication required" : "invalid token", "",
               "send the header 'Authorization: Bearer TOKEN'");
    return httplib::Server::HandlerResponse::Handled;
  });
  http_.set_error_handler([this](const Request&, Response& res) {
    if (!res.body.empty()) return;
    switch (res.status) {
      case 404: send_error(res, 404, "not found", "", "see docs/api.md for the endpoints"); break;
      case 413:
        send_error(res, 413, "request body too large", "", "this server accepts at most " + std::to_string(cfg_.max_body_bytes) + " bytes");
        break;
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
    std::cerr << "moreau-server: internal error: " << what << "\n";
    send_error(res, 500, "internal error", "", what);
  });
  http_.set_logger([this](const Request& req, const Response& res) {
    {
      std::lock_guard lock(stats_mu_);
      ++responses_[res.status];
    }
    if (cfg_.log_requests) {
      std::fprintf(stderr, "moreau-server: %s %s %d %zu\n", req.method.c_str(), req.path.c_str(), res.status, res.body.size());
    }
  });

  http_.Get("/healthz", [this](const Request&, Response& res) {
    if (jobs_.stopping()) return send_json(res, 503, {{"status", "stopping"}});
    send_json(res, 200, {{"status", "ok"}});
  });
  http_.Get("/metrics", [this](const Request& req, Response& res) { metrics(req, res); });
  http_.Get("/v1/scenes", [this](const Request& req, Response& res) { list_scenes(req, res); });
  http_.Get(R"(/v1/scenes/([^/]+))", [this](const Request& req, Response& res) { get_scene(req, res); });
  http_.Post("/v1/jobs", [this](const Request& req, Response& res) { post_job(req, res); });
  http_.Get("/v1/jobs", [this](const Request& req, Response& res) { list_jobs(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+))", [this](const Request& req, Response& res) { get_job(req, res, JobKind::kRun); });
  http_.Delete(R"(/v1/jobs/([^/]+))", [this](const Request& req, Response& res) { delete_job(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+)/events)", [this](const Request& req, Response& res) { job_events(req, res, JobKind::kRun); });
  http_.Get(R"(/v1/jobs/([^/]+)/report)", [this](const Request& req, Response& res) { job_report(req, res); });
  http_.Get(R"(/v1/jobs/([^/]+)/trajectory)", [this](const Request& req, Response& res) { job_trajectory(req, res); });
  http_.Get(R"(/v1/jobs/([^/]+)/figure)", [this](const Request& req, Response& res) { job_figure(req, res); });
  http_.Post("/v1/studies", [this](const Request& req, Response& res) { post_study(req, res); });
  http_.Get("/v1/studies", [this](const Request& req, Response& res) { list_jobs(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+))", [this](const Request& req, Response& res) { get_job(req, res, JobKind::kStudy); });
  http_.Delete(R"(/v1/studies/([^/]+))", [this](const Request& req, Response& res) { delete_job(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+)/events)", [this](const Request& req, Response& res) { job_events(req, res, JobKind::kStudy); });
  http_.Get(R"(/v1/studies/([^/]+)/table)", [this](const Request& req, Response& res) { study_table(req, res); });
  http_.Get(R"(/v1/studies/([^/]+)/figure)", [this](const Request& req, Response& res) { study_figure(req, res); });
}

namespace {

// The JSON object body of a POST: checks the content type (415) and the syntax (400), and that it is an
// object whose fields are among `fields` (given as "scene, overrides?, stream?"), with "scene".
json post_body(const Request& req, const char* endpoint, const std::vector<std::string>& fields, const std::string& shape) {
  const std::string type_header = req.get_header_value("Content-Type");
  const std::string content_type = lower(trim(type_header.substr(0, type_header.find(';'))));
  if (content_type != "application/json")
    throw BadRequest{415, "unsupported content type", "", std::string(endpoint) + " takes application/json, got '" + type_header + "'", ""};
  // Bounded nesting before parsing: the JSON library copies and prints recursively.
  if (const auto at = scene::json_depth_exceeded(req.body)) {
    throw BadRequest{400, "malformed JSON", "",
                     "nested deeper than " + std::to_string(scene::kMaxJsonDepth) + " levels at byte " + std::to_string(*at),
                     "request"};
  }
  json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded()) {
    std::string why = "the body is not valid JSON";
    try {
      const json ignored = json::parse(req.body);
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
    if (it == files.end()) throw BadRequest{400, "invalid request", "/scene", "no shipped scene by that name (GET /v1/scenes lists them)", "request"};
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

void Server::Impl::post_job(const Request& req, Response& res) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(req, "POST /v1/jobs", {"scene", "overrides", "stream"}, "{scene, overrides?, stream?}");
    json doc = request_scene(body);

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
              throw BadRequest{400, "invalid request", ptr, "expected an UPPER_SNAKE channel prefix such as \"MOREAU\" ([A-Z][A-Z0-9_]*, at most 64)", "request"};
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

    scene::Simulation sim = scene::Simulation::from_json(doc);
    const json stored_doc = doc;

    // Limits. Fixed steps are known now; adaptive rules get this server's step limit as max_steps.
    const auto* lag = sim.lagrangian();
    const bool fixed = !lag || lag->settings.step_rule == StepRule::kFixed;
    const std::int64_t planned = sim.planned_steps();
    bool recompile = false;
    if (fixed && planned > cfg_.max_steps) {
      throw BadRequest{400, "invalid scene", "/integrator/h",
                       "h = " + fmt_g(sim.h()) + " over [" + fmt_g(sim.t0()) + ", " + fmt_g(sim.t_end()) + "] needs " +
                           std::to_string(planned) + " steps; this server runs at most " + std::to_string(cfg_.max_steps) +
                           " steps per job",
                       "scene"};
    }
    if (!fixed && lag->settings.max_steps > cfg_.max_steps) {
      doc["integrator"]["max_steps"] = cfg_.max_steps;
      recompile = true;
    }
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
    // Streaming needs a sample at least once per period: sample the run more finely than the
    // trajectory's decimation if needed (the trajectory keeps the scene's own rows).
    std::int64_t engine_every = every;
    if (stream.enabled) {
      const std::int64_t per_period = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(stream.period / sim.h() + 1e-9)));
      if (every > per_period) {
        engine_every = std::gcd(every, per_period);
        doc["output"]["every"] = engine_every;
        recompile = true;
      }
    }
    if (recompile) sim = scene::Simulation::from_json(doc);

    if (stream.enabled) {
      try {
        hub_.open();
      } catch (const std::exception& e) {
        throw BadRequest{503, "streaming is not available", "/stream", e.what(), "request"};
      }
    }

    auto job = jobs_.make_job();
    job->scene_name = sim.name().empty() ? "scene" : sim.name();
    job->t0 = sim.t0();
    job->t_end = sim.t_end();
    job->t_now = sim.t0();
    job->planned_steps = planned;
    job->record_every = every;
    job->stream = stream;
    if (stream.enabled) set_channels(job->stream, job->id);
    job->sim.emplace(std::move(sim));
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    queue_and_answer(job, stored_doc, nullptr, res);
  });
}

void Server::Impl::post_study(const Request& req, Response& res) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(req, "POST /v1/studies", {"scene", "overrides", "study"}, "{scene, overrides?, study?}");
    const json doc = request_scene(body);
    // A Lur'e scene is refused here at /system/type, a constrained one by the check below.
    scene::LagrangianScene sc = scene::load_scene(doc);
    scene::StudySettings st;
    try {
      st = scene::study_settings_from_json(body.contains("study") ? body["study"] : json(), "/study");
    } catch (const scene::SceneError& e) {
      throw BadRequest{400, "invalid request", e.pointer(), e.reason(), "request"};
    }
    if (!sc.constraint_names.empty()) {
      throw BadRequest{400, "invalid scene", "/system/constraints",
                       "studies compare abl, explicit and regularized, which do not integrate unilateral constraints", "scene"};
    }
    const std::int64_t planned = scene::study_planned_steps(sc, st);
    if (planned > cfg_.max_steps) {
      throw BadRequest{400, "invalid request", "/study/h",
                       "this study takes about " + std::to_string(planned) + " integration steps over all its runs (" +
                           std::to_string(st.schemes.size()) + " schemes, " + std::to_string(st.h.size()) +
                           " step sizes, 1 + " + std::to_string(st.repeats) +
                           " runs each); this server runs at most " + std::to_string(cfg_.max_steps) +
                           " steps per job: use larger step sizes, fewer schemes or fewer repeats",
                       "request"};
    }
    // Adaptive step rules may take more steps than planned: each run gets this server's limit.
    sc.settings.max_steps = std::min<std::int64_t>(sc.settings.max_steps, cfg_.max_steps);

    auto job = jobs_.make_job();
    job->kind = JobKind::kStudy;
    job->scene_name = sc.name.empty() ? "scene" : sc.name;
    job->t0 = sc.settings.t0;
    job->t_end = sc.settings.t_end;
    job->planned_steps = planned;
    job->rows_total = static_cast<std::int64_t>(st.schemes.size() * st.h.size());
    job->study = std::move(st);
    job->study_scene.emplace(std::move(sc));
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    const json settings = scene::study_settings_to_json(job->study);
    queue_and_answer(job, doc, &settings, res);
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
  if (wait && *wait > 0) jobs_.wait_final(*job, std::chrono::milliseconds(static_cast<std::int64_t>(*wait * 1000)));
  const auto report = read_report(*job);
  send_json(res, 200, job_json(*job, report ? &*report : nullptr));
}

void Server::Impl::list_jobs(const Request& req, Response& res, JobKind kind) {
  std::string state = req.has_param("state") ? req.get_param_value("state") : "";
  if (!state.empty() && state != "queued" && state != "running" && state != "done" && state != "failed" && state != "cancelled")
    return send_error(res, 400, "bad query", "", "state must be queued, running, done, failed or cancelled");
  std::optional<double> limit;
  try {
    limit = number_param(req, "limit", 1, 1e9);
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  json list = json::array();
  const auto all = jobs_.list();
  std::vector<std::shared_ptr<Job>> picked;
  std::size_t total = 0;
  for (const auto& job : all) {
    if (job->kind != kind) continue;
    ++total;
    if (state.empty() || to_string(state_of(*job)) == state) picked.push_back(job);
  }
  std::size_t from = 0;
  if (limit && picked.size() > static_cast<std::size_t>(*limit)) from = picked.size() - static_cast<std::size_t>(*limit);
  for (std::size_t i = from; i < picked.size(); ++i) list.push_back(job_json(*picked[i], nullptr));
  send_json(res, 200, {{kind == JobKind::kStudy ? "studies" : "jobs", list}, {"count", list.size()}, {"total", total}});
}

void Server::Impl::delete_job(const Request& req, Response& res, JobKind kind) {
  auto job = job_for(req, res, kind);
  if (!job) return;
  const auto outcome = jobs_.cancel(job, std::chrono::milliseconds(5000));
  if (outcome == JobManager::Cancel::kAlreadyFinished) {
    const char* what = kind == JobKind::kStudy ? "study" : "job";
    return send_error(res, 409, std::string(what) + " already finished", "",
                      std::string("the ") + what + " is " + to_string(state_of(*job)));
  }
  send_json(res, 200, job_json(*job, nullptr));
}

void Server::Impl::job_events(const Request& req, Response& res, JobKind kind) {
  auto job = job_for(req, res, kind);
  if (!job) return;
  auto last = std::make_shared<std::uint64_t>(0);
  if (req.has_header("Last-Event-ID")) {
    try {
      *last = std::stoull(req.get_header_value("Last-Event-ID"));
    } catch (const std::exception&) {
      *last = 0;
    }
  }
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Accel-Buffering", "no");
  res.set_chunked_content_provider("text/event-stream", [this, job, last](std::size_t, httplib::DataSink& sink) {
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
  });
}

void Server::Impl::job_report(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  auto text = final_with(*job, &Job::has_report) ? read_file(job->dir / "report.json") : std::nullopt;
  if (!text) return send_error(res, 409, "no report yet", "", std::string("the job is ") + to_string(state_of(*job)));
  res.status = 200;
  res.set_content(std::move(*text), "application/json");
}

void Server::Impl::job_trajectory(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv") return send_error(res, 400, "bad query", "", "format must be json or csv");
  auto text = final_with(*job, &Job::has_trajectory) ? read_file(job->dir / "trajectory.csv") : std::nullopt;
  if (!text) {
    return send_error(res, 409, "no trajectory yet", "",
                      std::string("the job is ") + to_string(state_of(*job)) + "; the trajectory is served once it has finished");
  }
  if (format == "csv") {
    res.status = 200;
    res.set_header("Content-Disposition", "attachment; filename=\"" + job->id + ".csv\"");
    res.set_content(std::move(*text), "text/csv");
    return;
  }
  std::string error;
  auto out = trajectory_json(*text, &error);
  if (!out) return send_error(res, 500, "stored trajectory unreadable", "", error);
  res.status = 200;
  res.set_content(std::move(*out), "application/json");
}

void Server::Impl::job_figure(const Request& req, Response& res) {
  auto job = job_for(req, res);
  if (!job) return;
  const std::string kind = req.has_param("kind") ? req.get_param_value("kind") : "state";
  if (!is_figure_kind(kind)) return send_error(res, 400, "bad query", "", "kind must be state, energy, step or phase");
  const auto size = figure_size(req, res);
  if (!size) return;
  if (!final_with(*job, &Job::has_trajectory)) {
    return send_error(res, 409, "no trajectory yet", "",
                      std::string("the job is ") + to_string(state_of(*job)) + "; figures are drawn once it has finished");
  }
  static const std::map<std::string, std::string> kFiles = {
      {"state", "figure-state.png"}, {"energy", "figure-energy.png"}, {"step", "figure-step.png"}, {"phase", "figure-phase.png"}};
  send_png(res, job->dir / kFiles.at(kind), *size, [&] {
    auto csv = read_file(job->dir / "trajectory.csv");
    if (!csv) throw StoredFileUnreadable{"stored trajectory unreadable"};
    std::optional<double> converged;
    if (auto report = read_report(*job)) {
      if (report->contains("converged_time") && (*report)["converged_time"].is_number())
        converged = (*report)["converged_time"].get<double>();
    }
    return figure_png(kind, *csv, converged, size->first, size->second, job->scene_name + " (" + job->id.substr(0, 8) + ")");
  });
}

void Server::Impl::study_table(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kStudy);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv") return send_error(res, 400, "bad query", "", "format must be json or csv");
  auto text = final_with(*job, &Job::has_report) ? read_file(job->dir / (format == "csv" ? "table.csv" : "result.json"))
                                                 : std::nullopt;
  if (!text) {
    return send_error(res, 409, "no table yet", "",
                      std::string("the study is ") + to_string(state_of(*job)) + "; the table is served once it is done");
  }
  res.status = 200;
  if (format == "csv") res.set_header("Content-Disposition", "attachment; filename=\"study-" + job->id + ".csv\"");
  res.set_content(std::move(*text), format == "csv" ? "text/csv" : "application/json");
}

void Server::Impl::study_figure(const Request& req, Response& res) {
  auto job = job_for(req, res, JobKind::kStudy);
  if (!job) return;
  const std::string kind = req.has_param("kind") ? req.get_param_value("kind") : "work";
  if (kind != "work" && kind != "order") return send_error(res, 400, "bad query", "", "kind must be work or order");
  const auto size = figure_size(req, res);
  if (!size) return;
  if (!final_with(*job, &Job::has_report)) {
    return send_error(res, 409, "no table yet", "",
                      std::string("the study is ") + to_string(state_of(*job)) + "; figures are drawn once it is done");
  }
  send_png(res, job->dir / (kind == "work" ? "figure-work.png" : "figure-order.png"), *size, [&] {
    auto result = read_file(job->dir / "result.json");
    if (!result) throw StoredFileUnreadable{"stored study result unreadable"};
    return study_figure_png(kind, *result, size->first, size->second);
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
  if (it == files.end()) return send_error(res, 404, "no such scene", "", "GET /v1/scenes lists the shipped scenes");
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
