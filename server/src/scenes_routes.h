// The shipped scenes: GET /v1/scenes (their names, titles and descriptions) and GET /v1/scenes/{name}
// (the document), read from --scenes-dir; a submission names one by its name (submission.h).
#pragma once

#include <filesystem>
#include <map>
#include <string>

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// The scene files of the scenes directory: name (file stem) -> path. Names come from the listing, never
// from the request.
std::map<std::string, std::filesystem::path> scene_files(const ServerConfig& config);

void list_scenes(ApiContext& api, const httplib::Request& req, httplib::Response& res);
void get_scene(ApiContext& api, const httplib::Request& req, httplib::Response& res);

}  // namespace moreau::server
