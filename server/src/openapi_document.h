// The OpenAPI 3.1 document of the HTTP API (server/openapi.json), compiled into the server and served at
// GET /v1/openapi.json. The file in the repository is the source; the build embeds it byte for byte.
#pragma once

#include <string_view>

namespace moreau::server {

std::string_view openapi_document();

}  // namespace moreau::server
