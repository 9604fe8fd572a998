#include "jobs.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>

#include "job_observer.h"
#include "moreau/scene/trajectory_csv.h"
#include "storage.h"

namespace moreau::server {
namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::size_t kMaxEventsKept = 512;  // per job, for late subscribers; older progress is dropped

const char* kReasonRestartedRunning = "server restarted while the job was running";
const char* kReasonRestartedQueued = "server restarted before the job ran";
const char* kReasonStoppedRunning = "server stopped while the job was running";
const char* kReasonStoppedQueued = "server stopped before the job ran";

std::optional<JobState> parse_state(const std::string& s) {
  if (s == "queued") return JobState::kQueued;
  if (s == "running") return JobState::kRunning;
  if (s == "cancelling") return JobState::kCancelling;
  if (s == "done") return JobState::kDone;
  if (s == "failed") return JobState::kFailed;
  if (s == "cancelled") return JobState::kCancelled;
  return std::nullopt;
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

json finite_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

std::int64_t max_trajectory_row_bytes(const scene::Simulation& sim) {
  const auto columns = static_cast<std::int64_t>(sim.position_names().size() + sim.velocity_names().size() + 3);
  return columns * 25;
}

std::int64_t max_trajectory_rows(const ServerConfig& config, const scene::Simulation& sim) {
  return std::min(config.max_samples, std::max<std::int64_t>(3, config.max_result_bytes / max_trajectory_row_bytes(sim)));
}

const char* to_string(JobState s) {
  switch (s) {
    case JobState::kQueued: return "queued";
    case JobState::kRunning: return "running";
    case JobState::kCancelling: return "cancelling";
    case JobState::kDone: return "done";
    case JobState::kFailed: return "failed";
    case JobState::kCancelled: return "cancelled";
  }
  return "?";
}

bool is_final(JobState s) { return s == JobState::kDone || s == JobState::kFailed || s == JobState::kCancelled; }

json job_json(const Job& job, const json* report) {
  std::unique_lock lock(job.mu);
  const bool study = job.kind == JobKind::kStudy;
  json j;
  j["id"] = job.id;
  j["kind"] = study ? "study" : "run";
  j["url"] = (study ? "/v1/studies/" : "/v1/jobs/") + job.id;
  j["scene"] = job.scene_name;
  j["state"] = to_string(job.state);
  if (!job.reason.empty()) j["reason"] = job.reason;
  j["created"] = job.created;
  j["started"] = job.started > 0 ? json(job.started) : json(nullptr);
  j["finished"] = job.finished > 0 ? json(job.finished) : json(nullptr);
  const std::string url = j["url"];
  json links = {{"events", url + "/events"}};
  if (study) {
    const std::int64_t done = job.state == JobState::kDone ? job.rows_total : job.rows_done.load();
    j["progress"] = {{"rows", done},
                     {"rows_total", job.rows_total},
                     {"fraction", job.rows_total > 0 ? static_cast<double>(done) / static_cast<double>(job.rows_total) : 0.0}};
    if (job.has_report) {
      links["table"] = url + "/table";
      links["csv"] = url + "/table?format=csv";
      links["work_figure"] = url + "/figure?kind=work";
      links["order_figure"] = url + "/figure?kind=order";
    }
  } else {
    double t = job.t_now.load();
    std::int64_t step = job.step_now.load();
    if (job.state == JobState::kQueued) t = job.t0;
    if (job.state == JobState::kDone) t = job.t_end;
    if (report && report->contains("t_final") && (*report)["t_final"].is_number()) t = (*report)["t_final"].get<double>();
    if (report && report->contains("steps") && (*report)["steps"].is_number()) step = (*report)["steps"].get<std::int64_t>();
    const double span = job.t_end - job.t0;
    j["progress"] = {{"t", finite_or_null(t)},
                     {"t0", job.t0},
                     {"t_end", job.t_end},
                     {"step", step},
                     {"planned_steps", job.planned_steps},
                     {"fraction", span > 0 ? finite_or_null(std::clamp((t - job.t0) / span, 0.0, 1.0)) : json(0.0)}};
    if (job.has_report) links["report"] = url + "/report";
    if (job.has_trajectory) {
      links["trajectory"] = url + "/trajectory";
      links["figure"] = url + "/figure?kind=state";
    }
  }
  j["links"] = links;
  if (job.stream.enabled) {
    j["stream"] = {{"state_channel", job.stream.state_channel},
                   {"event_channel", job.stream.event_channel},
                   {"period", job.stream.period},
                   {"realtime", job.stream.realtime}};
  }
  lock.unlock();
  if (report) j[study ? "result" : "report"] = *report;
  return j;
}

// ---- JobManager ----

JobManager::JobManager(const ServerConfig& config, LcmHub& hub)
    : config_(config), hub_(hub), jobs_dir_(fs::path(config.data_dir) / "jobs") {
  if (config.data_dir.empty()) throw std::runtime_error("no data directory given (--data DIR)");
  std::error_code ec;
  fs::create_directories(jobs_dir_, ec);
  if (ec || !fs::is_directory(jobs_dir_)) {
    throw std::runtime_error("cannot use data directory '" + config.data_dir + "': " + (ec ? ec.message() : "not a directory"));
  }
}

JobManager::~JobManager() { stop(); }

std::shared_ptr<Job> JobManager::make_job() const {
  auto job = std::make_shared<Job>();
  job->id = new_job_id();
  job->dir = jobs_dir_ / job->id;
  job->created = unix_now();
  return job;
}

json JobManager::record_locked(const Job& job, JobState state, const std::string& reason, double started, double finished) {
  json r = {{"id", job.id},
            {"kind", job.kind == JobKind::kStudy ? "study" : "run"},
            {"scene", job.scene_name},
            {"state", to_string(state)},
            {"created", job.created},
            {"started", started},
            {"finished", finished},
            {"t0", job.t0},
            {"t_end", job.t_end},
            {"planned_steps", job.planned_steps}};
  if (job.kind == JobKind::kStudy) r["rows_total"] = job.rows_total;
  if (!reason.empty()) r["reason"] = reason;
  // Where a run got to, so that a restarted server shows the progress it had.
  if (is_final(state)) {
    r["progress"] = {{"t", finite_or_null(job.t_now.load())}, {"step", job.step_now.load()}, {"rows", job.rows_done.load()}};
  }
  if (job.stream.enabled) {
    r["stream"] = {{"prefix", job.stream.prefix}, {"period", job.stream.period}, {"realtime", job.stream.realtime}};
  }
  if (job.strict) r["strict"] = true;
  return r;
}

void JobManager::write_record(const json& record, const Job& job, Durability durability) const {
  write_file_atomic(job.dir / "job.json", record.dump(2) + "\n", durability);
}

void JobManager::recover() {
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
    job->kind = record.value("kind", "run") == "study" ? JobKind::kStudy : JobKind::kRun;
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
    const bool study = job->kind == JobKind::kStudy;
    job->has_report = fs::exists(job->dir / (study ? "result.json" : "report.json"), ec);
    job->has_trajectory = fs::exists(job->dir / (study ? "table.csv" : "trajectory.csv"), ec);
    const std::optional<JobState> recorded = parse_state(record.value("state", ""));
    bool rewrite = false;
    if (recorded && is_final(*recorded)) {
      job->state = *recorded;
    } else if (job->has_report && study) {
      // The study's result was committed (only completed studies write one), the record not updated.
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
    } else {
      job->state = JobState::kFailed;
      job->reason = recorded == JobState::kQueued ? kReasonRestartedQueued : kReasonRestartedRunning;
      rewrite = true;
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
        write_record(record_locked(*job, job->state, job->reason, job->started, job->finished), *job, Durability::kRename);
      } catch (const std::exception& e) {
        std::cerr << "moreau-server: job " << job->id << ": " << e.what() << "\n";
      }
    }
    found.push_back(std::move(job));
  }
  std::sort(found.begin(), found.end(),
            [](const auto& a, const auto& b) { return a->created != b->created ? a->created < b->created : a->id < b->id; });
  {
    std::lock_guard lock(mu_);
    for (auto& job : found) {
      push_event(*job, "state", {{"id", job->id}, {"state", to_string(job->state)}});
      jobs_.emplace(job->id, job);
      order_.push_back(job);
      ++finished_;  // every recovered job is final
    }
  }
  prune();
}

void JobManager::start() {
  const int n = config_.workers > 0 ? config_.workers : std::max(1u, std::thread::hardware_concurrency());
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { worker_loop(); });
  for (int i = 0; i < std::max(1, config_.io_threads); ++i) committers_.emplace_back([this] { committer_loop(); });
}

void JobManager::stop() {
  if (stopping_.exchange(true)) return;
  std::deque<std::shared_ptr<Job>> queued;
  std::vector<std::shared_ptr<Job>> all;
  {
    std::lock_guard lock(mu_);
    queued.swap(queue_);
    all = order_;
  }
  queue_cv_.notify_all();
  for (auto& job : queued) {
    job->sim.reset();
    job->study_scene.reset();
    set_state(*job, JobState::kFailed, kReasonStoppedQueued);
  }
  auto wake = [](Job& job) {
    { std::lock_guard l(job.mu); }  // a waiter is either before its predicate check or blocked
    job.cv.notify_all();
  };
  for (auto& job : all) {
    job->shutdown = true;
    job->cancel = true;
    wake(*job);
  }
  for (auto& w : workers_)
    if (w.joinable()) w.join();
  workers_.clear();
  // The runs that ended are stored before the I/O threads stop.
  {
    std::lock_guard lock(commit_mu_);
    commit_stop_ = true;
  }
  commit_cv_.notify_all();
  for (auto& t : committers_)
    if (t.joinable()) t.join();
  committers_.clear();
  for (auto& job : all) wake(*job);
}

JobManager::Submit JobManager::submit(const std::shared_ptr<Job>& job, const json& scene_doc, int* retry_after, const json* study_doc) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Submit::kStopping;
    if (static_cast<int>(queue_.size()) >= config_.queue) {
      std::lock_guard s(stats_mu_);
      ++rejected_;
      const int workers = std::max<int>(1, static_cast<int>(workers_.size()));
      const double wait = avg_job_seconds_ * static_cast<double>(queue_.size()) / workers;
      if (retry_after) *retry_after = std::clamp(static_cast<int>(std::ceil(wait)), 1, 60);
      return Submit::kQueueFull;
    }
  }
  // Accepted means stored: the scene and the record are on disk (fsync'ed, and the directory too)
  // before the 202. A write that fails (a full disk, say) refuses the job (507) and leaves nothing.
  try {
    fs::create_directories(job->dir);
    write_file_atomic(job->dir / "scene.json", scene_doc.dump(2) + "\n", Durability::kFsync);
    if (study_doc) write_file_atomic(job->dir / "study.json", study_doc->dump(2) + "\n", Durability::kFsync);
    json record;
    {
      std::lock_guard lock(job->mu);
      record = record_locked(*job, job->state, job->reason, job->started, job->finished);
    }
    write_record(record, *job, Durability::kFsync);
    fsync_path(job->dir);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(job->dir, ec);
    throw;
  }
  push_event(*job, "state", {{"id", job->id}, {"state", "queued"}});
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Submit::kStopping;
    // The queue may have filled up while the records were written: accept anyway, it is one more.
    jobs_.emplace(job->id, job);
    order_.push_back(job);
    queue_.push_back(job);
  }
  {
    std::lock_guard s(stats_mu_);
    ++submitted_;
  }
  queue_cv_.notify_one();
  return Submit::kQueued;
}

std::shared_ptr<Job> JobManager::find(const std::string& id) const {
  std::lock_guard lock(mu_);
  auto it = jobs_.find(id);
  return it == jobs_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<Job>> JobManager::list() const {
  std::lock_guard lock(mu_);
  return order_;
}

void JobManager::push_event(Job& job, const std::string& name, const json& data) {
  {
    std::lock_guard lock(job.mu);
    job.events.push_back(SseEvent{job.next_event_id++, name, data.dump()});
    if (job.events.size() > kMaxEventsKept) {
      // Drop the oldest progress event (state changes are kept).
      auto it = std::find_if(job.events.begin(), job.events.end(), [](const SseEvent& e) { return e.name == "progress"; });
      job.events.erase(it != job.events.end() ? it : job.events.begin());
    }
  }
  job.cv.notify_all();
}

bool JobManager::set_state(Job& job, JobState state, const std::string& reason) {
  json data = {{"id", job.id}, {"state", to_string(state)}};
  if (!reason.empty()) data["reason"] = reason;
  std::lock_guard change(job.state_change_mu);
  bool became_final = false;
  double started = 0, finished = 0;
  json record;
  {
    std::lock_guard lock(job.mu);
    if (is_final(job.state)) return false;
    // A job cancelled between the queue and its worker's start stays cancelling; its run stops at once.
    if (job.state == JobState::kCancelling && state == JobState::kRunning) return false;
    became_final = is_final(state) && !is_final(job.state);
    started = state == JobState::kRunning ? unix_now() : job.started;
    finished = is_final(state) ? unix_now() : job.finished;
    record = record_locked(job, state, reason, started, finished);
  }
  // 1. The record. A final state that cannot be recorded is still published (the results are committed
  // and a restart derives the state from them), but said on stderr.
  try {
    write_record(record, job, is_final(state) ? Durability::kFsync : Durability::kRename);
  } catch (const std::exception& e) {
    std::cerr << "moreau-server: job " << job.id << ": " << e.what() << "\n";
  }
  // 2. The store as a final state leaves it: older finished jobs beyond --keep-jobs are deleted now,
  // before anyone can see this job final (this job is not yet final for prune(), so it stays).
  if (became_final) {
    ++finished_;
    prune();
  }
  // 3. Published: the state and its event change together, so a stream that sees a final state has its
  // event, and a waiter woken by it sees steps 1 and 2 done.
  {
    std::lock_guard lock(job.mu);
    job.state = state;
    job.reason = reason;
    job.started = started;
    job.finished = finished;
    job.events.push_back(SseEvent{job.next_event_id++, "state", data.dump()});
  }
  job.cv.notify_all();
  return true;
}

void JobManager::prune() {
  const std::int64_t keep = config_.keep_jobs;
  const std::int64_t batch = std::max<std::int64_t>(1, keep / 10);  // prune a tenth at a time
  if (keep <= 0 || finished_.load() < keep + batch || stopping_) return;
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

JobManager::Cancel JobManager::cancel(const std::shared_ptr<Job>& job) {
  bool was_queued = false;
  {
    std::lock_guard lock(mu_);
    auto it = std::find(queue_.begin(), queue_.end(), job);
    if (it != queue_.end()) {
      queue_.erase(it);
      was_queued = true;
    }
  }
  if (was_queued) {
    job->sim.reset();
    job->study_scene.reset();
    job->cancel_requested = true;
    set_state(*job, JobState::kCancelled, "cancelled before it ran");
    return Cancel::kCancelled;
  }
  {
    std::lock_guard lock(job->mu);
    if (job->state == JobState::kCancelled) return Cancel::kCancelled;
    if (job->state == JobState::kCancelling) return Cancel::kCancelling;
    if (is_final(job->state)) return Cancel::kAlreadyFinished;
    // Running, or between the queue and its worker's first step: the worker sees the flag.
    job->cancel_requested = true;
    job->cancel = true;
  }
  if (set_state(*job, JobState::kCancelling, "cancelling by request")) return Cancel::kCancelling;
  // The run ended meanwhile, and its final state stands.
  std::lock_guard lock(job->mu);
  return job->state == JobState::kCancelled ? Cancel::kCancelled : Cancel::kAlreadyFinished;
}

void JobManager::wait_final(Job& job, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(job.mu);
  job.cv.wait_for(lock, timeout, [&] { return is_final(job.state) || stopping_.load(); });
}

std::vector<SseEvent> JobManager::events_after(Job& job, std::uint64_t after, std::chrono::milliseconds timeout, bool& done) const {
  std::unique_lock lock(job.mu);
  auto has_new = [&] { return !job.events.empty() && job.events.back().id > after; };
  job.cv.wait_for(lock, timeout, [&] { return has_new() || is_final(job.state) || stopping_.load(); });
  std::vector<SseEvent> out;
  for (const auto& e : job.events)
    if (e.id > after) out.push_back(e);
  done = is_final(job.state) || stopping_.load();
  return out;
}

void JobManager::worker_loop() {
  while (true) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock lock(mu_);
      queue_cv_.wait(lock, [&] { return !queue_.empty() || stopping_; });
      if (stopping_) return;
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    ++busy_;
    try {
      run(job);
    } catch (const std::exception& e) {
      // (A stream opened by run() is closed when its Commit, never queued, is destroyed.)
      std::cerr << "moreau-server: job " << job->id << " failed: " << e.what() << "\n";
      job->sim.reset();
      job->study_scene.reset();
      set_state(*job, JobState::kFailed, std::string("internal error: ") + e.what());
    }
    --busy_;
  }
}

void JobManager::run(const std::shared_ptr<Job>& job) {
  const auto wall_start = Clock::now();
  if (job->cancel) {
    job->sim.reset();
    job->study_scene.reset();
    if (job->shutdown && !job->cancel_requested)
      set_state(*job, JobState::kFailed, kReasonStoppedQueued);
    else
      set_state(*job, JobState::kCancelled, "cancelled before it ran");
    return;
  }
  set_state(*job, JobState::kRunning, "");
  auto commit = std::make_unique<Commit>();
  commit->job = job;
  commit->wall_start = wall_start;
  if (job->kind == JobKind::kStudy) return run_study(job, std::move(commit));
  commit->files = {"trajectory.csv", "report.json"};
  const scene::Simulation& sim = *job->sim;

  std::optional<StreamObserver> stream_observer;
  if (job->stream.enabled) {
    commit->stream = std::make_shared<JobStream>(job->id, job->stream, sim.dof());
    hub_.add(commit->stream);
    stream_observer.emplace(commit->stream, sim.t0(), &job->cancel);
    commit->stream->push_event(
        "started", 0, sim.t0(),
        "job " + job->id + " started: " + sim.name() + ", t in [" + std::to_string(sim.t0()) + ", " + std::to_string(sim.t_end()) + "]");
  }

  const fs::path csv_tmp = job->dir / "trajectory.csv.tmp";
  scene::TrajectoryCsvWriter csv(csv_tmp.string(), sim.position_names(), sim.velocity_names());
  auto progress = [this, &job] {
    push_event(*job, "progress", {{"t", job->t_now.load()}, {"step", job->step_now.load()}, {"t0", job->t0}, {"t_end", job->t_end}});
  };
  const std::int64_t max_rows = max_trajectory_rows(config_, sim);
  JobObserver observer(*job, csv, job->record_every, sim.output_every(), max_rows, stream_observer ? &*stream_observer : nullptr, progress);

  RunSummary summary = sim.run(&observer);
  observer.finish();
  if (stream_observer) {
    stream_observer->flush_last(summary);
    commit->stream->flush();
  }

  // The results go to temporary files here; an I/O thread makes them durable and renames them
  // (commit()), while this worker goes on with the next job.
  const auto t_write = Clock::now();
  try {
    csv.close();
  } catch (const std::exception& e) {
    return fail_to_store(*job, e.what());
  }
  for (auto& [name, s] : summary.phase_seconds)
    if (name == "integrate") s = std::max(0.0, s - csv.seconds());
  summary.phase_seconds.insert(summary.phase_seconds.begin(), {"load", job->load_seconds});

  if (observer.overflow()) {
    summary.status = RunStatus::kFailed;
    summary.message = "the trajectory reached this server's limit of " + std::to_string(max_rows) +
                      " output samples (--max-samples, --max-result-bytes) at t = " + std::to_string(job->t_now.load()) +
                      ": raise /output/every";
  }
  // The guarantees: a hypothesis the run relies on that fails is a warning (an event on the stream), or
  // with `strict` the end of the job (failed, the report says why).
  if (summary.status == RunStatus::kCompleted) {
    commit->hypothesis_failure = sim.guarantees(summary).relied_on_failure();
    if (job->strict && !commit->hypothesis_failure.empty()) {
      summary.status = RunStatus::kFailed;
      summary.message = "strict: " + commit->hypothesis_failure;
    }
  }
  commit->state = JobState::kDone;
  if (summary.status == RunStatus::kFailed) {
    commit->state = JobState::kFailed;
    commit->reason = summary.message;
  } else if (summary.status == RunStatus::kCancelled) {
    if (job->shutdown && !job->cancel_requested) {
      commit->state = JobState::kFailed;
      commit->reason = kReasonStoppedRunning;
    } else {
      commit->state = JobState::kCancelled;
      commit->reason = "cancelled by request (" + summary.message + ")";
    }
  }
  summary.add_phase("write", csv.seconds() + seconds_since(t_write));
  const std::string report = sim.report_json(summary).dump(2) + "\n";
  try {
    write_file(job->dir / "report.json.tmp", report);
  } catch (const std::exception& e) {
    return fail_to_store(*job, e.what());
  }
  for (const auto& [name, s] : summary.phase_seconds)
    if (name == "integrate") commit->integrate_seconds = s;
  job->sim.reset();
  commit->summary = std::move(summary);
  enqueue_commit(std::move(commit));
}

void JobManager::enqueue_commit(std::unique_ptr<Commit> commit) {
  {
    std::lock_guard lock(commit_mu_);
    commits_.push_back(std::move(commit));
  }
  commit_cv_.notify_one();
}

void JobManager::run_study(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit) {
  scene::StudySettings st = job->study;
  st.cancel = &job->cancel;
  st.on_row = [this, &job](std::size_t done, std::size_t total) {
    job->rows_done = static_cast<std::int64_t>(done);
    push_event(*job, "progress", {{"rows", done}, {"rows_total", total}});
  };
  const scene::LagrangianScene& sc = *job->study_scene;
  std::optional<scene::StudyResult> result;
  try {
    result = scene::run_study(sc, st);
  } catch (const scene::StudyCancelled&) {
    const bool stopped = job->shutdown && !job->cancel_requested;
    commit->state = stopped ? JobState::kFailed : JobState::kCancelled;
    commit->reason = stopped ? kReasonStoppedRunning : "cancelled by request";
  } catch (const scene::SceneError& e) {
    commit->state = JobState::kFailed;
    commit->reason = e.what();
  }
  job->study_scene.reset();
  if (result) {
    // The table's steps count every run of the study.
    for (const auto& row : result->rows) commit->summary.steps += row.steps;
    try {
      write_file(job->dir / "table.csv.tmp", result->to_csv());
      write_file(job->dir / "result.json.tmp", result->to_json().dump(2) + "\n");
    } catch (const std::exception& e) {
      return fail_to_store(*job, e.what());
    }
    commit->files = {"table.csv", "result.json"};
    commit->state = JobState::kDone;
  }
  enqueue_commit(std::move(commit));
}

void JobManager::fail_to_store(Job& job, const std::string& what) {
  // A full or failing disk: the partial results would go on holding the space, and are of no use.
  std::error_code ec;
  for (const char* name : {"trajectory.csv.tmp", "report.json.tmp", "table.csv.tmp", "result.json.tmp"}) fs::remove(job.dir / name, ec);
  job.sim.reset();
  std::cerr << "moreau-server: job " << job.id << ": cannot store the results: " << what << "\n";
  set_state(job, JobState::kFailed, "cannot store the results: " + what);
}

void JobManager::committer_loop() {
  while (true) {
    std::unique_ptr<Commit> c;
    {
      std::unique_lock lock(commit_mu_);
      commit_cv_.wait(lock, [&] { return !commits_.empty() || commit_stop_; });
      if (commits_.empty()) return;  // stopping, and nothing left to store
      c = std::move(commits_.front());
      commits_.pop_front();
    }
    try {
      commit(*c);
    } catch (const std::exception& e) {
      if (c->stream) c->stream->close();
      fail_to_store(*c->job, e.what());
    }
  }
}

void JobManager::commit(Commit& c) {
  Job& job = *c.job;
  const RunSummary& summary = c.summary;
  // The trajectory (or table) first, then the report (or result), which commits the job: each fsync'ed
  // before its rename.
  for (const char* name : c.files) {
    const fs::path target = job.dir / name;
    fs::path tmp = target;
    tmp += ".tmp";
    fsync_path(tmp);
    fs::rename(tmp, target);
  }
  // The renames themselves survive a power loss once the directory is synced.
  if (!c.files.empty()) fsync_path(job.dir);
  if (!c.files.empty()) {
    std::lock_guard lock(job.mu);
    job.has_report = true;
    job.has_trajectory = true;
  }
  job.t_now = summary.t_final;
  job.step_now = summary.steps;
  // Counted before the state changes: whoever sees the job final sees it in /metrics too.
  count_finished(summary.steps, c.integrate_seconds, seconds_since(c.wall_start));
  set_state(job, c.state, c.reason);
  // The stream's last events after the state: a subscriber that reacts to "finished" finds the job
  // final over HTTP, with its results stored.
  if (c.stream) {
    if (!c.hypothesis_failure.empty()) c.stream->push_event("hypothesis_failed", summary.steps, summary.t_final, c.hypothesis_failure);
    if (summary.converged_step) {
      c.stream->push_event("converged", *summary.converged_step, summary.converged_time.value_or(summary.t_final),
                           "v == 0.0 exactly from step " + std::to_string(*summary.converged_step) + " to the end");
    }
    const char* kind = c.state == JobState::kDone ? "finished" : c.state == JobState::kCancelled ? "cancelled" : "failed";
    c.stream->push_event(kind, summary.steps, summary.t_final, c.reason.empty() ? summary.BriefReport() : c.reason);
    c.stream->close();
  }
}

void JobManager::count_finished(std::int64_t steps, double integrate_seconds, double wall_seconds) {
  std::lock_guard lock(stats_mu_);
  steps_total_ += steps;
  integrate_total_ += integrate_seconds;
  avg_job_seconds_ = 0.9 * avg_job_seconds_ + 0.1 * wall_seconds;
  const auto now = Clock::now();
  recent_steps_.emplace_back(now, steps);
  while (!recent_steps_.empty() && now - recent_steps_.front().first > std::chrono::seconds(10)) recent_steps_.pop_front();
}

bool JobManager::idle() const {
  std::lock_guard lock(mu_);
  return queue_.empty() && busy_.load() == 0;
}

Metrics JobManager::metrics() const {
  Metrics m;
  for (const char* s : {"queued", "running", "cancelling", "done", "failed", "cancelled"}) m.jobs_by_state[s] = 0;
  {
    std::lock_guard lock(mu_);
    for (const auto& job : order_) {
      std::lock_guard jl(job->mu);
      ++m.jobs_by_state[to_string(job->state)];
    }
    m.queue_length = static_cast<std::int64_t>(queue_.size());
    m.workers = static_cast<std::int64_t>(workers_.size());
  }
  m.queue_capacity = config_.queue;
  m.workers_busy = busy_.load();
  {
    std::lock_guard lock(stats_mu_);
    m.submitted = submitted_;
    m.rejected_queue_full = rejected_;
    m.steps_total = steps_total_;
    m.integrate_seconds_total = integrate_total_;
    const auto now = Clock::now();
    std::int64_t recent = 0;
    for (const auto& [when, steps] : recent_steps_)
      if (now - when <= std::chrono::seconds(10)) recent += steps;
    m.steps_per_second = static_cast<double>(recent) / 10.0;
  }
  m.lcm_published = hub_.published();
  m.lcm_dropped = hub_.dropped();
  return m;
}

}  // namespace moreau::server
