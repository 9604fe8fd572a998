// The server assembled: the operator's settings, the job runner, the LCM hub and the HTTP transport, the
// handlers every request passes (request_screening.h) and every answer (errors, security headers, the
// request log), and the API's routes (routes.h), each resource's in its own file.
#include "moreau/server/server.h"

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <thread>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>

#include "api_context.h"
#include "campaigns_routes.h"
#include "jobs_routes.h"
#include "job_runner.h"
#include "lcm_stream.h"
#include "request_screening.h"
#include "responses.h"
#include "routes.h"
#include "storage.h"
#include "studies_routes.h"

// After Eigen (through the job headers): see http_transport.h.
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

bool is_loopback(const std::string& host) { return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0; }

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

}  // namespace

class Server::Impl {
 public:
  explicit Impl(ServerConfig config)
      : cfg_(std::move(config)), hub_(cfg_.lcm_url), jobs_(cfg_, hub_), http_(transport_limits(cfg_)), api_(cfg_, jobs_, hub_, http_) {
    if (cfg_.scenes_dir.empty()) cfg_.scenes_dir = default_scenes_dir();
    if (!cfg_.lcm_url.empty()) hub_.open();
    requeue_recovered(jobs_.recover());
    set_up_transport();
    register_routes(http_, api_);
  }

  ~Impl() { stop(); }

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

 private:
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
          case JobKind::kRun: prepare_run(api_, *job, stored("scene.json"), job->stream); break;
          case JobKind::kStudy: prepare_study(api_, *job, stored("scene.json"), study_settings_at(stored("study.json"))); break;
          case JobKind::kCampaign: prepare_campaign(api_, *job, stored("campaign.json")); break;
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

  // The socket, the limits httplib keeps itself, and the handlers around the routes: screening, errors,
  // exceptions, the headers of every answer, and the request log with the count of answers.
  void set_up_transport();

  ServerConfig cfg_;
  LcmHub hub_;
  JobRunner jobs_;
  GuardedHttpServer http_;
  ApiContext api_;
  std::thread listener_;
  std::thread housekeeper_;
  int port_ = -1;
  int listen_socket_ = -1;  // the bound socket (set by the socket options callback)
  std::mutex stop_mu_;
  std::condition_variable stop_cv_;
  bool stopped_ = false;    // stop() has begun
  bool stop_done_ = false;  // stop() has finished
};

void Server::Impl::set_up_transport() {
  http_.set_tcp_nodelay(true);
  // cpp-httplib's default socket options set SO_REUSEPORT, with which a second server binds the same
  // port and silently takes part of the connections. SO_REUSEADDR alone still allows a restart while
  // old connections are in TIME_WAIT, and a port in use is an error ("cannot bind").
  http_.set_socket_options([this](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listen_socket_ = sock;
  });
  // Bodies are read by read_body (decoded size) and the transport (size as sent); this only keeps
  // httplib from reading a body it would not pass to a handler.
  http_.set_payload_max_length(cfg_.max_body_bytes);
  http_.set_keep_alive_timeout(cfg_.keep_alive_seconds);
  http_.set_keep_alive_max_count(static_cast<std::size_t>(std::max(1, cfg_.keep_alive_requests)));
  http_.on_refused = [this](int status) { api_.responses.count(status); };

  // Every request passes here once its headers are read, before any of its body is. Answered requests
  // close their connection: their body is never read.
  http_.set_pre_routing_handler([this](const Request& req, Response& res) {
    return screen(api_, req, res) ? httplib::Server::HandlerResponse::Handled : httplib::Server::HandlerResponse::Unhandled;
  });
  // "Expect: 100-continue" is answered before routing: the client sends its body only after a 100, so
  // a request refused here never sends it.
  http_.set_expect_100_continue_handler([this](const Request& req, Response& res) { return screen(api_, req, res) ? res.status : 100; });
  http_.set_error_handler([this](const Request& req, Response& res) {
    if (!res.body.empty()) return;
    const ConnectionContext* conn = current_connection();
    if (conn && conn->timed_out) return send_error(res, 408, "request timeout", "", "the request did not arrive in time");
    if (conn && conn->headers_too_large) {
      close_connection_after(res);
      return send_error(res, 431, "request headers too large", "",
                        "the request line and headers may take at most " + std::to_string(http_.limits().max_header_bytes) + " bytes");
    }
    if (conn && conn->too_large) return send_body_too_large(cfg_, res);
    // No route of this method: 405 if the path takes others (routes.h).
    if (res.status == 404) {
      if (const std::string allow = allowed_methods(req.path); !allow.empty())
        return send_method_not_allowed(res, req.method, req.path, allow);
    }
    switch (res.status) {
      case 404: send_error(res, 404, "not found", "", no_endpoint(req)); break;
      case 414:  // httplib's own answer to a request line over its limit; its headers were skipped, not read
        close_connection_after(res);
        send_error(res, 414, "URI too long", "", "the request line may take at most " + std::to_string(kMaxRequestLineBytes) + " bytes");
        break;
      case 413: send_body_too_large(cfg_, res); break;
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
  // answer carries a policy of its own (the web page's files, static_page.cc) one under which nothing it
  // holds (a figure, a CSV, a report, an error quoting a client's text) loads or runs anything, or is
  // framed, when a browser opens it. The answers the transport writes itself carry the same
  // (http_transport.cc). httplib calls this as it writes each response, after the error handler.
  http_.set_post_routing_handler([](const Request&, Response& res) {
    if (!res.has_header("X-Content-Type-Options")) res.set_header("X-Content-Type-Options", "nosniff");
    if (!res.has_header("Content-Security-Policy")) res.set_header("Content-Security-Policy", kApiContentSecurityPolicy);
  });
  http_.set_logger([this](const Request& req, const Response& res) {
    api_.responses.count(res.status);
    if (cfg_.log_requests) {
      std::fprintf(stderr, "moreau-server: %s %s %d %zu\n", log_escaped(req.method, 16).c_str(), log_escaped(req.path).c_str(), res.status,
                   res.body.size());
    }
  });
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
