// How the API answers, whatever the route: JSON bodies, error bodies ({"error", "pointer", "where",
// "reason"}), conditional answers (ETag, 304), the numbers of query parameters, and BadRequest, which a
// handler throws to answer 4xx from deep inside a submission.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "moreau/scene/scene.h"

// After Eigen (through the scene headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// Answers `status` with `j` as one line of JSON. Invalid UTF-8 (quoted from a request into an error
// message) is replaced by U+FFFD rather than making dump() throw.
void send_json(httplib::Response& res, int status, const nlohmann::json& j);

// Error bodies: {"error": what went wrong, "pointer": the JSON pointer of the field at fault, "where":
// "scene" (pointer into the scene) or "request" (pointer into the request body), "reason"}; the empty
// ones are left out.
void send_error(httplib::Response& res, int status, const std::string& error, const std::string& pointer = "",
                const std::string& reason = "", const std::string& where = "");

// Sets the ETag of a finished result, figure or static file, and answers 304 Not Modified (no body)
// when the request's If-None-Match already holds it; false if the answer is still to be given.
bool not_modified(const httplib::Request& req, httplib::Response& res, const std::string& etag);

// Ends the connection after this response: its request was answered without reading all of its body,
// so the bytes left on it cannot be read as a next request.
void close_connection_after(httplib::Response& res);

// The reason of a 404 for a path no endpoint serves: the method and path asked for (bounded).
std::string no_endpoint(const httplib::Request& req);

// A query parameter as a number in [lo, hi], or nullopt (absent); throws std::invalid_argument saying
// which and why.
std::optional<double> number_param(const httplib::Request& req, const char* name, double lo, double hi);

// ASCII lower case, and a copy without leading and trailing spaces and tabs (header values).
std::string lower(std::string s);
std::string trim(std::string s);

// A refusal thrown while a submission is read and checked, answered as send_error(status, error, pointer,
// reason, where) by answer_bad_requests.
struct BadRequest {
  int status;
  std::string error, pointer, reason, where;
};

// Runs a POST handler, answering what it throws: BadRequest as itself, scene::SceneError as 400 "invalid
// scene" with the pointer into the scene.
template <class Handler>
void answer_bad_requests(httplib::Response& res, Handler&& handle) {
  try {
    handle();
  } catch (const BadRequest& e) {
    send_error(res, e.status, e.error, e.pointer, e.reason, e.where);
  } catch (const scene::SceneError& e) {
    send_error(res, 400, "invalid scene", e.pointer(), e.reason(), "scene");
  }
}

}  // namespace moreau::server
