#include "responses.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "conditional.h"
#include "moreau/platform/number_text.h"

namespace moreau::server {

using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

void send_json(Response& res, int status, const json& j) {
  res.status = status;
  res.set_content(j.dump(-1, ' ', false, json::error_handler_t::replace) + "\n", "application/json");
}

void send_error(Response& res, int status, const std::string& error, const std::string& pointer, const std::string& reason,
                const std::string& where) {
  json j = {{"error", error}};
  if (!pointer.empty()) j["pointer"] = pointer;
  if (!where.empty()) j["where"] = where;
  if (!reason.empty()) j["reason"] = reason;
  send_json(res, status, j);
}

bool not_modified(const Request& req, Response& res, const std::string& etag) {
  res.set_header("ETag", etag);
  if (!req.has_header("If-None-Match") || !if_none_match(req.get_header_value("If-None-Match"), etag)) return false;
  res.status = 304;
  return true;
}

void close_connection_after(Response& res) {
  if (auto* c = current_connection()) c->close_after = true;
  res.set_header("Connection", "close");
}

std::string no_endpoint(const Request& req) {
  return "no endpoint " + req.method.substr(0, 16) + " " + req.path.substr(0, 256) + "; see docs/api.md for the endpoints";
}

std::optional<double> number_param(const Request& req, const char* name, double lo, double hi) {
  if (!req.has_param(name)) return std::nullopt;
  // The whole value, as JSON spells numbers (std::from_chars: no hex, no leading space or '+', and a NUL
  // byte ends nothing: strtod read "600\0abc" as 600 and "\0" as 0).
  const std::string v = req.get_param_value(name);
  double d = 0.0;
  const auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), d, std::chars_format::general);
  if (v.empty() || ec != std::errc() || end != v.data() + v.size() || !std::isfinite(d) || d < lo || d > hi)
    throw std::invalid_argument(std::string("query parameter '") + name + "' must be a number in [" + platform::significant(lo, 10) + ", " +
                                platform::significant(hi, 10) + "]");
  return d;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string trim(std::string s) {
  const auto b = s.find_first_not_of(" \t");
  const auto e = s.find_last_not_of(" \t");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

}  // namespace moreau::server
