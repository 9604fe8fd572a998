// What the three submissions (POST /v1/jobs, /v1/studies, /v1/campaigns) share: the JSON body checked,
// the scene it names with its overrides applied, and the queueing of the validated job with its answer.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "api_context.h"
#include "job.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// The JSON object body of a POST: no NUL byte, nesting within scene::kMaxJsonDepth, valid JSON (400
// "malformed JSON"), an object whose fields are among `fields`, with "scene" (400 "invalid request");
// `shape` ("{scene, overrides?, stream?}") says what the object should be. Throws BadRequest.
nlohmann::json post_body(const std::string& text, const std::vector<std::string>& fields, const std::string& shape);

// The scene document of a request body: "scene" (an object, or the name of a shipped scene) with
// "overrides" applied, as `moreau run --set` applies them. Throws BadRequest or scene::SceneError.
nlohmann::json request_scene(const ApiContext& api, const nlohmann::json& body);

// Queues a validated job and answers: 202 with it and its Location, 429 with Retry-After when the queue
// is full, 503 while stopping, 507 if its records cannot be written (a full disk, say). `spec_doc`: a
// study's settings or a campaign's spec, stored beside its scene.
void queue_and_answer(ApiContext& api, const std::shared_ptr<Job>& job, const nlohmann::json& scene_doc, const nlohmann::json* spec_doc,
                      httplib::Response& res);

}  // namespace moreau::server
