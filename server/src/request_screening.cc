#include "request_screening.h"

#include <algorithm>
#include <cstdint>

#include "responses.h"
#include "routes.h"

namespace moreau::server {

using httplib::Request;
using httplib::Response;

bool constant_time_equal(const std::string& given, const std::string& secret) {
  volatile unsigned char diff = given.size() != secret.size() ? 1 : 0;
  for (std::size_t i = 0; i < secret.size(); ++i) {
    const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
    diff = static_cast<unsigned char>(diff | (g ^ static_cast<unsigned char>(secret[i])));
  }
  return diff == 0;
}

void send_body_too_large(const ServerConfig& config, Response& res) {
  close_connection_after(res);
  send_error(res, 413, "request body too large", "",
             "this server accepts bodies of at most " + std::to_string(config.max_body_bytes) +
                 " bytes (counted after Content-Encoding is decoded)");
}

bool screen(const ApiContext& api, const Request& req, Response& res) {
  const ServerConfig& cfg = api.config;
  auto refuse = [&](int status, const std::string& error, const std::string& reason) {
    close_connection_after(res);
    send_error(res, status, error, "", reason);
    return true;
  };
  // Framing (RFC 9112 section 6): a request with both, or with two lengths, can be read two ways by two
  // servers in a row (request smuggling), so it is refused, not interpreted.
  const std::size_t te = req.headers.count("Transfer-Encoding"), cl = req.headers.count("Content-Length");
  if (te > 0 && cl > 0) return refuse(400, "bad request framing", "both Transfer-Encoding and Content-Length are given");
  if (cl > 1) return refuse(400, "bad request framing", "Content-Length is given more than once");
  if (te > 1 || (te == 1 && lower(trim(req.get_header_value("Transfer-Encoding"))) != "chunked"))
    return refuse(400, "bad request framing", "the only Transfer-Encoding accepted is chunked");
  std::optional<std::uint64_t> length;
  if (cl == 1) {
    const std::string v = trim(req.get_header_value("Content-Length"));
    if (v.empty() || v.size() > 19 || !std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return refuse(400, "bad request framing", "Content-Length is not a decimal number");
    length = std::stoull(v);
  }

  // CORS (--cors-origin): a request from the configured origin gets its answer marked readable by that
  // origin, errors included (a page must be able to read why); a preflight is answered here, before the
  // token, since browsers send preflights without credentials. Off by default: no header at all.
  // Origins compare without case (browsers send scheme and host in lower case). An answer that depends on
  // the Origin says so (Vary) to every client, so that a cache never serves one origin's answer to another.
  const std::string origin = req.get_header_value("Origin");
  const bool cors = !cfg.cors_origin.empty() && !origin.empty() && (cfg.cors_origin == "*" || lower(origin) == lower(cfg.cors_origin));
  if (!cfg.cors_origin.empty() && cfg.cors_origin != "*") res.set_header("Vary", "Origin");
  if (cors) {
    res.set_header("Access-Control-Allow-Origin", cfg.cors_origin == "*" ? std::string("*") : origin);
    res.set_header("Access-Control-Expose-Headers", "Location, Retry-After, ETag, WWW-Authenticate, Moreau-Columns");
    if (req.method == "OPTIONS" && req.has_header("Access-Control-Request-Method")) {
      const std::string allow = allowed_methods(req.path);
      if (allow.empty()) return refuse(404, "not found", no_endpoint(req));
      res.status = 204;
      res.set_header("Allow", allow);
      res.set_header("Access-Control-Allow-Methods", allow);
      res.set_header("Access-Control-Allow-Headers", "Authorization, Content-Type, Content-Encoding, Last-Event-ID, If-None-Match");
      res.set_header("Access-Control-Max-Age", "600");
      return true;
    }
  }

  // Open without the token: the health check, and the web page's static files (they hold no data; the
  // page asks for the token and sends it with every API request).
  if (!cfg.token.empty() && !is_open_path(req.path)) {
    const std::string auth = req.get_header_value("Authorization");
    const std::string prefix = "Bearer ";
    const bool ok = auth.size() > prefix.size() && lower(auth.substr(0, prefix.size())) == "bearer " &&
                    constant_time_equal(trim(auth.substr(prefix.size())), cfg.token);
    if (!ok) {
      res.set_header("WWW-Authenticate", "Bearer realm=\"moreau\"");
      return refuse(401, auth.empty() ? "authentication required" : "invalid token", "send the header 'Authorization: Bearer TOKEN'");
    }
  }

  const bool has_body = te == 1 || (length && *length > 0);
  // No route takes PUT or PATCH: answered before any body is read.
  if (req.method == "PUT" || req.method == "PATCH") {
    if (const std::string allow = allowed_methods(req.path); !allow.empty()) {
      close_connection_after(res);
      send_method_not_allowed(res, req.method, req.path, allow);
      return true;
    }
    return refuse(404, "not found", no_endpoint(req));
  }
  // A query parameter the path does not read is refused, not ignored (format=svg on a server that only
  // drew PNG returned a PNG).
  if (const std::string why = unknown_query_parameter(req); !why.empty()) {
    if (has_body) close_connection_after(res);
    send_error(res, 400, "bad query", "", why);
    return true;
  }
  // OPTIONS: which methods a path takes, without a body.
  if (req.method == "OPTIONS") {
    if (has_body) return refuse(400, "unexpected body", "OPTIONS requests take no body");
    const std::string allow = allowed_methods(req.path);
    if (allow.empty()) return refuse(404, "not found", no_endpoint(req));
    res.status = 204;
    res.set_header("Allow", allow);
    return true;
  }
  if (req.method != "POST") {
    if (has_body) return refuse(400, "unexpected body", req.method + " requests take no body");
    // No body, and httplib reads one for some methods unless told its length: it is 0 (RFC 9112 6.3).
    if (cl == 0) const_cast<Request&>(req).headers.emplace("Content-Length", "0");
    return false;
  }
  if (te == 0 && cl == 0) return refuse(411, "length required", "send the body with Content-Length or Transfer-Encoding: chunked");
  const std::string type_header = req.get_header_value("Content-Type");
  const std::string content_type = lower(trim(type_header.substr(0, type_header.find(';'))));
  if (content_type != "application/json")
    return refuse(415, "unsupported content type", "POST " + req.path + " takes application/json, got '" + type_header + "'");
  const std::string encoding = lower(trim(req.get_header_value("Content-Encoding")));
  if (!encoding.empty() && encoding != "identity" && encoding != "gzip" && encoding != "deflate")
    return refuse(415, "unsupported content encoding", "Content-Encoding may be gzip, deflate or identity, got '" + encoding + "'");
  if (length && *length > cfg.max_body_bytes) {
    send_body_too_large(cfg, res);
    return true;
  }
  return false;
}

std::optional<std::string> read_body(const ApiContext& api, Response& res, const httplib::ContentReader& reader) {
  const ServerConfig& cfg = api.config;
  std::string body;
  bool over = false;
  // Decoded bytes are counted as they come: a compressed body stops expanding at the limit.
  const bool ok = reader([&](const char* data, std::size_t n) {
    if (body.size() + n > cfg.max_body_bytes) {
      over = true;
      return false;
    }
    body.append(data, n);
    return true;
  });
  if (ok) return body;
  ConnectionContext* conn = current_connection();
  close_connection_after(res);
  if (over || (conn && conn->too_large)) {
    send_body_too_large(cfg, res);
  } else if (conn && conn->timed_out) {
    send_error(res, 408, "request timeout", "", "the body did not arrive within " + std::to_string(cfg.body_timeout_ms) + " ms");
  } else {
    send_error(res, 400, "bad request body", "", "the body could not be read (broken chunked framing or content encoding)");
  }
  return std::nullopt;
}

}  // namespace moreau::server
