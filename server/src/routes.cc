#include "routes.h"

#include <algorithm>

#include "campaigns_routes.h"
#include "events_routes.h"
#include "figures_routes.h"
#include "jobs_routes.h"
#include "kinematics_routes.h"
#include "metrics.h"
#include "request_screening.h"
#include "responses.h"
#include "scenes_routes.h"
#include "static_page.h"
#include "studies_routes.h"

namespace moreau::server {

using httplib::Request;
using httplib::Response;

namespace {

// A handler of one job kind: the collections /v1/jobs, /v1/studies and /v1/campaigns share theirs.
template <void (*handle)(ApiContext&, const Request&, Response&, JobKind), JobKind kind>
void of_kind(ApiContext& api, const Request& req, Response& res) {
  handle(api, req, res, kind);
}

constexpr JobKind kRun = JobKind::kRun, kStudy = JobKind::kStudy, kCampaign = JobKind::kCampaign;
constexpr Access kOpen = Access::kOpen, kToken = Access::kToken;

}  // namespace

const char* method_name(Method method) {
  switch (method) {
    case Method::kGet: return "GET";
    case Method::kPost: return "POST";
    case Method::kDelete: return "DELETE";
  }
  return "GET";
}

const std::vector<Route>& api_routes() {
  using M = Method;
  static const std::vector<std::string_view> kList = {"state", "scene", "limit", "before"}, kWait = {"wait"}, kPurge = {"purge"},
                                             kFigure = {"kind", "width", "height", "format"}, kFormat = {"format"},
                                             kJobFigure = {"kind", "width", "height", "format", "robust_y"};
  static const std::vector<Route> routes = {
      // The web page (server/web/), the health check, the metrics, the API's description, the shipped scenes.
      {M::kGet, "/", "webPage", {}, kOpen, web_page},
      {M::kGet, "/ui/app.js", "webPageScript", {}, kOpen, web_page_script},
      {M::kGet, "/ui/robot3d.js", "webPageRobot3D", {}, kOpen, web_page_robot3d},
      {M::kGet, "/ui/style.css", "webPageStyle", {}, kOpen, web_page_style},
      {M::kGet, "/ui/three.min.js", "webPageThree", {}, kOpen, web_page_three},
      {M::kGet, "/ui/OrbitControls.js", "webPageOrbitControls", {}, kOpen, web_page_orbit_controls},
      {M::kGet, "/healthz", "health", {}, kOpen, health},
      {M::kGet, "/metrics", "metrics", {}, kToken, metrics},
      {M::kGet, "/v1/openapi.json", "openapi", {}, kToken, openapi},
      {M::kGet, "/v1/scenes", "listScenes", {}, kToken, list_scenes},
      {M::kGet, "/v1/scenes/{name}", "getScene", {}, kToken, get_scene},
      // Runs.
      {M::kGet, "/v1/jobs", "listJobs", kList, kToken, of_kind<list_jobs, kRun>},
      {M::kPost, "/v1/jobs", "submitJob", {}, kToken, nullptr, post_job},
      {M::kGet, "/v1/jobs/{id}", "getJob", kWait, kToken, of_kind<get_job, kRun>},
      {M::kDelete, "/v1/jobs/{id}", "cancelJob", kPurge, kToken, of_kind<delete_job, kRun>},
      {M::kGet, "/v1/jobs/{id}/events", "jobEvents", {}, kToken, of_kind<job_events, kRun>},
      {M::kGet, "/v1/jobs/{id}/report", "getReport", {}, kToken, job_report},
      {M::kGet, "/v1/jobs/{id}/trajectory", "getTrajectory", {"format", "from", "to", "every"}, kToken, job_trajectory},
      {M::kGet, "/v1/jobs/{id}/kinematics", "getKinematics", {"t", "from", "to", "max_samples"}, kToken, job_kinematics},
      {M::kGet, "/v1/jobs/{id}/figure", "getJobFigure", kJobFigure, kToken, job_figure},
      // Studies.
      {M::kGet, "/v1/studies", "listStudies", kList, kToken, of_kind<list_jobs, kStudy>},
      {M::kPost, "/v1/studies", "submitStudy", {}, kToken, nullptr, post_study},
      {M::kGet, "/v1/studies/{id}", "getStudy", kWait, kToken, of_kind<get_job, kStudy>},
      {M::kDelete, "/v1/studies/{id}", "cancelStudy", kPurge, kToken, of_kind<delete_job, kStudy>},
      {M::kGet, "/v1/studies/{id}/events", "studyEvents", {}, kToken, of_kind<job_events, kStudy>},
      {M::kGet, "/v1/studies/{id}/table", "getStudyTable", kFormat, kToken, study_table},
      {M::kGet, "/v1/studies/{id}/figure", "getStudyFigure", kFigure, kToken, study_figure},
      // Campaigns.
      {M::kGet, "/v1/campaigns", "listCampaigns", kList, kToken, of_kind<list_jobs, kCampaign>},
      {M::kPost, "/v1/campaigns", "submitCampaign", {}, kToken, nullptr, post_campaign},
      {M::kGet, "/v1/campaigns/{id}", "getCampaign", kWait, kToken, of_kind<get_job, kCampaign>},
      {M::kDelete, "/v1/campaigns/{id}", "cancelCampaign", kPurge, kToken, of_kind<delete_job, kCampaign>},
      {M::kGet, "/v1/campaigns/{id}/events", "campaignEvents", {}, kToken, of_kind<job_events, kCampaign>},
      {M::kGet, "/v1/campaigns/{id}/summary", "getCampaignSummary", kFormat, kToken, campaign_summary},
      {M::kGet, "/v1/campaigns/{id}/samples", "getCampaignSamples", kFormat, kToken, campaign_samples},
      {M::kGet, "/v1/campaigns/{id}/figure", "getCampaignFigure", kFigure, kToken, campaign_figure},
  };
  return routes;
}

bool path_matches(std::string_view path, std::string_view pattern) {
  if (path == pattern) return true;  // "/" included, whose one segment is empty
  while (!path.empty() || !pattern.empty()) {
    if (path.empty() || pattern.empty() || path[0] != '/' || pattern[0] != '/') return false;
    path.remove_prefix(1);
    pattern.remove_prefix(1);
    const std::string_view seg = path.substr(0, path.find('/')), want = pattern.substr(0, pattern.find('/'));
    path.remove_prefix(seg.size());
    pattern.remove_prefix(want.size());
    if (seg.empty()) return false;
    if (want.size() >= 2 && want.front() == '{' && want.back() == '}') continue;
    if (seg != want) return false;
  }
  return true;
}

std::string route_regex(std::string_view pattern) {
  std::string out;
  while (!pattern.empty()) {
    if (pattern[0] == '{') {
      const auto close = pattern.find('}');
      out += "([^/]+)";
      pattern.remove_prefix(close == std::string_view::npos ? pattern.size() : close + 1);
      continue;
    }
    if (std::string_view("\\^$.|?*+()[]{}").find(pattern[0]) != std::string_view::npos) out += '\\';
    out += pattern[0];
    pattern.remove_prefix(1);
  }
  return out;
}

std::string allowed_methods(std::string_view path) {
  bool any = false, get = false, post = false, del = false;
  for (const Route& r : api_routes()) {
    if (!path_matches(path, r.path)) continue;
    any = true;
    get = get || r.method == Method::kGet;
    post = post || r.method == Method::kPost;
    del = del || r.method == Method::kDelete;
  }
  if (!any) return "";
  std::string allow = get ? "GET, HEAD, " : "";
  if (post) allow += "POST, ";
  if (del) allow += "DELETE, ";
  return allow + "OPTIONS";
}

bool is_open_path(std::string_view path) {
  const auto& routes = api_routes();
  return std::any_of(routes.begin(), routes.end(), [&](const Route& r) { return r.access == Access::kOpen && path_matches(path, r.path); });
}

std::string unknown_query_parameter(const Request& req) {
  // Each method reads its own: DELETE /v1/jobs/ID?wait=5 would otherwise be accepted and the wait
  // ignored. HEAD reads what GET reads; a method the path does not take reads none.
  const std::string method = req.method == "HEAD" ? "GET" : req.method;
  bool served = false;
  const Route* route = nullptr;
  for (const Route& r : api_routes()) {
    if (!path_matches(req.path, r.path)) continue;
    served = true;
    if (method == method_name(r.method)) route = &r;
  }
  if (!served) return "";
  static const std::vector<std::string_view> kNone;
  const std::vector<std::string_view>& params = route ? route->query : kNone;
  for (const auto& [name, value] : req.params) {
    // Given twice, a parameter would be read as its first value and the second ignored unseen.
    if (const auto n = req.params.count(name); n > 1 && std::find(params.begin(), params.end(), name) != params.end())
      return "query parameter '" + name.substr(0, 64) + "' is given " + std::to_string(n) + " times; give it once";
    if (std::find(params.begin(), params.end(), name) != params.end()) continue;
    std::string takes;
    for (const std::string_view p : params) {
      if (!takes.empty()) takes += ", ";
      takes += p;
    }
    return "unknown query parameter '" + name.substr(0, 64) + "' on " + req.method.substr(0, 16) + " " + req.path.substr(0, 256) +
           (takes.empty() ? " (it takes none)" : " (it takes " + takes + ")");
  }
  return "";
}

void send_method_not_allowed(Response& res, const std::string& method, const std::string& path, const std::string& allow) {
  res.set_header("Allow", allow);
  send_error(res, 405, "method not allowed", "", method + " is not allowed on " + path + "; allowed: " + allow);
}

void register_routes(GuardedHttpServer& http, ApiContext& api) {
  for (const Route& route : api_routes()) {
    const std::string regex = route_regex(route.path);
    switch (route.method) {
      case Method::kGet: http.Get(regex, [&api, h = route.handler](const Request& req, Response& res) { h(api, req, res); }); break;
      case Method::kDelete: http.Delete(regex, [&api, h = route.handler](const Request& req, Response& res) { h(api, req, res); }); break;
      case Method::kPost:
        http.Post(regex, [&api, h = route.body_handler](const Request& req, Response& res, const httplib::ContentReader& reader) {
          if (auto body = read_body(api, res, reader)) h(api, req, res, *body);
        });
        break;
    }
  }
  // Any other POST: answered without reading its body (the connection then closes).
  http.Post(".*", [](const Request& req, Response& res, const httplib::ContentReader&) {
    close_connection_after(res);
    if (const std::string allow = allowed_methods(req.path); !allow.empty())
      return send_method_not_allowed(res, req.method, req.path, allow);
    send_error(res, 404, "not found", "", no_endpoint(req));
  });
}

}  // namespace moreau::server
