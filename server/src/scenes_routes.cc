#include "scenes_routes.h"

#include <nlohmann/json.hpp>

#include "responses.h"
#include "storage.h"

namespace moreau::server {

namespace fs = std::filesystem;
using json = nlohmann::json;
using httplib::Request;
using httplib::Response;

std::map<std::string, fs::path> scene_files(const ServerConfig& config) {
  std::map<std::string, fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(config.scenes_dir, ec)) {
    if (e.is_regular_file(ec) && e.path().extension() == ".json") out.emplace(e.path().stem().string(), e.path());
  }
  return out;
}

void list_scenes(ApiContext& api, const Request&, Response& res) {
  json list = json::array();
  for (const auto& [name, path] : scene_files(api.config)) {
    json entry = {{"name", name}, {"url", "/v1/scenes/" + name}};
    if (auto text = read_file(path)) {
      json doc = json::parse(*text, nullptr, false);
      if (doc.is_object()) {
        if (doc.contains("name") && doc["name"].is_string()) entry["title"] = doc["name"];
        if (doc.contains("description") && doc["description"].is_string()) entry["description"] = doc["description"];
      }
    }
    list.push_back(entry);
  }
  send_json(res, 200, {{"scenes", list}, {"count", list.size()}});
}

void get_scene(ApiContext& api, const Request& req, Response& res) {
  const auto files = scene_files(api.config);
  auto it = files.find(req.matches[1].str());
  if (it == files.end())
    return send_error(res, 404, "no such scene", "",
                      "no shipped scene '" + req.matches[1].str().substr(0, 64) + "'; GET /v1/scenes lists them");
  auto text = read_file(it->second);
  if (!text) return send_error(res, 500, "scene unreadable");
  res.status = 200;
  res.set_content(std::move(*text), "application/json");
}

}  // namespace moreau::server
