// Conditional GET (RFC 9110 sections 8.8.3 and 13.1.2): entity tags for finished results, figures and
// the static files, and the If-None-Match test that turns a repeated request into 304 Not Modified.
#pragma once

#include <string>
#include <string_view>

namespace moreau::server {

// A strong tag of these bytes: "\"" + 16 hex digits of their 64-bit FNV-1a hash + "\"". For bodies held
// whole (a report, a figure, a table): equal bytes, equal tag, whatever served them.
std::string strong_etag(std::string_view bytes);

// A weak tag ("W/\"...\"") of what a streamed body is made from (a stored file's identity and the
// request's parameters), for bodies never held whole (the trajectory).
std::string weak_etag(std::string_view identity);

// Whether an If-None-Match header value matches `etag`: "*", or a comma-separated list holding it, by
// the weak comparison the header uses (W/ prefixes ignored).
bool if_none_match(std::string_view header, std::string_view etag);

}  // namespace moreau::server
