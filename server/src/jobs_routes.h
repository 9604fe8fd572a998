// The job collections, /v1/jobs, /v1/studies and /v1/campaigns alike (one JobKind each): a job by id
// (with ?wait, a long poll until it is final), the list (filtered by state and scene, paged by a cursor),
// and DELETE (cancel; with ?purge, delete a final job and its results). And what only runs have: the
// submission (POST /v1/jobs), the report and the trajectory.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "api_context.h"
#include "job.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

void get_job(ApiContext& api, const httplib::Request& req, httplib::Response& res, JobKind kind);
void list_jobs(ApiContext& api, const httplib::Request& req, httplib::Response& res, JobKind kind);
void delete_job(ApiContext& api, const httplib::Request& req, httplib::Response& res, JobKind kind);

// POST /v1/jobs: {scene, overrides?, stream?, strict?}.
void post_job(ApiContext& api, const httplib::Request& req, httplib::Response& res, const std::string& body);
// A run's compiled scene and fields from its scene document, within this server's limits (steps, rows,
// bytes), with the LCM hub opened if it streams: at submission, and again for a run a restarted server
// takes up (server.cc). Throws BadRequest or scene::SceneError.
void prepare_run(ApiContext& api, Job& job, const nlohmann::json& doc, const StreamSettings& stream);

void job_report(ApiContext& api, const httplib::Request& req, httplib::Response& res);
// The trajectory as JSON or CSV, optionally a window of it (from, to, every), streamed from the stored
// file with a weak ETag.
void job_trajectory(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
