// What every route handler works with: the operator's settings, the jobs, the LCM hub, the transport's
// statistics, the bounded resources requests share and the count of answers. One per server, owned by
// Server::Impl (server.cc), which outlives every request.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>

#include "budget.h"
#include "job_runner.h"
#include "lcm_stream.h"
#include "moreau/server/server_config.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// The answers sent, by status code: routed ones, those refused while screening, errors, and those the
// transport writes itself (GuardedHttpServer::on_refused). /metrics shows them.
class ResponseCounts {
 public:
  void count(int status) {
    std::lock_guard lock(mu_);
    ++by_status_[status];
  }
  std::map<int, std::int64_t> by_status() const {
    std::lock_guard lock(mu_);
    return by_status_;
  }

 private:
  mutable std::mutex mu_;
  std::map<int, std::int64_t> by_status_;
};

struct ApiContext {
  ApiContext(const ServerConfig& config, JobRunner& jobs, LcmHub& hub, const GuardedHttpServer& http)
      : config(config), jobs(jobs), hub(hub), http(http), waiting(config.max_waiting), drawing(config.figures_at_once) {}
  ApiContext(const ApiContext&) = delete;
  ApiContext& operator=(const ApiContext&) = delete;

  const ServerConfig& config;
  JobRunner& jobs;
  LcmHub& hub;                    // opened by the first job that streams, if no LCM URL opened it at start
  const GuardedHttpServer& http;  // for its limits and statistics
  Budget waiting;                 // long polls (?wait) and event streams open now
  Budget drawing;                 // figures being drawn now
  ResponseCounts responses;
};

}  // namespace moreau::server
