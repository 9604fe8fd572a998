// Jobs, the bounded queue, the worker pool and the job records under the data directory:
//
//   DATA/jobs/<id>/job.json        the job's record (state, reason, times, scene name)
//   DATA/jobs/<id>/scene.json      the scene as run (overrides applied)
//   DATA/jobs/<id>/trajectory.csv  t, h, q..., v..., energy (as `moreau run --out` writes it)
//   DATA/jobs/<id>/report.json     the report (as `moreau run --json` prints it)
//   DATA/jobs/<id>/figure-<kind>.png  figures, drawn on first request
//
// A study (POST /v1/studies) is a job of kind "study" in the same place, with
//
//   DATA/jobs/<id>/study.json      the study settings
//   DATA/jobs/<id>/table.csv       the table (as `moreau study --csv` writes it)
//   DATA/jobs/<id>/result.json     the table, orders and reference (as `moreau study --json` prints it)
//   DATA/jobs/<id>/figure-work.png, figure-order.png  drawn on first request
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

#include "lcm_stream.h"
#include "moreau/scene/simulation.h"
#include "storage.h"
#include "moreau/scene/study.h"
#include "moreau/server/server_config.h"

namespace moreau::server {

// kCancelling: a running job asked to stop (DELETE); it becomes kCancelled when its run has stopped
// and what it computed is stored.
enum class JobState { kQueued, kRunning, kCancelling, kDone, kFailed, kCancelled };
enum class JobKind { kRun, kStudy };
const char* to_string(JobState s);
bool is_final(JobState s);

// A server-sent event: "id: <id>\nevent: <name>\ndata: <data>\n\n".
struct SseEvent {
  std::uint64_t id = 0;
  std::string name;
  std::string data;  // one line of JSON
};

struct Job {
  // Fixed when the job is created.
  JobKind kind = JobKind::kRun;
  std::string id;
  std::filesystem::path dir;
  std::string scene_name;
  double t0 = 0, t_end = 0;
  std::int64_t planned_steps = 0;
  double created = 0;  // Unix time, seconds
  StreamSettings stream;
  // The request's `strict`: a run whose relied-on hypothesis fails ends failed (else a warning).
  bool strict = false;

  // Set before the job is queued, used by its worker, released when it ends.
  std::optional<scene::Simulation> sim;
  std::int64_t record_every = 1;  // trajectory decimation: the scene's /output/every
  double load_seconds = 0;        // validation and compilation at submission
  // Studies: the compiled scene and the settings, and the rows of the table done so far.
  std::optional<scene::LagrangianScene> study_scene;
  scene::StudySettings study;
  std::int64_t rows_total = 0;
  std::atomic<std::int64_t> rows_done{0};

  std::atomic<bool> cancel{false};            // the run stops at its next check (every 256 steps: within 50 ms)
  std::atomic<bool> shutdown{false};          // ... because the server is stopping
  std::atomic<bool> cancel_requested{false};  // ... because a client asked (DELETE): it ends cancelled

  // The job's files: readers hold it shared while they check `deleted` and open what they read; pruning
  // holds it exclusively while it deletes them. An open file stays readable after its deletion.
  mutable std::shared_mutex files_mu;
  bool deleted = false;  // under files_mu
  std::atomic<double> t_now{0};
  std::atomic<std::int64_t> step_now{0};

  std::mutex state_change_mu;  // one state change at a time (JobManager::set_state)
  mutable std::mutex mu;
  std::condition_variable cv;  // state changes and new events
  JobState state = JobState::kQueued;
  std::string reason;  // why it failed or was cancelled
  double started = 0, finished = 0;
  bool has_report = false, has_trajectory = false;  // a study: result.json, table.csv
  std::deque<SseEvent> events;
  std::uint64_t next_event_id = 1;
};

struct Metrics {
  std::map<std::string, std::int64_t> jobs_by_state;
  std::int64_t queue_length = 0, queue_capacity = 0, workers = 0, workers_busy = 0;
  std::int64_t submitted = 0, rejected_queue_full = 0;
  std::int64_t steps_total = 0;
  double integrate_seconds_total = 0;
  double steps_per_second = 0;  // over the last 10 s
  std::uint64_t lcm_published = 0, lcm_dropped = 0;
};

class JobManager {
 public:
  JobManager(const ServerConfig& config, LcmHub& hub);
  ~JobManager();

  // Reads DATA/jobs: finished jobs are served again; jobs left queued or running are marked failed.
  void recover();
  void start();
  // Fails the queued jobs, stops the running ones (failed: the server stopped) and joins the workers.
  void stop();
  bool stopping() const { return stopping_.load(); }
  // No job queued or running.
  bool idle() const;

  // A fresh job with a random id and its directory path (not yet created).
  std::shared_ptr<Job> make_job() const;

  enum class Submit { kQueued, kQueueFull, kStopping };
  // Writes the job's records (scene.json, job.json; study.json for a study) and queues it. On kQueueFull, *retry_after is a
  // suggested wait in seconds.
  Submit submit(const std::shared_ptr<Job>& job, const nlohmann::json& scene_doc, int* retry_after,
                const nlohmann::json* study_doc = nullptr);

  std::shared_ptr<Job> find(const std::string& id) const;
  std::vector<std::shared_ptr<Job>> list() const;

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
    RunSummary summary;
    JobState state = JobState::kDone;
    std::string reason;
    std::string hypothesis_failure;  // a hypothesis the run relies on that fails (guarantees.h), or ""
    double integrate_seconds = 0;
    std::chrono::steady_clock::time_point wall_start;
    ~Commit() {
      if (stream) stream->close();
    }
  };

  void worker_loop();
  void run(const std::shared_ptr<Job>& job);
  void run_study(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit);
  void enqueue_commit(std::unique_ptr<Commit> commit);
  void committer_loop();
  void commit(Commit& c);
  // The run's results could not be written: removes its temporary files and fails the job, saying so.
  void fail_to_store(Job& job, const std::string& what);
  // Changes the state (and reason): records it in job.json, then (for a final state) prunes, and only
  // then publishes it to readers and event streams, so that whoever sees the new state sees the store
  // as it is after it.
  // A final state is never left: returns false (and changes nothing) if the job is already final.
  bool set_state(Job& job, JobState state, const std::string& reason);
  // Deletes the oldest finished jobs (records, results, memory) once more than ServerConfig::keep_jobs
  // are finished, down to keep_jobs.
  void prune();
  void push_event(Job& job, const std::string& name, const nlohmann::json& data);
  // Writes job.json (atomically; fsync'ed with kFsync). Throws std::runtime_error.
  void write_record(const nlohmann::json& record, const Job& job, Durability durability) const;
  // The record of `job` as it would be in `state`; job.mu must be held.
  static nlohmann::json record_locked(const Job& job, JobState state, const std::string& reason, double started, double finished);
  void count_finished(std::int64_t steps, double integrate_seconds, double wall_seconds);

  const ServerConfig& config_;
  LcmHub& hub_;
  std::filesystem::path jobs_dir_;

  mutable std::mutex mu_;
  std::condition_variable queue_cv_;
  std::map<std::string, std::shared_ptr<Job>, std::less<>> jobs_;
  std::vector<std::shared_ptr<Job>> order_;  // by creation
  std::deque<std::shared_ptr<Job>> queue_;
  std::vector<std::thread> workers_;
  std::atomic<bool> stopping_{false};
  std::atomic<std::int64_t> finished_{0};  // jobs in a final state, in jobs_

  std::mutex commit_mu_;
  std::condition_variable commit_cv_;
  std::deque<std::unique_ptr<Commit>> commits_;
  bool commit_stop_ = false;
  std::vector<std::thread> committers_;
  std::atomic<std::int64_t> busy_{0};

  mutable std::mutex stats_mu_;
  std::int64_t submitted_ = 0, rejected_ = 0, steps_total_ = 0;
  double integrate_total_ = 0;
  double avg_job_seconds_ = 0.01;
  std::deque<std::pair<std::chrono::steady_clock::time_point, std::int64_t>> recent_steps_;
};

// The job as GET /v1/jobs/{id} shows it (with the report when `report` is given); a study as
// GET /v1/studies/{id} shows it (with its result as "result").
nlohmann::json job_json(const Job& job, const nlohmann::json* report);

double unix_now();

// The most bytes one trajectory row of `sim` can take: every column in its shortest round-trip form
// ("-2.2250738585072014e-308", 24 characters) and a separator.
std::int64_t max_trajectory_row_bytes(const scene::Simulation& sim);
// The trajectory rows a job may write: --max-samples, and --max-result-bytes over the widest row.
std::int64_t max_trajectory_rows(const ServerConfig& config, const scene::Simulation& sim);

}  // namespace moreau::server
