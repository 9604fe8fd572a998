// moreau-server: the HTTP job API (docs/api.md) and live state over LCM (docs/streaming.md). It adds
// queueing, storage, streaming and access around scene::Simulation; no numerics of its own.
#pragma once

#include <memory>
#include <string>

#include "moreau/server/server_config.h"

namespace lcm {
class LCM;
}

namespace moreau::server {

// Where /v1/scenes reads from when ServerConfig::scenes_dir is empty: the source tree's scenes/ if it
// exists, else /usr/share/moreau/scenes.
std::string default_scenes_dir();

class Server {
 public:
  // Opens (or creates) the data directory and recovers the jobs stored there: finished jobs are served
  // again; jobs that were queued, or interrupted by a stop, are queued again, and so is a job the
  // previous server died under, once (docs/api.md, "Storage and restarts"). Throws std::runtime_error if
  // the directory cannot be used or the LCM URL cannot be opened.
  explicit Server(ServerConfig config);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Binds and serves from background threads; returns the bound port. Throws if it cannot bind.
  int start();
  // Stops accepting requests, ends event streams, stops running jobs and queues them again (queued jobs
  // stay queued: a server started on the same data directory runs them), then joins every thread.
  // Idempotent.
  void stop();
  // Blocks until stop() has been called (from another thread or a signal handler's thread).
  void wait();

  int port() const;
  // The LCM instance jobs publish on, or nullptr if none has been opened yet (it is opened at start
  // when an LCM URL is configured, else at the first job that asks for streaming).
  lcm::LCM* lcm();

  class Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace moreau::server
