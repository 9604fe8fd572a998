// A job as the routes find and read it: by the id in its URL (404 otherwise), its state and stored files
// read under its locks, and the answers every route gives alike for a job that is deleted, a result that
// is not there yet, or too many waiting requests.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "api_context.h"
#include "job.h"

// After Eigen (through the job headers): see http_transport.h.
#include "http_transport.h"

namespace moreau::server {

// The job of `kind` named by the request's first capture, or nullptr after answering 404. The id is
// checked against [0-9a-f]{32} and looked up in memory: request data never reaches a path.
std::shared_ptr<Job> job_for(const ApiContext& api, const httplib::Request& req, httplib::Response& res, JobKind kind = JobKind::kRun);

// Whether the job was deleted (purged, or pruned beyond --keep-jobs), under its files lock.
bool is_deleted(const Job& job);
// The job's state, under its lock.
JobState state_of(const Job& job);
// Whether the job is final and has the results `what` points to (has_report or has_trajectory).
bool final_with(const Job& job, bool Job::*what);

// A file of a finished job, read under its files lock: nullopt if the job has no such result yet (`has`
// unset or not final), or was deleted meanwhile; then *deleted says which.
std::optional<std::string> job_file(const Job& job, bool Job::*has, const char* name, bool* deleted = nullptr);

// The committed report of a run (report.json), result of a study (result.json) or summary of a campaign
// (summary.json), parsed; nullopt if there is none (yet) or it does not parse.
std::optional<nlohmann::json> read_report(const Job& job);

// A stored result of a finished job (its report, a study's table, a campaign's summary), whole, with its
// strong ETag; 409 `not_yet` (the job's state, then `when` it comes) until the job has it, 404 once the
// job is deleted. `attachment`: a download's file name, or "".
void send_result_file(const httplib::Request& req, httplib::Response& res, const Job& job, const char* name, const char* content_type,
                      const char* not_yet, const std::string& when, const std::string& attachment = "");

// 404 for a job deleted while the request was answered.
void send_deleted(httplib::Response& res);

// 429 with Retry-After: every place for a long poll or an event stream (--max-waiting) is taken.
void send_too_many_waiting(const ApiContext& api, httplib::Response& res);

// The job's JSON with its place in the queue (1: the next to run) when it is queued.
nlohmann::json with_queue_position(nlohmann::json j, const std::map<std::string, int>& positions);

}  // namespace moreau::server
