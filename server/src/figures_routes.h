// The figures of finished jobs: GET /v1/jobs/{id}/figure (from the trajectory), /v1/studies/{id}/figure
// (from the table) and /v1/campaigns/{id}/figure (from the records). Each takes ?kind= (figure_kind.h),
// ?width=, ?height= and ?format= (png or svg); at the default size the image is cached beside the job's
// results. At most --figures-at-once are drawn at once; 501 on a server built without render/.
#pragma once

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

void job_figure(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void study_figure(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void campaign_figure(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
