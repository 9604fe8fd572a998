// Robustness campaigns (docs/campaigns.md) over the API: the submission (POST /v1/campaigns), the summary
// (JSON or text) and the samples' records (CSV or JSON lines, streamed). Their figures are in
// figures_routes.h; the rest of the collection (get, list, cancel, events) is the jobs' own
// (jobs_routes.h, events_routes.h).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "api_context.h"
#include "job.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// POST /v1/campaigns: {scene, overrides?, campaign}.
void post_campaign(ApiContext& api, const httplib::Request& req, httplib::Response& res, const std::string& body);

// A campaign's validated spec and fields from its spec with the scene inlined, within this server's
// limits (samples, steps per sample and in all, bytes of the records): at submission, and again for a
// campaign a restarted server takes up (server.cc). Throws BadRequest or scene::SceneError.
void prepare_campaign(ApiContext& api, Job& job, const nlohmann::json& spec_doc);

void campaign_summary(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void campaign_samples(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
