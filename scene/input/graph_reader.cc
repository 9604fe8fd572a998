// The feedback graphs of a Lur'e scene (/system/feedback/i): the named graphs of Brogliato (2003) and
// general piecewise-linear ones from their vertices, each checked maximal monotone with the field that
// breaks it named.
#include "graph_reader.h"

#include <cmath>

#include "json_checks.h"
#include "moreau/scene/scene.h"

namespace moreau::scene::detail {

using nlohmann::json;

MonotoneGraph read_feedback_graph(const json& f, const std::string& ptr, std::string& type, const ConstantReader& constant) {
  require_object(f, ptr);
  static const char* kTypes = "relay, coulomb, saturation, dead_zone, complementarity, mos, adhesive, graph";
  if (!f.contains("type") || !f["type"].is_string()) throw SceneError(ptr + "/type", std::string("missing feedback type (") + kTypes + ")");
  type = f["type"].get<std::string>();
  auto value = [&](const char* key, bool required, double fallback) {
    if (!f.contains(key)) {
      if (required) throw SceneError(ptr, std::string("missing '") + key + "' for a " + type + " feedback");
      return fallback;
    }
    return constant(f[key], ptr + "/" + key);
  };
  auto nonnegative = [&](const char* key, bool required, double fallback) {
    const double v = value(key, required, fallback);
    if (!(v >= 0.0)) throw SceneError(ptr + "/" + key, "must be >= 0 (the graph must be monotone), got " + format(v));
    return v;
  };
  auto positive_value = [&](const char* key, bool required, double fallback) {
    const double v = value(key, required, fallback);
    if (!(v > 0.0)) throw SceneError(ptr + "/" + key, "must be > 0, got " + format(v));
    return v;
  };
  if (type == "relay") {
    check_fields(f, ptr, {"type", "gain"});
    return MonotoneGraph::relay(nonnegative("gain", true, 0.0));
  }
  if (type == "coulomb") {
    check_fields(f, ptr, {"type", "gain", "slope"});
    const double a = nonnegative("gain", true, 0.0);
    return MonotoneGraph::coulomb(a, nonnegative("slope", false, 0.0));
  }
  // The named graphs compute their vertices; each must be a finite number (MonotoneGraph would fall
  // back to the zero graph otherwise), and is refused at the field that makes it overflow.
  auto finite_vertex = [&](double v, const char* key, const std::string& what) {
    if (!std::isfinite(v)) throw SceneError(ptr + "/" + key, what + " overflows a double (" + format(v) + ")");
  };
  if (type == "saturation") {
    check_fields(f, ptr, {"type", "slope", "limit"});
    const double k = positive_value("slope", true, 0.0);
    const double limit = positive_value("limit", true, 0.0);
    // Vertices (-limit/slope, -limit) and (limit/slope, limit): the segment rises by 2 limit over 2 limit/slope.
    finite_vertex(2.0 * limit, "limit", "the rise 2 limit of the sloped segment");
    finite_vertex(2.0 * (limit / k), "slope", "the run 2 limit / slope of the sloped segment");
    return MonotoneGraph::saturation(k, limit);
  }
  if (type == "dead_zone") {
    check_fields(f, ptr, {"type", "width", "slope"});
    const double d = nonnegative("width", true, 0.0);
    return MonotoneGraph::dead_zone(d, positive_value("slope", true, 0.0));
  }
  if (type == "complementarity") {
    check_fields(f, ptr, {"type"});
    return MonotoneGraph::complementarity();
  }
  if (type == "mos") {
    check_fields(f, ptr, {"type", "threshold", "limit", "slope"});
    const double b = nonnegative("threshold", false, 0.0);
    const double a = positive_value("limit", true, 0.0);
    if (!(a > b)) throw SceneError(ptr + "/limit", "must be > threshold (" + format(b) + "), got " + format(a));
    const double k = nonnegative("slope", true, 0.0);
    finite_vertex(k * (a - b), "slope", "the value at the walls slope * (limit - threshold)");
    return MonotoneGraph::mos(b, a, k);
  }
  if (type == "adhesive") {
    check_fields(f, ptr, {"type", "force", "stiffness"});
    const double force = nonnegative("force", true, 0.0);
    const double k = f.contains("stiffness") ? positive_value("stiffness", true, 0.0) : 0.0;
    if (k > 0.0) finite_vertex(force / k, "stiffness", "the breakpoint force / stiffness");
    return MonotoneGraph::adhesive(force, k);
  }
  if (type == "graph") {
    check_fields(f, ptr, {"type", "vertices", "left", "right"});
    if (!f.contains("vertices")) throw SceneError(ptr, "missing 'vertices' ([[u0, w0], [u1, w1], ...])");
    const json& vs = f["vertices"];
    if (!vs.is_array() || vs.empty())
      throw SceneError(ptr + "/vertices", "expected a non-empty array of vertices [u, w], got " + type_name(vs));
    if (vs.size() > 1024) throw SceneError(ptr + "/vertices", "more than 1024 vertices");
    std::vector<double> u, w;
    for (std::size_t k = 0; k < vs.size(); ++k) {
      const std::string vp = ptr + "/vertices/" + std::to_string(k);
      if (!vs[k].is_array() || vs[k].size() != 2) throw SceneError(vp, "expected a vertex [u, w], got " + brief(vs[k]));
      u.push_back(constant(vs[k][0], vp + "/0"));
      w.push_back(constant(vs[k][1], vp + "/1"));
    }
    auto end = [&](const char* key, MonotoneGraph::End& kind, double& slope) {
      kind = MonotoneGraph::End::kSlope;
      slope = 0.0;
      if (!f.contains(key)) return;
      const json& e = f[key];
      if (e.is_string() && e.get<std::string>() == "wall") {
        kind = MonotoneGraph::End::kWall;
        return;
      }
      try {
        slope = constant(e, ptr + "/" + key);
      } catch (const SceneError& err) {
        throw SceneError(ptr + "/" + key, "expected \"wall\" or the slope of the ray (a number >= 0): " + err.reason());
      }
    };
    MonotoneGraph::End left, right;
    double sl, sr;
    end("left", left, sl);
    end("right", right, sr);
    MonotoneGraph::Problem problem;
    if (!MonotoneGraph::check(u, w, left, sl, right, sr, &problem)) {
      std::string where = ptr + "/" + problem.field;
      if (problem.index >= 0) where += "/" + std::to_string(problem.index);
      if (problem.coordinate >= 0) where += "/" + std::to_string(problem.coordinate);
      throw SceneError(where, problem.reason);
    }
    return MonotoneGraph(u, w, left, sl, right, sr);
  }
  throw SceneError(ptr + "/type", "unknown feedback type '" + type + "' (expected one of: " + kTypes + ")");
}

}  // namespace moreau::scene::detail
