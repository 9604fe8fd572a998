#include "job_runner.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>

#include "job_observer.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/trajectory_csv.h"
#include "moreau/platform/number_text.h"
#include "storage.h"

namespace moreau::server {
namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

const char* kReasonStoppedRunning = "the server stopped while the job was running: it runs again from the start when the server restarts";

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// Why a job stopped by --max-job-seconds failed; `where` says how far it got.
std::string timed_out_reason(double max_job_seconds, const std::string& where) {
  return "the job ran longer than this server's limit of " + platform::significant(max_job_seconds, 6) +
         " s of wall-clock time (--max-job-seconds) and was stopped " + where + "; what it wrote is kept";
}

// The results a run writes before its commit renames them (JobRunner::commit), removed when they will
// never be committed.
void remove_uncommitted_results(const Job& job) {
  std::error_code ec;
  for (const char* name : {"trajectory.csv.tmp", "report.json.tmp", "table.csv.tmp", "result.json.tmp"}) fs::remove(job.dir / name, ec);
}

}  // namespace

JobRunner::JobRunner(const ServerConfig& config, LcmHub& hub) : config_(config), hub_(hub), store_(config) {}

JobRunner::~JobRunner() { stop(); }

void JobRunner::start() {
  const int n = config_.workers > 0 ? config_.workers : std::max(1u, std::thread::hardware_concurrency());
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { worker_loop(); });
  for (int i = 0; i < std::max(1, config_.io_threads); ++i) committers_.emplace_back([this] { committer_loop(); });
  if (config_.max_job_seconds > 0) watchdog_ = std::thread([this] { watchdog_loop(); });
}

void JobRunner::watchdog_loop() {
  std::unique_lock lock(watchdog_mu_);
  while (!watchdog_stop_) {
    auto next = Clock::time_point::max();
    const auto now = Clock::now();
    for (auto it = deadlines_.begin(); it != deadlines_.end();) {
      if (it->second <= now) {
        // The run, study or campaign stops at its next check (every 256 steps, or between samples and
        // rows), as for a cancellation; timed_out makes it end failed, with the reason.
        it->first->timed_out = true;
        it->first->cancel = true;
        it = deadlines_.erase(it);
      } else {
        next = std::min(next, it->second);
        ++it;
      }
    }
    if (next == Clock::time_point::max())
      watchdog_cv_.wait(lock);
    else
      watchdog_cv_.wait_until(lock, next);
  }
}

void JobRunner::stop() {
  if (stopping_.exchange(true)) return;
  std::deque<std::shared_ptr<Job>> queued;
  std::vector<std::shared_ptr<Job>> all;
  {
    std::lock_guard lock(mu_);
    queued.swap(queue_);
    all = store_.list();
  }
  queue_cv_.notify_all();
  // The queued jobs, out of the queue so that no worker starts them, stay queued in their state and
  // records: a server started on the same data directory runs them (JobStore::recover).
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
  {
    std::lock_guard lock(watchdog_mu_);
    watchdog_stop_ = true;
  }
  watchdog_cv_.notify_all();
  if (watchdog_.joinable()) watchdog_.join();
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

void JobRunner::requeue(const std::shared_ptr<Job>& job, const std::string& refused) {
  if (!refused.empty()) {
    job->release_compiled();
    set_state(*job, JobState::kFailed, "the restarted server cannot run the job again: " + refused);
    return;
  }
  std::string reason;
  {
    std::lock_guard lock(job->mu);
    reason = job->reason;
  }
  set_state(*job, JobState::kQueued, reason);  // the record (with its crashes) and the state event
  {
    std::lock_guard lock(mu_);
    queue_.push_back(job);  // beyond --queue if need be: it was accepted
  }
  queue_cv_.notify_one();
}

JobRunner::Submit JobRunner::submit(const std::shared_ptr<Job>& job, const json& scene_doc, int* retry_after, const json* spec_doc) {
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
  // Accepted means stored: the scene and the record are on disk before the 202 (507 when they cannot be).
  store_.write_new(*job, scene_doc, spec_doc);
  push_event(*job, "state", {{"id", job->id}, {"state", "queued"}});
  {
    std::lock_guard lock(mu_);
    if (stopping_) return Submit::kStopping;
    // The queue may have filled up while the records were written: accept anyway, it is one more.
    store_.add(job);
    queue_.push_back(job);
  }
  {
    std::lock_guard s(stats_mu_);
    ++submitted_;
  }
  queue_cv_.notify_one();
  return Submit::kQueued;
}

bool JobRunner::set_state(Job& job, JobState state, const std::string& reason) {
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
    record = job_record(job, state, reason, started, finished);
  }
  // 1. The record. A final state that cannot be recorded is still published (the results are committed
  // and a restart derives the state from them), but said on stderr.
  try {
    store_.write_record(record, job, is_final(state) ? Durability::kFsync : Durability::kRename);
  } catch (const std::exception& e) {
    std::cerr << "moreau-server: job " << job.id << ": " << e.what() << "\n";
  }
  // 2. The store as a final state leaves it: older finished jobs beyond --keep-jobs are deleted now,
  // before anyone can see this job final (this job is not yet final for prune(), so it stays).
  if (became_final) {
    store_.count_final();
    if (!stopping_) store_.prune();
  }
  // 3. Published: the state and its event change together, so a stream that sees a final state has its
  // event, and a waiter woken by it sees steps 1 and 2 done.
  {
    std::lock_guard lock(job.mu);
    job.state = state;
    job.reason = reason;
    job.started = started;
    job.finished = finished;
    // A final job's figures show its run: its live-plot samples go, and it keeps its state changes and progress.
    if (became_final)
      job.events.erase(std::remove_if(job.events.begin(), job.events.end(), [](const SseEvent& e) { return e.name == "sample"; }),
                       job.events.end());
    job.events.push_back(SseEvent{job.next_event_id++, "state", data.dump()});
  }
  job.cv.notify_all();
  return true;
}

JobRunner::Cancel JobRunner::cancel(const std::shared_ptr<Job>& job) {
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
    job->release_compiled();
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

void JobRunner::wait_final(Job& job, std::chrono::milliseconds timeout) const {
  std::unique_lock lock(job.mu);
  job.cv.wait_for(lock, timeout, [&] { return is_final(job.state) || stopping_.load(); });
}

std::vector<SseEvent> JobRunner::events_after(Job& job, std::uint64_t after, std::chrono::milliseconds timeout, bool& done) const {
  std::unique_lock lock(job.mu);
  auto has_new = [&] { return !job.events.empty() && job.events.back().id > after; };
  job.cv.wait_for(lock, timeout, [&] { return has_new() || is_final(job.state) || stopping_.load(); });
  std::vector<SseEvent> out;
  for (const auto& e : job.events)
    if (e.id > after) out.push_back(e);
  done = is_final(job.state) || stopping_.load();
  return out;
}

void JobRunner::worker_loop() {
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
    if (config_.max_job_seconds > 0) {
      {
        std::lock_guard lock(watchdog_mu_);
        deadlines_[job] =
            Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config_.max_job_seconds));
      }
      watchdog_cv_.notify_all();
    }
    try {
      run(job);
    } catch (const std::exception& e) {
      // (A stream opened by run() is closed when its Commit, never queued, is destroyed.)
      std::cerr << "moreau-server: job " << job->id << " failed: " << e.what() << "\n";
      job->release_compiled();
      set_state(*job, JobState::kFailed, std::string("internal error: ") + e.what());
    }
    if (config_.max_job_seconds > 0) {
      std::lock_guard lock(watchdog_mu_);
      deadlines_.erase(job);
    }
    --busy_;
  }
}

void JobRunner::run(const std::shared_ptr<Job>& job) {
  const auto wall_start = Clock::now();
  if (job->cancel) {
    job->release_compiled();
    // Taken from the queue as the server stopped: it stays queued, for the restarted server.
    if (!job->shutdown || job->cancel_requested) set_state(*job, JobState::kCancelled, "cancelled before it ran");
    return;
  }
  set_state(*job, JobState::kRunning, "");
  auto commit = std::make_unique<Commit>();
  commit->job = job;
  commit->wall_start = wall_start;
  if (job->kind == JobKind::kStudy) return run_study(job, std::move(commit));
  if (job->kind == JobKind::kCampaign) return run_campaign(job, std::move(commit));
  commit->files = {"trajectory.csv", "report.json"};
  const scene::Simulation& sim = *job->sim;

  std::optional<StreamObserver> stream_observer;
  if (job->stream.enabled) {
    // What the states hold, for viewers that know nothing of the scene.
    StreamDescription description{sim.name(),           sim.system_type(),    "E = 1/2 <M(q) v, v> (kinetic energy)",
                                  sim.position_names(), sim.velocity_names(), sim.t0(),
                                  sim.t_end(),          sim.signal_names()};
    if (const scene::LureScene* lure = sim.lure())
      description.energy = lure->storage ? "W = 1/2 x^T P x (storage)" : "1/2 |x|^2 (no storage matrix)";
    commit->stream = std::make_shared<JobStream>(job->id, job->stream, sim.dof(), std::move(description));
    hub_.add(commit->stream);
    stream_observer.emplace(commit->stream, sim.t0(), &job->cancel);
    commit->stream->push_event(
        "started", 0, sim.t0(),
        "job " + job->id + " started: " + sim.name() + ", t in [" + std::to_string(sim.t0()) + ", " + std::to_string(sim.t_end()) + "]");
  }

  const fs::path csv_tmp = job->dir / "trajectory.csv.tmp";
  scene::TrajectoryCsvWriter csv(csv_tmp.string(), sim.position_names(), sim.velocity_names(), sim.signal_names());
  auto progress = [this, &job] {
    push_event(*job, "progress", {{"t", job->t_now.load()}, {"step", job->step_now.load()}, {"t0", job->t0}, {"t_end", job->t_end}});
  };
  auto sample = [&job, names = sim.position_names()](const Sample& s) { push_event(*job, "sample", sample_event(s, names)); };
  const std::int64_t max_rows = max_trajectory_rows(config_, sim);
  JobObserver observer(*job, csv, job->record_every, sim.output_every(), max_rows, stream_observer ? &*stream_observer : nullptr, progress,
                       sample);

  RunSummary summary = sim.run(&observer);
  observer.finish();
  if (summary.status == RunStatus::kCancelled && job->shutdown && !job->cancel_requested) {
    if (commit->stream) commit->stream->push_event("stopped", summary.steps, summary.t_final, kReasonStoppedRunning);
    return queue_again_after_stop(*job, kReasonStoppedRunning);
  }
  if (summary.status == RunStatus::kCancelled && job->timed_out && !job->cancel_requested) {
    summary.status = RunStatus::kFailed;
    summary.message = timed_out_reason(config_.max_job_seconds,
                                       "at step " + std::to_string(summary.steps) + " (t = " + std::to_string(summary.t_final) + ")");
  }
  if (stream_observer) {
    stream_observer->flush_last(summary);
    commit->announced_rest = stream_observer->announced_rest();
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
    commit->hypothesis_failure = sim.hypothesis_failure(summary);
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
    commit->state = JobState::kCancelled;
    // Said once: "cancelled by request at step 147968", not "cancelled by request (cancelled at step 147968)".
    const std::string said = "cancelled ";
    commit->reason = summary.message.rfind(said, 0) == 0 ? "cancelled by request " + summary.message.substr(said.size())
                                                         : "cancelled by request (" + summary.message + ")";
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

void JobRunner::enqueue_commit(std::unique_ptr<Commit> commit) {
  {
    std::lock_guard lock(commit_mu_);
    commits_.push_back(std::move(commit));
  }
  commit_cv_.notify_one();
}

void JobRunner::run_study(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit) {
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
    if (job->shutdown && !job->cancel_requested) return queue_again_after_stop(*job, kReasonStoppedRunning);
    if (job->timed_out && !job->cancel_requested) {
      commit->state = JobState::kFailed;
      commit->reason = timed_out_reason(config_.max_job_seconds, "after " + std::to_string(job->rows_done.load()) + " rows of its table");
    } else {
      commit->state = JobState::kCancelled;
      commit->reason = "cancelled by request";
    }
  } catch (const scene::SceneError& e) {
    commit->state = JobState::kFailed;
    commit->reason = e.what();
  }
  job->study_scene.reset();
  if (result) {
    // The table's steps count every run of the study, and its time is integration time too (the runs
    // and the references they are measured against): /metrics' moreau_integrate_seconds_total.
    for (const auto& row : result->rows) commit->summary.steps += row.steps;
    commit->integrate_seconds = result->wall_seconds;
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

void JobRunner::run_campaign(const std::shared_ptr<Job>& job, std::unique_ptr<Commit> commit) {
  const scene::CampaignSpec spec = std::move(*job->campaign);
  job->campaign.reset();
  scene::CampaignRunOptions options;
  options.workers = config_.campaign_threads > 0 ? config_.campaign_threads : std::max<int>(1, static_cast<int>(workers_.size()));
  options.stop = &job->cancel;
  options.max_steps = config_.max_steps;
  options.max_bytes = config_.max_result_bytes;
  options.max_total_steps = config_.max_campaign_steps;  // stops the run at the budget, whatever the samples take
  // Progress at most ten times a second (and at the last sample): the event stream's bound keeps the
  // latest progress events, and a client needs no more.
  Clock::time_point last_event{};
  options.progress = [&](std::int64_t done, std::int64_t total) {
    job->rows_done = done;
    const auto now = Clock::now();
    if (done < total && now - last_event < std::chrono::milliseconds(100)) return;
    last_event = now;
    push_event(*job, "progress", {{"samples", done}, {"samples_total", total}});
  };
  const auto t_start = Clock::now();
  try {
    const scene::CampaignRunResult result = scene::run_campaign(spec, job->dir.string(), options);
    commit->summary.steps = result.steps;  // counted in /metrics with the integrate seconds
    const std::int64_t have = job->rows_done.load();
    if (result.summarized) {
      commit->state = JobState::kDone;
    } else if (job->shutdown && !job->cancel_requested) {
      // The records written so far stay; the restarted server's run skips their samples.
      return queue_again_after_stop(*job, "the server stopped while the campaign was running (" + std::to_string(have) + " of " +
                                              std::to_string(spec.samples) +
                                              " samples finished; their records are kept): it goes on from them when the server restarts");
    } else if (result.stopped && job->timed_out && !job->cancel_requested) {
      commit->state = JobState::kFailed;
      commit->reason = timed_out_reason(config_.max_job_seconds, "after " + std::to_string(have) + " of " + std::to_string(spec.samples) +
                                                                     " samples (their records are kept)");
    } else if (result.stopped) {
      commit->state = JobState::kCancelled;
      commit->reason = "cancelled by request (" + std::to_string(have) + " of " + std::to_string(spec.samples) +
                       " samples finished; their records are kept)";
    } else {
      commit->state = JobState::kFailed;
      commit->reason = "the campaign ended without every sample (" + std::to_string(have) + " of " + std::to_string(spec.samples) + ")";
    }
  } catch (const std::exception& e) {
    commit->state = JobState::kFailed;
    commit->reason = std::string("the campaign could not be run: ") + e.what();
  }
  commit->integrate_seconds = seconds_since(t_start);
  commit->files_in_place = {"samples.jsonl", "samples.csv", "summary.json", "summary.txt"};
  enqueue_commit(std::move(commit));
}

void JobRunner::fail_to_store(Job& job, const std::string& what) {
  // A full or failing disk: the partial results would go on holding the space, and are of no use.
  remove_uncommitted_results(job);
  job.release_compiled();
  std::cerr << "moreau-server: job " << job.id << ": cannot store the results: " << what << "\n";
  set_state(job, JobState::kFailed, "cannot store the results: " + what);
}

void JobRunner::queue_again_after_stop(Job& job, const std::string& why) {
  remove_uncommitted_results(job);
  job.release_compiled();
  job.t_now = job.t0;
  job.step_now = 0;
  job.rows_done = 0;
  set_state(job, JobState::kQueued, why);
}

void JobRunner::committer_loop() {
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

void JobRunner::commit(Commit& c) {
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
  // A campaign's files were written in place as its samples finished: made durable here.
  for (const char* name : c.files_in_place) {
    std::error_code ec;
    if (fs::exists(job.dir / name, ec)) fsync_path(job.dir / name);
  }
  // The renames themselves survive a power loss once the directory is synced.
  if (!c.files.empty() || !c.files_in_place.empty()) fsync_path(job.dir);
  if (!c.files.empty()) {
    std::lock_guard lock(job.mu);
    job.has_report = true;
    job.has_trajectory = true;
  } else if (!c.files_in_place.empty()) {
    // A campaign: its summary once every sample is present, its records once one is.
    std::error_code ec;
    const bool has_summary = fs::exists(job.dir / "summary.json", ec), has_records = fs::exists(job.dir / "samples.jsonl", ec);
    std::lock_guard lock(job.mu);
    job.has_report = has_summary;
    job.has_trajectory = has_records;
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
    // "converged" went out when the rest was detected (StreamObserver); the end confirms it silently, or
    // says so when the report's verdict differs from what the stream last said.
    if (summary.converged_step != c.announced_rest) {
      if (c.announced_rest) {
        std::string why = "the report does not count the rest from step " + std::to_string(*c.announced_rest) + " as convergence: ";
        if (summary.status == RunStatus::kFailed)
          why += "the run failed";
        else if (summary.rest_step == c.announced_rest)
          why += "the final state is not an equilibrium of the scheme (Theorem 4.3's inclusion)";
        else
          why += "the rest ended";
        c.stream->push_event("convergence_withdrawn", summary.steps, summary.t_final, why);
      }
      if (summary.converged_step) {
        c.stream->push_event("converged", *summary.converged_step, summary.converged_time.value_or(summary.t_final),
                             "v == 0.0 exactly from step " + std::to_string(*summary.converged_step) + " to the end");
      }
    }
    const char* kind = c.state == JobState::kDone ? "finished" : c.state == JobState::kCancelled ? "cancelled" : "failed";
    c.stream->push_event(kind, summary.steps, summary.t_final, c.reason.empty() ? summary.BriefReport() : c.reason);
    c.stream->close();
  }
}

void JobRunner::count_finished(std::int64_t steps, double integrate_seconds, double wall_seconds) {
  std::lock_guard lock(stats_mu_);
  steps_total_ += steps;
  integrate_total_ += integrate_seconds;
  avg_job_seconds_ = 0.9 * avg_job_seconds_ + 0.1 * wall_seconds;
  const auto now = Clock::now();
  recent_steps_.emplace_back(now, steps);
  while (!recent_steps_.empty() && now - recent_steps_.front().first > std::chrono::seconds(10)) recent_steps_.pop_front();
}

bool JobRunner::idle() const {
  std::lock_guard lock(mu_);
  return queue_.empty() && busy_.load() == 0;
}

std::map<std::string, int> JobRunner::queue_positions() const {
  std::lock_guard lock(mu_);
  std::map<std::string, int> out;
  int place = 0;
  for (const auto& job : queue_) out.emplace(job->id, ++place);
  return out;
}

Metrics JobRunner::metrics() const {
  Metrics m;
  for (const char* s : {"queued", "running", "cancelling", "done", "failed", "cancelled"}) m.jobs_by_state[s] = 0;
  for (const auto& job : store_.list()) {
    std::lock_guard jl(job->mu);
    ++m.jobs_by_state[to_string(job->state)];
  }
  {
    std::lock_guard lock(mu_);
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
