#include "moreau/analysis/campaign.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string_view>
#include <thread>

#include <boost/math/distributions/normal.hpp>
#include <boost/random/sobol.hpp>

#include "campaign_sensitivity.h"
#include "moreau/analysis/sensitivity.h"
#include "moreau/core/observer.h"
#include "moreau/core/stepping_driver.h"
#include "moreau/platform/fnv1a.h"
#include "moreau/platform/number_text.h"
#include "moreau/scene/json_number.h"
#include "moreau/scene/line_reader.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"
#include "scene_reader.h"

namespace moreau::scene {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// ---- the spec ----

// The checks and quoting of the spec's JSON are scene/input/json_checks.h's, as for a scene.
using detail::brief;
using detail::check_fields;
using detail::path_as_pointer;
using detail::required_field;

double finite_number(const json& j, const std::string& ptr) {
  if (!j.is_number()) throw SceneError(ptr, "expected a number, got " + brief(j));
  const double v = j.get<double>();
  if (!std::isfinite(v)) throw SceneError(ptr, "expected a finite number");
  return v;
}

InputDistribution parse_distribution(const json& d, const std::string& ptr) {
  if (!d.is_object()) throw SceneError(ptr, "expected an object with a 'type', got " + brief(d));
  const json& type = required_field(d, ptr, "type");
  if (!type.is_string()) throw SceneError(ptr + "/type", "expected a string");
  const std::string t = type.get<std::string>();
  InputDistribution r;
  auto bounds = [&](bool positive) {
    r.low = finite_number(required_field(d, ptr, "low"), ptr + "/low");
    r.high = finite_number(required_field(d, ptr, "high"), ptr + "/high");
    if (!(r.low < r.high)) throw SceneError(ptr + "/high", "the bounds are inverted or equal: low must be below high");
    if (positive && !(r.low > 0.0)) throw SceneError(ptr + "/low", "a log-uniform distribution needs low > 0");
    if (!std::isfinite(r.high - r.low)) throw SceneError(ptr + "/high", "high - low overflows a double");
  };
  if (t == "uniform") {
    check_fields(d, ptr, {"type", "low", "high"});
    r.kind = InputDistribution::Kind::kUniform;
    bounds(false);
  } else if (t == "log-uniform") {
    check_fields(d, ptr, {"type", "low", "high"});
    r.kind = InputDistribution::Kind::kLogUniform;
    bounds(true);
  } else if (t == "normal") {
    check_fields(d, ptr, {"type", "mean", "std", "low", "high"});
    r.kind = InputDistribution::Kind::kNormal;
    r.mean = finite_number(required_field(d, ptr, "mean"), ptr + "/mean");
    r.stddev = finite_number(required_field(d, ptr, "std"), ptr + "/std");
    if (!(r.stddev > 0.0)) throw SceneError(ptr + "/std", "the standard deviation must be positive");
    bounds(false);
    // Phi(b) - Phi(a) must not vanish: bounds many deviations away from the mean leave nothing to draw.
    double mass = 0.0;
    try {
      const boost::math::normal n(r.mean, r.stddev);
      mass = boost::math::cdf(n, r.high) - boost::math::cdf(n, r.low);
    } catch (const std::exception&) {
      throw SceneError(ptr, "mean, std and bounds out of the range a normal distribution can be evaluated in");
    }
    if (!(mass > 1e-12)) throw SceneError(ptr + "/low", "the bounds hold no probability of this normal (they lie far in one tail)");
  } else if (t == "discrete" || t == "grid") {
    r.kind = t == "grid" ? InputDistribution::Kind::kGrid : InputDistribution::Kind::kDiscrete;
    if (d.contains("values")) {
      check_fields(d, ptr, {"type", "values"});
      const json& v = d["values"];
      if (!v.is_array() || v.empty()) throw SceneError(ptr + "/values", "expected a non-empty array of values");
      if (v.size() > 1'000'000) throw SceneError(ptr + "/values", "more than 1000000 values");
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (v[i].is_number()) finite_number(v[i], ptr + "/values/" + std::to_string(i));
        r.all_numbers_ = r.all_numbers_ && v[i].is_number();
        r.values.push_back(v[i]);
      }
    } else if (t == "grid") {
      check_fields(d, ptr, {"type", "low", "high", "count"});
      bounds(false);
      const json& c = required_field(d, ptr, "count");
      if (!c.is_number_integer() || c.get<std::int64_t>() < 2 || c.get<std::int64_t>() > 1'000'000)
        throw SceneError(ptr + "/count", "expected a whole number of points in [2, 1000000]");
      const auto n = c.get<std::int64_t>();
      for (std::int64_t i = 0; i < n; ++i)
        r.values.push_back(r.low + (r.high - r.low) * static_cast<double>(i) / static_cast<double>(n - 1));
    } else {
      throw SceneError(ptr, "a discrete distribution needs 'values'");
    }
  } else {
    throw SceneError(ptr + "/type", "unknown distribution '" + t + "' (uniform, normal, log-uniform, discrete, grid)");
  }
  return r;
}

// ---- reproducible randomness ----

// SplitMix64 (Steele, Lea and Flood 2014): a bijective mixer; mixing the seed, the sample and the input
// gives each (sample, input) its own uniform number, whatever order samples run in.
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
// In [0, 1): the top 53 bits.
double unit_from_bits(std::uint64_t x) { return static_cast<double>(x >> 11) * 0x1.0p-53; }
double hashed_unit(std::uint64_t seed, std::uint64_t stream, std::uint64_t i, std::uint64_t d) {
  return unit_from_bits(splitmix64(splitmix64(splitmix64(seed ^ stream) + i) + d));
}
constexpr std::uint64_t kMonteCarloStream = 0x4d43, kLatinJitterStream = 0x4c4a, kLatinPermutationStream = 0x4c50;

}  // namespace

json InputDistribution::at(double u) const {
  switch (kind) {
    case Kind::kUniform: return std::min(high, low + u * (high - low));
    case Kind::kLogUniform: return std::clamp(std::exp(std::log(low) + u * (std::log(high) - std::log(low))), low, high);
    case Kind::kNormal: {
      const boost::math::normal n(mean, stddev);
      const double pa = boost::math::cdf(n, low), pb = boost::math::cdf(n, high);
      const double p = pa + u * (pb - pa);
      if (!(p > 0.0)) return low;
      if (!(p < 1.0)) return high;
      return std::clamp(boost::math::quantile(n, p), low, high);
    }
    case Kind::kDiscrete:
    case Kind::kGrid: {
      const auto n = values.size();
      return values[std::min(n - 1, static_cast<std::size_t>(u * static_cast<double>(n)))];
    }
  }
  return nullptr;
}

bool is_campaign_name(const std::string& name) {
  if (name.empty() || name.size() > kMaxCampaignNameLength) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
  });
}

namespace {
// Whole doubles below 2^53 as integers (exact there), everything else as it is: one text for documents
// that are equal as JSON values.
json canonical(const json& j) {
  if (j.is_object()) {
    json out = json::object();
    for (auto it = j.begin(); it != j.end(); ++it) out[it.key()] = canonical(it.value());
    return out;
  }
  if (j.is_array()) {
    json out = json::array();
    for (const json& e : j) out.push_back(canonical(e));
    return out;
  }
  if (j.is_number_float()) {
    const double x = j.get<double>();
    if (std::isfinite(x) && std::trunc(x) == x && std::abs(x) < 0x1.0p53) return json(static_cast<std::int64_t>(x));
  }
  return j;
}
}  // namespace

std::string campaign_spec_hash(const json& document) {
  return platform::fnv1a64_hex(canonical(document).dump(-1, ' ', false, json::error_handler_t::replace));
}

CampaignSpec CampaignSpec::from_json(const json& spec, const std::string& base_dir) {
  if (!spec.is_object()) throw SceneError("/", "a campaign spec is a JSON object");
  check_fields(
      spec, "",
      {"name", "description", "scene", "inputs", "sampler", "seed", "samples", "target", "tracking", "full_report", "map", "sensitivity"});
  CampaignSpec s;
  s.document = spec;
  if (spec.contains("name") && !spec["name"].is_string()) throw SceneError("/name", "expected a string");
  s.name = spec.value("name", "campaign");
  // Names are data: they reach Slurm's batch script and command lines, file names and messages.
  if (!is_campaign_name(s.name))
    throw SceneError("/name", brief(json(s.name)) + " is not a campaign name: 1 to " + std::to_string(kMaxCampaignNameLength) +
                                  " characters, each a letter A-Z or a-z, a digit, '.', '_' or '-'");
  // The scene: inline, or a file relative to the spec's directory.
  const json& scene = required_field(spec, "", "scene");
  if (scene.is_string()) {
    fs::path p = scene.get<std::string>();
    if (p.is_relative()) p = fs::path(base_dir) / p;
    try {
      s.scene = read_scene_file(p.string());
    } catch (const SceneError& e) {
      throw SceneError("/scene", "the scene file '" + p.string() + "': " + e.what());
    }
    s.document["scene"] = s.scene;
  } else if (scene.is_object()) {
    s.scene = scene;
  } else {
    throw SceneError("/scene", "expected a scene (an object) or the path of a scene file");
  }
  // The scene itself must be valid: its errors name their field under /scene.
  int dof = 0;
  try {
    const Simulation nominal = Simulation::from_json(s.scene);
    dof = nominal.dof();
    s.unread_parameters = nominal.lagrangian() ? nominal.lagrangian()->unread_parameters : nominal.lure()->unread_parameters;
  } catch (const SceneError& e) {
    throw SceneError("/scene" + (e.pointer() == "/" ? std::string() : e.pointer()), e.reason());
  }

  const json& inputs = required_field(spec, "", "inputs");
  if (!inputs.is_array() || inputs.empty()) throw SceneError("/inputs", "expected a non-empty array of uncertain inputs");
  if (inputs.size() > static_cast<std::size_t>(kMaxCampaignInputs))
    throw SceneError("/inputs", "more than " + std::to_string(kMaxCampaignInputs) + " inputs");
  std::set<std::string> seen;
  std::size_t total_values = 0;
  for (std::size_t k = 0; k < inputs.size(); ++k) {
    const std::string ptr = "/inputs/" + std::to_string(k);
    const json& in = inputs[k];
    if (!in.is_object()) throw SceneError(ptr, "expected an object with 'path' and 'distribution'");
    check_fields(in, ptr, {"path", "distribution"});
    const json& path = required_field(in, ptr, "path");
    if (!path.is_string() || path.get<std::string>().empty())
      throw SceneError(ptr + "/path", "expected a scene path such as /parameters/m2");
    CampaignInput ci;
    ci.path = path_as_pointer(path.get<std::string>());
    json::json_pointer jp;
    try {
      jp = json::json_pointer(ci.path);
    } catch (const json::exception&) {
      throw SceneError(ptr + "/path", "'" + path.get<std::string>() + "' is not a valid JSON pointer");
    }
    // contains() throws, not answers false, for an array index beyond size_t (nlohmann::json 3.11: found by
    // the campaign fuzzer, /initial/x/6666...6660 aborted the process).
    bool present = false;
    try {
      present = s.scene.contains(jp);
    } catch (const json::exception&) {
    }
    if (!present) throw SceneError(ptr + "/path", "the scene has nothing at '" + ci.path + "'");
    if (!seen.insert(ci.path).second) throw SceneError(ptr + "/path", "'" + ci.path + "' is already an input");
    for (const CampaignInput& other : s.inputs) {
      // One input inside another (/parameters and /parameters/m1) would overwrite it.
      const std::string& a = other.path.size() < ci.path.size() ? other.path : ci.path;
      const std::string& b = other.path.size() < ci.path.size() ? ci.path : other.path;
      if (b.compare(0, a.size(), a) == 0 && b.size() > a.size() && b[a.size()] == '/')
        throw SceneError(ptr + "/path", "'" + ci.path + "' and the input '" + other.path + "' overlap (one holds the other)");
    }
    ci.distribution = parse_distribution(required_field(in, ptr, "distribution"), ptr + "/distribution");
    // The values of discrete inputs and grids are held in memory: a few kilobytes of spec must not ask
    // for gigabytes.
    total_values += ci.distribution.values.size();
    if (total_values > 1'000'000)
      throw SceneError(ptr + "/distribution", "the inputs' discrete values and grid points number more than 1000000 in all");
    s.inputs.push_back(std::move(ci));
  }

  std::string sampler = "monte-carlo";
  if (spec.contains("sampler")) {
    if (!spec["sampler"].is_string()) throw SceneError("/sampler", "expected a string");
    sampler = spec["sampler"].get<std::string>();
  }
  if (sampler == "monte-carlo")
    s.sampler = Sampler::kMonteCarlo;
  else if (sampler == "latin-hypercube")
    s.sampler = Sampler::kLatinHypercube;
  else if (sampler == "sobol")
    s.sampler = Sampler::kSobol;
  else if (sampler == "grid")
    s.sampler = Sampler::kGrid;
  else
    throw SceneError("/sampler", "unknown sampler '" + sampler + "' (monte-carlo, latin-hypercube, sobol, grid)");

  if (spec.contains("seed")) {
    const json& seed = spec["seed"];
    if (!seed.is_number_unsigned() && !(seed.is_number_integer() && seed.get<std::int64_t>() >= 0))
      throw SceneError("/seed", "expected a whole number >= 0");
    s.seed = spec["seed"].get<std::uint64_t>();
  }

  if (spec.contains("sensitivity")) {
    campaign_detail::read_campaign_sensitivity(spec, s);  // Saltelli's design: N (k + 2) samples
  } else if (s.sampler == Sampler::kGrid) {
    // The full grid: the product of every input's points, the last input varying fastest.
    std::int64_t total = 1;
    for (std::size_t k = 0; k < s.inputs.size(); ++k) {
      const auto& d = s.inputs[k].distribution;
      if (d.kind != InputDistribution::Kind::kGrid && d.kind != InputDistribution::Kind::kDiscrete)
        throw SceneError("/inputs/" + std::to_string(k) + "/distribution",
                         "the grid sampler needs a grid or discrete values for every input");
      const auto n = static_cast<std::int64_t>(d.values.size());
      if (n > kMaxCampaignSamples / total)
        throw SceneError("/inputs", "the grid has more than " + std::to_string(kMaxCampaignSamples) + " points");
      total *= n;
    }
    if (spec.contains("samples") && spec["samples"] != total)
      throw SceneError("/samples", "the grid has " + std::to_string(total) + " points; leave 'samples' out or give that number");
    s.samples = total;
  } else {
    const json& n = required_field(spec, "", "samples");
    if (!n.is_number_integer() || n.get<std::int64_t>() < 1)
      throw SceneError("/samples", "expected a whole number of samples >= 1, got " + brief(n));
    s.samples = n.get<std::int64_t>();
    if (s.samples > kMaxCampaignSamples)
      throw SceneError("/samples", "more than the limit of " + std::to_string(kMaxCampaignSamples) + " samples");
    if (s.sampler == Sampler::kLatinHypercube && s.samples * static_cast<std::int64_t>(s.inputs.size()) > 8 * kMaxLatinHypercubeSamples)
      throw SceneError("/samples", "a Latin hypercube keeps 4 bytes per sample and input: at most " +
                                       std::to_string(8 * kMaxLatinHypercubeSamples) + " samples times inputs (use sobol or monte-carlo)");
    if (s.sampler == Sampler::kLatinHypercube && s.samples > kMaxLatinHypercubeSamples)
      throw SceneError("/samples", "a Latin hypercube of more than " + std::to_string(kMaxLatinHypercubeSamples) +
                                       " samples (use sobol or monte-carlo)");
  }

  if (spec.contains("map")) {
    const json& m = spec["map"];
    if (!m.is_array() || m.size() != 2) throw SceneError("/map", "expected the paths of two inputs (the axes of the success map)");
    for (std::size_t k = 0; k < 2; ++k) {
      const std::string ptr = "/map/" + std::to_string(k);
      if (!m[k].is_string()) throw SceneError(ptr, "expected the path of an input");
      const std::string path = path_as_pointer(m[k].get<std::string>());
      const auto it = std::find_if(s.inputs.begin(), s.inputs.end(), [&](const CampaignInput& in) { return in.path == path; });
      if (it == s.inputs.end()) throw SceneError(ptr, "'" + m[k].get<std::string>() + "' is not one of the inputs");
      if (!it->distribution.numeric()) throw SceneError(ptr, "'" + path + "' takes values that are not numbers");
      s.map_inputs[k] = static_cast<int>(it - s.inputs.begin());
    }
    if (s.map_inputs[0] == s.map_inputs[1]) throw SceneError("/map/1", "the two axes are the same input");
  } else {
    // The first two numeric inputs, if there are two.
    int found = 0;
    for (std::size_t k = 0; k < s.inputs.size() && found < 2; ++k)
      if (s.inputs[k].distribution.numeric()) s.map_inputs[found++] = static_cast<int>(k);
    if (found < 2) s.map_inputs = {-1, -1};
  }
  if (spec.contains("full_report")) {
    if (!spec["full_report"].is_boolean()) throw SceneError("/full_report", "expected true or false");
    s.full_report = spec["full_report"].get<bool>();
  }
  if (spec.contains("target")) {
    const json& t = spec["target"];
    if (!t.is_object()) throw SceneError("/target", "expected {\"q\": [...], \"tolerance\": ...}");
    check_fields(t, "/target", {"q", "tolerance"});
    const json& q = required_field(t, "/target", "q");
    if (!q.is_array() || static_cast<int>(q.size()) != dof)
      throw SceneError("/target/q", "expected an array of " + std::to_string(dof) + " numbers (the scene's coordinates)");
    for (std::size_t i = 0; i < q.size(); ++i) s.target_q.push_back(finite_number(q[i], "/target/q/" + std::to_string(i)));
    s.target_tolerance = finite_number(required_field(t, "/target", "tolerance"), "/target/tolerance");
    if (s.target_tolerance < 0.0) throw SceneError("/target/tolerance", "expected a number >= 0");
  }
  if (spec.contains("tracking")) {
    const json& t = spec["tracking"];
    if (!t.is_object()) throw SceneError("/tracking", "expected {\"error\": ..., \"after\": ...}");
    check_fields(t, "/tracking", {"error", "after"});
    if (!s.scene.contains("system") || !s.scene["system"].is_object() || !s.scene["system"].contains("tracking"))
      throw SceneError("/tracking", "a tracking target needs a tracking scene (/scene/system/tracking)");
    if (!s.target_q.empty()) throw SceneError("/tracking", "give a tracking target or a target set (/target), not both");
    s.tracking_error = finite_number(required_field(t, "/tracking", "error"), "/tracking/error");
    if (*s.tracking_error < 0.0) throw SceneError("/tracking/error", "expected a number >= 0");
    s.tracking_after = t.contains("after") ? finite_number(t["after"], "/tracking/after") : 0.0;
  }
  s.hash = campaign_spec_hash(s.document);
  return s;
}

CampaignSpec CampaignSpec::from_file(const std::string& path) {
  const json doc = read_scene_file(path);
  return from_json(doc, fs::path(path).parent_path().string());
}

// ---- the design ----

CampaignDesign::CampaignDesign(const CampaignSpec& spec) : spec_(spec) {
  if (spec.sampler != Sampler::kLatinHypercube) return;
  // One permutation of the strata 0..N-1 per input (Fisher-Yates driven by SplitMix64, so the same on
  // every platform, unlike std::shuffle): sample i lies in stratum strata_[d][i] of input d.
  const auto n = static_cast<std::uint32_t>(spec.samples);
  strata_.resize(spec.inputs.size());
  for (std::size_t d = 0; d < spec.inputs.size(); ++d) {
    auto& p = strata_[d];
    p.resize(n);
    std::iota(p.begin(), p.end(), 0u);
    for (std::uint32_t i = n; i > 1; --i) {
      const std::uint64_t r = splitmix64(splitmix64(spec.seed ^ kLatinPermutationStream) + (static_cast<std::uint64_t>(d) << 32) + i);
      std::swap(p[i - 1], p[static_cast<std::uint32_t>(r % i)]);
    }
  }
}

std::vector<double> CampaignDesign::unit_point(std::int64_t i) const {
  // Saltelli's design (sensitivity.h): sample i is one block of row j = i / (k + 2), and the row is the
  // base sampler's point j in [0, 1)^(2k) (a, then b). Monte Carlo and Sobol only (the spec's reader).
  std::optional<SaltelliPlace> place;
  if (spec_.sobol) {
    place = saltelli_place(i, static_cast<int>(spec_.inputs.size()));
    i = place->row;
  }
  const std::size_t d = place ? 2 * spec_.inputs.size() : spec_.inputs.size();
  std::vector<double> u(d);
  const auto ui = static_cast<std::uint64_t>(i);
  switch (spec_.sampler) {
    case Sampler::kMonteCarlo:
      for (std::size_t k = 0; k < d; ++k) u[k] = hashed_unit(spec_.seed, kMonteCarloStream, ui, k);
      break;
    case Sampler::kLatinHypercube:
      for (std::size_t k = 0; k < d; ++k)
        u[k] = (strata_[k][static_cast<std::size_t>(i)] + hashed_unit(spec_.seed, kLatinJitterStream, ui, k)) /
               static_cast<double>(spec_.samples);
      break;
    case Sampler::kSobol: {
      // The Sobol sequence from its origin: point 0 is (0, ..., 0) and point i >= 1 is Boost's (i-1)-th
      // (Joe and Kuo's direction numbers; Boost's engine skips the origin and seeks to a point in O(log i)).
      // With the origin, any 2^m points from index 0 put one point in each of the 2^m strata of every
      // input (a (0, m, 1)-net); without it they would not. The seed does not scramble the points: the
      // same spec gives the same points.
      // An engine is built once per thread and dimension (building one costs ten seeks): seed() sets the
      // whole state, so the point does not depend on the engine's past.
      if (i > 0) {
        thread_local std::optional<boost::random::sobol> engine;
        if (!engine || engine->dimension() != d) engine.emplace(d);
        engine->seed(ui - 1);
        for (std::size_t k = 0; k < d; ++k) u[k] = static_cast<double>((*engine)()) * 0x1.0p-64;
      }
      break;
    }
    case Sampler::kGrid: {
      std::uint64_t rest = ui;
      for (std::size_t k = d; k-- > 0;) {
        const auto n = spec_.inputs[k].distribution.values.size();
        u[k] = (static_cast<double>(rest % n) + 0.5) / static_cast<double>(n);
        rest /= n;
      }
      break;
    }
  }
  if (place) return saltelli_point(u, place->block);
  return u;
}

std::vector<json> CampaignDesign::values(std::int64_t i) const {
  const std::vector<double> u = unit_point(i);
  std::vector<json> v;
  v.reserve(u.size());
  for (std::size_t k = 0; k < u.size(); ++k) v.push_back(spec_.inputs[k].distribution.at(u[k]));
  return v;
}

// ---- the steps of the samples ----

namespace {

// A scene document's integrator settings, read as both compilers read them (read_interval, read_max_steps,
// check_step_count) without compiling the system: ceil((t_end - t0) / h). Throws as the compilers would
// for settings they refuse (the sample is then invalid and runs no step).
class IntegratorReader : public detail::SceneReader {
 public:
  explicit IntegratorReader(const json& doc) : SceneReader(doc) {}
  std::int64_t steps() {
    return detail::compile_scene([&] {
      declare_parameters();
      if (!doc_.contains("integrator")) throw SceneError("/integrator", "missing required field 'integrator' (h and t_end)");
      const json& in = doc_["integrator"];
      detail::require_object(in, "/integrator");
      double h = 0, t0 = 0, t_end = 0;
      read_interval(in, h, t0, t_end);
      const std::int64_t max_steps = read_max_steps(in);
      check_step_count(t0, t_end, h, max_steps, true);  // beyond max_steps the compilers refuse the scene
      return std::min(fixed_step_count(t0, t_end, h), max_steps);
    });
  }
};

// The bound of one document: its integrator's steps, or 0 when the settings are refused (the compilers
// read them with the same functions, after more checks, so they refuse the sample too: it runs no step),
// or the compiled scene's should the reader fail otherwise; capped by `cap`.
std::int64_t steps_of(const json& doc, std::optional<std::int64_t> cap) {
  std::int64_t n = 0;
  try {
    n = IntegratorReader(doc).steps();
  } catch (const SceneError&) {
    n = 0;
  } catch (const std::exception&) {
    try {
      const Simulation sim = Simulation::from_json(doc);
      n = std::min(sim.planned_steps(), sim.max_steps());
    } catch (const std::exception&) {
      n = 0;
    }
  }
  return cap ? std::min(n, *cap) : n;
}

bool under(const std::string& path, const std::string& root) {
  return path == root || (path.size() > root.size() && path.compare(0, root.size(), root) == 0 && path[root.size()] == '/');
}

}  // namespace

CampaignStepBound campaign_step_bound(const CampaignSpec& spec, std::optional<std::int64_t> cap, std::int64_t stop_above) {
  CampaignStepBound b;
  b.base = steps_of(spec.scene, cap);
  // Which inputs can change a sample's steps: an integrator setting, or a parameter when the settings
  // are expressions (which may use parameters, and parameters other parameters).
  bool settings_are_numbers = true;
  if (spec.scene.contains("integrator") && spec.scene["integrator"].is_object())
    for (const char* field : {"h", "t0", "t_end", "max_steps"})
      if (spec.scene["integrator"].contains(field) && !spec.scene["integrator"][field].is_number()) settings_are_numbers = false;
  std::vector<int> changing;
  for (std::size_t k = 0; k < spec.inputs.size(); ++k) {
    const std::string& path = spec.inputs[k].path;
    if (under(path, "/integrator") || (!settings_are_numbers && under(path, "/parameters"))) changing.push_back(static_cast<int>(k));
  }
  b.inputs_change_steps = !changing.empty();
  const auto add = [&](std::int64_t n) {
    b.total = n > std::numeric_limits<std::int64_t>::max() - b.total ? std::numeric_limits<std::int64_t>::max() : b.total + n;
  };
  if (!b.inputs_change_steps) {
    b.largest = b.base;
    b.largest_sample = spec.samples > 0 ? 0 : -1;
    b.total = b.base > 0 && spec.samples > std::numeric_limits<std::int64_t>::max() / b.base ? std::numeric_limits<std::int64_t>::max()
                                                                                             : b.base * spec.samples;
    b.stopped = false;
    return b;
  }
  // Sample by sample, from its own document (every input's path written, as the runner writes them).
  const CampaignDesign design(spec);
  json doc = spec.scene;
  std::vector<json::json_pointer> paths;
  for (const CampaignInput& in : spec.inputs) paths.emplace_back(in.path);
  std::vector<json> worst_values;
  for (std::int64_t i = 0; i < spec.samples; ++i) {
    std::vector<json> values = design.values(i);
    for (std::size_t k = 0; k < values.size(); ++k) doc[paths[k]] = values[k];
    const std::int64_t n = steps_of(doc, cap);
    add(n);
    if (n > b.largest || b.largest_sample < 0) {
      b.largest = n;
      b.largest_sample = i;
      worst_values = std::move(values);
    }
    if (b.total > stop_above && i + 1 < spec.samples) {
      b.stopped = true;
      break;
    }
  }
  // Which input raises the worst sample most: each changing input's value alone on the scene.
  std::int64_t most = -1;
  for (int k : changing) {
    json alone = spec.scene;
    alone[paths[static_cast<std::size_t>(k)]] = worst_values[static_cast<std::size_t>(k)];
    const std::int64_t n = steps_of(alone, cap);
    if (n > most) {
      most = n;
      b.input = k;
    }
  }
  return b;
}

// ---- one sample ----

namespace {

// The largest |q_i| and energy over every state of the run.
class ExtremaTracker final : public RunObserver {
 public:
  void on_sample(const Sample& s) override {
    for (int i = 0; i < s.n; ++i) max_abs_q = std::max(max_abs_q, std::abs(s.q[i]));
    max_energy = std::max(max_energy, s.kinetic_energy);
  }
  double max_abs_q = 0.0, max_energy = 0.0;
};

// The largest ||e||_inf of a tracking run (its signals e_<q>, the second of each coordinate's four:
// TrackingIntegrator) over the recorded states at t >= after; NaN when no state was seen there.
class TrackingErrorTracker final : public ForwardingObserver {
 public:
  TrackingErrorTracker(double after, RunObserver* next) : ForwardingObserver(next), after_(after) {}
  void on_sample(const Sample& s) override {
    if (s.t >= after_ && s.signals)
      for (int i = 1; i < s.m; i += 4)
        max_error = std::isnan(max_error) ? std::abs(s.signals[i]) : std::max(max_error, std::abs(s.signals[i]));
    ForwardingObserver::on_sample(s);
  }
  double max_error = std::nan("");

 private:
  double after_;
};

// A tracking scene whose controller's model (/system/tracking/nominal/parameters) does not name every
// parameter gets the document's values written there: a campaign varies the plant, and the controller
// keeps the model it was given, whether a sample is compiled in full (its parameters written into the
// document) or bound to a scene compiled once (whose nominal model is the document's).
json with_nominal_model_pinned(json scene) {
  if (!scene.contains("system") || !scene["system"].is_object() || !scene["system"].contains("tracking") ||
      !scene["system"]["tracking"].is_object() || !scene.contains("parameters") || !scene["parameters"].is_object())
    return scene;
  json& nominal = scene["system"]["tracking"]["nominal"];
  if (nominal.is_null()) nominal = json::object();
  if (!nominal.is_object()) return scene;  // the scene compiler says what is wrong
  json& params = nominal["parameters"];
  if (params.is_null()) params = json::object();
  if (!params.is_object()) return scene;
  for (const auto& [name, value] : scene["parameters"].items())
    if (value.is_number() && !params.contains(name)) params[name] = value;
  return scene;
}

json numbers(const std::vector<double>& v) {
  json a = json::array();
  for (double x : v) a.push_back(finite_or_null(x));
  return a;
}

}  // namespace

CampaignSampleRunner::CampaignSampleRunner(const CampaignSpec& spec, const CampaignDesign& design, std::optional<std::int64_t> max_steps,
                                           Compile compile)
    : spec_(spec), design_(design), max_steps_(max_steps), doc_(with_nominal_model_pinned(spec.scene)) {
  for (const CampaignInput& in : spec.inputs) paths_.emplace_back(in.path);
  if (compile != Compile::kOnceWhenPossible || system_type(spec.scene) != "lagrangian") return;
  // Where each input goes, if every one is a parameter or a coordinate of the initial state.
  std::vector<std::string> free;
  for (const json::json_pointer& path : paths_) {
    const std::string parent = path.parent_pointer().to_string(), leaf = path.back();
    const bool index =
        !leaf.empty() && leaf.size() < 4 && std::all_of(leaf.begin(), leaf.end(), [](char c) { return c >= '0' && c <= '9'; });
    if (parent == "/parameters" && spec.scene.at(path).is_number()) {
      targets_.push_back({Target::kParameter, static_cast<int>(free.size())});
      free.push_back(leaf);
    } else if ((parent == "/initial/q" || parent == "/initial/v") && index) {
      targets_.push_back({parent == "/initial/q" ? Target::kInitialQ : Target::kInitialV, std::stoi(leaf)});
    } else {
      targets_.clear();
      return;
    }
  }
  try {
    auto parametric = std::make_unique<ParametricLagrangianScene>(doc_, free);
    const int n = parametric->nominal().n;
    for (const Target& t : targets_)
      if (t.kind != Target::kParameter && t.index >= n) return;
    parametric_ = std::move(parametric);
  } catch (const std::exception&) {
    // A free parameter the compiler needs as a number (a gain, the step, another parameter), or any other
    // reason: every sample is compiled in full, and says what is wrong with it if anything is.
  }
}

CampaignSampleRunner::~CampaignSampleRunner() = default;

json CampaignSampleRunner::record_head(std::int64_t i, const std::vector<json>& values) const {
  json inputs = json::object();
  for (std::size_t k = 0; k < values.size(); ++k) inputs[spec_.inputs[k].path] = values[k];
  return {{"index", i}, {"inputs", std::move(inputs)}, {"spec_hash", spec_.hash}};
}

json CampaignSampleRunner::record_of(std::int64_t i, const std::vector<json>& values, const Simulation& sim) const {
  const CampaignSpec& spec = spec_;
  json record = record_head(i, values);
  ExtremaTracker extrema;
  TrackingErrorTracker tracking(spec.tracking_after.value_or(0.0), &extrema);
  RunDiagnostics diagnostics;
  const RunSummary summary = sim.run(spec.tracking_error ? static_cast<RunObserver*>(&tracking) : &extrema, &diagnostics);
  const bool completed = summary.status == RunStatus::kCompleted;
  record["status"] = to_string(summary.status);
  record["converged"] = summary.converged_step.has_value();
  record["converged_time"] = summary.converged_time ? finite_or_null(*summary.converged_time) : json(nullptr);
  record["final_q"] = numbers(summary.q_final);
  record["final_v"] = numbers(summary.v_final);
  // No target: nothing to check. A final state of another size than the target's (a sample that
  // changed the system) is not within it.
  double distance = spec.target_q.empty() ? 0.0 : std::nan("");
  if (!spec.target_q.empty() && summary.q_final.size() == spec.target_q.size()) {
    distance = 0.0;
    for (std::size_t k = 0; k < spec.target_q.size(); ++k) distance += std::pow(summary.q_final[k] - spec.target_q[k], 2);
    distance = std::sqrt(distance);
    record["target_distance"] = finite_or_null(distance);
  } else {
    record["target_distance"] = nullptr;
  }
  record["max_abs_q"] = finite_or_null(extrema.max_abs_q);
  record["max_energy"] = finite_or_null(extrema.max_energy);
  record["steps"] = summary.steps;
  const std::string failure = completed ? sim.hypothesis_failure(summary) : std::string();
  record["hypothesis_failed"] = failure.empty() ? json(nullptr) : json(failure);
  if (spec.tracking_error) {
    record["tracking_error"] = finite_or_null(tracking.max_error);
    record["success"] = completed && std::isfinite(tracking.max_error) && tracking.max_error <= *spec.tracking_error;
  } else {
    record["success"] = completed && summary.converged_step.has_value() &&
                        (spec.target_q.empty() || (std::isfinite(distance) && distance <= spec.target_tolerance));
  }
  record["message"] = summary.message;
  record["error"] = nullptr;
  if (spec.full_report) record["report"] = sim.report_json(summary, diagnostics);
  return record;
}

json CampaignSampleRunner::run_compiled(std::int64_t i, const std::vector<json>& values) {
  try {
    for (std::size_t k = 0; k < values.size(); ++k) doc_[paths_[k]] = values[k];
    return record_of(i, values, Simulation::from_json(doc_).with_limits(RunLimits{max_steps_, 1}));
  } catch (const std::exception& e) {
    json record = record_head(i, values);
    record["status"] = "invalid";
    record["success"] = false;
    // Anything else a sample's values provoke is that sample's failure, not the campaign's.
    const auto* scene_error = dynamic_cast<const SceneError*>(&e);
    record["error"] = scene_error ? json{{"pointer", scene_error->pointer()}, {"reason", scene_error->reason()}}
                                  : json{{"pointer", "/"}, {"reason", std::string("the sample could not be run: ") + e.what()}};
    return record;
  }
}

std::optional<json> CampaignSampleRunner::run_bound(std::int64_t i, const std::vector<json>& values) {
  const LagrangianScene& nominal = parametric_->nominal();
  std::vector<double> params, q0 = nominal.q0, v0 = nominal.v0;
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (!values[k].is_number()) return std::nullopt;
    const double v = values[k].get<double>();
    if (!std::isfinite(v)) return std::nullopt;
    const Target& t = targets_[k];
    if (t.kind == Target::kParameter) {
      params.push_back(v);  // bind() throws for a value the graph folds specially (0); the catch below then
                            // leaves the sample to the full compile
    } else {
      (t.kind == Target::kInitialQ ? q0 : v0)[static_cast<std::size_t>(t.index)] = v;
    }
  }
  try {
    return record_of(i, values, Simulation::from_scene(parametric_->bind(params, q0, v0), RunLimits{max_steps_, 1}, doc_));
  } catch (const std::exception&) {
    return std::nullopt;  // the full compile says what is wrong with this sample
  }
}

namespace {
// A record without what differs from one run of a sample to the next: wall times.
json without_times(json r) {
  r.erase("wall_seconds");
  if (r.contains("report") && r["report"].is_object()) {
    r["report"].erase("wall_seconds");
    r["report"].erase("phase_seconds");
  }
  return r;
}
}  // namespace

json CampaignSampleRunner::run(std::int64_t i) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<json> values = design_.values(i);
  std::optional<json> bound;
  if (parametric_) bound = run_bound(i, values);
  json record;
  if (bound && checked_) {
    record = std::move(*bound);
  } else {
    record = run_compiled(i, values);
    if (bound) {
      // The first bound sample: the full compile must give the same record, else compile every sample.
      checked_ = true;
      if (without_times(*bound) != without_times(record)) parametric_.reset();
    }
  }
  record["wall_seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return record;
}

// ---- statistics ----

WilsonInterval wilson_interval(std::int64_t successes, std::int64_t n, double z) {
  if (n <= 0) return {0.0, 1.0};
  const double nn = static_cast<double>(n), p = static_cast<double>(successes) / nn, z2 = z * z;
  const double denom = 1.0 + z2 / nn;
  const double center = (p + z2 / (2.0 * nn)) / denom;
  const double half = z / denom * std::sqrt(p * (1.0 - p) / nn + z2 / (4.0 * nn * nn));
  return {std::max(0.0, center - half), std::min(1.0, center + half)};
}

double quantile_sorted(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return std::nan("");
  const double h = (static_cast<double>(sorted.size()) - 1.0) * q;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(sorted.size() - 1, lo + 1);
  return sorted[lo] + (h - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

namespace {
std::vector<double> ranks(const std::vector<double>& x) {
  std::vector<std::size_t> order(x.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return x[a] < x[b]; });
  std::vector<double> r(x.size());
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    while (j + 1 < order.size() && x[order[j + 1]] == x[order[i]]) ++j;
    const double average = (static_cast<double>(i) + static_cast<double>(j)) / 2.0 + 1.0;  // ranks from 1
    for (std::size_t k = i; k <= j; ++k) r[order[k]] = average;
    i = j + 1;
  }
  return r;
}
}  // namespace

std::optional<double> spearman(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size() || x.size() < 3) return std::nullopt;
  const std::vector<double> rx = ranks(x), ry = ranks(y);
  const double n = static_cast<double>(x.size());
  const double mx = std::accumulate(rx.begin(), rx.end(), 0.0) / n, my = std::accumulate(ry.begin(), ry.end(), 0.0) / n;
  double sxy = 0, sxx = 0, syy = 0;
  for (std::size_t i = 0; i < rx.size(); ++i) {
    sxy += (rx[i] - mx) * (ry[i] - my);
    sxx += (rx[i] - mx) * (rx[i] - mx);
    syy += (ry[i] - my) * (ry[i] - my);
  }
  if (!(sxx > 0.0) || !(syy > 0.0)) return std::nullopt;
  return sxy / std::sqrt(sxx * syy);
}

// ---- the summary ----

namespace {
constexpr double kQuantiles[] = {0.05, 0.25, 0.5, 0.75, 0.95};

json quantiles_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  json q = {{"count", v.size()}};
  if (v.empty()) return q;
  q["min"] = v.front();
  q["max"] = v.back();
  for (double p : kQuantiles) {
    const int percent = static_cast<int>(std::lround(p * 100));
    q[(percent < 10 ? "p0" : "p") + std::to_string(percent)] = quantile_sorted(v, p);
  }
  return q;
}

}  // namespace

namespace {

CampaignOutcome row_of(const CampaignSpec& spec, const json& r) {
  CampaignOutcome row;
  row.index = r["index"].get<std::int64_t>();
  const std::string status = r.value("status", "");
  row.success = r.value("success", false);
  row.converged = r.value("converged", false);
  row.failure_class = status == "invalid" ? 3 : status == "failed" ? 2 : !row.success ? 1 : 0;
  row.hypothesis_failed = r.contains("hypothesis_failed") && r["hypothesis_failed"].is_string();
  auto number = [&](const char* key) { return r.contains(key) ? number_or_nan(r[key]) : std::nan(""); };
  row.converged_time = row.converged ? number("converged_time") : std::nan("");
  row.target_distance = number("target_distance");
  row.max_abs_q = number("max_abs_q");
  const json& inputs = r.contains("inputs") ? r["inputs"] : json::object();
  for (const auto& in : spec.inputs) row.inputs.push_back(inputs.contains(in.path) ? number_or_nan(inputs[in.path]) : std::nan(""));
  return row;
}

json summarize_rows(const CampaignSpec& spec, const std::vector<CampaignOutcome>& rows) {
  const auto n = static_cast<std::int64_t>(rows.size());
  std::int64_t successes = 0, converged = 0, invalid = 0, failed = 0, hypothesis = 0;
  std::vector<double> conv_times, errors;
  for (const CampaignOutcome& r : rows) {
    successes += r.success;
    converged += r.converged;
    invalid += r.failure_class == 3;
    failed += r.failure_class == 2;
    hypothesis += r.hypothesis_failed;
    if (std::isfinite(r.converged_time)) conv_times.push_back(r.converged_time);
    if (std::isfinite(r.target_distance)) errors.push_back(r.target_distance);
  }
  const WilsonInterval w = wilson_interval(successes, n);
  json s = {
      {"name", spec.name},
      {"samples", n},
      {"successes", successes},
      {"success_rate", n ? static_cast<double>(successes) / static_cast<double>(n) : 0.0},
      {"success_rate_95", {{"method", "Wilson score interval"}, {"low", w.low}, {"high", w.high}}},
      {"converged", converged},
      {"failed_runs", failed},
      {"invalid_samples", invalid},
      {"hypothesis_failed", hypothesis},
      {"success_means", spec.tracking_error ? "completed, with max |e| <= " + platform::significant(*spec.tracking_error, 6) +
                                                  " at every recorded state from t = " + platform::significant(*spec.tracking_after, 6)
                        : spec.target_q.empty() ? "converged (v == 0.0 exactly for the report's window, to the end, at an equilibrium)"
                                                : "converged, with the final q within the target's tolerance"},
      {"convergence_time", quantiles_of(conv_times)},
      {"target_distance", quantiles_of(errors)}};
  s["success_rate_95"].update(campaign_detail::success_interval_assumptions(spec));

  // The worst samples: failures first (invalid, failed run, did not succeed), then the largest distance
  // to the target, then the latest convergence; ties by index.
  std::vector<std::size_t> order(rows.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  auto badness = [&](const CampaignOutcome& r) {
    return std::make_tuple(r.failure_class, std::isfinite(r.target_distance) ? r.target_distance : 0.0,
                           std::isfinite(r.converged_time) ? r.converged_time : 0.0);
  };
  const std::size_t worst_count = std::min<std::size_t>(10, rows.size());
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(worst_count), order.end(),
                    [&](std::size_t a, std::size_t b) {
                      const auto ba = badness(rows[a]), bb = badness(rows[b]);
                      return ba != bb ? ba > bb : rows[a].index < rows[b].index;
                    });
  json worst = json::array();
  for (std::size_t k = 0; k < worst_count; ++k) {
    const CampaignOutcome& r = rows[order[k]];
    json inputs = json::object();
    for (std::size_t d = 0; d < spec.inputs.size(); ++d) inputs[spec.inputs[d].path] = finite_or_null(r.inputs[d]);
    worst.push_back({{"index", r.index},
                     {"inputs", inputs},
                     {"success", r.success},
                     {"outcome", r.failure_class == 3   ? "invalid"
                                 : r.failure_class == 2 ? "failed run"
                                 : r.success            ? "succeeded"
                                                        : "did not succeed"},
                     {"converged_time", finite_or_null(r.converged_time)},
                     {"target_distance", finite_or_null(r.target_distance)}});
  }
  s["worst"] = worst;

  // First-order sensitivity: Spearman's rank correlation of each outcome with each numeric input, over
  // the samples where both are numbers.
  json sens = json::array();
  const std::vector<std::pair<const char*, double (*)(const CampaignOutcome&)>> outcomes = {
      {"success", [](const CampaignOutcome& r) { return r.success ? 1.0 : 0.0; }},
      {"converged_time", [](const CampaignOutcome& r) { return r.converged_time; }},
      {"target_distance", [](const CampaignOutcome& r) { return r.target_distance; }},
      {"max_abs_q", [](const CampaignOutcome& r) { return r.max_abs_q; }}};
  for (std::size_t d = 0; d < spec.inputs.size(); ++d) {
    if (!spec.inputs[d].distribution.numeric()) continue;
    json row = {{"input", spec.inputs[d].path}};
    for (const auto& [name, get] : outcomes) {
      std::vector<double> x, y;
      for (const CampaignOutcome& r : rows) {
        const double xi = r.inputs[d], yi = get(r);
        if (std::isfinite(xi) && std::isfinite(yi)) {
          x.push_back(xi);
          y.push_back(yi);
        }
      }
      const auto rho = spearman(x, y);
      row[name] = rho ? json(*rho) : json(nullptr);
    }
    sens.push_back(row);
  }
  s["sensitivity"] = {{"method", "Spearman rank correlation of each outcome with each input (null: constant or fewer than 3 samples)"},
                      {"inputs", sens}};
  if (spec.sobol) s["sobol"] = campaign_detail::summarize_campaign_sobol(spec, rows, sens);
  return s;
}

}  // namespace

json summarize_campaign(const CampaignSpec& spec, const std::vector<json>& records) {
  std::vector<CampaignOutcome> rows;
  rows.reserve(records.size());
  for (const json& r : records) rows.push_back(row_of(spec, r));
  std::sort(rows.begin(), rows.end(), [](const CampaignOutcome& a, const CampaignOutcome& b) { return a.index < b.index; });
  return summarize_rows(spec, rows);
}

std::string format_campaign_summary(const json& s) {
  std::ostringstream o;
  const auto percent = [](const json& rate) { return platform::fixed(100.0 * rate.get<double>(), 2) + "%"; };
  const auto g4 = [](const json& v) { return platform::significant(v.get<double>(), 4); };
  const std::int64_t n = s["samples"], k = s["successes"];
  o << s["name"].get<std::string>() << ": " << k << " of " << n << " samples succeeded (" << percent(s["success_rate"])
    << "; 95% Wilson interval [" << percent(s["success_rate_95"]["low"]) << ", " << percent(s["success_rate_95"]["high"]) << "]"
    << (s["success_rate_95"].contains("assumes") ? ", which assumes independent samples" : "") << ")\n";
  o << campaign_detail::format_success_interval_note(s) << "  success means " << s["success_means"].get<std::string>() << "\n";
  o << "  converged " << s["converged"].get<std::int64_t>() << ", failed runs " << s["failed_runs"].get<std::int64_t>()
    << ", invalid samples " << s["invalid_samples"].get<std::int64_t>() << ", a hypothesis failed in "
    << s["hypothesis_failed"].get<std::int64_t>() << "\n";
  for (const char* key : {"convergence_time", "target_distance"}) {
    const json& q = s[key];
    if (q["count"] == 0) continue;
    std::string label = key;
    label.resize(std::max<std::size_t>(label.size(), 16), ' ');
    o << "  " << label << " min " << g4(q["min"]) << "  p05 " << g4(q["p05"]) << "  p25 " << g4(q["p25"]) << "  median " << g4(q["p50"])
      << "  p75 " << g4(q["p75"]) << "  p95 " << g4(q["p95"]) << "  max " << g4(q["max"]) << " (" << q["count"].get<std::int64_t>()
      << " samples)\n";
  }
  o << "  rank correlation (Spearman) with success / convergence time / target distance / max |q|:\n";
  for (const json& r : s["sensitivity"]["inputs"]) {
    o << "    " << r["input"].get<std::string>() << ":";
    for (const char* key : {"success", "converged_time", "target_distance", "max_abs_q"}) {
      if (r[key].is_number()) {
        const double rho = r[key].get<double>();
        o << " " << (std::signbit(rho) ? "" : "+") << platform::fixed(rho, 3);
      } else {
        o << " -";
      }
    }
    o << "\n";
  }
  o << campaign_detail::format_campaign_sobol(s);
  o << "  worst samples:";
  for (const json& w : s["worst"]) o << " " << w["index"].get<std::int64_t>() << (w["success"].get<bool>() ? "" : "*");
  o << " (* did not succeed)\n";
  return o.str();
}

// ---- the campaign directory ----

namespace {

constexpr std::size_t kMaxRecordLine = std::size_t{64} << 20;

// What to do with a last line that has no '\n' (a writer killed in the middle of a record, or one
// still writing it).
enum class CutLine {
  kRepair,  // cut it off the file (a file only this process writes), so the next record starts a line
  kIgnore,  // skip it (another task's file, perhaps being written)
  kError,   // refuse the file, naming it and the line
};

// Calls `each(record, where)` with every record of a records file, read one bounded line at a time (a
// million records never sit in memory together); `where` is "'FILE' line N", for errors.
template <class Each>
void for_each_record(const fs::path& file, CutLine cut, Each each) {
  if (!fs::exists(file)) return;
  std::uintmax_t good_end = 0;
  bool partial = false;
  {
    std::ifstream in(file, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read '" + file.string() + "'");
    std::string line;
    for (std::size_t line_no = 1;; ++line_no) {
      const std::string where = "'" + file.string() + "' line " + std::to_string(line_no);
      if (!read_line(in, line, kMaxRecordLine, where, "64 MiB")) break;
      if (in.eof()) {  // the input ended before this line's '\n'
        if (cut == CutLine::kError) throw std::runtime_error(where + " is cut short (a task killed while writing it?)");
        partial = true;
        break;
      }
      json r;
      try {
        r = json::parse(line);
      } catch (const json::exception& e) {
        throw std::runtime_error(where + " is not a sample record (not JSON: " + e.what() + ")");
      }
      if (!r.is_object() || !r.contains("index") || !r["index"].is_number_integer())
        throw std::runtime_error(where + " is not a sample record (no index)");
      good_end += line.size() + 1;
      each(std::move(r), where);
    }
  }
  if (partial && cut == CutLine::kRepair) fs::resize_file(file, good_end);
}

// The samples a reader wants: a task needs only its own range, a collection all of them.
struct SampleRange {
  std::int64_t begin = 0, end = std::numeric_limits<std::int64_t>::max();
  bool contains(std::int64_t i) const { return i >= begin && i < end; }
  bool overlaps(std::int64_t b, std::int64_t e) const { return b < end && e > begin; }
};

// The range a part file's name states (parts/<begin>-<end>.jsonl[.partial]), or nothing for another name.
std::optional<std::pair<std::int64_t, std::int64_t>> part_range(const std::string& name) {
  std::int64_t b = 0, e = 0;
  const char* p = name.c_str();
  const char* const last = p + name.size();
  auto [after_b, eb] = std::from_chars(p, last, b);
  if (eb != std::errc() || after_b == last || *after_b != '-') return std::nullopt;
  auto [after_e, ee] = std::from_chars(after_b + 1, last, e);
  if (ee != std::errc() || std::string_view(after_e, static_cast<std::size_t>(last - after_e)).rfind(".jsonl", 0) != 0) return std::nullopt;
  return std::pair{b, e};
}

// The records files of a campaign directory: samples.jsonl (a run on one machine) and the parts of
// ranges run as separate tasks, parts/<begin>-<end>.jsonl (complete) or .jsonl.partial (running, or
// stopped: its complete lines are records like any other). Parts whose named range lies outside `wanted`
// are left out. A task completes its part by linking X.jsonl to X.jsonl.partial and then removing the
// .partial, so a listing taken in between holds both names for one file: the complete name is kept.
std::vector<fs::path> record_files(const fs::path& dir, SampleRange wanted) {
  std::vector<fs::path> files;
  if (fs::exists(dir / "samples.jsonl")) files.push_back(dir / "samples.jsonl");
  if (fs::is_directory(dir / "parts")) {
    std::set<std::string> complete, partial;
    for (const auto& e : fs::directory_iterator(dir / "parts")) {
      const std::string name = e.path().filename().string();
      auto ends_with = [&](const std::string& suffix) {
        return name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
      };
      if (const auto r = part_range(name); r && !wanted.overlaps(r->first, r->second)) continue;
      if (ends_with(".jsonl"))
        complete.insert(name);
      else if (ends_with(".jsonl.partial"))
        partial.insert(name.substr(0, name.size() - std::string(".partial").size()));
    }
    // Sorted by name, the complete and the running parts together.
    std::set<std::string> names = complete;
    for (const std::string& p : partial)
      if (!complete.count(p)) names.insert(p + ".partial");
    for (const std::string& n : names) files.push_back(dir / "parts" / n);
  }
  return files;
}

std::string csv_cell(const json& j) {
  if (j.is_null()) return "";
  if (j.is_string()) {
    std::string s = j.get<std::string>(), out = "\"";
    for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c == '\n' ? ' ' : c);
    return out + "\"";
  }
  if (j.is_boolean()) return j.get<bool>() ? "1" : "0";
  if (j.is_structured()) return csv_cell(json(j.dump()));               // a discrete value that is an array or object: quoted
  if (j.is_number_float()) return platform::shortest(j.get<double>());  // reads back bit for bit, as in every CSV
  return j.dump();
}

std::string csv_header(const CampaignSpec& spec, int dof) {
  std::string h = "index";
  for (const auto& in : spec.inputs) h += "," + csv_cell(in.path);
  h += ",status,success,converged,converged_time,target_distance,max_abs_q,max_energy,steps,wall_seconds,hypothesis_failed,error";
  for (int i = 0; i < dof; ++i) h += ",final_q" + std::to_string(i + 1);
  return h + "\n";
}

std::string csv_row(const CampaignSpec& spec, const json& r, int dof) {
  std::string row = std::to_string(r["index"].get<std::int64_t>());
  const json inputs = r.contains("inputs") && r["inputs"].is_object() ? r["inputs"] : json::object();
  for (const auto& in : spec.inputs) row += "," + (inputs.contains(in.path) ? csv_cell(inputs[in.path]) : std::string());
  for (const char* key : {"status", "success", "converged", "converged_time", "target_distance", "max_abs_q", "max_energy", "steps",
                          "wall_seconds", "hypothesis_failed"})
    row += "," + (r.contains(key) ? csv_cell(r[key]) : std::string());
  if (r.contains("error") && r["error"].is_object()) {
    const json& e = r["error"];
    row += "," + csv_cell(json(e.value("pointer", std::string("/")) + ": " + e.value("reason", std::string())));
  } else {
    row += ",";
  }
  const bool has_q = r.contains("final_q") && r["final_q"].is_array();
  for (int i = 0; i < dof; ++i)
    row += "," + (has_q && static_cast<int>(r["final_q"].size()) > i ? csv_cell(r["final_q"][i]) : std::string());
  return row + "\n";
}

}  // namespace

// campaign.json: the spec as given (scene inlined). A directory with another campaign's spec is refused.
void claim_campaign_directory(const CampaignSpec& spec, const std::string& dir_name) {
  const fs::path dir = dir_name;
  fs::create_directories(dir);
  const fs::path file = dir / "campaign.json";
  if (fs::exists(file)) {
    json held;
    try {
      held = read_scene_file(file.string());
    } catch (const std::exception& e) {
      throw std::runtime_error("'" + file.string() + "' is not a campaign spec: " + e.what());
    }
    if (held != spec.document)
      throw std::runtime_error("'" + dir.string() +
                               "' holds a different campaign (its campaign.json differs from this spec): use another directory");
    return;
  }
  // A name of this process's own: the tasks of a split campaign may all claim the directory at once (they
  // write the same text, and rename is atomic).
  const fs::path tmp = dir / ("campaign.json.tmp." + std::to_string(::getpid()) + "." + std::to_string(std::random_device{}()));
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << spec.document.dump(2) << "\n";
    out.close();
    if (!out) {
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw std::runtime_error("cannot write '" + tmp.string() + "' (disk full?)");
    }
  }
  fs::rename(tmp, file);
}

namespace {

void write_summary(const fs::path& dir, const json& summary) {
  for (const auto& [name, text] : {std::pair<const char*, std::string>{"summary.json", summary.dump(2) + "\n"},
                                   std::pair<const char*, std::string>{"summary.txt", format_campaign_summary(summary)}}) {
    const fs::path tmp = dir / (std::string(name) + ".tmp." + std::to_string(::getpid()));
    std::ofstream out(tmp, std::ios::trunc);
    out << text;
    out.close();
    if (!out) throw std::runtime_error("cannot write '" + tmp.string() + "'");
    fs::rename(tmp, dir / name);
  }
}

}  // namespace

namespace {

// A record's value for a message: its serialization, at most about 200 bytes of it (whole UTF-8 characters).
std::string quoted(const json& j) { return j.is_null() ? std::string("nothing") : brief(j); }

// Refuses (std::runtime_error at `where`, "'FILE' line N") a record that is not sample i of this campaign
// as the spec defines it: another spec's hash (or none), inputs other than those the sampler draws for
// its index, or an outcome its own fields contradict. `i` is in range. Returns its steps (0 for none).
std::int64_t check_record(const CampaignSpec& spec, const CampaignDesign& design, const json& r, std::int64_t i, const std::string& where) {
  const auto bad = [&](const std::string& what) {
    return std::runtime_error(where + " is not a record of this campaign: " + what +
                              " (a record of another campaign or an edited one; remove it, or run the campaign in another directory)");
  };
  const auto hash = r.find("spec_hash");
  if (hash == r.end() || !hash->is_string()) throw bad("it has no spec_hash (records carry the hash of the spec they were run for)");
  if (hash->get<std::string>() != spec.hash)
    throw bad("its spec_hash " + quoted(*hash) + " is not this spec's \"" + spec.hash + "\" (campaign.json)");
  // The inputs exactly as drawn: a double is written with round-trip precision, so it reads back equal;
  // a value that is not a finite number is written as null.
  const std::vector<json> drawn = design.values(i);
  const auto inputs = r.find("inputs");
  if (inputs == r.end() || !inputs->is_object() || inputs->size() != drawn.size())
    throw bad("sample " + std::to_string(i) + "'s inputs are not the spec's " + std::to_string(drawn.size()) + " inputs");
  for (std::size_t k = 0; k < drawn.size(); ++k) {
    const std::string& path = spec.inputs[k].path;
    const json want = drawn[k].is_number_float() ? finite_or_null(drawn[k].get<double>()) : drawn[k];
    const auto got = inputs->find(path);
    if (got == inputs->end() || *got != want)
      throw bad("sample " + std::to_string(i) + "'s input " + path + " is " +
                (got == inputs->end() ? std::string("missing") : quoted(*got)) + ", the sampler draws " + quoted(want) + " for it");
  }
  // The outcome as the record's own fields define it (record_of): success means completed, converged and,
  // with a target, within its tolerance.
  const auto status = r.find("status");
  const auto success = r.find("success");
  if (status == r.end() || !status->is_string() || success == r.end() || !success->is_boolean())
    throw bad("it has no status (a string) or no success (true or false)");
  const auto converged = r.find("converged");
  if (converged != r.end() && !converged->is_boolean()) throw bad("its converged is not true or false");
  const auto distance = r.find("target_distance");
  const bool within =
      spec.target_q.empty() || (distance != r.end() && distance->is_number() && distance->get<double>() <= spec.target_tolerance);
  const auto tracking_error = r.find("tracking_error");
  const bool expected = spec.tracking_error ? *status == "completed" && tracking_error != r.end() && tracking_error->is_number() &&
                                                  tracking_error->get<double>() <= *spec.tracking_error
                                            : *status == "completed" && converged != r.end() && converged->get<bool>() && within;
  if (success->get<bool>() != expected)
    throw bad(std::string("its success is ") + (success->get<bool>() ? "true" : "false") +
              ", but its status, convergence and target distance make it " + (expected ? "true" : "false"));
  const auto steps = r.find("steps");
  if (steps == r.end()) return 0;
  if (!steps->is_number_integer() || steps->get<std::int64_t>() < 0)
    throw bad("its steps " + quoted(*steps) + " is not a whole number >= 0");
  return steps->get<std::int64_t>();
}

// Every record of the directory in `wanted`, each index once and inside the campaign, as summary rows
// (and as rows of `csv` when given); present[i] says whether sample i has a record. `own` (a file this
// process writes) has a cut last line repaired; the others' cut lines are handled as `others` says.
// Each is checked to be one of this campaign's (check_record); `steps`, when given, gets the sum of
// their steps.
std::vector<CampaignOutcome> load_rows(const CampaignSpec& spec, const CampaignDesign& design, const fs::path& dir, const fs::path& own,
                                       CutLine others, std::vector<bool>& present, std::ofstream* csv, int dof, SampleRange wanted = {},
                                       std::int64_t* steps = nullptr) {
  present.assign(static_cast<std::size_t>(spec.samples), false);
  std::vector<CampaignOutcome> rows;
  std::vector<fs::path> files = record_files(dir, wanted);
  if (!own.empty() && std::find(files.begin(), files.end(), own) == files.end() && fs::exists(own)) files.push_back(own);
  for (fs::path file : files) {
    // Another task's running part completed since the listing: its records are under the complete name
    // now (read here unless the listing already held that name).
    if (file != own && file.extension() == ".partial" && !fs::exists(file)) {
      file.replace_extension();
      if (std::find(files.begin(), files.end(), file) != files.end()) continue;
    }
    for_each_record(file, file == own ? CutLine::kRepair : others, [&](json&& r, const std::string& where) {
      const auto i = r["index"].get<std::int64_t>();
      if (i < 0 || i >= spec.samples)
        throw std::runtime_error(where + " holds sample " + std::to_string(i) + ", outside the campaign's " + std::to_string(spec.samples) +
                                 " samples");
      if (!wanted.contains(i)) return;
      const std::int64_t record_steps = check_record(spec, design, r, i, where);
      if (steps)
        *steps = record_steps > std::numeric_limits<std::int64_t>::max() - *steps ? std::numeric_limits<std::int64_t>::max()
                                                                                  : *steps + record_steps;
      if (present[static_cast<std::size_t>(i)])
        throw std::runtime_error("sample " + std::to_string(i) + " is present twice (the second time in '" + file.string() + "')");
      present[static_cast<std::size_t>(i)] = true;
      if (csv) *csv << csv_row(spec, r, dof);
      rows.push_back(row_of(spec, r));
    });
  }
  return rows;
}

json summarize_and_write(const CampaignSpec& spec, const fs::path& dir, std::vector<CampaignOutcome>& rows) {
  std::sort(rows.begin(), rows.end(), [](const CampaignOutcome& a, const CampaignOutcome& b) { return a.index < b.index; });
  json summary = summarize_rows(spec, rows);
  write_summary(dir, summary);
  return summary;
}

}  // namespace

std::string range_part_name(std::int64_t begin, std::int64_t end) { return std::to_string(begin) + "-" + std::to_string(end); }

CampaignRunResult run_campaign(const CampaignSpec& spec, const std::string& dir_name, const CampaignRunOptions& options) {
  const fs::path dir = dir_name;
  claim_campaign_directory(spec, dir.string());
  const int dof = Simulation::from_json(spec.scene).dof();
  const std::int64_t begin = std::clamp<std::int64_t>(options.begin, 0, spec.samples);
  const std::int64_t end = options.end < 0 ? spec.samples : std::clamp<std::int64_t>(options.end, begin, spec.samples);
  // A task of a split campaign writes its own part file, renamed from .partial once its range is done;
  // a run of the whole campaign writes samples.jsonl and the table beside it.
  const bool task = options.part;
  fs::path own = dir / "samples.jsonl", own_done;
  if (task) {
    fs::create_directories(dir / "parts");
    own_done = dir / "parts" / (range_part_name(begin, end) + ".jsonl");
    own = own_done;
    own += ".partial";
  }
  const CampaignDesign design(spec);
  std::vector<bool> done;
  std::int64_t present = 0;       // samples with a record before this run
  std::int64_t steps_before = 0;  // the steps of their records
  CampaignRunResult result;
  if (task) {
    // A block that is complete is left as it is: nothing is opened, created or renamed.
    load_rows(spec, design, dir, fs::path(), CutLine::kIgnore, done, nullptr, dof, SampleRange{begin, end});
    bool complete = true;
    for (std::int64_t i = begin; i < end && complete; ++i) complete = done[static_cast<std::size_t>(i)];
    if (complete) {
      result.skipped = end - begin;
      return result;
    }
  }
  // One writer per records file: a second process on the same file (two tasks given the same block, a
  // requeued task whose first run still writes, two runs of the whole campaign in one directory) is
  // refused, not mixed in. Taken before the file is read, so that its cut last line is repaired by its
  // one writer.
  const int lock_fd = ::open(own.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (lock_fd < 0) throw std::runtime_error("cannot write '" + own.string() + "'");
  struct Unlock {
    int fd;
    ~Unlock() { ::close(fd); }  // closing releases the lock
  } unlock{lock_fd};
  if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0)
    throw std::runtime_error("'" + own.string() + "' is being written by another process (the same samples run twice at once?)");
  std::ofstream out_csv;
  if (task) {
    present = static_cast<std::int64_t>(
        load_rows(spec, design, dir, own, CutLine::kIgnore, done, nullptr, dof, SampleRange{begin, end}, &steps_before).size());
  } else {
    // The table is rewritten from the records: it may have been cut at another point than they were.
    const fs::path csv = dir / "samples.csv";
    {
      std::ofstream table(csv, std::ios::trunc);
      table << csv_header(spec, dof);
      present = static_cast<std::int64_t>(load_rows(spec, design, dir, own, CutLine::kIgnore, done, &table, dof, {}, &steps_before).size());
      if (!table) throw std::runtime_error("cannot write '" + csv.string() + "'");
    }
    out_csv.open(csv, std::ios::app);
    if (!out_csv) throw std::runtime_error("cannot write '" + csv.string() + "'");
  }
  result.skipped = 0;
  for (std::int64_t i = begin; i < end; ++i) result.skipped += done[static_cast<std::size_t>(i)];
  std::ofstream out_jsonl(own, std::ios::app | std::ios::binary);
  if (!out_jsonl) throw std::runtime_error("cannot write '" + own.string() + "'");

  std::atomic<std::int64_t> next{begin};
  // The integration steps so far (the records present, then every finished sample), for max_total_steps.
  std::atomic<std::int64_t> steps_so_far{steps_before};
  std::string step_limit;  // why the run stopped at max_total_steps (under write_mu)
  std::mutex write_mu;
  std::exception_ptr error;
  std::int64_t finished = result.skipped;
  // The limit is on what the records and the table take on disk, so what a stopped run left there counts:
  // a campaign resumed any number of times (a restarted server goes on from its records) stays within it.
  std::int64_t written_bytes =
      static_cast<std::int64_t>(fs::file_size(own)) + (task ? 0 : static_cast<std::int64_t>(fs::file_size(dir / "samples.csv")));
  std::atomic<bool> failed{false};
  auto work = [&] {
    CampaignSampleRunner runner(spec, design, options.max_steps);
    while (!(options.stop && options.stop->load()) && !failed.load()) {
      std::int64_t i = next.fetch_add(1);
      while (i < end && done[static_cast<std::size_t>(i)]) i = next.fetch_add(1);  // done[] of a skipped sample never changes
      if (i >= end) return;
      if (options.max_total_steps > 0 && steps_so_far.load() >= options.max_total_steps) {
        // No sample starts once the count reaches the limit; the samples running now finish and their
        // records are written (their steps are taken), then the run ends with the reason.
        std::lock_guard lock(write_mu);
        if (step_limit.empty())
          step_limit = "the campaign reached the limit of " + std::to_string(options.max_total_steps) +
                       " integration steps (its samples ran " + std::to_string(steps_so_far.load()) +
                       ") with samples still to run, from sample " + std::to_string(i) + "; the records of the finished samples are kept";
        failed = true;
        return;
      }
      json r = runner.run(i);
      const std::int64_t steps = r.value("steps", std::int64_t{0});  // an invalid sample has none
      const std::string line = r.dump() + '\n', row = task ? std::string() : csv_row(spec, r, dof);
      r = json();  // nothing of a finished sample stays in memory: it is on disk
      std::lock_guard lock(write_mu);
      if (error) return;
      written_bytes += static_cast<std::int64_t>(line.size() + row.size());
      if (options.max_bytes > 0 && written_bytes > options.max_bytes) {
        error = std::make_exception_ptr(std::runtime_error("the records reached the limit of " + std::to_string(options.max_bytes) +
                                                           " bytes at sample " + std::to_string(i)));
        failed = true;
        return;
      }
      // The record, then its row: the records are the truth (the table is rebuilt from them).
      out_jsonl << line;
      out_jsonl.flush();
      if (!task) {
        out_csv << row;
        out_csv.flush();
      }
      if (!out_jsonl || (!task && !out_csv)) {
        error = std::make_exception_ptr(std::runtime_error("writing to '" + dir.string() + "' failed (disk full?)"));
        failed = true;
        return;
      }
      ++result.ran;
      result.steps += steps;
      steps_so_far += steps;
      if (options.progress) options.progress(++finished, end - begin);
    }
  };
  // An exception in a worker (out of memory, a failing progress callback) ends the run with it, never
  // std::terminate.
  auto worker = [&] {
    try {
      work();
    } catch (...) {
      std::lock_guard lock(write_mu);
      if (!error) error = std::current_exception();
      failed = true;
    }
  };
  const std::int64_t todo = (end - begin) - result.skipped;
  const int workers = static_cast<int>(
      std::clamp<std::int64_t>(options.workers, 1, std::min<std::int64_t>(kMaxCampaignWorkers, std::max<std::int64_t>(1, todo))));
  {
    struct Joiner {
      std::vector<std::thread> threads;
      ~Joiner() {
        for (auto& t : threads)
          if (t.joinable()) t.join();
      }
    } pool;
    for (int t = 1; t < workers; ++t) pool.threads.emplace_back(worker);
    worker();
  }
  if (error) std::rethrow_exception(error);
  if (!step_limit.empty() && result.ran + result.skipped < end - begin) throw std::runtime_error(step_limit);
  result.stopped = result.ran + result.skipped < end - begin;
  out_jsonl.close();
  if (task) {
    // The range is complete: the part appears under its final name at once (a hard link is atomic and,
    // unlike rename, never replaces a complete part that is already there).
    if (!result.stopped) {
      if (::link(own.c_str(), own_done.c_str()) != 0)
        throw std::runtime_error("cannot name the complete part '" + own_done.string() + "': " + std::strerror(errno) +
                                 " (its records stay in '" + own.string() + "')");
      fs::remove(own);
    }
  } else if (present + result.ran == spec.samples) {
    // Every sample is present: the summary's rows are read back from the records (while samples run,
    // memory does not grow with them).
    std::vector<CampaignOutcome> rows = load_rows(spec, design, dir, fs::path(), CutLine::kError, done, nullptr, dof);
    summarize_and_write(spec, dir, rows);
    result.summarized = true;
  }
  return result;
}

std::pair<std::int64_t, std::int64_t> task_range(std::int64_t samples, std::int64_t task, std::int64_t tasks) {
  // Contiguous blocks whose sizes differ by at most one. samples * k stays far inside 64 bits: at most
  // kMaxCampaignSamples (10^7) times k < tasks, and tasks is clamped to the samples.
  tasks = std::clamp<std::int64_t>(tasks, 1, std::max<std::int64_t>(1, samples));
  task = std::clamp<std::int64_t>(task, 0, tasks - 1);
  const auto edge = [&](std::int64_t k) { return samples * k / tasks; };
  return {edge(task), edge(task + 1)};
}

std::vector<std::int64_t> missing_per_task(const std::string& dir_name, const CampaignSpec& spec, std::int64_t tasks) {
  std::vector<bool> present;
  const CampaignDesign design(spec);
  load_rows(spec, design, dir_name, fs::path(), CutLine::kIgnore, present, nullptr, 0);
  std::vector<std::int64_t> missing(static_cast<std::size_t>(tasks), 0);
  for (std::int64_t k = 0; k < tasks; ++k) {
    const auto [b, e] = task_range(spec.samples, k, tasks);
    for (std::int64_t i = b; i < e; ++i) missing[static_cast<std::size_t>(k)] += !present[static_cast<std::size_t>(i)];
  }
  return missing;
}

std::vector<CampaignOutcome> read_campaign_outcomes(const CampaignSpec& spec, const std::string& dir) {
  std::vector<bool> present;
  const CampaignDesign design(spec);
  std::vector<CampaignOutcome> rows = load_rows(spec, design, dir, fs::path(), CutLine::kError, present, nullptr, 0);
  std::sort(rows.begin(), rows.end(), [](const CampaignOutcome& a, const CampaignOutcome& b) { return a.index < b.index; });
  return rows;
}

json collect_campaign(const std::string& dir_name) {
  const fs::path dir = dir_name;
  const fs::path spec_file = dir / "campaign.json";
  if (!fs::exists(spec_file)) throw std::runtime_error("'" + dir.string() + "' holds no campaign.json: not a campaign directory");
  const CampaignSpec spec = CampaignSpec::from_json(read_scene_file(spec_file.string()), dir.string());
  // The table of every record, rebuilt (a split campaign's tasks write only their parts).
  const fs::path csv = dir / "samples.csv", csv_tmp = dir / "samples.csv.tmp";
  const int dof = Simulation::from_json(spec.scene).dof();
  std::vector<bool> present;
  std::vector<CampaignOutcome> rows;
  {
    std::ofstream table(csv_tmp, std::ios::trunc);
    table << csv_header(spec, dof);
    rows = load_rows(spec, CampaignDesign(spec), dir, fs::path(), CutLine::kError, present, &table, dof);
    table.close();
    if (!table) throw std::runtime_error("cannot write '" + csv_tmp.string() + "'");
  }
  fs::rename(csv_tmp, csv);
  std::int64_t missing = 0, first_missing = -1;
  for (std::int64_t i = 0; i < spec.samples; ++i)
    if (!present[static_cast<std::size_t>(i)] && missing++ == 0) first_missing = i;
  if (missing)
    throw std::runtime_error(std::to_string(missing) + " of " + std::to_string(spec.samples) + " samples are missing (the first: " +
                             std::to_string(first_missing) + "): run the campaign again on the same directory to finish it");
  return summarize_and_write(spec, dir, rows);
}

}  // namespace moreau::scene
