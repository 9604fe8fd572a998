// What every request passes before its handler: its framing, CORS, the token, the methods and query
// parameters its path takes (routes.h), and whether a body may come at all (only POST takes one, as
// application/json, announced within the limit). And the reading of a POST's body, bounded as decoded.
#pragma once

#include <optional>
#include <string>

#include "api_context.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// Runs once a request's headers are read, before any of its body is (and before a 100 Continue is
// sent). Answers a request that is refused here, marking its connection to be closed when its body would
// go unread, and returns true; false if the request may go on to its handler.
bool screen(const ApiContext& api, const httplib::Request& req, httplib::Response& res);

// The body of a POST, decoded, or nullopt after answering 413 (over --max-body-bytes as decoded), 408
// (too slow) or 400 (broken framing or encoding).
std::optional<std::string> read_body(const ApiContext& api, httplib::Response& res, const httplib::ContentReader& reader);

// 413 for a body over --max-body-bytes; the connection closes after it.
void send_body_too_large(const ServerConfig& config, httplib::Response& res);

// Compares in time that depends on the secret's length only, not on where the strings differ.
bool constant_time_equal(const std::string& given, const std::string& secret);

}  // namespace moreau::server
