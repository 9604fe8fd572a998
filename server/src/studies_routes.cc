#include "studies_routes.h"

#include <algorithm>
#include <chrono>

#include "job_access.h"
#include "responses.h"
#include "submission.h"

namespace moreau::server {

using json = nlohmann::json;
using httplib::Request;
using httplib::Response;
using Clock = std::chrono::steady_clock;

scene::StudySettings study_settings_at(const json& fields) {
  try {
    return scene::study_settings_from_json(fields, "/study");
  } catch (const scene::SceneError& e) {
    throw BadRequest{400, "invalid request", e.pointer(), e.reason(), "request"};
  }
}

void prepare_study(ApiContext& api, Job& job, const json& doc, scene::StudySettings st) {
  const ServerConfig& cfg = api.config;
  // A Lur'e scene is refused here at /system/type, a constrained one by the check below.
  scene::LagrangianScene sc = scene::load_scene(doc);
  if (!sc.constraint_names.empty()) {
    throw BadRequest{400, "invalid scene", "/system/constraints",
                     "studies compare abl, explicit and regularized, which do not integrate unilateral constraints", "scene"};
  }
  const std::int64_t planned = scene::study_planned_steps(sc, st);
  if (planned > cfg.max_steps) {
    throw BadRequest{400, "invalid request", "/study/h",
                     "this study takes about " + std::to_string(planned) + " integration steps over all its runs (" +
                         std::to_string(st.schemes.size()) + " schemes, " + std::to_string(st.h.size()) + " step sizes, 1 + " +
                         std::to_string(st.repeats) + " runs each); this server runs at most " + std::to_string(cfg.max_steps) +
                         " steps per job: use larger step sizes, fewer schemes or fewer repeats",
                     "request"};
  }
  // The study's own checks (every h and the reference h positive, finite, within the interval and the
  // scene's step limit; an exact solution finite on the grid), at submission rather than in the run:
  // their option names (--reference-h) become pointers into the request (/study/reference_h).
  try {
    scene::check_study_settings(sc, st);
  } catch (const scene::SceneError& e) {
    std::string pointer = e.pointer();
    if (pointer.rfind("--", 0) != 0) throw;
    pointer = "/study/" + pointer.substr(2);
    std::replace(pointer.begin(), pointer.end(), '-', '_');
    throw BadRequest{400, "invalid request", pointer, e.reason(), "request"};
  }
  // Adaptive step rules may take more steps than planned: each run gets this server's limit.
  sc.settings.max_steps = std::min<std::int64_t>(sc.settings.max_steps, cfg.max_steps);

  job.kind = JobKind::kStudy;
  job.scene_name = sc.name.empty() ? "scene" : sc.name;
  job.t0 = sc.settings.t0;
  job.t_end = sc.settings.t_end;
  job.planned_steps = planned;
  job.rows_total = static_cast<std::int64_t>(st.schemes.size() * st.h.size());
  job.study = std::move(st);
  job.study_scene.emplace(std::move(sc));
}

void post_study(ApiContext& api, const Request&, Response& res, const std::string& text) {
  const auto t_load = Clock::now();
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "study"}, "{scene, overrides?, study?}");
    const json doc = request_scene(api, body);
    auto job = api.jobs.make_job();
    prepare_study(api, *job, doc, study_settings_at(body.contains("study") ? body["study"] : json()));
    job->load_seconds = std::chrono::duration<double>(Clock::now() - t_load).count();

    const json settings = scene::study_settings_to_json(job->study);
    queue_and_answer(api, job, doc, &settings, res);
  });
}

void study_table(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res, JobKind::kStudy);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "csv") return send_error(res, 400, "bad query", "", "format must be json or csv");
  send_result_file(req, res, *job, format == "csv" ? "table.csv" : "result.json", format == "csv" ? "text/csv" : "application/json",
                   "no table yet", "; the table is served once it is done", format == "csv" ? "study-" + job->id + ".csv" : "");
}

}  // namespace moreau::server
