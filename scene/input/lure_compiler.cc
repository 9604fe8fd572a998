// The Lur'e compiler: a scene of system type "lure" (x' = A x - B y_L, y = C x, y_L in d phi(y), eq. (4) of
// Brogliato 2003) -> a LureScene, with Lemma 1's domain condition and Lemmas 1-2's hypotheses
// (minimality, strict positive realness or a given storage matrix) decided at compile time. See
// docs/scene-format.md; the parts shared with the Lagrangian compiler are scene_reader.h.
#include "moreau/scene/scene.h"

#include <cmath>
#include <set>

#include "graph_reader.h"
#include "scene_reader.h"

namespace moreau::scene {

namespace {

using nlohmann::json;
using namespace detail;
using expr::Node;

class LureCompiler : SceneReader {
 public:
  explicit LureCompiler(const json& doc) : SceneReader(doc) {}
  LureScene compile();

 private:
  void lure_integrator(LureScene& scene) {
    if (!doc_.contains("integrator")) throw SceneError("/integrator", "missing required field 'integrator' (h and t_end)");
    const json& in = doc_["integrator"];
    require_object(in, "/integrator");
    check_fields(in, "/integrator", {"scheme", "h", "t_end", "t0", "theta", "step_rule", "max_steps"});
    if (in.contains("scheme")) {
      if (!in["scheme"].is_string()) throw SceneError("/integrator/scheme", "expected a string");
      const std::string sch = in["scheme"].get<std::string>();
      const std::optional<Scheme> named = scheme_from_name(sch);
      const std::string expected = scheme_names_for_scenes(SystemType::kLure);
      if (named && traits(*named).system != SystemType::kLure)
        throw SceneError("/integrator/scheme", "the " + sch + " scheme is for lagrangian systems; a lure system takes " + expected);
      if (!named || !traits(*named).scene_can_name)
        throw SceneError("/integrator/scheme", "unknown scheme '" + sch + "' (expected: " + expected + ")");
      scene.scheme = *named;
    }
    LureSettings& s = scene.settings;
    read_interval(in, s.h, s.t0, s.t_end);
    if (in.contains("theta")) {
      s.theta = constant(in["theta"], "/integrator/theta");
      if (!(s.theta >= 0.5 && s.theta <= 1.0))
        throw SceneError("/integrator/theta", "must be in [1/2, 1] (the theta-method is unstable below 1/2), got " + format(s.theta));
    }
    if (in.contains("step_rule") && in["step_rule"] != "fixed")
      throw SceneError("/integrator/step_rule", "the implicit-euler scheme uses a fixed step (\"fixed\"), got " + brief(in["step_rule"]));
    s.max_steps = read_max_steps(in);
    check_step_count(s.t0, s.t_end, s.h, s.max_steps, /*fixed=*/true);
  }
};

LureScene LureCompiler::compile() {
  LureScene scene;
  scene.name = read_top_level();
  declare_parameters();
  if (!doc_.contains("system")) throw SceneError("/system", "missing required field 'system'");
  const json& system = doc_["system"];
  require_object(system, "/system");
  if (!system.contains("type") || system["type"] != "lure") throw SceneError("/system/type", "expected \"lure\"");
  check_fields(system, "/system", {"type", "states", "A", "B", "C", "feedback", "P"});
  check_all_parameters();
  for (const char* f : {"A", "B", "C", "feedback"})
    if (!system.contains(f))
      throw SceneError("/system", std::string("missing required field '") + f + "' (x' = A x - B y_L, y = C x, y_L in d phi(y))");
  scene.A = constant_matrix(system["A"], "/system/A", -1, -1, "the n x n matrix A");
  const int n = static_cast<int>(scene.A.rows());
  if (scene.A.cols() != n)
    throw SceneError("/system/A/0", "A must be square: " + std::to_string(n) + " rows but " + std::to_string(scene.A.cols()) + " columns");
  scene.B = constant_matrix(system["B"], "/system/B", n, -1, "B has one row per state");
  const int m = static_cast<int>(scene.B.cols());
  if (m > kMaxConstraints) throw SceneError("/system/B", "more than " + std::to_string(kMaxConstraints) + " feedback components");
  scene.C = constant_matrix(system["C"], "/system/C", m, n, "C is m x n: one row per column of B, one column per state");
  scene.n = n;
  scene.m = m;
  n_ = n;
  const json& fb = system["feedback"];
  if (!fb.is_array()) throw SceneError("/system/feedback", "expected an array with one graph per output, got " + type_name(fb));
  if (fb.size() != static_cast<std::size_t>(m))
    throw SceneError("/system/feedback",
                     "expected " + std::to_string(m) + " graphs (one per output y = C x), got " + std::to_string(fb.size()));
  for (int i = 0; i < m; ++i) {
    std::string type;
    scene.feedback.push_back(read_feedback_graph(fb[i], "/system/feedback/" + std::to_string(i), type,
                                                 [this](const json& j, const std::string& p) { return constant(j, p); }));
    scene.feedback_types.push_back(type);
  }
  for (int i = 0; i < n; ++i) {
    std::string name = "x" + std::to_string(i + 1);
    if (system.contains("states")) {
      const json& st = system["states"];
      if (!st.is_array() || st.size() != static_cast<std::size_t>(n))
        throw SceneError("/system/states", "expected " + std::to_string(n) + " names (one per state)");
      const std::string ptr = "/system/states/" + std::to_string(i);
      if (!st[i].is_string() || !is_identifier(st[i].get<std::string>()))
        throw SceneError(ptr, "expected a name (letters, digits, _), got " + brief(st[i]));
      name = st[i].get<std::string>();
    }
    scene.states.push_back(name);
    scene.state_rates.push_back(name + "_dot");
  }
  // State names name the trajectory's columns as coordinate names do: the same rule.
  if (const auto conflict = column_name_conflict(scene.states, "state"))
    throw SceneError("/system/states/" + std::to_string(conflict->index), conflict->reason);
  if (system.contains("P")) scene.P = constant_matrix(system["P"], "/system/P", n, n, "P is n x n");

  if (!doc_.contains("initial")) throw SceneError("/initial", "missing required field 'initial' (x)");
  const json& ini = doc_["initial"];
  require_object(ini, "/initial");
  check_fields(ini, "/initial", {"x"});
  if (!ini.contains("x")) throw SceneError("/initial", "missing required field 'x'");
  scene.x0 = constant_vector(ini["x"], "/initial/x");
  lure_integrator(scene);
  if (const auto every = output_every()) scene.settings.output_every = *every;
  if (doc_.contains("exact")) {
    const json& ex = doc_["exact"];
    require_object(ex, "/exact");
    check_fields(ex, "/exact", {"x", "rest_time", "rest_x", "note"});
    if (ex.contains("x")) {
      std::vector<Node> outs;
      const json& arr = array_of(ex["x"], "/exact/x", static_cast<std::size_t>(n), "an array of expressions in t");
      for (int i = 0; i < n; ++i)
        outs.push_back(expression(arr[i], "/exact/x/" + std::to_string(i), kTime, "an exact solution (a function of t)"));
      scene.exact_tape = std::make_shared<expr::Tape>(expr::Tape::compile(graph_, outs, 1));
    }
    if (ex.contains("rest_time")) scene.exact_rest_time = constant(ex["rest_time"], "/exact/rest_time");
    if (ex.contains("rest_x")) scene.exact_rest_x = constant_vector(ex["rest_x"], "/exact/rest_x");
  }

  // Lemma 1 needs C x(0) in dom d phi.
  const Eigen::VectorXd x0 = Eigen::Map<const Eigen::VectorXd>(scene.x0.data(), n);
  const Eigen::VectorXd y0 = scene.C * x0;
  for (int i = 0; i < m; ++i) {
    if (!scene.feedback[i].in_domain(y0(i)))
      throw SceneError("/initial/x", "y0 = C x0 has component " + std::to_string(i) + " = " + format(y0(i)) +
                                         ", outside the domain of /system/feedback/" + std::to_string(i) +
                                         " (Lemma 1 needs C x(0) in dom d phi)");
  }
  // Lemmas 1-2: the given P, or a strict positive realness test; minimality either way.
  scene.minimality = check_minimality(scene.A, scene.B, scene.C);
  if (scene.P) {
    scene.p_check = check_storage_matrix(scene.A, scene.B, scene.C, *scene.P);
    scene.storage = scene.P;
    scene.storage_source = "scene";
  } else {
    scene.spr = test_strict_positive_realness(scene.A, scene.B, scene.C);
    if (scene.spr.storage_found()) {
      scene.storage = scene.spr.P;
      scene.storage_source = "found";
    }
  }
  // The report follows W = 1/2 x^T P x (P = I without a storage matrix): finite where the run starts.
  const Eigen::MatrixXd P = scene.storage ? *scene.storage : Eigen::MatrixXd::Identity(n, n);
  const double w0 = 0.5 * x0.dot(P * x0);
  if (!std::isfinite(w0))
    throw SceneError("/initial/x", "the storage function W = 1/2 x0^T P x0 is not finite at the initial state (" + format(w0) + ")");
  scene.unread_parameters = unread_parameters();
  return scene;
}

}  // namespace

std::string system_type(const nlohmann::json& doc) {
  if (doc.is_object() && doc.contains("system") && doc["system"].is_object() && doc["system"].contains("type") &&
      doc["system"]["type"].is_string())
    return doc["system"]["type"].get<std::string>();
  return "lagrangian";
}

LureScene load_lure_scene(const nlohmann::json& doc) {
  LureCompiler compiler(doc);
  return compile_scene([&] { return compiler.compile(); });
}

}  // namespace moreau::scene
