// The service's own state: GET /healthz (200 while serving, 503 while stopping; open without the token)
// and GET /metrics (Prometheus text: jobs by state, the queue and the workers, steps and integration time,
// LCM messages, HTTP connections and answers by status).
#pragma once

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

void health(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void metrics(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
