// The API's one route table: every operation (method, path, handler) with its identity in the OpenAPI
// document (server/openapi.json: the path as the document writes it, the operationId, the query
// parameters it reads, whether it needs the token). Everything that depends on which routes exist is
// derived from it, so that no second list can drift:
//   - the router (register_routes: one httplib handler per route, its regular expression made from the
//     path);
//   - the Allow header of a 405 and of an OPTIONS answer (allowed_methods: HEAD wherever GET is, OPTIONS
//     everywhere);
//   - the 400 for a query parameter the operation does not read (unknown_query_parameter);
//   - the paths open without the token (is_open_path).
// ServerRoutes.TableIsTheOpenApiDocument (tests/server/server_routes_test.cc) holds the table and the document
// to each other, both ways.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

enum class Method { kGet, kPost, kDelete };
// Whether an operation needs the token (--token), or is open (the document's `security: []`).
enum class Access { kToken, kOpen };
// "GET", "POST", "DELETE".
const char* method_name(Method method);

// A GET (also serving HEAD) or DELETE handler.
using Handler = void (*)(ApiContext& api, const httplib::Request& req, httplib::Response& res);
// A POST handler, called with the request's body once it is read and decoded (read_body,
// request_screening.h).
using BodyHandler = void (*)(ApiContext& api, const httplib::Request& req, httplib::Response& res, const std::string& body);

struct Route {
  Method method;
  // The path as the OpenAPI document writes it: "/v1/jobs/{id}/events". A "{name}" segment is any one
  // non-empty segment, given to the handler as req.matches[1].
  std::string_view path;
  std::string_view operation_id;  // the document's operationId
  // The query parameters the operation reads, in the document's order (a POST reads none): any other is
  // refused with 400 before the handler runs.
  std::vector<std::string_view> query = {};
  Access access = Access::kToken;
  Handler handler = nullptr;           // GET and DELETE
  BodyHandler body_handler = nullptr;  // POST
};

// Every operation of the API, in the order of server/openapi.json.
const std::vector<Route>& api_routes();

// Whether `path` matches a route's `pattern` segment by segment ("{...}": any one non-empty segment). No
// regular expressions: this runs for every request, before routing.
bool path_matches(std::string_view path, std::string_view pattern);

// The regular expression httplib routes `pattern` by: literal text escaped, "{...}" as "([^/]+)".
std::string route_regex(std::string_view pattern);

// The methods `path` takes, as the Allow header lists them ("GET, HEAD, POST, OPTIONS"), or "" for a path
// no route serves.
std::string allowed_methods(std::string_view path);

// Whether `path` is served without the token (the health check and the web page's static files).
bool is_open_path(std::string_view path);

// The first query parameter of the request that its operation does not read, with why, or "" if none (or
// if no route serves its path). A method the path does not take reads none.
std::string unknown_query_parameter(const httplib::Request& req);

// 405 for a path that exists under other methods, with the Allow header (RFC 9110 15.5.6).
void send_method_not_allowed(httplib::Response& res, const std::string& method, const std::string& path, const std::string& allow);

// Registers every route of api_routes() on `http`, and last a POST catch-all that answers 405 or 404
// without reading the body.
void register_routes(GuardedHttpServer& http, ApiContext& api);

}  // namespace moreau::server
