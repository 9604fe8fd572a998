#include "job.h"

#include <algorithm>
#include <cmath>

#include "moreau/analysis/figure_kind.h"
#include "moreau/scene/json_number.h"

namespace moreau::server {
using json = nlohmann::json;
using scene::finite_or_null;

namespace {
constexpr std::size_t kMaxEventsKept = 512;  // per job, for late subscribers; older progress and samples are dropped
constexpr int kMaxSampleCoordinates = 16;    // of q and of v in a sample event
bool droppable(const SseEvent& e) { return e.name == "progress" || e.name == "sample"; }
}  // namespace

std::optional<JobState> parse_state(const std::string& s) {
  if (s == "queued") return JobState::kQueued;
  if (s == "running") return JobState::kRunning;
  if (s == "cancelling") return JobState::kCancelling;
  if (s == "done") return JobState::kDone;
  if (s == "failed") return JobState::kFailed;
  if (s == "cancelled") return JobState::kCancelled;
  return std::nullopt;
}

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

const char* kind_name(JobKind k) {
  switch (k) {
    case JobKind::kRun: return "run";
    case JobKind::kStudy: return "study";
    case JobKind::kCampaign: return "campaign";
  }
  return "?";
}

std::string kind_url(JobKind k) {
  switch (k) {
    case JobKind::kRun: return "/v1/jobs/";
    case JobKind::kStudy: return "/v1/studies/";
    case JobKind::kCampaign: return "/v1/campaigns/";
  }
  return "/v1/jobs/";
}

bool is_final(JobState s) { return s == JobState::kDone || s == JobState::kFailed || s == JobState::kCancelled; }

namespace {
// "success-map" -> "success_map_figure": link names are identifiers.
std::string figure_link_name(std::string kind) {
  std::replace(kind.begin(), kind.end(), '-', '_');
  return kind + "_figure";
}
// A link to each figure of `Kind` (figure_kind.h) of the job at `url`.
template <class Kind>
void add_figure_links(json& links, const std::string& url) {
  for (const auto& [kind, name] : scene::FigureNames<Kind>::kTable) links[figure_link_name(name)] = url + "/figure?kind=" + name;
}
}  // namespace

json job_json(const Job& job, const json* report) {
  std::unique_lock lock(job.mu);
  const bool study = job.kind == JobKind::kStudy;
  json j;
  j["id"] = job.id;
  j["kind"] = kind_name(job.kind);
  j["url"] = kind_url(job.kind) + job.id;
  j["scene"] = job.scene_name;
  j["state"] = to_string(job.state);
  if (!job.reason.empty()) j["reason"] = job.reason;
  j["created"] = job.created;
  j["started"] = job.started > 0 ? json(job.started) : json(nullptr);
  j["finished"] = job.finished > 0 ? json(job.finished) : json(nullptr);
  const std::string url = j["url"];
  json links = {{"events", url + "/events"}};
  // Results are linked once the job is final: they are committed (has_report, has_trajectory) a moment
  // before the final state is set, and are served (not 409) only from then on.
  const bool final = is_final(job.state);
  if (study) {
    const std::int64_t done = job.state == JobState::kDone ? job.rows_total : job.rows_done.load();
    j["progress"] = {{"rows", done},
                     {"rows_total", job.rows_total},
                     {"fraction", job.rows_total > 0 ? static_cast<double>(done) / static_cast<double>(job.rows_total) : 0.0}};
    if (job.has_report && final) {
      links["table"] = url + "/table";
      links["csv"] = url + "/table?format=csv";
      add_figure_links<scene::StudyFigure>(links, url);
    }
  } else if (job.kind == JobKind::kCampaign) {
    const std::int64_t done = job.state == JobState::kDone ? job.rows_total : job.rows_done.load();
    j["progress"] = {{"samples", done},
                     {"samples_total", job.rows_total},
                     {"fraction", job.rows_total > 0 ? static_cast<double>(done) / static_cast<double>(job.rows_total) : 0.0}};
    // The records of the samples that finished are kept whatever the end (cancelled, failed, stopped).
    if (job.has_trajectory && final) {
      links["samples"] = url + "/samples?format=csv";
      links["records"] = url + "/samples?format=jsonl";
    }
    if (job.has_report && final) {
      links["summary"] = url + "/summary";
      links["summary_text"] = url + "/summary?format=text";
      add_figure_links<scene::CampaignFigure>(links, url);
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
    if (job.has_report && final) links["report"] = url + "/report";
    if (job.robot) links["kinematics"] = url + "/kinematics";  // from the rows written so far
    if (job.has_trajectory && final) {
      links["trajectory"] = url + "/trajectory";
      links["figure"] = url + "/figure?kind=" + scene::figure_name(scene::default_figure<scene::TrajectoryFigure>());
    }
  }
  j["links"] = links;
  if (job.stream.enabled) {
    j["stream"] = {{"state_channel", job.stream.state_channel},
                   {"event_channel", job.stream.event_channel},
                   {"description_channel", job.stream.description_channel},
                   {"period", job.stream.period},
                   {"realtime", job.stream.realtime}};
  }
  lock.unlock();
  if (report) j[study ? "result" : job.kind == JobKind::kCampaign ? "summary" : "report"] = *report;
  return j;
}

json job_record(const Job& job, JobState state, const std::string& reason, double started, double finished) {
  json r = {{"id", job.id},
            {"kind", kind_name(job.kind)},
            {"scene", job.scene_name},
            {"state", to_string(state)},
            {"created", job.created},
            {"started", started},
            {"finished", finished},
            {"t0", job.t0},
            {"t_end", job.t_end},
            {"planned_steps", job.planned_steps}};
  if (job.kind != JobKind::kRun) r["rows_total"] = job.rows_total;
  if (!reason.empty()) r["reason"] = reason;
  // Where a run got to, so that a restarted server shows the progress it had.
  if (is_final(state)) {
    r["progress"] = {{"t", finite_or_null(job.t_now.load())}, {"step", job.step_now.load()}, {"rows", job.rows_done.load()}};
  }
  if (job.stream.enabled) {
    r["stream"] = {{"prefix", job.stream.prefix}, {"period", job.stream.period}, {"realtime", job.stream.realtime}};
  }
  if (job.strict) r["strict"] = true;
  if (job.robot) r["robot"] = true;
  if (job.crashes > 0) r["crashes"] = job.crashes;
  // The id this state's event takes: the next one, since a record is written just before its state's
  // event is pushed (JobRunner::set_state). Exact for a final state (no progress event comes between);
  // JobStore::recover() continues the ids from it.
  r["event_id"] = job.next_event_id;
  return r;
}

json sample_event(const Sample& s, const std::vector<std::string>& q_names) {
  // All coordinates up to the bound; beyond it, kMaxSampleCoordinates of them evenly spread from the
  // first to the last, named by their indices.
  const int n = std::max(0, s.n);
  const int shown = std::min(n, kMaxSampleCoordinates);
  std::vector<int> indices;
  for (int i = 0; i < shown; ++i)
    indices.push_back(shown > 1 && n > shown ? static_cast<int>((static_cast<long>(i) * (n - 1)) / (shown - 1)) : i);
  json q = json::array(), v = json::array();
  for (int i : indices) {
    q.push_back(finite_or_null(s.q[i]));
    v.push_back(finite_or_null(s.v[i]));
  }
  json j = {{"t", finite_or_null(s.t)}, {"step", s.step}, {"n", n}, {"q", q}, {"v", v}, {"energy", finite_or_null(s.kinetic_energy)}};
  if (shown < n) j["indices"] = indices;
  if (static_cast<int>(q_names.size()) == n) {
    json names = json::array();
    for (int i : indices) names.push_back(q_names[static_cast<std::size_t>(i)]);
    j["names"] = std::move(names);
  }
  return j;
}

void push_event(Job& job, const std::string& name, const json& data) {
  {
    std::lock_guard lock(job.mu);
    job.events.push_back(SseEvent{job.next_event_id++, name, data.dump()});
    if (job.events.size() > kMaxEventsKept) {
      // Drop the oldest progress or sample event (state changes are kept).
      auto it = std::find_if(job.events.begin(), job.events.end(), droppable);
      job.events.erase(it != job.events.end() ? it : job.events.begin());
    }
  }
  job.cv.notify_all();
}

}  // namespace moreau::server
