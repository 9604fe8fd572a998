#include "job_access.h"

#include <mutex>
#include <shared_mutex>

#include "conditional.h"
#include "responses.h"
#include "storage.h"

namespace moreau::server {

using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

std::shared_ptr<Job> job_for(const ApiContext& api, const Request& req, Response& res, JobKind kind) {
  const std::string id = req.matches.size() > 1 ? req.matches[1].str() : std::string();
  std::shared_ptr<Job> job = is_job_id(id) ? api.jobs.find(id) : nullptr;
  if (job && job->kind != kind) job = nullptr;
  if (job && is_deleted(*job)) job = nullptr;
  if (!job) {
    // Says which id was not found, or why it cannot be an id (quoted, bounded; JSON escapes it).
    const std::string what = kind == JobKind::kRun ? "job" : kind_name(kind);
    const std::string post = "POST " + kind_url(kind).substr(0, kind_url(kind).size() - 1);
    send_error(res, 404, std::string("no such ") + what, "",
               is_job_id(id)
                   ? std::string("no ") + what + " " + id + " on this server (finished ones are deleted when purged, or beyond --keep-jobs)"
                   : std::string("'").append(id, 0, 64) + "' is not a " + what + " id: " + what + " ids are 32 lowercase hex digits, as " +
                         post + " returns them");
  }
  return job;
}

bool is_deleted(const Job& job) {
  std::shared_lock files(job.files_mu);
  return job.deleted;
}

JobState state_of(const Job& job) {
  std::lock_guard lock(job.mu);
  return job.state;
}

bool final_with(const Job& job, bool Job::*what) {
  std::lock_guard lock(job.mu);
  return job.*what && is_final(job.state);
}

std::optional<std::string> job_file(const Job& job, bool Job::*has, const char* name, bool* deleted) {
  std::shared_lock files(job.files_mu);
  if (deleted) *deleted = job.deleted;
  if (job.deleted || !final_with(job, has)) return std::nullopt;
  return read_file(job.dir / name);
}

std::optional<json> read_report(const Job& job) {
  auto text = job_file(job, &Job::has_report,
                       job.kind == JobKind::kStudy      ? "result.json"
                       : job.kind == JobKind::kCampaign ? "summary.json"
                                                        : "report.json");
  if (!text) return std::nullopt;
  json j = json::parse(*text, nullptr, false);
  if (j.is_discarded()) return std::nullopt;
  return j;
}

void send_result_file(const Request& req, Response& res, const Job& job, const char* name, const char* content_type, const char* not_yet,
                      const std::string& when, const std::string& attachment) {
  bool deleted = false;
  auto text = job_file(job, &Job::has_report, name, &deleted);
  if (deleted) return send_deleted(res);
  if (!text)
    return send_error(
        res, 409, not_yet, "",
        std::string("the ") + (job.kind == JobKind::kRun ? "job" : kind_name(job.kind)) + " is " + to_string(state_of(job)) + when);
  if (not_modified(req, res, strong_etag(*text))) return;
  res.status = 200;
  if (!attachment.empty()) res.set_header("Content-Disposition", "attachment; filename=\"" + attachment + "\"");
  res.set_content(std::move(*text), content_type);
}

void send_deleted(Response& res) {
  send_error(res, 404, "no such job", "",
             "the job was deleted (purged, or beyond the most recent finished jobs this server keeps: --keep-jobs)");
}

void send_too_many_waiting(const ApiContext& api, Response& res) {
  res.set_header("Retry-After", "1");
  send_error(res, 429, "too many waiting requests", "",
             "this server holds at most " + std::to_string(api.config.max_waiting) +
                 " long polls (?wait) and event streams open at once; retry, or poll without wait");
}

json with_queue_position(json j, const std::map<std::string, int>& positions) {
  if (auto it = positions.find(j.value("id", "")); it != positions.end()) j["queue_position"] = it->second;
  return j;
}

}  // namespace moreau::server
