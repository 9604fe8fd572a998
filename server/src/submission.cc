#include "submission.h"

#include <algorithm>

#include "job_access.h"
#include "moreau/scene/scene.h"
#include "responses.h"
#include "scenes_routes.h"

namespace moreau::server {

using json = nlohmann::json;
using httplib::Response;

namespace {

// scene::apply_override, with an error about the override itself (not of the form PATH=VALUE, a path too
// deep: pointer "/") reported at `pointer` in the request; errors about the scene path keep theirs.
void apply_request_override(json& doc, const std::string& assignment, const std::string& pointer) {
  try {
    scene::apply_override(doc, assignment);
  } catch (const scene::SceneError& e) {
    if (e.pointer() == "/") throw BadRequest{400, "invalid request", pointer, e.reason(), "request"};
    throw;
  }
}

}  // namespace

json post_body(const std::string& text, const std::vector<std::string>& fields, const std::string& shape) {
  // JSON text never holds a raw NUL (RFC 8259 escapes control characters): a NUL is a sign of a binary or
  // truncated upload, and would cut C strings made from the scene.
  if (const auto nul = text.find('\0'); nul != std::string::npos)
    throw BadRequest{400, "malformed JSON", "", "the body holds a NUL byte at offset " + std::to_string(nul), "request"};
  // Bounded nesting before parsing: the JSON library copies and prints recursively.
  if (const auto at = scene::json_depth_exceeded(text)) {
    throw BadRequest{400, "malformed JSON", "",
                     "nested deeper than " + std::to_string(scene::kMaxJsonDepth) + " levels at byte " + std::to_string(*at), "request"};
  }
  json body = json::parse(text, nullptr, false);
  if (body.is_discarded()) {
    std::string why = "the body is not valid JSON";
    try {
      const json ignored = json::parse(text);
    } catch (const json::exception& e) {  // parse_error, and out_of_range for a number such as 1e999
      why = e.what();
    }
    throw BadRequest{400, "malformed JSON", "", why, "request"};
  }
  if (!body.is_object()) throw BadRequest{400, "invalid request", "", "the body must be an object " + shape, "request"};
  std::string expected;
  for (const auto& f : fields) expected += (expected.empty() ? "" : ", ") + f;
  for (const auto& [key, value] : body.items()) {
    if (std::find(fields.begin(), fields.end(), key) == fields.end())
      throw BadRequest{400, "invalid request", "/" + key, "unknown field (expected " + expected + ")", "request"};
  }
  if (!body.contains("scene")) throw BadRequest{400, "invalid request", "/scene", "missing required field 'scene'", "request"};
  return body;
}

json request_scene(const ApiContext& api, const json& body) {
  // The scene: a document, or the name of a shipped scene.
  json doc;
  const json& scene = body["scene"];
  if (scene.is_object()) {
    doc = scene;
  } else if (scene.is_string()) {
    const auto files = scene_files(api.config);
    auto it = files.find(scene.get<std::string>());
    if (it == files.end())
      throw BadRequest{400, "invalid request", "/scene", "no shipped scene by that name (GET /v1/scenes lists them)", "request"};
    doc = scene::read_scene_file(it->second.string());
  } else {
    throw BadRequest{400, "invalid request", "/scene", "expected a scene object or the name of a shipped scene", "request"};
  }

  // Overrides, as `moreau run --set`: ["integrator.h=1e-4", ...] or {"integrator.h": 1e-4, ...}.
  if (body.contains("overrides")) {
    const json& o = body["overrides"];
    if (o.is_array()) {
      for (std::size_t i = 0; i < o.size(); ++i) {
        if (!o[i].is_string())
          throw BadRequest{400, "invalid request", "/overrides/" + std::to_string(i), "expected a string PATH=VALUE", "request"};
        apply_request_override(doc, o[i].get<std::string>(), "/overrides/" + std::to_string(i));
      }
    } else if (o.is_object()) {
      for (const auto& [path, value] : o.items())
        apply_request_override(doc, path + "=" + value.dump(), "/overrides/" + scene::json_pointer_token(path));
    } else {
      throw BadRequest{400, "invalid request", "/overrides", "expected an array of \"PATH=VALUE\" or an object {PATH: VALUE}", "request"};
    }
  }
  return doc;
}

void queue_and_answer(ApiContext& api, const std::shared_ptr<Job>& job, const json& scene_doc, const json* spec_doc, Response& res) {
  int retry_after = 1;
  JobRunner::Submit outcome;
  try {
    outcome = api.jobs.submit(job, scene_doc, &retry_after, spec_doc);
  } catch (const std::exception& e) {
    return send_error(res, 507, "cannot store the job", "", e.what());
  }
  switch (outcome) {
    case JobRunner::Submit::kQueued: break;
    case JobRunner::Submit::kQueueFull:
      res.set_header("Retry-After", std::to_string(retry_after));
      return send_error(
          res, 429, "queue full", "",
          "the server holds " + std::to_string(api.config.queue) + " queued jobs at most; retry in " + std::to_string(retry_after) + " s");
    case JobRunner::Submit::kStopping: return send_error(res, 503, "server stopping");
  }
  const json j = with_queue_position(job_json(*job, nullptr), api.jobs.queue_positions());
  res.set_header("Location", j["url"].get<std::string>());
  send_json(res, 202, j);
}

}  // namespace moreau::server
