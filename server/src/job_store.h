// The job store: every job the server knows, in memory (by id and by creation) and on disk:
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
//   DATA/jobs/<id>/figure-work.png, figure-order.png (and .svg)  drawn on first request
//
// trajectory.csv and report.json are written to temporary files when the run ends; an I/O thread then
// fsyncs and renames them (report.json last: it commits the job) and only then marks the job final, so
// "done" means stored. job.json is replaced (atomically) at each state change.
//
// Records are written atomically; recover() reads them back after a restart; prune() deletes the oldest
// finished jobs beyond --keep-jobs. Thread-safe; its lock is taken after the runner's queue lock, never
// before it.
#pragma once

#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "job.h"
#include "moreau/server/server_config.h"
#include "storage.h"

namespace moreau::server {

class JobStore {
 public:
  // Uses DATA/jobs (created if missing). Throws std::runtime_error when it cannot.
  explicit JobStore(const ServerConfig& config);

  // A fresh job with a random id and its directory path (not yet created).
  std::shared_ptr<Job> make_job() const;
  // Accepted means stored: the scene (and a study's settings as study.json, a campaign's spec as
  // campaign.json) and the record are on disk, fsync'ed with the directory. A write that fails (a full
  // disk, say) leaves nothing and throws.
  void write_new(const Job& job, const nlohmann::json& scene_doc, const nlohmann::json* spec_doc) const;
  // Makes the job visible to find() and list().
  void add(const std::shared_ptr<Job>& job);
  std::shared_ptr<Job> find(const std::string& id) const;
  std::vector<std::shared_ptr<Job>> list() const;  // by creation

  // Reads DATA/jobs: finished jobs are served again. Jobs left queued (accepted and not run, or stopped by
  // a clean stop while running) are returned in submission order, queued, to be run again; so are jobs
  // left running by a server that died, once (Job::crashes): the second time they fail. The recovered
  // jobs are added, then the finished ones pruned.
  std::vector<std::shared_ptr<Job>> recover();
  // Writes job.json (atomically; fsync'ed with kFsync). Throws std::runtime_error.
  void write_record(const nlohmann::json& record, const Job& job, Durability durability) const;
  // One more job reached a final state.
  void count_final() { ++finished_; }
  // Deletes the oldest finished jobs (records, results, memory) once more than ServerConfig::keep_jobs
  // are finished, down to keep_jobs; a job whose files a reader holds waits for a later pass.
  void prune();
  // Deletes one final job at its client's request (records, results, memory), once no reader holds its
  // files. False if it is not final (or already deleted).
  bool remove(const std::shared_ptr<Job>& job);

 private:
  const ServerConfig& config_;
  std::filesystem::path jobs_dir_;
  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Job>, std::less<>> jobs_;
  std::vector<std::shared_ptr<Job>> order_;  // by creation
  std::atomic<std::int64_t> finished_{0};    // jobs in a final state, in jobs_
};

}  // namespace moreau::server
