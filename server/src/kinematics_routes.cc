#include "kinematics_routes.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <optional>
#include <shared_mutex>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "job_access.h"
#include "moreau/scene/urdf.h"
#include "responses.h"
#include "storage.h"

namespace moreau::server {

namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

namespace {

// A frame as the answer writes it: the 3 x 4 matrix [R | p], row by row (r00 r01 r02 px r10 ... pz). The
// numbers are written in their shortest round-trip form, so a client reads back the very doubles.
json pose_json(const scene::UrdfFrame& f) {
  json out = json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.push_back(f.rotation(r, c));
    out.push_back(f.position(r));
  }
  return out;
}

json link_json(const scene::UrdfLink& link) {
  json visuals = json::array();
  for (const scene::UrdfVisual& v : link.visuals) {
    json j = {{"origin", pose_json(v.origin)}};
    switch (v.shape) {
      case scene::UrdfVisual::Shape::kBox:
        j["shape"] = "box";
        j["size"] = {v.size.x(), v.size.y(), v.size.z()};
        break;
      case scene::UrdfVisual::Shape::kCylinder:
        j["shape"] = "cylinder";
        j["radius"] = v.radius;
        j["length"] = v.length;
        break;
      case scene::UrdfVisual::Shape::kSphere:
        j["shape"] = "sphere";
        j["radius"] = v.radius;
        break;
    }
    visuals.push_back(std::move(j));
  }
  return {{"name", link.name},
          {"parent", link.parent.empty() ? json(nullptr) : json(link.parent)},
          {"joint", link.joint.empty() ? json(nullptr) : json(link.joint)},
          {"joint_origin", {link.joint_origin.x(), link.joint_origin.y(), link.joint_origin.z()}},
          {"visuals", std::move(visuals)},
          {"meshes", link.meshes}};
}

// A cell as a double, or nullopt if it is not a finite number.
std::optional<double> cell(std::string_view s) {
  double v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// The cells of a CSV row (views into `row`), at most `max` of them.
void split(std::string_view row, std::size_t max, std::vector<std::string_view>& cells) {
  cells.clear();
  while (cells.size() < max) {
    const auto comma = row.find(',');
    cells.push_back(row.substr(0, comma));
    if (comma == std::string_view::npos) break;
    row.remove_prefix(comma + 1);
  }
}

// The rows of a trajectory CSV (t, h, q_1..q_n, ...), read as they are on disk: a run still writing it
// may have left a last line cut short, which has no '\n' yet and is not a row.
class StoredRows {
 public:
  // Opens the file and reads its header; false if it cannot (not written yet).
  bool open(const fs::path& path) {
    in_.open(path, std::ios::binary);
    std::string header;
    if (!in_ || !std::getline(in_, header) || in_.eof()) return false;
    split(header, SIZE_MAX, cells_);
    columns_ = cells_.size();
    return true;
  }
  std::size_t columns() const { return columns_; }
  // The time and the file offset of every complete row with from <= t <= to, in file order.
  void index(double from, double to, std::vector<double>& times, std::vector<std::streamoff>& offsets) {
    std::string line;
    for (;;) {
      const std::streamoff at = in_.tellg();
      if (!std::getline(in_, line) || in_.eof()) break;  // the end, or a last line not yet complete
      if (line.empty()) continue;
      const auto t = cell(std::string_view(line).substr(0, line.find(',')));
      if (!t || *t < from) continue;
      if (*t > to) break;  // rows are in time order
      times.push_back(*t);
      offsets.push_back(at);
    }
  }
  // The joint positions of the row at `offset` (columns 2 .. 2 + n - 1); false if any is not a finite number.
  bool positions(std::streamoff offset, int n, std::vector<double>& q) {
    in_.clear();
    in_.seekg(offset);
    std::string line;
    if (!std::getline(in_, line)) return false;
    split(line, static_cast<std::size_t>(2 + n), cells_);
    if (cells_.size() < static_cast<std::size_t>(2 + n)) return false;
    q.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      const auto v = cell(cells_[static_cast<std::size_t>(2 + i)]);
      if (!v) return false;
      q[static_cast<std::size_t>(i)] = *v;
    }
    return true;
  }

 private:
  std::ifstream in_;
  std::vector<std::string_view> cells_;
  std::size_t columns_ = 0;
};

// Which of `count` rows the answer carries: all of them when they are at most `frames`, else `frames`
// spread evenly from the first to the last (both included).
std::vector<std::size_t> spread(std::size_t count, std::size_t frames) {
  std::vector<std::size_t> picked;
  if (count == 0) return picked;
  if (count <= frames) {
    for (std::size_t i = 0; i < count; ++i) picked.push_back(i);
  } else if (frames == 1) {
    picked.push_back(count - 1);  // the latest: what a viewer following a run shows
  } else {
    for (std::size_t k = 0; k < frames; ++k)
      picked.push_back(static_cast<std::size_t>(
          std::llround(static_cast<double>(k) * static_cast<double>(count - 1) / static_cast<double>(frames - 1))));
  }
  return picked;
}

}  // namespace

void job_kinematics(ApiContext& api, const Request& req, Response& res) {
  auto job = job_for(api, req, res);
  if (!job) return;

  // The query: a window of rows (from <= t <= to), of which max_samples spread evenly, or with t the one
  // row of the window that holds the state at time t.
  std::optional<double> t, from, to, samples;
  try {
    t = number_param(req, "t", -1e300, 1e300);
    from = number_param(req, "from", -1e300, 1e300);
    to = number_param(req, "to", -1e300, 1e300);
    samples = number_param(req, "max_samples", 1, kMaxKinematicsFrames);
    if (samples && *samples != std::floor(*samples)) throw std::invalid_argument("query parameter 'max_samples' must be a whole number");
  } catch (const std::exception& e) {
    return send_error(res, 400, "bad query", "", e.what());
  }
  if (from && to && *from > *to) return send_error(res, 400, "bad query", "", "query parameter 'from' is after 'to'");

  // The stored scene and trajectory, opened under the files lock (an open file stays readable if the job is
  // deleted meanwhile). A finished run's rows are trajectory.csv; a running one's, the rows its writer has
  // put on disk so far in trajectory.csv.tmp, renamed to trajectory.csv when the run is committed.
  const JobState state = state_of(*job);
  const bool finished = is_final(state);
  std::optional<std::string> scene_text;
  StoredRows rows;
  bool have_rows = false;
  {
    std::shared_lock files(job->files_mu);
    if (job->deleted) return send_deleted(res);
    scene_text = read_file(job->dir / "scene.json");
    if (finished) {
      have_rows = final_with(*job, &Job::has_trajectory) && rows.open(job->dir / "trajectory.csv");
    } else if (state != JobState::kQueued) {
      have_rows = rows.open(job->dir / "trajectory.csv.tmp") || rows.open(job->dir / "trajectory.csv");
    }
  }
  if (!scene_text) return send_error(res, 500, "stored scene unreadable", "", "the job's scene.json cannot be read");
  const json doc = json::parse(*scene_text, nullptr, false);
  const json* urdf = nullptr;
  if (doc.is_object() && doc.contains("system") && doc["system"].is_object() && doc["system"].contains("urdf") &&
      doc["system"]["urdf"].is_object())
    urdf = &doc["system"]["urdf"];
  if (!urdf || !urdf->contains("text") || !(*urdf)["text"].is_string())
    return send_error(res, 404, "not a robot", "",
                      "job " + job->id + " runs a scene without a URDF robot (/system/urdf): only URDF scenes have link poses");

  // The robot, selected as its scene selects it (/system/urdf/root, tip): the same model the run used.
  scene::UrdfRobot robot;
  try {
    scene::UrdfSelection selection;
    if (urdf->contains("root") && (*urdf)["root"].is_string()) selection.root_link = (*urdf)["root"].get<std::string>();
    if (urdf->contains("tip") && (*urdf)["tip"].is_string()) selection.tip_link = (*urdf)["tip"].get<std::string>();
    robot = scene::read_urdf((*urdf)["text"].get<std::string>(), selection);
  } catch (const std::exception& e) {
    return send_error(res, 500, "stored scene unreadable", "", std::string("the job's URDF no longer reads: ") + e.what());
  }
  const int n = robot.model.dof();

  json links = json::array();
  for (const scene::UrdfLink& link : robot.links) links.push_back(link_json(link));
  json joints = json::array();
  for (const RigidBody& body : robot.model.bodies) joints.push_back(body.joint_name);

  // The rows: their times and places in the file, then the positions of those the answer carries.
  std::vector<double> times;
  std::vector<std::streamoff> offsets;
  if (have_rows) {
    // t, h, then the n joint positions in the model's order (the scene's coordinates), n velocities, energy.
    if (rows.columns() < static_cast<std::size_t>(3 + 2 * n))
      return send_error(res, 500, "stored trajectory unreadable", "",
                        "the trajectory has " + std::to_string(rows.columns()) + " columns; the robot's " + std::to_string(n) +
                            " joints need at least " + std::to_string(3 + 2 * n));
    rows.index(from.value_or(-HUGE_VAL), to.value_or(HUGE_VAL), times, offsets);
  }
  const std::size_t per_link = std::max<std::size_t>(1, kMaxKinematicsPoses / std::max<std::size_t>(1, robot.links.size()));
  const std::size_t frames_cap = std::min<std::size_t>(kMaxKinematicsFrames, per_link);
  std::vector<std::size_t> picked;
  if (t) {
    // The last row at or before t (the state the run had then), or the first row for a t before it. One
    // frame: within any max_samples.
    if (!times.empty()) {
      const auto after = std::upper_bound(times.begin(), times.end(), *t);
      picked.push_back(after == times.begin() ? 0 : static_cast<std::size_t>(after - times.begin()) - 1);
    }
  } else {
    picked = spread(times.size(), std::min<std::size_t>(frames_cap, samples ? static_cast<std::size_t>(*samples)
                                                                            : static_cast<std::size_t>(kDefaultKinematicsFrames)));
  }

  RigidBodyData data(robot.model);
  std::vector<double> q;
  std::vector<scene::UrdfFrame> poses;
  json frames = json::array();
  for (const std::size_t i : picked) {
    if (!rows.positions(offsets[i], n, q)) continue;  // a row whose positions are not finite numbers (a run that diverged)
    scene::link_poses(robot, data, q.data(), poses);
    json p = json::array();
    for (const scene::UrdfFrame& f : poses) p.push_back(pose_json(f));
    frames.push_back({{"t", times[i]}, {"row", i}, {"q", q}, {"poses", std::move(p)}});
  }

  json body = {{"id", job->id},
               {"state", to_string(state)},
               {"final", finished},
               {"robot", robot.name},
               {"root_link", robot.root_link},
               {"joints", std::move(joints)},
               {"links", std::move(links)},
               {"rows", times.size()},
               {"max_frames", frames_cap},
               {"frames", std::move(frames)}};
  if (!times.empty()) {
    body["t_first"] = times.front();
    body["t_last"] = times.back();
  }
  // A running job's answer changes with every row written: never reused from a cache.
  res.set_header("Cache-Control", "no-store");
  send_json(res, 200, body);
}

}  // namespace moreau::server
