#include "static_page.h"

#include <string>
#include <string_view>

#include "conditional.h"
#include "embedded_files.h"
#include "responses.h"

namespace moreau::server {

using httplib::Request;
using httplib::Response;

namespace {

// One file of the web page. Its policy lets the page load only its own script and style, and images it
// made from fetched figures (blob:) or its empty icon (data:, which spares the browser a /favicon.ico
// request).
void send_page_file(const Request& req, Response& res, std::string_view text, const std::string& etag, const char* type) {
  // Before the conditional answer: a 304 carries the page's policy too (a cache may update the stored
  // answer's headers from it), never the API's, which would forbid the page its own script.
  res.set_header("Content-Security-Policy",
                 "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' blob: data:; connect-src 'self'; "
                 "base-uri 'none'; form-action 'none'; frame-ancestors 'none'");
  res.set_header("X-Content-Type-Options", "nosniff");
  res.set_header("Referrer-Policy", "no-referrer");
  res.set_header("Cache-Control", "no-cache");
  if (not_modified(req, res, etag)) return;
  res.status = 200;
  res.set_content(std::string(text), type);
}

}  // namespace

void web_page(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_index_html());
  send_page_file(req, res, web_index_html(), etag, "text/html; charset=utf-8");
}

void web_page_script(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_app_js());
  send_page_file(req, res, web_app_js(), etag, "text/javascript; charset=utf-8");
}

void web_page_style(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_style_css());
  send_page_file(req, res, web_style_css(), etag, "text/css; charset=utf-8");
}

void web_page_robot3d(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_robot3d_js());
  send_page_file(req, res, web_robot3d_js(), etag, "text/javascript; charset=utf-8");
}

namespace {

// A file of libjs-three, or 404 when the server was built without it (the 3D view then says so).
void send_three_file(const Request& req, Response& res, std::string_view text, const std::string& etag) {
  if (text.empty())
    return send_error(
        res, 404, "three.js is not built in", "",
        "this server was built without Debian's libjs-three; install it (scripts/install-deps.sh) and rebuild for the 3D view");
  send_page_file(req, res, text, etag, "text/javascript; charset=utf-8");
}

}  // namespace

void web_page_three(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_three_js());
  send_three_file(req, res, web_three_js(), etag);
}

void web_page_orbit_controls(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(web_orbit_controls_js());
  send_three_file(req, res, web_orbit_controls_js(), etag);
}

void openapi(ApiContext&, const Request& req, Response& res) {
  static const std::string etag = strong_etag(openapi_document());
  if (not_modified(req, res, etag)) return;
  res.status = 200;
  res.set_content(std::string(openapi_document()), "application/json");
}

}  // namespace moreau::server
