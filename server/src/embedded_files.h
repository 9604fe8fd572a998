// Files compiled into the server byte for byte (server/CMakeLists.txt, moreau_embed): the OpenAPI
// document of the HTTP API and the web page's static files. The files in the repository are the source.
#pragma once

#include <string_view>

namespace moreau::server {

std::string_view openapi_document();  // server/openapi.json, served at GET /v1/openapi.json
std::string_view web_index_html();    // server/web/index.html, served at GET /
std::string_view web_app_js();        // server/web/app.js, at GET /ui/app.js
std::string_view web_style_css();     // server/web/style.css, at GET /ui/style.css

}  // namespace moreau::server
