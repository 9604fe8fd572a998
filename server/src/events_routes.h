// A job's events as a server-sent event stream: GET /v1/jobs/{id}/events, and the same of studies and
// campaigns. Resumes after a Last-Event-ID the job has issued; sends a comment every 15 s while nothing
// happens; ends once the job is final and every event is sent. Each stream holds a place of --max-waiting.
#pragma once

#include "api_context.h"
#include "job.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

void job_events(ApiContext& api, const httplib::Request& req, httplib::Response& res, JobKind kind);

}  // namespace moreau::server
