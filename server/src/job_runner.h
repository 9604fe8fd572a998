// The job runner: the bounded queue, the worker pool and the I/O threads, and every change of a job's
// state, over the job store (job_store.h).
//
// trajectory.csv and report.json are written to temporary files when the run ends; an I/O thread then
// fsyncs and renames them (report.json last: it commits the job) and only then marks the job final, so
// "done" means stored. job.json is replaced (atomically) at each state change.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "job.h"
#include "job_store.h"
#include "lcm_stream.h"
#include "moreau/server/server_config.h"
#include "storage.h"

namespace moreau::server {

struct Metrics {
  std::map<std::string, std::int64_t> jobs_by_state;
  std::int64_t queue_length = 0, queue_capacity = 0, workers = 0, workers_busy = 0;
  std::int64_t submitted = 0, rejected_queue_full = 0;
  std::int64_t steps_total = 0;
  double integrate_seconds_total = 0;
  double steps_per_second = 0;  // over the last 10 s
  std::uint64_t lcm_published = 0, lcm_dropped = 0;
};

class JobRunner {
 public:
  JobRunner(const ServerConfig& config, LcmHub& hub);
  ~JobRunner();

  // The jobs a previous server left (JobStore::recover); returns those to run again, for requeue().
  std::vector<std::shared_ptr<Job>> recover() { return store_.recover(); }
  // Queues a job recover() returned, compiled again (`refused` empty), or fails it with `refused` (why this
  // server cannot run it).
  void requeue(const std::shared_ptr<Job>& job, const std::string& refused);
  void start();
  // Stops the running jobs and joins the workers. Nothing accepted is lost: queued jobs stay queued, and a
  // run the stop interrupts is queued again (its partial results dropped; a campaign keeps its finished
  // samples' records), so that a restarted server runs them (recover()).
  void stop();
  bool stopping() const { return stopping_.load(); }
  // No job queued or running.
  bool idle() const;

  std::shared_ptr<Job> make_job() const { return store_.make_job(); }

  enum class Submit { kQueued, kQueueFull, kStopping };
  // Writes the job's records (scene.json, job.json; study.json for a study, campaign.json for a campaign)
  // and queues it. On kQueueFull, *retry_after is a suggested wait in seconds.
  Submit submit(const std::shared_ptr<Job>& job, const nlohmann::json& scene_doc, int* retry_after,
                const nlohmann::json* spec_doc = nullptr);

  std::shared_ptr<Job> find(const std::string& id) const { return store_.find(id); }
  std::vector<std::shared_ptr<Job>> list() const { return store_.list(); }
  // Each queued job's place in the queue, 1 for the next to run (runs and studies share the queue).
  std::map<std::string, int> queue_positions() const;
  // Deletes a final job and its files (JobStore::remove); false if it is not final.
  bool remove(const std::shared_ptr<Job>& job) { return store_.remove(job); }

  enum class Cancel { kCancelled, kCancelling, kAlreadyFinished };
  // Cancels a queued job at once (kCancelled); asks a running one to stop (kCancelling: its state is
  // cancelling until the run has stopped and been stored, then cancelled).
  Cancel cancel(const std::shared_ptr<Job>& job);
  // Waits until the job is in a final state or `timeout` passed (or the server stops).
  void wait_final(Job& job, std::chrono::milliseconds timeout) const;
  // Events with an id above `after`, waiting up to `timeout` if there is none yet. `done` is set
  // when the job is final and every event has been returned.
  std::vector<SseEvent> events_after(Job& job, std::uint64_t after, std::chrono::milliseconds timeout, bool& done) const;

  Metrics metrics() const;

 private:
  // What a finished run leaves for an I/O thread: its results in temporary files, to be made durable,
  // renamed into place and announced.
  struct Commit {
    std::shared_ptr<Job> job;
    std::shared_ptr<JobStream> stream;
    std::vector<const char*> files;  // renamed from NAME.tmp in this order; the last one commits the job
    // Written in place by the run (a campaign's records and summary, campaign.h): made durable, not renamed.
    std::vector<const char*> files_in_place;
    RunSummary summary;
    JobState state = JobState::kDone;
    std::string reason;
    std::string hypothesis_failure;              // a hypothesis the run relies on that fails (guarantees.h), or ""
    std::optional<std::int64_t> announced_rest;  // the rest a "converged" event announced during the run, if it stands
    double integrate_seconds = 0;
    std::chrono::steady_clock::time_point wall_start;
    ~Commit() {
      if (stream) stream->close();
    }
  };

  void worker_loop();
  // --max-job-seconds: one thread sets a running job's timed_out and cancel flags at its deadline.
  void watchdog_loop();
  void run(const std::shared_ptr<Job>& job);
  void run_study(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit);
  void run_campaign(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit);
  void enqueue_commit(std::unique_ptr<Commit> commit);
  void committer_loop();
  void commit(Commit& c);
  // The run's results could not be written: removes its temporary files and fails the job, saying so.
  void fail_to_store(Job& job, const std::string& what);
  // A run the server's stop interrupted: its temporary files go, and it is queued again (on disk: the
  // restarted server runs it), with `why`.
  void queue_again_after_stop(Job& job, const std::string& why);
  // Changes the state (and reason): records it in job.json, then (for a final state) prunes, and only
  // then publishes it to readers and event streams, so that whoever sees the new state sees the store
  // as it is after it.
  // A final state is never left: returns false (and changes nothing) if the job is already final.
  bool set_state(Job& job, JobState state, const std::string& reason);
  void count_finished(std::int64_t steps, double integrate_seconds, double wall_seconds);

  const ServerConfig& config_;
  LcmHub& hub_;
  JobStore store_;

  mutable std::mutex mu_;  // the queue; taken before the store's lock, never after it
  std::condition_variable queue_cv_;
  std::deque<std::shared_ptr<Job>> queue_;
  std::vector<std::thread> workers_;
  std::atomic<bool> stopping_{false};

  std::mutex commit_mu_;
  std::condition_variable commit_cv_;
  std::deque<std::unique_ptr<Commit>> commits_;
  bool commit_stop_ = false;
  std::vector<std::thread> committers_;
  std::atomic<std::int64_t> busy_{0};

  // Deadlines of the running jobs (--max-job-seconds), by job; the watchdog waits for the earliest.
  std::mutex watchdog_mu_;
  std::condition_variable watchdog_cv_;
  std::map<std::shared_ptr<Job>, std::chrono::steady_clock::time_point> deadlines_;
  bool watchdog_stop_ = false;
  std::thread watchdog_;

  mutable std::mutex stats_mu_;
  std::int64_t submitted_ = 0, rejected_ = 0, steps_total_ = 0;
  double integrate_total_ = 0;
  double avg_job_seconds_ = 0.01;
  std::deque<std::pair<std::chrono::steady_clock::time_point, std::int64_t>> recent_steps_;
};

}  // namespace moreau::server
