#include "figures_routes.h"

#include <cstdint>
#include <filesystem>
#include <iostream>
#include <optional>
#include <shared_mutex>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "conditional.h"
#include "figures.h"
#include "job_access.h"
#include "moreau/analysis/campaign.h"
#include "moreau/analysis/figure_kind.h"
#include "moreau/scene/simulation.h"
#include "responses.h"
#include "storage.h"

namespace moreau::server {

namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;
using scene::CampaignFigure;
using scene::FigureFormat;
using scene::StudyFigure;
using scene::TrajectoryFigure;

namespace {

constexpr int kDefaultFigureWidth = 1200, kDefaultFigureHeight = 800;

// Thrown while drawing a figure when a stored file of a finished job cannot be read: a 500, not a 422.
struct StoredFileUnreadable {
  std::string error;
};
// ... or when the job was deleted (pruned) meanwhile: a 404.
struct JobDeleted {};

// The ?kind= of a figure of `Kind`: its default when absent, or nullopt after answering 400.
template <class Kind>
std::optional<Kind> figure_kind(const Request& req, Response& res) {
  if (!req.has_param("kind")) return scene::default_figure<Kind>();
  const auto kind = scene::figure_from_name<Kind>(req.get_param_value("kind"));
  if (!kind) send_error(res, 400, "bad query", "", "kind must be " + scene::figure_name_list<Kind>());
  return kind;
}

struct FigureRequest {
  std::pair<int, int> size{kDefaultFigureWidth, kDefaultFigureHeight};
  FigureFormat format = scene::default_figure<FigureFormat>();
  bool robust_y = false;  // a run's figures only
  // The figure every request without size or options gets: the one kept in the job's directory.
  bool is_default() const { return size == std::pair<int, int>{kDefaultFigureWidth, kDefaultFigureHeight} && !robust_y; }
};

// The requested figure: size (width, height: 64 to 4096, default 1200x800, at most --max-figure-pixels in
// all) and format (png, the default, or svg), or nullopt after answering 501 (no render/ in this build) or
// 400.
std::optional<FigureRequest> figure_request(const ApiContext& api, const Request& req, Response& res) {
  if (!figures_available()) {
    send_error(res, 501, "figures not available", "", "this server was built without render/ (no OSMesa)");
    return std::nullopt;
  }
  FigureRequest f;
  try {
    if (auto w = number_param(req, "width", 64, 4096)) f.size.first = static_cast<int>(*w);
    if (auto h = number_param(req, "height", 64, 4096)) f.size.second = static_cast<int>(*h);
  } catch (const std::exception& e) {
    send_error(res, 400, "bad query", "", e.what());
    return std::nullopt;
  }
  if (static_cast<std::int64_t>(f.size.first) * f.size.second > api.config.max_figure_pixels) {
    send_error(res, 400, "bad query", "",
               "a figure has at most " + std::to_string(api.config.max_figure_pixels) + " pixels (width times height); asked for " +
                   std::to_string(static_cast<std::int64_t>(f.size.first) * f.size.second));
    return std::nullopt;
  }
  if (req.has_param("robust_y")) {
    const std::string value = req.get_param_value("robust_y");
    if (value != "true" && value != "false") {
      send_error(res, 400, "bad query", "", "query parameter 'robust_y' must be true or false");
      return std::nullopt;
    }
    f.robust_y = value == "true";
  }
  if (req.has_param("format")) {
    const auto format = scene::figure_from_name<FigureFormat>(req.get_param_value("format"));
    if (!format) {
      send_error(res, 400, "bad query", "", "query parameter 'format' must be " + scene::figure_name_list<FigureFormat>());
      return std::nullopt;
    }
    f.format = *format;
  }
  return f;
}

// Answers with the figure `draw` makes (422 if it throws, 500 if a stored file is unreadable). At the
// default size it is read from, or written to, the job's file "figure-KIND.png" or ".svg": a name from the
// kinds' table, never from the request.
template <class Kind, class Draw>
void send_figure(ApiContext& api, const Request& req, Response& res, const Job& job, Kind kind, const FigureRequest& f, Draw&& draw) {
  const bool svg = f.format == FigureFormat::kSvg;
  const char* content_type = svg ? "image/svg+xml" : "image/png";
  const fs::path cache = job.dir / (std::string("figure-") + scene::figure_name(kind) + "." + scene::figure_name(f.format));
  const bool default_size = f.is_default();
  if (default_size) {
    std::shared_lock files(job.files_mu);  // the cache is the job's file: never read one being deleted
    if (job.deleted) return send_deleted(res);
    if (auto bytes = read_file(cache)) {
      if (not_modified(req, res, strong_etag(*bytes))) return;
      res.status = 200;
      return res.set_content(std::move(*bytes), content_type);
    }
  }
  // At most --figures-at-once are drawn at once (each holds its trajectory and a frame buffer).
  if (!api.drawing.take(std::chrono::seconds(30))) {
    res.set_header("Retry-After", "1");
    return send_error(res, 503, "figures busy", "", "every figure slot stayed busy for 30 s; retry");
  }
  std::string bytes;
  try {
    bytes = draw();
  } catch (const StoredFileUnreadable& e) {
    api.drawing.give_back();
    return send_error(res, 500, e.error);
  } catch (const JobDeleted&) {
    api.drawing.give_back();
    return send_deleted(res);
  } catch (const std::exception& e) {
    api.drawing.give_back();
    return send_error(res, 422, "cannot draw this figure", "", e.what());
  }
  api.drawing.give_back();
  if (default_size) {
    // Not into a job deleted (purged, pruned) while it was drawn: its directory is going.
    std::shared_lock files(job.files_mu);
    if (job.deleted) return send_deleted(res);
    try {
      write_file_atomic(cache, bytes, Durability::kFsync);
    } catch (const std::exception& e) {
      std::cerr << "moreau-server: " << e.what() << "\n";
    }
  }
  if (not_modified(req, res, strong_etag(bytes))) return;
  res.status = 200;
  res.set_content(std::move(bytes), content_type);
}

}  // namespace

void job_figure(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res);
  if (!job) return;
  const auto kind = figure_kind<TrajectoryFigure>(req, res);
  if (!kind) return;
  const auto figure = figure_request(api, req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_trajectory)) {
    return send_error(res, 409, "no trajectory yet", "",
                      std::string("the job is ") + to_string(state_of(*job)) + "; figures are drawn once it has finished");
  }
  if (is_deleted(*job)) return send_deleted(res);
  send_figure(api, req, res, *job, *kind, *figure, [&] {
    std::error_code size_ec;
    const auto bytes = fs::file_size(job->dir / "trajectory.csv", size_ec);
    if (!size_ec && static_cast<std::int64_t>(bytes) > api.config.max_figure_source_bytes) {
      throw std::invalid_argument("the trajectory has " + std::to_string(bytes) + " bytes; this server draws figures from at most " +
                                  std::to_string(api.config.max_figure_source_bytes) +
                                  ": fetch a window (/trajectory?format=csv&from=&to=&every=) and draw it with moreau plot");
    }
    bool deleted = false;
    auto csv = job_file(*job, &Job::has_trajectory, "trajectory.csv", &deleted);
    if (deleted) throw JobDeleted{};
    if (!csv) throw StoredFileUnreadable{"stored trajectory unreadable"};
    // Marked as `moreau run --figure` marks them: the converged time and the impacts, from the report.
    TrajectoryMarks marks;
    marks.robust_y = figure->robust_y;
    if (auto report = read_report(*job)) {
      if (report->contains("converged_time") && (*report)["converged_time"].is_number())
        marks.converged_time = (*report)["converged_time"].get<double>();
      const json impacts = report->value("/contacts/impacts"_json_pointer, json::array());
      if (impacts.is_array())
        for (const json& impact : impacts)
          if (impact.is_object() && impact.contains("t") && impact["t"].is_number())
            marks.impact_times.push_back(impact["t"].get<double>());
    }
    // Labelled for the kind of system the stored scene is, as the command line labels them: units, the
    // mechanical energy beside the kinetic, a Lur'e system's state x, output y and storage W.
    std::optional<scene::Simulation> system;
    if (auto text = job_file(*job, &Job::has_trajectory, "scene.json")) {
      const json doc = json::parse(*text, nullptr, false);
      if (!doc.is_discarded()) {
        try {
          system.emplace(scene::Simulation::from_json(doc));
        } catch (const std::exception&) {
          // A scene this build no longer compiles: the figure keeps the default labels.
        }
      }
    }
    return figure_image(*kind, *csv, marks, figure->size.first, figure->size.second, job->scene_name + " (" + job->id.substr(0, 8) + ")",
                        figure->format, system ? &*system : nullptr);
  });
}

void study_figure(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res, JobKind::kStudy);
  if (!job) return;
  const auto kind = figure_kind<StudyFigure>(req, res);
  if (!kind) return;
  const auto figure = figure_request(api, req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_report)) {
    return send_error(res, 409, "no table yet", "",
                      std::string("the study is ") + to_string(state_of(*job)) + "; figures are drawn once it is done");
  }
  send_figure(api, req, res, *job, *kind, *figure, [&] {
    bool deleted = false;
    auto result = job_file(*job, &Job::has_report, "result.json", &deleted);
    if (deleted) throw JobDeleted{};
    if (!result) throw StoredFileUnreadable{"stored study result unreadable"};
    return study_figure_image(*kind, *result, figure->size.first, figure->size.second, figure->format);
  });
}

void campaign_figure(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res, JobKind::kCampaign);
  if (!job) return;
  const auto kind = figure_kind<CampaignFigure>(req, res);
  if (!kind) return;
  const auto figure = figure_request(api, req, res);
  if (!figure) return;
  if (!final_with(*job, &Job::has_report)) {
    return send_error(res, 409, "no summary yet", "",
                      std::string("the campaign is ") + to_string(state_of(*job)) + "; figures are drawn once every sample is done");
  }
  send_figure(api, req, res, *job, *kind, *figure, [&] {
    bool deleted = false;
    auto spec_text = job_file(*job, &Job::has_report, "campaign.json", &deleted);
    if (deleted) throw JobDeleted{};
    if (!spec_text) throw StoredFileUnreadable{"stored campaign spec unreadable"};
    const json spec_doc = json::parse(*spec_text, nullptr, false);
    if (!spec_doc.is_object() || !spec_doc.contains("scene") || !spec_doc["scene"].is_object())
      throw StoredFileUnreadable{"stored campaign spec unreadable"};
    // Read under the files lock: the records are read whole (a few numbers per sample are kept).
    std::shared_lock files(job->files_mu);
    if (job->deleted) throw JobDeleted{};
    return campaign_figure_image(*kind, scene::CampaignSpec::from_json(spec_doc, ""), job->dir.string(), job->t_end, figure->size.first,
                                 figure->size.second, figure->format);
  });
}

}  // namespace moreau::server
