// Files compiled into the server byte for byte (server/CMakeLists.txt, moreau_embed): the OpenAPI
// document of the HTTP API and the web page's static files. The files in the repository are the source.
#pragma once

#include <string_view>

namespace moreau::server {

std::string_view openapi_document();  // server/openapi.json, served at GET /v1/openapi.json
std::string_view web_index_html();    // server/web/index.html, served at GET /
std::string_view web_app_js();        // server/web/app.js, at GET /ui/app.js
std::string_view web_style_css();     // server/web/style.css, at GET /ui/style.css
std::string_view web_robot3d_js();    // server/web/robot3d.js, at GET /ui/robot3d.js
// three.js r111 and its OrbitControls, from Debian's libjs-three (MIT), for the page's 3D view: at GET
// /ui/three.min.js and /ui/OrbitControls.js. Empty when the package was not installed at build time.
std::string_view web_three_js();
std::string_view web_orbit_controls_js();

}  // namespace moreau::server
