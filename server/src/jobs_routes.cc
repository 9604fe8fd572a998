#include "jobs_routes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numeric>
#include <optional>
#include <shared_mutex>
#include <system_error>
#include <vector>

#include "conditional.h"
#include "job_access.h"
#include "moreau/scene/simulation.h"
#include "moreau/platform/number_text.h"
#include "responses.h"
#include "submission.h"
#include "trajectory.h"

namespace moreau::server {

namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;
using Clock = std::chrono::steady_clock;

namespace {

// The longest long poll (?wait), in seconds.
constexpr int kMaxWaitSeconds = 60;

bool valid_channel_prefix(const std::string& s) {
  if (s.empty() || s.size() > 64 || !(s[0] >= 'A' && s[0] <= 'Z')) return false;
  return std::all_of(s.begin(), s.end(), [](char c) { return (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_'; });
}

}  // namespace

void get_job(ApiContext& api, const Request& req, Response& res, JobKind kind) {
  auto job = job_for(api, req, res, kind);
  if (!job) return;
  std::optional<double> wait;
  try {
    wait = number_param(req, "wait", 0, kMaxWaitSeconds);
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  if (wait && *wait > 0) {
    if (!api.waiting.try_take()) return send_too_many_waiting(api, res);
    api.jobs.wait_final(*job, std::chrono::milliseconds(static_cast<std::int64_t>(*wait * 1000)));
    api.waiting.give_back();
  }
  const auto report = read_report(*job);
  if (is_deleted(*job)) return send_deleted(res);  // purged (or pruned) while it waited
  send_json(res, 200, with_queue_position(job_json(*job, report ? &*report : nullptr), api.jobs.queue_positions()));
}

void list_jobs(ApiContext& api, const Request& req, Response& res, JobKind kind) {
  const std::string state = req.has_param("state") ? req.get_param_value("state") : "";
  if (!state.empty() && state != "queued" && state != "running" && state != "cancelling" && state != "done" && state != "failed" &&
      state != "cancelled")
    return send_error(res, 400, "bad query", "", "state must be queued, running, cancelling, done, failed or cancelled");
  const std::string scene = req.has_param("scene") ? req.get_param_value("scene") : "";
  std::optional<double> limit;
  try {
    limit = number_param(req, "limit", 1, 1e9);
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  const char* plural = kind == JobKind::kStudy ? "studies" : kind == JobKind::kCampaign ? "campaigns" : "jobs";
  // The cursor: only jobs created before this one (the "next" link of a page names the oldest of it).
  const std::string before = req.has_param("before") ? req.get_param_value("before") : "";
  const auto all = api.jobs.list();  // by creation
  auto end = all.end();
  if (!before.empty()) {
    end = std::find_if(all.begin(), all.end(), [&](const auto& job) { return job->id == before && job->kind == kind; });
    if (end == all.end() || is_deleted(**end))
      return send_error(res, 400, "bad query", "",
                        "query parameter 'before' names no " + std::string(kind == JobKind::kRun ? "job" : kind_name(kind)) +
                            " on this server (a cursor is the id of a listed one; it may have been deleted since: list again)");
  }
  std::vector<std::shared_ptr<Job>> picked;
  std::size_t total = 0;
  for (auto it = all.begin(); it != end; ++it) {
    const auto& job = *it;
    if (job->kind != kind) continue;
    ++total;
    if (!state.empty() && to_string(state_of(*job)) != state) continue;
    if (!scene.empty() && job->scene_name != scene) continue;
    picked.push_back(job);
  }
  std::size_t from = 0;
  if (limit && picked.size() > static_cast<std::size_t>(*limit)) from = picked.size() - static_cast<std::size_t>(*limit);
  const auto positions = api.jobs.queue_positions();
  json list = json::array();
  for (std::size_t i = from; i < picked.size(); ++i) list.push_back(with_queue_position(job_json(*picked[i], nullptr), positions));
  json body = {{plural, list}, {"count", list.size()}, {"total", total}};
  // The page of older ones, with the same filters.
  if (from > 0) {
    std::string next =
        std::string("/v1/") + plural + "?limit=" + std::to_string(static_cast<std::int64_t>(*limit)) + "&before=" + picked[from]->id;
    if (!state.empty()) next += "&state=" + state;
    if (!scene.empty()) next += "&scene=" + httplib::detail::encode_query_param(scene);
    body["next"] = next;
  }
  send_json(res, 200, body);
}

void delete_job(ApiContext& api, const Request& req, Response& res, JobKind kind) {
  auto job = job_for(api, req, res, kind);
  if (!job) return;
  const char* what = kind == JobKind::kRun ? "job" : kind_name(kind);
  // ?purge=true deletes a final job with its records and results; without it DELETE cancels, and never
  // deletes results (a cancel that races the run's end must not lose them).
  if (req.has_param("purge")) {
    const std::string v = req.get_param_value("purge");
    if (v != "true" && v != "1") return send_error(res, 400, "bad query", "", "query parameter 'purge' must be true or 1");
    if (!api.jobs.remove(job)) {
      if (is_deleted(*job)) return send_deleted(res);
      return send_error(res, 409, std::string(what) + " not finished", "",
                        std::string("the ") + what + " is " + to_string(state_of(*job)) +
                            "; cancel it (DELETE without purge), then purge it once it is final");
    }
    return send_json(res, 200, {{"id", job->id}, {"deleted", true}});
  }
  const auto outcome = api.jobs.cancel(job);
  // The status is read off the same snapshot as the body: a run can stop between the cancel and the
  // snapshot, and a 202 must never carry a final state. A run that ended done or failed before it saw
  // the request (its last steps raced the DELETE) was not cancelled: the job is finished (409).
  const json body = job_json(*job, nullptr);
  const std::string state = body.value("state", "");
  if (outcome == JobRunner::Cancel::kAlreadyFinished || state == "done" || state == "failed") {
    return send_error(res, 409, std::string(what) + " already finished", "",
                      std::string("the ") + what + " is " + state + " (DELETE ?purge=true deletes it with its results)");
  }
  // 200: cancelled (it was queued, or its run has already stopped); 202: cancelling, and cancelled once
  // its run stops.
  send_json(res, state == "cancelling" ? 202 : 200, body);
}

void prepare_run(ApiContext& api, Job& job, const json& doc, const StreamSettings& stream) {
  const ServerConfig& cfg = api.config;
  // The scene is compiled once; this server's limits then apply to the compiled simulation
  // (Simulation::with_limits), never by rewriting the scene.
  const scene::Simulation sim = scene::Simulation::from_json(doc);

  // Limits. Fixed steps are known now; for the adaptive rules (h their largest step) the count is a
  // lower bound, and the run gets this server's step limit as its max_steps.
  const auto* lag = sim.lagrangian();
  const bool fixed = !lag || lag->settings.step_rule == StepRule::kFixed;
  const std::int64_t planned = sim.planned_steps();
  scene::RunLimits limits;
  if (planned > cfg.max_steps) {
    throw BadRequest{400, "invalid scene", "/integrator/h",
                     "h = " + platform::significant(sim.h(), 10) + " over [" + platform::significant(sim.t0(), 10) + ", " +
                         platform::significant(sim.t_end(), 10) + "] needs " + (fixed ? "" : "at least ") + std::to_string(planned) +
                         " steps; this server runs at most " + std::to_string(cfg.max_steps) + " steps per job",
                     "scene"};
  }
  if (sim.max_steps() > cfg.max_steps) limits.max_steps = cfg.max_steps;
  const std::int64_t every = sim.output_every();
  const std::int64_t rows = planned / every + 2;
  if (rows > cfg.max_samples) {
    const std::int64_t need = (planned + cfg.max_samples - 3) / std::max<std::int64_t>(1, cfg.max_samples - 2);
    throw BadRequest{400, "invalid scene", "/output/every",
                     "the trajectory would have about " + std::to_string(rows) + " rows (" + std::to_string(planned) +
                         " steps, one row every " + std::to_string(every) + "); this server keeps at most " +
                         std::to_string(cfg.max_samples) + ": set /output/every to at least " + std::to_string(need),
                     "scene"};
  }
  // Bytes: rows times the widest row bounds the file.
  const std::int64_t row_bytes = max_trajectory_row_bytes(sim);
  if (rows > cfg.max_result_bytes / row_bytes) {
    const std::int64_t max_rows = std::max<std::int64_t>(3, cfg.max_result_bytes / row_bytes);
    const std::int64_t need = (planned + max_rows - 3) / std::max<std::int64_t>(1, max_rows - 2);
    throw BadRequest{422, "result too large", "/output/every",
                     "the trajectory could take about " + std::to_string(rows) + " rows of up to " + std::to_string(row_bytes) +
                         " bytes (" + std::to_string(rows / 1'000'000 * row_bytes) + " MB); this server stores at most " +
                         std::to_string(cfg.max_result_bytes) + " bytes per job: set /output/every to at least " + std::to_string(need),
                     "scene"};
  }
  // Streaming needs a sample at least once per period: sample the run more finely than the
  // trajectory's decimation if needed (the trajectory keeps the scene's own rows).
  std::int64_t engine_every = every;
  if (stream.enabled) {
    const std::int64_t per_period = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(stream.period / sim.h() + 1e-9)));
    if (every > per_period) {
      engine_every = std::gcd(every, per_period);
      limits.output_every = engine_every;
    }
  }

  if (stream.enabled) {
    try {
      api.hub.open();
    } catch (const std::exception& e) {
      throw BadRequest{503, "streaming is not available", "/stream", e.what(), "request"};
    }
  }

  job.scene_name = sim.name().empty() ? "scene" : sim.name();
  job.t0 = sim.t0();
  job.t_end = sim.t_end();
  job.t_now = sim.t0();
  job.planned_steps = planned;
  job.record_every = every;
  job.robot = lag && lag->compiled && lag->compiled->robot;
  job.stream = stream;
  if (stream.enabled) set_channels(job.stream, job.id);
  job.sim.emplace(sim.with_limits(limits));
}

void post_job(ApiContext& api, const Request&, Response& res, const std::string& text) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "stream", "strict"}, "{scene, overrides?, stream?, strict?}");
    const json doc = request_scene(api, body);
    if (body.contains("strict") && !body["strict"].is_boolean())
      throw BadRequest{400, "invalid request", "/strict", "expected true or false", "request"};

    // Streaming: true, or {"channel": PREFIX, "period": seconds, "realtime": bool}.
    StreamSettings stream;
    if (body.contains("stream")) {
      const json& s = body["stream"];
      if (s.is_boolean()) {
        stream.enabled = s.get<bool>();
      } else if (s.is_object()) {
        stream.enabled = true;
        for (const auto& [key, value] : s.items()) {
          const std::string ptr = "/stream/" + key;
          if (key == "channel") {
            if (!value.is_string() || !valid_channel_prefix(value.get<std::string>()))
              throw BadRequest{400, "invalid request", ptr,
                               "expected an UPPER_SNAKE channel prefix such as \"MOREAU\" ([A-Z][A-Z0-9_]*, at most 64)", "request"};
            stream.prefix = value.get<std::string>();
          } else if (key == "period") {
            if (!value.is_number() || !(value.get<double>() > 0) || !std::isfinite(value.get<double>()))
              throw BadRequest{400, "invalid request", ptr, "expected a positive number of simulation seconds", "request"};
            stream.period = value.get<double>();
          } else if (key == "realtime") {
            if (!value.is_boolean()) throw BadRequest{400, "invalid request", ptr, "expected true or false", "request"};
            stream.realtime = value.get<bool>();
          } else {
            throw BadRequest{400, "invalid request", ptr, "unknown field (expected channel, period, realtime)", "request"};
          }
        }
      } else {
        throw BadRequest{400, "invalid request", "/stream", "expected true or an object {channel?, period?, realtime?}", "request"};
      }
    }

    auto job = api.jobs.make_job();
    job->strict = body.contains("strict") && body["strict"].get<bool>();
    prepare_run(api, *job, doc, stream);
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    queue_and_answer(api, job, doc, nullptr, res);
  });
}

void job_report(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res);
  if (!job) return;
  send_result_file(req, res, *job, "report.json", "application/json", "no report yet", "");
}

void job_trajectory(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv" && format != "npy")
    return send_error(res, 400, "bad query", "", "format must be json, csv or npy");
  RowWindow window;
  try {
    if (auto from = number_param(req, "from", -1e300, 1e300)) window.from = *from;
    if (auto to = number_param(req, "to", -1e300, 1e300)) window.to = *to;
    if (auto every = number_param(req, "every", 1, 1e15)) {
      if (*every != std::floor(*every)) throw std::invalid_argument("query parameter 'every' must be a whole number of rows");
      window.every = static_cast<std::int64_t>(*every);
    }
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  if (window.from > window.to) return send_error(res, 400, "bad query", "", "query parameter 'from' is after 'to'");
  // Opened under the files lock; read piece by piece as the client takes it (bounded memory for any
  // length), from the open file even if the job is deleted meanwhile.
  auto reader = std::make_shared<TrajectoryReader>();
  std::string error;
  std::string identity;  // of the stored file and of the window asked for: the weak ETag's source
  {
    std::shared_lock files(job->files_mu);
    if (job->deleted) return send_deleted(res);
    if (!final_with(*job, &Job::has_trajectory)) {
      return send_error(res, 409, "no trajectory yet", "",
                        std::string("the job is ") + to_string(state_of(*job)) + "; the trajectory is served once it has finished");
    }
    const auto as = format == "csv"   ? TrajectoryReader::Format::kCsv
                    : format == "npy" ? TrajectoryReader::Format::kNpy
                                      : TrajectoryReader::Format::kJson;
    if (!reader->open((job->dir / "trajectory.csv").string(), window, as, &error))
      return send_error(res, 500, "stored trajectory unreadable", "", error);
    std::error_code ec;
    const auto size = fs::file_size(job->dir / "trajectory.csv", ec);
    const auto mtime = fs::last_write_time(job->dir / "trajectory.csv", ec);
    // Appended piece by piece: GCC 12 warns falsely on "literal" + std::string&& here (-Wrestrict, bug 105329).
    identity = job->id;
    for (const std::string& part : {std::to_string(size), std::to_string(mtime.time_since_epoch().count()), format,
                                    platform::shortest(window.from), platform::shortest(window.to), std::to_string(window.every)})
      identity.append("|").append(part);
  }
  if (not_modified(req, res, weak_etag(identity))) return;
  res.status = 200;
  if (format != "json") res.set_header("Content-Disposition", "attachment; filename=\"" + job->id + "." + format + "\"");
  // An .npy body is the array alone: its columns' names come in a header.
  if (format == "npy") res.set_header("Moreau-Columns", columns_header_value(reader->names()));
  const char* type = format == "csv" ? "text/csv" : format == "npy" ? "application/octet-stream" : "application/json";
  if (format == "npy") {
    // Converting text to doubles costs more than sending them: made ahead on a thread of its own.
    std::shared_ptr<TrajectoryPrefetcher> parts;
    try {
      parts = std::make_shared<TrajectoryPrefetcher>(reader);
    } catch (const std::system_error&) {  // no thread to be had: made as sent, like the other forms
    }
    if (parts) {
      res.set_chunked_content_provider(type, [parts](std::size_t, httplib::DataSink& sink) {
        std::string part;
        const bool more = parts->next(part);
        if (!part.empty() && !sink.write(part.data(), part.size())) return false;
        if (!more) sink.done();
        return true;
      });
      return;
    }
  }
  res.set_chunked_content_provider(type, [reader](std::size_t, httplib::DataSink& sink) {
    std::string part;
    const bool more = reader->next(part);
    if (!part.empty() && !sink.write(part.data(), part.size())) return false;
    if (!more) sink.done();
    return true;
  });
}

}  // namespace moreau::server
