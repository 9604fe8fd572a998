// Studies (docs/studies.md) over the API: the submission (POST /v1/studies) and the table
// (/v1/studies/{id}/table, JSON or CSV). Their figures are in figures_routes.h; the rest of the
// collection (get, list, cancel, events) is the jobs' own (jobs_routes.h, events_routes.h).
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "api_context.h"
#include "job.h"
#include "moreau/analysis/study.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// POST /v1/studies: {scene, overrides?, study?}.
void post_study(ApiContext& api, const httplib::Request& req, httplib::Response& res, const std::string& body);

// The study settings of a request's "study" or of a stored study.json, their errors at /study. Throws
// BadRequest.
scene::StudySettings study_settings_at(const nlohmann::json& fields);

// A study's compiled scene and fields from its scene document and settings, within this server's limits:
// at submission, and again for a study a restarted server takes up (server.cc). Throws BadRequest or
// scene::SceneError.
void prepare_study(ApiContext& api, Job& job, const nlohmann::json& doc, scene::StudySettings settings);

void study_table(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
