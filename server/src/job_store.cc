#include "job_store.h"

#include <algorithm>
#include <iostream>

namespace moreau::server {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {
// A job the server died under twice is not run a third time: it may be what kills the server.
constexpr int kMaxCrashes = 2;
const char* kReasonCrashedTwice = "the server died twice while the job was running: it is not run again (it may be what stops the server)";
std::string reason_crashed(JobKind kind) {
  return kind == JobKind::kCampaign
             ? "the server died while the campaign was running: it goes on from the samples whose records were written"
             : "the server died while the job was running: it runs again from the start";
}
}  // namespace

JobStore::JobStore(const ServerConfig& config) : config_(config), jobs_dir_(fs::path(config.data_dir) / "jobs") {
  if (config.data_dir.empty()) throw std::runtime_error("no data directory given (--data DIR)");
  std::error_code ec;
  fs::create_directories(jobs_dir_, ec);
  if (ec || !fs::is_directory(jobs_dir_)) {
    throw std::runtime_error("cannot use data directory '" + config.data_dir + "': " + (ec ? ec.message() : "not a directory"));
  }
}

std::shared_ptr<Job> JobStore::make_job() const {
  auto job = std::make_shared<Job>();
  job->id = new_job_id();
  job->dir = jobs_dir_ / job->id;
  job->created = unix_now();
  return job;
}

void JobStore::write_new(const Job& job, const json& scene_doc, const json* spec_doc) const {
  try {
    fs::create_directories(job.dir);
    write_file_atomic(job.dir / "scene.json", scene_doc.dump(2) + "\n", Durability::kFsync);
    if (spec_doc) {
      const char* name = job.kind == JobKind::kCampaign ? "campaign.json" : "study.json";
      write_file_atomic(job.dir / name, spec_doc->dump(2) + "\n", Durability::kFsync);
    }
    json record;
    {
      std::lock_guard lock(job.mu);
      record = job_record(job, job.state, job.reason, job.started, job.finished);
    }
    write_record(record, job, Durability::kFsync);
    fsync_path(job.dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(job.dir, ec);
    throw;
  }
}

void JobStore::add(const std::shared_ptr<Job>& job) {
  std::lock_guard lock(mu_);
  jobs_.emplace(job->id, job);
  order_.push_back(job);
}

std::shared_ptr<Job> JobStore::find(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<Job>> JobStore::list() const {
  std::lock_guard lock(mu_);
  return order_;
}

void JobStore::write_record(const json& record, const Job& job, Durability durability) const {
  write_file_atomic(job.dir / "job.json", record.dump(2) + "\n", durability);
}

std::vector<std::shared_ptr<Job>> JobStore::recover() {
  std::error_code ec;
  std::vector<std::shared_ptr<Job>> found;
  for (const auto& entry : fs::directory_iterator(jobs_dir_, ec)) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_directory() || !is_job_id(name)) continue;
    auto job = std::make_shared<Job>();
    job->id = name;
    job->dir = entry.path();
    // Leftovers of writes interrupted by a crash.
    for (const auto& f : fs::directory_iterator(job->dir, ec)) {
      if (f.path().extension() == ".tmp") fs::remove(f.path(), ec);
    }
    json record;
    if (auto text = read_file(job->dir / "job.json")) {
      record = json::parse(*text, nullptr, false);
    }
    if (!record.is_object()) {
      std::cerr << "moreau-server: skipping " << job->dir << ": no readable job.json\n";
      continue;
    }
    const std::string kind = record.value("kind", "run");
    job->kind = kind == "study" ? JobKind::kStudy : kind == "campaign" ? JobKind::kCampaign : JobKind::kRun;
    job->rows_total = record.value("rows_total", std::int64_t{0});
    job->scene_name = record.value("scene", "");
    job->created = record.value("created", 0.0);
    job->started = record.value("started", 0.0);
    job->finished = record.value("finished", 0.0);
    job->t0 = record.value("t0", 0.0);
    job->t_end = record.value("t_end", 0.0);
    job->planned_steps = record.value("planned_steps", std::int64_t{0});
    job->reason = record.value("reason", "");
    job->strict = record.contains("strict") && record["strict"].is_boolean() && record["strict"].get<bool>();
    job->robot = record.contains("robot") && record["robot"].is_boolean() && record["robot"].get<bool>();
    job->crashes = record.contains("crashes") && record["crashes"].is_number_integer() ? record["crashes"].get<int>() : 0;
    if (record.contains("progress") && record["progress"].is_object()) {
      const json& p = record["progress"];
      if (p.contains("t") && p["t"].is_number()) job->t_now = p["t"].get<double>();
      if (p.contains("step") && p["step"].is_number_integer()) job->step_now = p["step"].get<std::int64_t>();
      if (p.contains("rows") && p["rows"].is_number_integer()) job->rows_done = p["rows"].get<std::int64_t>();
    } else {
      job->t_now = job->t0;
    }
    if (record.contains("stream") && record["stream"].is_object()) {
      job->stream.enabled = true;
      job->stream.prefix = record["stream"].value("prefix", "MOREAU");
      job->stream.period = record["stream"].value("period", 1.0 / 64);
      job->stream.realtime = record["stream"].value("realtime", false);
      set_channels(job->stream, job->id);
    }
    const bool study = job->kind == JobKind::kStudy, campaign = job->kind == JobKind::kCampaign;
    job->has_report = fs::exists(job->dir / (study ? "result.json" : campaign ? "summary.json" : "report.json"), ec);
    job->has_trajectory = fs::exists(job->dir / (study ? "table.csv" : campaign ? "samples.jsonl" : "trajectory.csv"), ec);
    const std::optional<JobState> recorded = parse_state(record.value("state", ""));
    // Event ids continue (a Last-Event-ID from before the restart resumes exactly): a final record's state
    // event took the record's event_id, and is replayed with it; a job that was not final may have sent
    // progress events after its record, so its new state event comes after all of them.
    const std::uint64_t recorded_event_id =
        record.contains("event_id") && record["event_id"].is_number_unsigned() ? record["event_id"].get<std::uint64_t>() : 0;
    job->next_event_id =
        recorded && is_final(*recorded) && recorded_event_id > 0 ? recorded_event_id : recorded_event_id + kEventIdGapAfterRestart;
    bool rewrite = false;
    if (recorded && is_final(*recorded)) {
      job->state = *recorded;
    } else if (job->has_report && (study || campaign)) {
      // The study's result (or the campaign's summary) was committed (only a complete one is written), the
      // record not updated.
      job->state = JobState::kDone;
      rewrite = true;
    } else if (job->has_report) {
      // The run ended and its report was committed, but the record was not updated.
      json report = json::parse(read_file(job->dir / "report.json").value_or(""), nullptr, false);
      const std::string status = report.is_object() ? report.value("status", "") : "";
      job->state = status == "completed" ? JobState::kDone : status == "cancelled" ? JobState::kCancelled : JobState::kFailed;
      if (job->state != JobState::kDone && job->reason.empty() && report.is_object()) job->reason = report.value("message", "");
      if (report.is_object() && report.contains("t_final") && report["t_final"].is_number()) job->t_now = report["t_final"].get<double>();
      if (report.is_object() && report.contains("steps") && report["steps"].is_number_integer())
        job->step_now = report["steps"].get<std::int64_t>();
      rewrite = true;
    } else if (recorded == JobState::kCancelling) {
      // Asked to stop, and the server went down before the run had: it was cancelled all the same.
      job->state = JobState::kCancelled;
      job->reason = "cancelled by request (the server restarted before the run had stopped)";
      rewrite = true;
    } else if (recorded == JobState::kQueued) {
      // Accepted and not yet run, or run until a clean stop (its reason says so): it runs now.
      job->state = JobState::kQueued;
    } else if (job->crashes + 1 >= kMaxCrashes) {
      // Running when the server died, and not for the first time.
      job->crashes += 1;
      job->state = JobState::kFailed;
      job->reason = kReasonCrashedTwice;
      if (campaign && job->has_trajectory)
        job->reason += " (the records of the samples that had finished are kept: GET " + kind_url(job->kind) + job->id + "/samples)";
      rewrite = true;
    } else {
      // Running when the server died (no clean stop recorded it): it runs again, once.
      job->crashes += 1;
      job->state = JobState::kQueued;
      job->reason = reason_crashed(job->kind);
    }
    if (job->finished == 0 && rewrite) job->finished = unix_now();
    if (job->state == JobState::kDone) {
      job->t_now = job->t_end;
      job->step_now = std::max(job->step_now.load(), job->planned_steps);
      job->rows_done = job->rows_total;
    }
    if (rewrite) {
      try {
        std::lock_guard lock(job->mu);
        write_record(job_record(*job, job->state, job->reason, job->started, job->finished), *job, Durability::kRename);
      } catch (const std::exception& e) {
        std::cerr << "moreau-server: job " << job->id << ": " << e.what() << "\n";
      }
    }
    found.push_back(std::move(job));
  }
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a->created != b->created ? a->created < b->created : a->id < b->id; });
  std::vector<std::shared_ptr<Job>> pending;
  {
    std::lock_guard lock(mu_);
    for (auto& job : found) {
      jobs_.emplace(job->id, job);
      order_.push_back(job);
      if (!is_final(job->state)) {
        pending.push_back(job);  // its state event comes when it is queued again (JobRunner::requeue)
        continue;
      }
      // As JobRunner::set_state published it: with the reason, if there is one.
      json data = {{"id", job->id}, {"state", to_string(job->state)}};
      if (!job->reason.empty()) data["reason"] = job->reason;
      push_event(*job, "state", data);
      ++finished_;
    }
  }
  prune();
  return pending;
}

bool JobStore::remove(const std::shared_ptr<Job>& job) {
  // Readers hold the files lock (shared) only while they open or read a whole file: wait for them, before
  // the store's lock (prune() takes that one first, but only tries the files lock).
  std::unique_lock files(job->files_mu);
  {
    std::lock_guard lock(mu_);
    {
      std::lock_guard jl(job->mu);
      if (!is_final(job->state)) return false;
    }
    if (job->deleted) return false;
    job->deleted = true;
    jobs_.erase(job->id);
    order_.erase(std::remove(order_.begin(), order_.end(), job), order_.end());
    --finished_;
  }
  std::error_code ec;
  fs::remove_all(job->dir, ec);
  if (ec) std::cerr << "moreau-server: cannot delete job " << job->id << ": " << ec.message() << "\n";
  return true;
}

void JobStore::prune() {
  const std::int64_t keep = config_.keep_jobs;
  const std::int64_t batch = std::max<std::int64_t>(1, keep / 10);  // prune a tenth at a time
  if (keep <= 0 || finished_.load() < keep + batch) return;
  std::vector<std::shared_ptr<Job>> doomed;
  {
    std::lock_guard lock(mu_);
    std::int64_t excess = finished_.load() - keep;
    std::vector<std::shared_ptr<Job>> kept;
    kept.reserve(order_.size());
    for (auto& job : order_) {  // oldest first
      bool final = false;
      {
        std::lock_guard jl(job->mu);
        final = is_final(job->state);
      }
      if (excess > 0 && final) {
        // A reader holding the files now is let finish; the job is pruned at a later pass.
        std::unique_lock files(job->files_mu, std::try_to_lock);
        if (files.owns_lock()) {
          job->deleted = true;
          jobs_.erase(job->id);
          doomed.push_back(job);
          --excess;
          continue;
        }
        kept.push_back(job);
      } else {
        kept.push_back(job);
      }
    }
    order_.swap(kept);
    finished_ -= static_cast<std::int64_t>(doomed.size());
  }
  for (const auto& job : doomed) {
    std::error_code ec;
    fs::remove_all(job->dir, ec);
    if (ec) std::cerr << "moreau-server: cannot delete old job " << job->id << ": " << ec.message() << "\n";
  }
}

}  // namespace moreau::server
