// A job (a run, a study or a campaign submitted to the server): what it is, its state and events, and its record
// and JSON as the API shows them. job_store.h keeps the jobs and their files; job_runner.h runs them.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "lcm_stream.h"
#include "moreau/analysis/campaign.h"
#include "moreau/scene/simulation.h"
#include "moreau/analysis/study.h"
#include "moreau/core/observer.h"
#include "moreau/server/server_config.h"

namespace moreau::server {

// kCancelling: a running job asked to stop (DELETE); it becomes kCancelled when its run has stopped
// and what it computed is stored.
enum class JobState { kQueued, kRunning, kCancelling, kDone, kFailed, kCancelled };
enum class JobKind { kRun, kStudy, kCampaign };
const char* to_string(JobState s);
// "run", "study", "campaign": the kind as the API and the job records name it.
const char* kind_name(JobKind k);
// Where the API serves jobs of this kind: "/v1/jobs/", "/v1/studies/", "/v1/campaigns/".
std::string kind_url(JobKind k);
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
  // A URDF robot's run: GET /v1/jobs/{id}/kinematics serves its link poses (links.kinematics). In job.json
  // as "robot".
  bool robot = false;
  // How many times the server died (no clean stop) while this job ran: it is run again after the first,
  // not after the second (JobStore::recover). In job.json as "crashes".
  int crashes = 0;

  // Set before the job is queued, used by its worker, released when it ends.
  std::optional<scene::Simulation> sim;
  std::int64_t record_every = 1;  // trajectory decimation: the scene's /output/every
  double load_seconds = 0;        // validation and compilation at submission
  // Studies: the compiled scene and the settings, and the rows of the table done so far.
  std::optional<scene::LagrangianScene> study_scene;
  scene::StudySettings study;
  std::int64_t rows_total = 0;  // a study's rows; a campaign's samples
  std::atomic<std::int64_t> rows_done{0};
  // Campaigns: the validated spec (its scene inlined). The campaign's directory (campaign.h) is the job's:
  // campaign.json, samples.jsonl, samples.csv, summary.json and summary.txt beside job.json.
  std::optional<scene::CampaignSpec> campaign;
  // Frees what the job was compiled to (run, study or campaign): when it ends, or leaves the queue unrun.
  void release_compiled() {
    sim.reset();
    study_scene.reset();
    campaign.reset();
  }

  std::atomic<bool> cancel{false};            // the run stops at its next check (every 256 steps: within 50 ms)
  std::atomic<bool> shutdown{false};          // ... because the server is stopping
  std::atomic<bool> cancel_requested{false};  // ... because a client asked (DELETE): it ends cancelled
  std::atomic<bool> timed_out{false};         // ... because it ran longer than --max-job-seconds: it ends failed

  // The job's files: readers hold it shared while they check `deleted` and open what they read; pruning
  // holds it exclusively while it deletes them. An open file stays readable after its deletion.
  mutable std::shared_mutex files_mu;
  bool deleted = false;  // under files_mu
  std::atomic<double> t_now{0};
  std::atomic<std::int64_t> step_now{0};

  std::mutex state_change_mu;  // one state change at a time (JobRunner::set_state)
  mutable std::mutex mu;
  std::condition_variable cv;  // state changes and new events
  JobState state = JobState::kQueued;
  std::string reason;  // why it failed or was cancelled
  double started = 0, finished = 0;
  bool has_report = false, has_trajectory = false;  // a study: result.json, table.csv
  std::deque<SseEvent> events;
  std::uint64_t next_event_id = 1;  // ids go on across restarts (job_record's event_id, JobStore::recover)
};

// How far past its record's event id a job that was not final continues after a restart: beyond every
// progress and sample event it can have sent since the record (10 of each a second for 6 years).
inline constexpr std::uint64_t kEventIdGapAfterRestart = std::uint64_t{1} << 32;

// The job as GET /v1/jobs/{id} shows it (with the report when `report` is given); a study as
// GET /v1/studies/{id} shows it (with its result as "result"); a campaign as GET /v1/campaigns/{id} shows
// it (with its summary as "summary").
nlohmann::json job_json(const Job& job, const nlohmann::json* report);

// The record of `job` (DATA/jobs/<id>/job.json) as it would be in `state`; job.mu must be held.
nlohmann::json job_record(const Job& job, JobState state, const std::string& reason, double started, double finished);

// The state a record names, if it names one.
std::optional<JobState> parse_state(const std::string& s);

// Appends an event for the job's streams (the oldest progress and sample events go first beyond a bound).
void push_event(Job& job, const std::string& name, const nlohmann::json& data);

// The data of a `sample` event: t, step, n, the energy, and q and v (at most 16 coordinates of each,
// evenly spread from the first to the last, with their "indices" when n is larger), and the shown
// coordinates' "names" when `q_names` names all n. Not finite: null.
nlohmann::json sample_event(const Sample& s, const std::vector<std::string>& q_names = {});

double unix_now();

// The most bytes one trajectory row of `sim` can take: every column in its shortest round-trip form
// ("-2.2250738585072014e-308", 24 characters) and a separator.
std::int64_t max_trajectory_row_bytes(const scene::Simulation& sim);
// The trajectory rows a job may write: --max-samples, and --max-result-bytes over the widest row.
std::int64_t max_trajectory_rows(const ServerConfig& config, const scene::Simulation& sim);

}  // namespace moreau::server
