#include "campaigns_routes.h"

#include <fstream>
#include <memory>
#include <shared_mutex>
#include <vector>

#include "job_access.h"
#include "moreau/analysis/campaign.h"
#include "moreau/scene/simulation.h"
#include "moreau/platform/number_text.h"
#include "responses.h"
#include "submission.h"

namespace moreau::server {

using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

namespace {

// A campaign's records on disk, at most: a bound on one record (its inputs, outcomes and final state;
// with full_report, the run's report too) times the samples, for the refusal at submission.
// run_campaign holds the run to the limit itself (CampaignRunOptions::max_bytes), whatever a record takes.
std::int64_t campaign_bytes_bound(const scene::CampaignSpec& spec, int dof) {
  std::int64_t per_record = 1024 + 64 * (2 * dof + static_cast<std::int64_t>(spec.inputs.size()));
  for (const auto& in : spec.inputs) per_record += 2 * static_cast<std::int64_t>(in.path.size());
  if (spec.full_report) per_record += 16384 + 1024 * dof;
  return per_record * spec.samples;
}

}  // namespace

void prepare_campaign(ApiContext& api, Job& job, const json& spec_doc) {
  const ServerConfig& cfg = api.config;
  const scene::Simulation sim = scene::Simulation::from_json(spec_doc.at("scene"));  // its errors: 400 invalid scene, at the scene's field
  // This server's sample limit first, whatever the number's form (1e12 is a float in JSON): the spec
  // reader's own limit is the command line's, far above it.
  if (spec_doc.contains("samples") && spec_doc["samples"].is_number() &&
      spec_doc["samples"].get<double>() > static_cast<double>(cfg.max_campaign_samples))
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     (spec_doc["samples"].is_number_float() ? platform::significant(spec_doc["samples"].get<double>(), 10)
                                                            : spec_doc["samples"].dump()) +
                         " samples; this server runs at most " + std::to_string(cfg.max_campaign_samples) +
                         " per campaign (run larger ones with moreau campaign, on one machine or a Slurm cluster)",
                     "request"};
  scene::CampaignSpec spec;
  try {
    spec = scene::CampaignSpec::from_json(spec_doc, "");
  } catch (const scene::SceneError& e) {
    throw BadRequest{400, "invalid request", "/campaign" + (e.pointer() == "/" ? std::string() : e.pointer()), e.reason(), "request"};
  }
  // Limits: the samples, the steps of each (a job's limit) and of all, the bytes of the records.
  if (spec.samples > cfg.max_campaign_samples)
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     std::to_string(spec.samples) + " samples; this server runs at most " + std::to_string(cfg.max_campaign_samples) +
                         " per campaign (run larger ones with moreau campaign, on one machine or a Slurm cluster)",
                     "request"};
  const std::int64_t planned = sim.planned_steps();
  if (planned > cfg.max_steps)
    throw BadRequest{400, "invalid scene", "/integrator/h",
                     "h = " + platform::significant(sim.h(), 10) + " over [" + platform::significant(sim.t0(), 10) + ", " +
                         platform::significant(sim.t_end(), 10) + "] needs " + std::to_string(planned) +
                         " steps per sample; this server runs at most " + std::to_string(cfg.max_steps) + " steps per run",
                     "scene"};
  if (planned > cfg.max_campaign_steps / spec.samples)
    throw BadRequest{400, "invalid request", "/campaign/samples",
                     std::to_string(spec.samples) + " samples of " + std::to_string(planned) + " steps each; this server runs at most " +
                         std::to_string(cfg.max_campaign_steps) + " steps per campaign",
                     "request"};
  // Each sample by its own settings: an input may be t_end, h or a parameter they use. Sample i's bound is
  // ceil((t_end - t0) / h) of its scene, capped by --max-steps (the runner stops a sample there); the
  // run itself stops at --max-campaign-steps whatever the samples take (job_runner).
  const scene::CampaignStepBound steps = scene::campaign_step_bound(spec, cfg.max_steps, cfg.max_campaign_steps);
  if (steps.total > cfg.max_campaign_steps) {
    const std::string pointer = steps.input >= 0 ? "/campaign/inputs/" + std::to_string(steps.input) : std::string("/campaign/samples");
    std::string values;
    if (steps.input >= 0) {
      const std::vector<json> drawn = scene::CampaignDesign(spec).values(steps.largest_sample);
      const std::string shown = drawn[static_cast<std::size_t>(steps.input)].dump();
      values = ", with " + spec.inputs[static_cast<std::size_t>(steps.input)].path + " = " +
               (shown.size() > 40 ? shown.substr(0, 37) + "..." : shown);
    }
    throw BadRequest{400, "invalid request", pointer,
                     "with their inputs applied, the samples need " + std::string(steps.stopped ? "more than " : "") +
                         std::to_string(steps.total) + " steps in all (sample " + std::to_string(steps.largest_sample) + values +
                         ", needs " + std::to_string(steps.largest) + "; the scene alone " + std::to_string(planned) +
                         " per sample); this server runs at most " + std::to_string(cfg.max_campaign_steps) + " steps per campaign",
                     "request"};
  }
  const std::int64_t bytes = campaign_bytes_bound(spec, sim.dof());
  if (bytes > cfg.max_result_bytes)
    throw BadRequest{422, "result too large", spec.full_report ? "/campaign/full_report" : "/campaign/samples",
                     "the records could take about " + std::to_string(bytes) + " bytes; this server stores at most " +
                         std::to_string(cfg.max_result_bytes) + " per campaign" +
                         (spec.full_report ? ": set full_report to false (each record then holds the outcomes without the run's report)"
                                           : ": run fewer samples"),
                     "request"};

  job.kind = JobKind::kCampaign;
  job.scene_name = sim.name().empty() ? "scene" : sim.name();
  job.t0 = sim.t0();
  job.t_end = sim.t_end();
  job.planned_steps = steps.total;
  job.rows_total = spec.samples;
  job.campaign.emplace(std::move(spec));
}

void post_campaign(ApiContext& api, const Request&, Response& res, const std::string& text) {
  answer_bad_requests(res, [&] {
    const json body = post_body(text, {"scene", "overrides", "campaign"}, "{scene, overrides?, campaign}");
    const json doc = request_scene(api, body);
    if (!body.contains("campaign"))
      throw BadRequest{400, "invalid request", "/campaign",
                       "missing required field 'campaign' (the uncertain inputs, the sampler and the samples: docs/campaigns.md)",
                       "request"};
    const json& fields = body["campaign"];
    if (!fields.is_object())
      throw BadRequest{400, "invalid request", "/campaign",
                       "expected an object {inputs, samples, sampler?, seed?, target?, map?, full_report?}", "request"};
    // The scene is the request's own (an object, or a shipped scene's name, with overrides): a path in the
    // spec would be a file on this machine.
    if (fields.contains("scene"))
      throw BadRequest{400, "invalid request", "/campaign/scene",
                       "the scene is the request's 'scene' (an object, or the name of a shipped scene), not a field of 'campaign'",
                       "request"};
    json spec_doc = fields;
    spec_doc["scene"] = doc;
    auto job = api.jobs.make_job();
    prepare_campaign(api, *job, spec_doc);
    const json stored = job->campaign->document;
    queue_and_answer(api, job, doc, &stored, res);
  });
}

void campaign_summary(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res, JobKind::kCampaign);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "json";
  if (format != "json" && format != "text") return send_error(res, 400, "bad query", "", "format must be json or text");
  send_result_file(req, res, *job, format == "text" ? "summary.txt" : "summary.json",
                   format == "text" ? "text/plain; charset=utf-8" : "application/json", "no summary yet",
                   "; the summary is served once every sample is done");
}

void campaign_samples(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res, JobKind::kCampaign);
  if (!job) return;
  const std::string format = req.has_param("format") ? req.get_param_value("format") : "csv";
  if (format != "csv" && format != "jsonl") return send_error(res, 400, "bad query", "", "format must be csv or jsonl");
  // Opened under the files lock, then sent piece by piece as the client takes it (bounded memory for
  // any size), from the open file even if the campaign is deleted meanwhile.
  auto in = std::make_shared<std::ifstream>();
  {
    std::shared_lock files(job->files_mu);
    if (job->deleted) return send_deleted(res);
    if (!final_with(*job, &Job::has_trajectory))
      return send_error(res, 409, "no samples yet", "",
                        std::string("the campaign is ") + to_string(state_of(*job)) +
                            "; its records are served once it has ended (GET it for its progress, or follow /events)");
    in->open(job->dir / (format == "csv" ? "samples.csv" : "samples.jsonl"), std::ios::binary);
    if (!*in) return send_error(res, 500, "stored samples unreadable");
  }
  res.status = 200;
  res.set_header("Content-Disposition", "attachment; filename=\"campaign-" + job->id + (format == "csv" ? ".csv\"" : ".jsonl\""));
  res.set_chunked_content_provider(format == "csv" ? "text/csv" : "application/jsonl", [in](std::size_t, httplib::DataSink& sink) {
    char buffer[1 << 16];
    in->read(buffer, sizeof buffer);
    const auto n = static_cast<std::size_t>(in->gcount());
    if (n > 0 && !sink.write(buffer, n)) return false;
    if (!*in) sink.done();
    return true;
  });
}

}  // namespace moreau::server
