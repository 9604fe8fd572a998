// moreau sweep SCENE --vary PATH=VALUES... [--shard i/N] --out DIR : runs its share of a parameter sweep;
// moreau sweep --merge DIR [--csv FILE] [--json FILE] : combines the shards' results.
//
// The sweep is the Cartesian product of the --vary lists, in the order given (the last varies fastest);
// point p goes to shard p mod N. Each shard writes DIR/shard-<i>-of-<N>.jsonl: a header line describing
// the sweep, then one line per point with its overrides and its report. Merging checks that every point
// of the same sweep is present exactly once.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "commands.h"
#include "moreau/scene/line_reader.h"
#include "moreau/scene/simulation.h"

namespace moreau::cli {
namespace {

struct Dimension {
  std::string path;
  std::vector<std::string> values;  // as given, each a JSON value or a string
};

// PATH=v1,v2,... or PATH=a:b:n (n evenly spaced values from a to b). JSON arrays in values are allowed
// when the list uses ';' instead of ',' (PATH=[0,1];[1,0]).
Dimension parse_vary(const std::string& spec) {
  const std::size_t eq = spec.find('=');
  if (eq == std::string::npos || eq == 0) throw std::runtime_error("--vary '" + spec + "' is not PATH=VALUES");
  Dimension d{spec.substr(0, eq), {}};
  const std::string list = spec.substr(eq + 1);
  const char sep = list.find(';') != std::string::npos ? ';' : ',';
  if (sep == ',' && std::count(list.begin(), list.end(), ':') == 2 && list.find('[') == std::string::npos) {
    std::stringstream ss(list);
    std::string a, b, c;
    std::getline(ss, a, ':');
    std::getline(ss, b, ':');
    std::getline(ss, c, ':');
    auto number = [&](const std::string& text) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || end != text.c_str() + text.size())
        throw std::runtime_error("--vary " + d.path + ": '" + text + "' is not a number");
      if (!std::isfinite(v)) throw std::runtime_error("--vary " + d.path + ": '" + text + "' is not a finite number");
      return v;
    };
    const double lo = number(a), hi = number(b);
    if (!std::isfinite(hi - lo)) throw std::runtime_error("--vary " + d.path + ": the range " + a + ":" + b + " overflows a double");
    char* end = nullptr;
    const long n = std::strtol(c.c_str(), &end, 10);
    if (c.empty() || *end != '\0' || n < 1 || n > 100000)
      throw std::runtime_error("--vary " + d.path + ": count must be a whole number in [1, 100000], got '" + c + "'");
    for (int i = 0; i < n; ++i) {
      std::ostringstream v;
      v.precision(15);
      v << (n == 1 ? lo : lo + (hi - lo) * i / (n - 1));
      d.values.push_back(v.str());
    }
  } else {
    std::stringstream ss(list);
    for (std::string item; std::getline(ss, item, sep);)
      if (!item.empty()) d.values.push_back(item);
  }
  if (d.values.empty()) throw std::runtime_error("--vary " + d.path + ": no values");
  return d;
}

// Largest number of points in one sweep (all shards together).
constexpr std::size_t kMaxSweepPoints = 10'000'000;

// Longest line of a shard file: a point's report. Lines never get near it; a file that is not a shard
// (or never ends a line) is refused there instead of being read whole.
constexpr std::size_t kMaxShardLine = scene::kMaxSceneFileBytes;

struct SweepOptions {
  std::string scene_path;
  std::vector<std::string> vary, overrides;
  std::string shard = "0/1";
  std::string out_dir;
  std::string merge_dir, merge_csv, merge_json;
};

int run_shard(const SweepOptions& opt) {
  std::vector<Dimension> dims;
  for (const auto& v : opt.vary) dims.push_back(parse_vary(v));
  // The product is checked before it is formed: four lists of 100000 values would wrap a size_t.
  std::size_t total = 1;
  for (const auto& d : dims) {
    if (d.values.size() > kMaxSweepPoints / total)
      throw std::runtime_error("--vary: the sweep has more than " + std::to_string(kMaxSweepPoints) +
                               " points (the product of the lengths of the --vary lists)");
    total *= d.values.size();
  }
  int shard = 0, shards = 1;
  char slash = 0;
  std::istringstream ss(opt.shard);
  if (!(ss >> shard >> slash >> shards) || slash != '/' || shards < 1 || shard < 0 || shard >= shards)
    throw std::runtime_error("--shard must be i/N with 0 <= i < N, got '" + opt.shard + "'");
  std::filesystem::create_directories(opt.out_dir);
  const std::string path = opt.out_dir + "/shard-" + std::to_string(shard) + "-of-" + std::to_string(shards) + ".jsonl";
  const std::string tmp = path + ".partial";
  std::ofstream out(tmp, std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write '" + tmp + "'");
  nlohmann::json header = {{"sweep", {{"scene", opt.scene_path}, {"points", total}, {"shards", shards}, {"shard", shard}}}};
  header["sweep"]["vary"] = nlohmann::json::array();
  for (const auto& d : dims) header["sweep"]["vary"].push_back({{"path", d.path}, {"values", d.values}});
  header["sweep"]["set"] = opt.overrides;
  out << header.dump() << "\n";
  int failed = 0, ran = 0;
  for (std::size_t p = static_cast<std::size_t>(shard); p < total; p += static_cast<std::size_t>(shards)) {
    std::vector<std::string> overrides = opt.overrides;
    std::size_t rest = p;
    std::vector<std::string> assignment(dims.size());
    for (std::size_t k = dims.size(); k-- > 0;) {
      assignment[k] = dims[k].path + "=" + dims[k].values[rest % dims[k].values.size()];
      rest /= dims[k].values.size();
    }
    overrides.insert(overrides.end(), assignment.begin(), assignment.end());
    nlohmann::json line = {{"index", p}, {"overrides", assignment}};
    try {
      const scene::Simulation sim = scene::Simulation::from_file(opt.scene_path, overrides);
      const RunSummary summary = sim.run(nullptr);
      line["report"] = sim.report_json(summary);
      failed += summary.status != RunStatus::kCompleted;
    } catch (const scene::SceneError& e) {
      line["error"] = {{"pointer", e.pointer()}, {"reason", e.reason()}};
      ++failed;
    }
    out << line.dump() << "\n";
    ++ran;
  }
  out.close();
  if (!out) throw std::runtime_error("writing '" + tmp + "' failed");
  std::filesystem::rename(tmp, path);  // a shard's file appears only once it is complete
  std::cerr << "moreau sweep: shard " << shard << "/" << shards << ": " << ran << " of " << total << " points, " << failed << " failed -> "
            << path << "\n";
  return 0;
}

int merge(const SweepOptions& opt) {
  nlohmann::json sweep;
  std::map<std::size_t, nlohmann::json> points;
  std::set<int> shards_seen;
  for (const auto& entry : std::filesystem::directory_iterator(opt.merge_dir)) {
    if (entry.path().extension() != ".jsonl") continue;
    std::ifstream in(entry.path());
    const std::string file = entry.path().string();
    std::size_t line_no = 1;
    // Each line is parsed like a scene file: a syntax error or a number out of range is a SceneError
    // naming the file, the line and the JSON pointer.
    auto next = [&](std::string& line) {
      return scene::read_line(in, line, kMaxShardLine, file + " line " + std::to_string(line_no), "64 MiB");
    };
    auto parse = [&](const std::string& line) { return scene::parse_json_text(line, file + " line " + std::to_string(line_no)); };
    std::string line;
    if (!next(line)) continue;
    const auto header = parse(line);
    nlohmann::json def = header.at("sweep");
    const int shard = def.at("shard");
    def.erase("shard");
    if (sweep.is_null()) sweep = def;
    if (def != sweep) throw std::runtime_error(entry.path().string() + " belongs to a different sweep");
    shards_seen.insert(shard);
    while (++line_no, next(line)) {
      auto j = parse(line);
      const std::size_t idx = j.at("index");
      if (!points.emplace(idx, std::move(j)).second) throw std::runtime_error("point " + std::to_string(idx) + " appears twice");
    }
  }
  if (sweep.is_null()) throw std::runtime_error("no shard files (*.jsonl) in '" + opt.merge_dir + "'");
  const std::size_t total = sweep.at("points");
  const int shards = sweep.at("shards");
  for (int s = 0; s < shards; ++s)
    if (!shards_seen.count(s)) throw std::runtime_error("shard " + std::to_string(s) + "/" + std::to_string(shards) + " is missing");
  if (points.size() != total)
    throw std::runtime_error("expected " + std::to_string(total) + " points, found " + std::to_string(points.size()));
  nlohmann::json merged = {{"sweep", sweep}, {"points", nlohmann::json::array()}};
  for (auto& [idx, j] : points) merged["points"].push_back(j);
  if (!opt.merge_json.empty()) std::ofstream(opt.merge_json) << merged.dump(2) << "\n";
  std::ostringstream csv;
  csv.precision(17);
  csv << "index";
  for (const auto& d : sweep["vary"]) csv << "," << d["path"].get<std::string>();
  csv << ",status,steps,converged_time,energy_nonincreasing,equilibrium_residual,wall_seconds,message\n";
  for (const auto& [idx, j] : points) {
    csv << idx;
    for (const auto& a : j["overrides"]) {
      const std::string s = a.get<std::string>();
      csv << ",\"" << s.substr(s.find('=') + 1) << "\"";
    }
    if (j.contains("report")) {
      const auto& r = j["report"];
      csv << "," << r["status"].get<std::string>() << "," << r["steps"] << ","
          << (r["converged_time"].is_null() ? "" : r["converged_time"].dump()) << "," << r["energy_nonincreasing"] << ","
          << r["equilibrium"]["residual"].dump() << "," << r["wall_seconds"] << ",\"" << r.value("message", "") << "\"\n";
    } else {
      csv << ",invalid,,,,,,\"" << j["error"]["pointer"].get<std::string>() << ": " << j["error"]["reason"].get<std::string>() << "\"\n";
    }
  }
  if (!opt.merge_csv.empty()) std::ofstream(opt.merge_csv) << csv.str();
  if (opt.merge_csv.empty() && opt.merge_json.empty()) std::cout << csv.str();
  std::cerr << "moreau sweep: merged " << total << " points from " << shards << " shards\n";
  return 0;
}

}  // namespace

void register_sweep_command(CLI::App& app, Actions& actions) {
  auto opt = std::make_shared<SweepOptions>();
  auto* cmd = app.add_subcommand("sweep", "Run a share of a parameter sweep (--shard i/N), or merge the shards (--merge DIR)");
  cmd->add_option("scene", opt->scene_path, "Scene file");
  cmd->add_option("--vary", opt->vary, "PATH=v1,v2,... or PATH=first:last:count (repeatable; the product is swept)");
  cmd->add_option("--set", opt->overrides, "Fixed override for every point: PATH=VALUE");
  cmd->add_option("--shard", opt->shard, "This process's share: i/N (points p with p mod N == i)")->capture_default_str();
  cmd->add_option("--out", opt->out_dir, "Directory for this shard's results");
  cmd->add_option("--merge", opt->merge_dir, "Merge the shard files in this directory");
  cmd->add_option("--csv", opt->merge_csv, "With --merge: write the table as CSV (default: stdout)");
  cmd->add_option("--json", opt->merge_json, "With --merge: write every point's report as one JSON document");
  actions[cmd] = [opt]() -> int {
    try {
      if (!opt->merge_dir.empty()) {
        return merge(*opt);
      } else {
        if (opt->scene_path.empty() || opt->vary.empty() || opt->out_dir.empty())
          throw std::runtime_error("a sweep needs SCENE, at least one --vary and --out DIR (or --merge DIR)");
        return run_shard(*opt);
      }
    } catch (const std::exception& e) {
      std::cerr << "moreau sweep: " << e.what() << "\n";
      return 2;
    }
  };
}

}  // namespace moreau::cli
