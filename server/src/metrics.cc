#include "metrics.h"

#include <sstream>

#include "responses.h"

namespace moreau::server {

using httplib::Request;
using httplib::Response;

void health(ApiContext& api, const Request&, Response& res) {
  if (api.jobs.stopping()) return send_json(res, 503, {{"status", "stopping"}});
  send_json(res, 200, {{"status", "ok"}});
}

void metrics(ApiContext& api, const Request&, Response& res) {
  const Metrics m = api.jobs.metrics();
  std::ostringstream os;
  os.precision(17);
  os << "# HELP moreau_jobs Jobs known to the server, by state.\n# TYPE moreau_jobs gauge\n";
  for (const auto& [state, count] : m.jobs_by_state) os << "moreau_jobs{state=\"" << state << "\"} " << count << "\n";
  os << "# HELP moreau_queue_length Jobs waiting for a worker.\n# TYPE moreau_queue_length gauge\n"
     << "moreau_queue_length " << m.queue_length << "\n";
  os << "# HELP moreau_queue_capacity Queued jobs beyond which submissions get 429.\n# TYPE moreau_queue_capacity gauge\n"
     << "moreau_queue_capacity " << m.queue_capacity << "\n";
  os << "# HELP moreau_workers Integrating threads.\n# TYPE moreau_workers gauge\nmoreau_workers " << m.workers << "\n";
  os << "# HELP moreau_workers_busy Threads running a job now.\n# TYPE moreau_workers_busy gauge\n"
     << "moreau_workers_busy " << m.workers_busy << "\n";
  os << "# HELP moreau_jobs_submitted_total Jobs accepted.\n# TYPE moreau_jobs_submitted_total counter\n"
     << "moreau_jobs_submitted_total " << m.submitted << "\n";
  os << "# HELP moreau_jobs_rejected_total Jobs refused because the queue was full.\n# TYPE moreau_jobs_rejected_total counter\n"
     << "moreau_jobs_rejected_total{reason=\"queue_full\"} " << m.rejected_queue_full << "\n";
  os << "# HELP moreau_steps_total Integration steps of finished jobs.\n# TYPE moreau_steps_total counter\n"
     << "moreau_steps_total " << m.steps_total << "\n";
  os << "# HELP moreau_integrate_seconds_total Time spent integrating.\n# TYPE moreau_integrate_seconds_total counter\n"
     << "moreau_integrate_seconds_total " << m.integrate_seconds_total << "\n";
  os << "# HELP moreau_steps_per_second Steps of the jobs finished in the last 10 s, per second.\n"
     << "# TYPE moreau_steps_per_second gauge\nmoreau_steps_per_second " << m.steps_per_second << "\n";
  os << "# HELP moreau_lcm_messages_total LCM messages published.\n# TYPE moreau_lcm_messages_total counter\n"
     << "moreau_lcm_messages_total " << m.lcm_published << "\n";
  os << "# HELP moreau_lcm_dropped_total States not published because a stream fell too far behind.\n"
     << "# TYPE moreau_lcm_dropped_total counter\nmoreau_lcm_dropped_total " << m.lcm_dropped << "\n";
  const TransportStats t = api.http.stats();
  os << "# HELP moreau_http_connections Open HTTP connections.\n# TYPE moreau_http_connections gauge\n"
     << "moreau_http_connections " << t.open << "\n";
  os << "# HELP moreau_http_connections_refused_total Connections refused over --max-connections or "
        "--max-connections-per-client.\n# TYPE moreau_http_connections_refused_total counter\n"
     << "moreau_http_connections_refused_total " << t.refused_total << "\n";
  os << "# HELP moreau_http_timeouts_total Requests whose headers or body missed their deadline.\n"
     << "# TYPE moreau_http_timeouts_total counter\nmoreau_http_timeouts_total " << t.timed_out_total << "\n";
  os << "# HELP moreau_http_responses_total HTTP responses, by status code.\n# TYPE moreau_http_responses_total counter\n";
  for (const auto& [code, count] : api.responses.by_status())
    os << "moreau_http_responses_total{code=\"" << code << "\"} " << count << "\n";
  res.status = 200;
  res.set_content(os.str(), "text/plain; version=0.0.4");
}

}  // namespace moreau::server
