// The files served as they are, compiled in (embedded_files.h): the web page (server/web/: GET /,
// /ui/app.js, /ui/robot3d.js, /ui/style.css, and three.js from Debian's libjs-three at /ui/three.min.js
// and /ui/OrbitControls.js; open without the token, the page asks for it) and the OpenAPI document
// (GET /v1/openapi.json). Each with its strong ETag, so that a browser's repeated request is a 304.
#pragma once

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

void web_page(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void web_page_script(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void web_page_style(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void web_page_robot3d(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void web_page_three(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void web_page_orbit_controls(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void openapi(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
