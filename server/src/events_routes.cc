#include "events_routes.h"

#include <algorithm>
#include <memory>
#include <mutex>
#include <string>

#include "job_access.h"
#include "responses.h"

namespace moreau::server {

using httplib::Request;
using httplib::Response;

void job_events(ApiContext& api, const Request& req, Response& res, JobKind kind) {
  auto job = job_for(api, req, res, kind);
  if (!job) return;
  auto last = std::make_shared<std::uint64_t>(0);
  if (req.has_header("Last-Event-ID")) {
    // An id this job has issued: decimal digits, at most the last id so far. Anything else would be
    // read as some other position (a negative number wraps around to a huge one).
    const std::string v = trim(req.get_header_value("Last-Event-ID"));
    std::uint64_t issued = 0;
    {
      std::lock_guard lock(job->mu);
      issued = job->next_event_id - 1;
    }
    const bool digits = !v.empty() && v.size() <= 19 && std::all_of(v.begin(), v.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (!digits || std::stoull(v) > issued) {
      return send_error(
          res, 400, "bad Last-Event-ID", "",
          "Last-Event-ID must be an event id this job has sent (0 to " + std::to_string(issued) + "), got '" + v.substr(0, 40) + "'");
    }
    *last = std::stoull(v);
  }
  if (!api.waiting.try_take()) return send_too_many_waiting(api, res);
  res.set_header("Cache-Control", "no-cache");
  res.set_header("X-Accel-Buffering", "no");
  res.set_chunked_content_provider(
      "text/event-stream",
      [&api, job, last](std::size_t, httplib::DataSink& sink) {
        bool done = false;
        const auto events = api.jobs.events_after(*job, *last, std::chrono::seconds(15), done);
        std::string out;
        for (const auto& e : events) {
          out += "id: " + std::to_string(e.id) + "\nevent: " + e.name + "\ndata: " + e.data + "\n\n";
          *last = e.id;
        }
        if (out.empty() && !done) out = ": keep-alive\n\n";
        if (!out.empty() && !sink.write(out.data(), out.size())) return false;
        if (done) sink.done();
        return true;
      },
      [&api](bool) { api.waiting.give_back(); });
}

}  // namespace moreau::server
