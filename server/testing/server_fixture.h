// Test support: a real moreau-server in-process on an ephemeral 127.0.0.1 port with its own temporary
// data directory, and keep-alive HTTP clients for it. The server is stopped (and the directory
// removed) when the fixture goes out of scope, also when the server fails to start.
#pragma once

#include <stdlib.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "moreau/scene/simulation.h"
#include "moreau/server/server.h"
#include "support/temp_dir.h"

// httplib.h after Eigen (simulation.h): its <resolv.h> defines a `_res` macro that breaks Eigen.
#include <httplib.h>

namespace moreau::server::testing {

using test_support::TempDir;

inline nlohmann::json read_json_file(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// scenes/manipulator.json (tests run from the source tree).
inline nlohmann::json manipulator() { return read_json_file("scenes/manipulator.json"); }

class TestServer {
 public:
  // With no data directory, the server gets a new one of its own (owned_data_, a member, so it is removed
  // even when Server's constructor throws).
  explicit TestServer(ServerConfig cfg = {}, std::filesystem::path data = {})
      : owned_data_(data.empty() ? std::optional<TempDir>(TempDir("server")) : std::nullopt),
        data_(data.empty() ? owned_data_->path() : data) {
    cfg.data_dir = data_.string();
    cfg.host = "127.0.0.1";
    cfg.port = 0;
    if (cfg.workers == 0) cfg.workers = 2;
    cfg.keep_alive_seconds = 1;
    cfg_ = cfg;
    server_ = std::make_unique<Server>(cfg);
    port_ = server_->start();
  }
  ~TestServer() { stop(); }
  void stop() {
    if (server_) server_->stop();
  }
  // Hands the data directory to the caller (for a restart: declare the next server after the returned
  // TempDir, so that it stops before the directory goes). Only for a server that made its own.
  TempDir release_data() {
    if (!owned_data_) throw std::logic_error("release_data: this server's data directory belongs to the caller");
    TempDir d = std::move(*owned_data_);
    owned_data_.reset();
    return d;
  }

  int port() const { return port_; }
  Server& server() { return *server_; }
  const std::filesystem::path& data() const { return data_; }

  std::unique_ptr<httplib::Client> client(const std::string& token = "") const {
    auto c = std::make_unique<httplib::Client>("127.0.0.1", port_);
    c->set_tcp_nodelay(true);
    c->set_keep_alive(true);
    c->set_read_timeout(30, 0);
    if (!token.empty()) c->set_bearer_token_auth(token);
    return c;
  }

 private:
  ServerConfig cfg_;
  std::optional<TempDir> owned_data_;  // before data_ and server_: made first, removed last
  std::filesystem::path data_;
  std::unique_ptr<Server> server_;
  int port_ = 0;
};

// POSTs {scene, overrides?, stream?} to /v1/jobs.
inline httplib::Result submit(httplib::Client& c, const nlohmann::json& request) {
  return c.Post("/v1/jobs", request.dump(), "application/json");
}

// The job's (or, with collection "/v1/studies/", the study's) JSON once it is final (long-polls ?wait=).
inline nlohmann::json wait_final(httplib::Client& c, const std::string& id, double seconds = 30,
                                 const std::string& collection = "/v1/jobs/") {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (true) {
    auto r = c.Get(collection + id + "?wait=5");
    if (!r || r->status != 200) throw std::runtime_error("GET job failed");
    auto j = nlohmann::json::parse(r->body);
    const std::string s = j["state"];
    if (s == "done" || s == "failed" || s == "cancelled") return j;
    if (std::chrono::steady_clock::now() > deadline) throw std::runtime_error("job did not finish in time");
  }
}

inline nlohmann::json wait_final_study(httplib::Client& c, const std::string& id, double seconds = 30) {
  return wait_final(c, id, seconds, "/v1/studies/");
}

// Polls until the job is running (or final).
inline std::string wait_running(httplib::Client& c, const std::string& id, double seconds = 10) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get("/v1/jobs/" + id);
    if (r && r->status == 200) {
      const std::string s = nlohmann::json::parse(r->body)["state"];
      if (s != "queued") return s;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return "queued";
}

// Polls a running job until its progress shows at least `step` (a run publishes its step at each
// cancellation check, every RunObserver::kControlInterval steps). Returns the step seen, or -1 when the
// deadline passes first.
inline std::int64_t wait_step(httplib::Client& c, const std::string& id, std::int64_t step, double seconds = 10) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < deadline) {
    auto r = c.Get("/v1/jobs/" + id);
    if (r && r->status == 200) {
      const nlohmann::json j = nlohmann::json::parse(r->body);
      const std::int64_t seen = j["progress"]["step"].get<std::int64_t>();
      if (seen >= step) return seen;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return -1;
}

}  // namespace moreau::server::testing
