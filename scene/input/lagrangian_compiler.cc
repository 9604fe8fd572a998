// The Lagrangian compiler: a scene of system type "lagrangian" (M(q) q'' + C(q, q') q' + grad V(q) + F in
// -dPhi(q'), with optional unilateral constraints) -> a LagrangianScene with its compiled tapes. See
// docs/scene-format.md; the parts shared with the Lur'e compiler are scene_reader.h.
#include "moreau/expr/interval.h"
#include "moreau/expr/linear_form.h"
#include "moreau/scene/scene.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>

#include "moreau/platform/number_text.h"
#include "moreau/scene/urdf.h"
#include "sparse_vector_tapes.h"
#include "scene_reader.h"

namespace moreau::scene {

namespace {

using nlohmann::json;
using namespace detail;
using expr::Graph;
using expr::Node;
using expr::Op;

class LagrangianCompiler : SceneReader {
 public:
  explicit LagrangianCompiler(const json& doc) : SceneReader(doc) {}
  LagrangianScene compile();
  // ParametricLagrangianScene: the parameters left free and their values in the document.
  void keep_free(std::vector<std::string> names, std::vector<double> values) {
    free_params_ = std::move(names);
    free_values_ = std::move(values);
  }
  // Whether some x^p in grad V + F has an exponent p that depends on a free parameter: whether x^p is
  // smooth everywhere (Assumption 3.3, Graph::smooth_everywhere) depends on p's value then.
  bool free_parameter_in_an_exponent() const {
    return std::any_of(g_.begin(), g_.end(), [this](Node f) {
      return graph_.any_reachable(
          f, [this](const expr::Graph::Entry& e) { return e.op == Op::kPow && !graph_.is_constant(e.b) && bound_only(e.b); });
    });
  }
  // check_at_initial_state for a binding of the free parameters.
  void check_binding(const LagrangianScene& scene, const std::vector<double>& values) { check_at_initial_state(scene, values.data()); }

 private:
  void coordinates(const json& system) {
    if (robot_) {
      for (const char* field : {"mass", "coordinates", "coriolis", "potential_gradient"})
        if (system.contains(field))
          throw SceneError(std::string("/system/") + field,
                           std::string("a URDF system takes its ") +
                               (std::string(field) == "coordinates" ? "coordinates (the joints)" : "dynamics") +
                               " from the robot model; remove '" + field + "'");
      n_ = robot_->model.dof();
      if (n_ > kMaxDof)
        throw SceneError("/system/urdf", "more than " + std::to_string(kMaxDof) + " moving joints (got " + std::to_string(n_) +
                                             "): a robot's M(q) is dense (each joint's inertia couples it to the joints above it) and "
                                             "changes with q, so each step factorises it whole, at a cost growing as n^3; the paths at "
                                             "scale need a constant sparse M (docs/scaling.md)");
      // Joint names as coordinate names: characters an expression cannot use become '_', and a name that
      // starts with a digit (or is empty) gets the prefix j_. The names then follow the rule of every
      // coordinate name (column_name_conflict): the error names the joint, and its line in the URDF.
      std::vector<std::string> names;
      for (int i = 0; i < n_; ++i) {
        std::string q = robot_->model.bodies[static_cast<std::size_t>(i)].joint_name;
        for (char& ch : q)
          if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_')) ch = '_';
        if (q.empty() || std::isdigit(static_cast<unsigned char>(q[0]))) q = "j_" + q;
        names.push_back(q);
      }
      if (const auto conflict = column_name_conflict(names, "coordinate")) {
        const std::string& joint = robot_->model.bodies[conflict->index].joint_name;
        const std::string& q = names[conflict->index];
        const int line = robot_->joint_lines[conflict->index];  // from the URDF module's own parse
        throw SceneError("/system/urdf/text", "joint '" + utf8_prefix(joint, 200) + "'" +
                                                  (line > 0 ? " (line " + std::to_string(line) + ")" : std::string()) +
                                                  (q == joint ? "" : " gives the coordinate name '" + q + "'") + ": " + conflict->reason);
      }
      for (int i = 0; i < n_; ++i) {
        const std::string& q = names[static_cast<std::size_t>(i)];
        for (const std::string& name : {q, q + "_dot"})
          if (params_.count(name))
            throw SceneError("/parameters/" + json_pointer_token(name),
                             "'" + name + "' is also the name of a coordinate or velocity (joint '" +
                                 utf8_prefix(robot_->model.bodies[static_cast<std::size_t>(i)].joint_name, 200) + "' of the URDF)");
        coord_names_.push_back(q);
        vel_names_.push_back(q + "_dot");
        coord_slot_[q] = 1 + i;
        coord_slot_[q + "_dot"] = 1 + n_ + i;
      }
      return;
    }
    if (!system.contains("mass")) throw SceneError("/system", "missing required field 'mass'");
    const json& mass = system["mass"];
    diagonal_mass_ = mass.is_object() && !mass.contains("bands");
    banded_mass_ = mass.is_object() && mass.contains("bands");
    if (diagonal_mass_) {
      check_fields(mass, "/system/mass", {"diagonal"});
      if (!mass.contains("diagonal") || !mass["diagonal"].is_array() || mass["diagonal"].empty())
        throw SceneError("/system/mass/diagonal", "expected a non-empty array (the diagonal of M, one entry per coordinate)");
    } else if (banded_mass_) {
      check_fields(mass, "/system/mass", {"bands"});
      const json& b = mass["bands"];
      if (!b.is_array() || b.empty() || !b[0].is_array() || b[0].empty())
        throw SceneError("/system/mass/bands", "expected an array of bands, the first the diagonal of M (one entry per coordinate)");
    } else if (!mass.is_array() || mass.empty()) {
      throw SceneError("/system/mass",
                       "expected a square array of arrays (the n x n mass matrix), {\"diagonal\": [...]} or "
                       "{\"bands\": [[...], ...]}, got " +
                           type_name(mass));
    }
    if (system.contains("coordinates")) {
      const json& c = system["coordinates"];
      if (!c.is_array() || c.empty()) throw SceneError("/system/coordinates", "expected a non-empty array of names");
      n_ = static_cast<int>(c.size());
    } else {
      n_ = static_cast<int>(diagonal_mass_ ? mass["diagonal"].size() : banded_mass_ ? mass["bands"][0].size() : mass.size());
    }
    const std::string n_ptr = system.contains("coordinates") ? "/system/coordinates" : "/system/mass";
    if (n_ > kMaxLargeContactDof)
      throw SceneError(n_ptr, "more than " + std::to_string(kMaxLargeContactDof) + " degrees of freedom (got " + std::to_string(n_) +
                                  "): the limit of one run, whose memory and step time grow with n");
    // Beyond the dense limits the scene runs on the large-contact path (large_contact_integrator.h),
    // whose requirements each field checks (large_requirement).
    const std::size_t constraints = system.contains("constraints") && system["constraints"].is_array() ? system["constraints"].size() : 0;
    large_ = n_ > kMaxDof || constraints > static_cast<std::size_t>(kMaxConstraints);
    if (n_ > kMaxDof && !diagonal_mass_ && !banded_mass_)
      throw SceneError(n_ptr, "more than " + std::to_string(kMaxDof) + " degrees of freedom (got " + std::to_string(n_) +
                                  ") with a full mass matrix: up to " + std::to_string(kMaxDof) +
                                  " the step is dense; beyond, give M as {\"diagonal\": [...]} or {\"bands\": [...]} of constants "
                                  "for the paths at scale (docs/scaling.md)");
    if (system.contains("coordinates")) {
      std::vector<std::string> names;
      for (int i = 0; i < n_; ++i) {
        const json& name = system["coordinates"][i];
        if (!name.is_string() || !is_identifier(name.get<std::string>()))
          throw SceneError("/system/coordinates/" + std::to_string(i), "expected a name (letters, digits, _), got " + brief(name));
        names.push_back(name.get<std::string>());
      }
      if (const auto conflict = column_name_conflict(names, "coordinate"))
        throw SceneError("/system/coordinates/" + std::to_string(conflict->index), conflict->reason);
    }
    for (int i = 0; i < n_; ++i) {
      std::string q = "q" + std::to_string(i + 1), v = "v" + std::to_string(i + 1);
      if (system.contains("coordinates")) {
        q = system["coordinates"][i].get<std::string>();
        v = q + "_dot";
      }
      for (const std::string& name : {q, v})
        if (params_.count(name))
          throw SceneError("/parameters/" + json_pointer_token(name), "'" + name + "' is also the name of a coordinate or velocity");
      coord_names_.push_back(q);
      vel_names_.push_back(v);
      coord_slot_[q] = 1 + i;
      coord_slot_[v] = 1 + n_ + i;
    }
  }

  // /system/urdf: the robot model (urdf.h). The text is inline ("text"); a "file" is read, relative to
  // the scene file, when the scene is read from one (read_scene_file), never here.
  void urdf(const json& system) {
    const json& u = system["urdf"];
    require_object(u, "/system/urdf");
    check_fields(u, "/system/urdf", {"text", "file", "root", "tip", "gravity", "friction", "limits"});
    if (u.contains("file"))
      throw SceneError("/system/urdf/file",
                       "a URDF file is read when the scene is read from a file (moreau run, moreau submit); "
                       "a scene sent as JSON carries the URDF itself in 'text'");
    if (!u.contains("text") || !u["text"].is_string()) throw SceneError("/system/urdf", "missing 'text' (the URDF) or 'file' (its path)");
    UrdfSelection sel;
    for (const char* field : {"root", "tip"}) {
      if (!u.contains(field)) continue;
      if (!u[field].is_string() || u[field].get<std::string>().empty())
        throw SceneError(std::string("/system/urdf/") + field, "expected the name of a link");
      (std::string(field) == "root" ? sel.root_link : sel.tip_link) = u[field].get<std::string>();
    }
    try {
      robot_ = std::make_shared<UrdfRobot>(read_urdf(u["text"].get<std::string>(), sel));
    } catch (const UrdfError& e) {
      throw SceneError("/system/urdf/text", e.what());
    }
    if (u.contains("gravity")) {
      const json& g = u["gravity"];
      if (!g.is_array() || g.size() != 3)
        throw SceneError("/system/urdf/gravity", "expected [gx, gy, gz] in m/s^2 (the base frame), got " + brief(g));
      for (int i = 0; i < 3; ++i) robot_->model.gravity_m_s2(i) = constant(g[i], "/system/urdf/gravity/" + std::to_string(i));
    }
  }

  // Joint friction of a URDF system, as part of Phi: viscous b_i v_i is d(1/2 b_i v_i^2), Coulomb
  // friction is d(mu_i |v_i|), both exactly the controller's quadratic and abs terms (Remark 4.2).
  // "urdf" takes <dynamics damping friction>; an object gives {"viscous": [...], "coulomb": [...]}.
  void joint_friction(const json& system, LagrangianScene& scene) {
    if (!robot_ || !system["urdf"].contains("friction")) return;
    const json& f = system["urdf"]["friction"];
    const std::string ptr = "/system/urdf/friction";
    auto& phi = scene.controller;
    if (f.is_string() && f.get<std::string>() == "urdf") {
      for (int i = 0; i < n_; ++i) {
        phi.weights(i) += robot_->damping[static_cast<std::size_t>(i)];
        phi.gains(i) += robot_->friction[static_cast<std::size_t>(i)];
      }
      return;
    }
    if (!f.is_object())
      throw SceneError(ptr, "expected \"urdf\" (the URDF's <dynamics>) or {\"viscous\": [...], \"coulomb\": [...]}, got " + brief(f));
    check_fields(f, ptr, {"viscous", "coulomb"});
    for (const char* field : {"viscous", "coulomb"}) {
      if (!f.contains(field)) continue;
      const std::string p = ptr + "/" + field;
      const json& a = array_of(f[field], p, static_cast<std::size_t>(n_), "an array (one entry per joint)");
      for (int i = 0; i < n_; ++i) {
        const double x = constant(a[i], p + "/" + std::to_string(i));
        if (!(x >= 0.0)) throw SceneError(p + "/" + std::to_string(i), "must be >= 0 (friction dissipates), got " + format(x));
        (std::string(field) == "viscous" ? phi.weights(i) : phi.gains(i)) += x;
      }
    }
  }

  // The URDF's joint limits as unilateral constraints q_i - lower_i >= 0 and upper_i - q_i >= 0, with
  // Newton restitution (eq. 8 of Brogliato 2003): {"restitution": e, "joints": [names]} (all limited
  // joints when "joints" is absent).
  void joint_limits(const json& system, LagrangianScene& scene) {
    if (!robot_ || !system["urdf"].contains("limits")) return;
    const json& l = system["urdf"]["limits"];
    const std::string ptr = "/system/urdf/limits";
    require_object(l, ptr);
    check_fields(l, ptr, {"restitution", "joints"});
    double e = 0.0;
    if (l.contains("restitution")) {
      e = constant(l["restitution"], ptr + "/restitution");
      if (!(e >= 0.0 && e <= 1.0))
        throw SceneError(ptr + "/restitution", "must be in [0, 1] (Newton's impact law U+ = -e U-), got " + format(e));
    }
    std::set<int> chosen;
    if (l.contains("joints")) {
      if (!l["joints"].is_array()) throw SceneError(ptr + "/joints", "expected an array of joint names");
      for (std::size_t k = 0; k < l["joints"].size(); ++k) {
        const json& name = l["joints"][k];
        const std::string p = ptr + "/joints/" + std::to_string(k);
        int found = -1;
        for (int i = 0; i < n_; ++i)
          if (name.is_string() && robot_->model.bodies[static_cast<std::size_t>(i)].joint_name == name.get<std::string>()) found = i;
        if (found < 0) throw SceneError(p, "is not a moving joint of the robot: " + brief(name));
        chosen.insert(found);
      }
    }
    for (const UrdfJointLimit& lim : robot_->limits) {
      if (l.contains("joints") && !chosen.count(lim.coordinate)) continue;
      chosen.erase(lim.coordinate);
      const Node q = graph_.variable(1 + lim.coordinate);
      const std::string& name = coord_names_[static_cast<std::size_t>(lim.coordinate)];
      const std::pair<Node, std::string> sides[] = {
          // The gap as expression text, whose numbers read back as the URDF's limits exactly.
          {graph_.binary(Op::kSub, q, graph_.constant(lim.lower)), name + " - (" + platform::shortest(lim.lower) + ")"},
          {graph_.binary(Op::kSub, graph_.constant(lim.upper), q), platform::shortest(lim.upper) + " - " + name}};
      for (int side = 0; side < 2; ++side) {
        gaps_.push_back(sides[side].first);
        for (int j = 0; j < n_; ++j) gap_gradients_.push_back(graph_.derivative(sides[side].first, 1 + j));
        scene.constraint_names.push_back(name + (side == 0 ? "_lower" : "_upper"));
        scene.constraint_gaps.push_back(sides[side].second);
        scene.restitution.push_back(e);
      }
    }
    if (!chosen.empty())
      throw SceneError(ptr + "/joints", "joint '" + robot_->model.bodies[static_cast<std::size_t>(*chosen.begin())].joint_name +
                                            "' has no <limit> (a continuous joint)");
    if (scene.constraint_names.size() > static_cast<std::size_t>(kMaxConstraints))
      throw SceneError(ptr, "more than " + std::to_string(kMaxConstraints) + " constraints (two per limited joint): choose 'joints'");
  }

  void mass_matrix(const json& mass) {
    if (banded_mass_) return banded_mass_matrix(mass["bands"]);
    if (diagonal_mass_) {
      const json& d = mass["diagonal"];
      if (d.size() != static_cast<std::size_t>(n_))
        throw SceneError("/system/mass/diagonal",
                         "expected " + std::to_string(n_) + " entries (one per coordinate), got " + std::to_string(d.size()));
      mass_diagonal_.resize(static_cast<std::size_t>(n_));
      for (int i = 0; i < n_; ++i) {
        const std::string ptr = "/system/mass/diagonal/" + std::to_string(i);
        mass_diagonal_[static_cast<std::size_t>(i)] = expression(d[i], ptr, kPosition, "the mass matrix (M depends on q only)");
        if (large_ && !graph_.is_constant(mass_diagonal_[static_cast<std::size_t>(i)])) throw large_requirement(ptr, "is not a constant");
      }
      if (large_) return;  // no dense M: the large-contact path reads mass_diagonal_
      M_.assign(static_cast<std::size_t>(n_ * n_), graph_.constant(0.0));
      for (int i = 0; i < n_; ++i) M_[static_cast<std::size_t>(i * n_ + i)] = mass_diagonal_[static_cast<std::size_t>(i)];
      return;
    }
    if (mass.size() != static_cast<std::size_t>(n_))
      throw SceneError("/system/mass", "expected " + std::to_string(n_) + " rows (one per coordinate), got " + std::to_string(mass.size()));
    M_.assign(static_cast<std::size_t>(n_ * n_), 0);
    for (int i = 0; i < n_; ++i) {
      const std::string row_ptr = "/system/mass/" + std::to_string(i);
      array_of(mass[i], row_ptr, static_cast<std::size_t>(n_), "a row of " + std::to_string(n_) + " entries");
      for (int j = 0; j < n_; ++j)
        M_[i * n_ + j] = expression(mass[i][j], row_ptr + "/" + std::to_string(j), kPosition, "the mass matrix (M depends on q only)");
    }
  }

  // {"bands": [b_0, b_1, ...]}: b_k[i] = M(i, i + k) = M(i + k, i), b_0 the diagonal (n entries), b_k of
  // n - k entries. Beyond the dense limits every entry is a constant (the large ABL path's M); within
  // them the bands fill the dense M.
  void banded_mass_matrix(const json& bands) {
    const std::string at = "/system/mass/bands";
    const int count = static_cast<int>(bands.size());
    if (count > n_) throw SceneError(at, "has " + std::to_string(count) + " bands: at most n = " + std::to_string(n_));
    if (large_ && 2LL * count - 1 > kMaxMassNonzerosPerCoordinate)
      throw large_requirement(at, "has " + std::to_string(count) + " bands: at most " +
                                      std::to_string((kMaxMassNonzerosPerCoordinate + 1) / 2) + " (M's nonzeros per coordinate bounded)");
    mass_bands_.assign(static_cast<std::size_t>(count), {});
    for (int k = 0; k < count; ++k) {
      const std::string ptr = at + "/" + std::to_string(k);
      const json& b =
          array_of(bands[k], ptr, static_cast<std::size_t>(n_ - k),
                   "band " + std::to_string(k) + " of " + std::to_string(n_ - k) + " entries (M(i, i + " + std::to_string(k) + "))");
      for (int i = 0; i < n_ - k; ++i) {
        const Node e = expression(b[i], ptr + "/" + std::to_string(i), kPosition, "the mass matrix (M depends on q only)");
        if (large_ && !graph_.is_constant(e)) throw large_requirement(ptr + "/" + std::to_string(i), "is not a constant");
        mass_bands_[static_cast<std::size_t>(k)].push_back(e);
      }
    }
    if (large_) return;  // no dense M: the large ABL path reads mass_bands_
    M_.assign(static_cast<std::size_t>(n_ * n_), graph_.constant(0.0));
    for (int k = 0; k < count; ++k)
      for (int i = 0; i < n_ - k; ++i) {
        const Node e = mass_bands_[static_cast<std::size_t>(k)][static_cast<std::size_t>(i)];
        M_[static_cast<std::size_t>(i * n_ + i + k)] = e;
        M_[static_cast<std::size_t>((i + k) * n_ + i)] = e;
      }
  }

  void coriolis(const json& system, LagrangianScene& scene) {
    if (large_) {
      // A constant M has no Christoffel symbols: C = 0 whether "christoffel" or "none" is asked.
      if (system.contains("coriolis") && !system["coriolis"].is_string())
        throw large_requirement("/system/coriolis", "an explicit C(q, v) is not taken");
      scene.coriolis = system.contains("coriolis") && system["coriolis"] == "none" ? CoriolisSource::kNone : CoriolisSource::kChristoffel;
      if (system.contains("coriolis") && system["coriolis"] != "none" && system["coriolis"] != "christoffel")
        throw SceneError("/system/coriolis", "expected \"christoffel\", \"none\" or an n x n matrix, got " + brief(system["coriolis"]));
      return;
    }
    C_.assign(static_cast<std::size_t>(n_ * n_), graph_.constant(0.0));
    std::string mode = "christoffel";
    if (system.contains("coriolis")) {
      const json& c = system["coriolis"];
      if (c.is_string()) {
        mode = c.get<std::string>();
        if (mode != "christoffel" && mode != "none")
          throw SceneError("/system/coriolis", "expected \"christoffel\", \"none\" or an n x n matrix, got \"" + mode + "\"");
      } else if (c.is_array()) {
        mode = "explicit";
        array_of(c, "/system/coriolis", static_cast<std::size_t>(n_), "an n x n matrix");
        for (int i = 0; i < n_; ++i) {
          const std::string row_ptr = "/system/coriolis/" + std::to_string(i);
          array_of(c[i], row_ptr, static_cast<std::size_t>(n_), "a row");
          for (int j = 0; j < n_; ++j)
            C_[i * n_ + j] = expression(c[i][j], row_ptr + "/" + std::to_string(j), kPosition | kVelocity,
                                        "the Coriolis matrix (C depends on q and v only)");
        }
      } else {
        throw SceneError("/system/coriolis", "expected \"christoffel\", \"none\" or an n x n matrix, got " + type_name(c));
      }
    }
    scene.coriolis = mode == "christoffel" ? CoriolisSource::kChristoffel
                     : mode == "none"      ? CoriolisSource::kNone
                                           : CoriolisSource::kExplicit;
    if (mode == "christoffel") {
      // (1.4)-(1.5): C_jk = sum_i C_ijk v_i, C_ijk = 1/2 (dM_jk/dq_i + dM_ji/dq_k - dM_ik/dq_j), exact.
      // A term whose three entries of M are constant is 0 (the graph folds 0 * v_i and x + 0 to the same
      // nodes), so it is skipped: a constant M, or a banded one, costs n^2 here instead of n^3 graph nodes.
      auto dM = [&](int a, int b, int i) { return graph_.derivative(sym(a, b), 1 + i); };
      auto constant_entry = [&](int a, int b) { return graph_.is_constant(sym(a, b)); };
      for (int j = 0; j < n_; ++j) {
        for (int k = 0; k < n_; ++k) {
          Node sum = graph_.constant(0.0);
          for (int i = 0; i < n_; ++i) {
            if (constant_entry(j, k) && constant_entry(j, i) && constant_entry(i, k)) continue;
            Node cijk = graph_.binary(Op::kSub, graph_.binary(Op::kAdd, dM(j, k, i), dM(j, i, k)), dM(i, k, j));
            cijk = graph_.binary(Op::kMul, graph_.constant(0.5), cijk);
            sum = graph_.binary(Op::kAdd, sum, graph_.binary(Op::kMul, cijk, graph_.variable(1 + n_ + i)));
          }
          C_[j * n_ + k] = sum;
        }
      }
    }
    for (int i = 0; i < n_ * n_; ++i) scene.christoffel_c.push_back(graph_.to_string(C_[i]));
  }

  // Whether `node` depends on the free parameters and constants alone (not on t, q or v).
  bool bound_only(Node node) const {
    return !graph_.any_reachable(node, [this](const expr::Graph::Entry& e) { return e.op == Op::kVar && e.slot < 1 + 2 * n_; });
  }

  // The symmetric mass entry used everywhere: the upper triangle (the lower one is checked equal).
  Node sym(int i, int j) const { return i <= j ? M_[i * n_ + j] : M_[j * n_ + i]; }
  // V(q): an expression, or an array of expressions (terms) whose sum is V, for a potential too long for
  // one expression (a chain of thousands of springs). The terms are added as a balanced tree, so that the
  // graph's depth grows as log2 of their number.
  Node potential(const json& v) {
    const char* what = "the potential (V depends on q only)";
    if (!v.is_array()) return expression(v, "/system/potential", kPosition, what);
    if (v.empty())
      throw SceneError("/system/potential", "expected a number or an expression, or a non-empty array of terms (their sum is V)");
    std::vector<Node> terms;
    for (std::size_t k = 0; k < v.size(); ++k) terms.push_back(expression(v[k], "/system/potential/" + std::to_string(k), kPosition, what));
    while (terms.size() > 1) {
      std::vector<Node> sums;
      for (std::size_t k = 0; k + 1 < terms.size(); k += 2) sums.push_back(graph_.binary(Op::kAdd, terms[k], terms[k + 1]));
      if (terms.size() % 2) sums.push_back(terms.back());
      terms = std::move(sums);
    }
    return terms.front();
  }

  void forces(const json& system, LagrangianScene& scene) {
    g_.assign(static_cast<std::size_t>(n_), graph_.constant(0.0));
    force_.assign(static_cast<std::size_t>(n_), graph_.constant(0.0));
    if (system.contains("potential") && system.contains("potential_gradient"))
      throw SceneError("/system/potential_gradient", "give either 'potential' or 'potential_gradient', not both");
    potential_ = -1;
    if (system.contains("potential")) {
      potential_ = potential(system["potential"]);
      if (large_) {
        // n derivatives of a potential of n terms would cost n^2: its affine form gives them at once, and
        // otherwise each term of its sum is differentiated in the coordinates it reads.
        if (const std::optional<expr::AffineForm> form = expr::affine_form(graph_, potential_)) {
          for (const auto& [slot, a] : form->coefficients) g_[static_cast<std::size_t>(slot - 1)] = graph_.constant(a);
        } else {
          gradient_by_terms();
        }
      } else {
        for (int i = 0; i < n_; ++i) g_[i] = graph_.derivative(potential_, 1 + i);
      }
    }
    if (system.contains("potential_gradient")) {
      const json& pg = array_of(system["potential_gradient"], "/system/potential_gradient", static_cast<std::size_t>(n_), "an array");
      for (int i = 0; i < n_; ++i)
        g_[i] =
            expression(pg[i], "/system/potential_gradient/" + std::to_string(i), kPosition, "the potential gradient (depends on q only)");
    }
    gradient_ = g_;
    scene.has_force = system.contains("force");
    has_force_ = scene.has_force;
    if (system.contains("force")) {
      const json& f = array_of(system["force"], "/system/force", static_cast<std::size_t>(n_), "an array");
      for (int i = 0; i < n_; ++i) {
        force_[i] = expression(f[i], "/system/force/" + std::to_string(i), kTime | kPosition | kVelocity, "the force");
        if (large_ && !graph_.is_constant(force_[i])) throw large_requirement("/system/force/" + std::to_string(i), "is not a constant");
        g_[i] = graph_.binary(Op::kAdd, g_[i], force_[i]);
      }
      // Theorem 4.3 needs F independent of t (4.16).
      for (int i = 0; i < n_; ++i) scene.force_depends_on_time = scene.force_depends_on_time || graph_.depends_on(g_[i], 0);
    }
    // Assumption 3.3 from the expressions alone. A given potential_gradient is not known to be a gradient
    // (curl-free), so V's existence is not concluded then.
    // (A constant one is: it is the gradient of g^T q, smooth everywhere.)
    bool constant_gradient = system.contains("potential_gradient");
    for (int i = 0; i < n_ && constant_gradient; ++i) constant_gradient = graph_.is_constant(gradient_[static_cast<std::size_t>(i)]);
    scene.forces_smooth_everywhere = !system.contains("potential_gradient") || constant_gradient;
    for (int i = 0; i < n_; ++i) scene.forces_smooth_everywhere = scene.forces_smooth_everywhere && graph_.smooth_everywhere(g_[i]);
  }

  void controller(const json& system, LagrangianScene& scene) {
    scene.controller = Controller<Eigen::Dynamic>::zero(n_);
    if (system.contains("controller")) read_controller(system["controller"], "/system/controller", scene.controller);
    if (large_ && scene.controller.norm_gain > 0.0) {
      const json& ctl = system["controller"];
      std::string ptr = "/system/controller";
      for (std::size_t k = 0; k < ctl.size(); ++k)
        if (ctl[k].contains("type") && ctl[k]["type"] == "norm") ptr += "/" + std::to_string(k);
      throw large_requirement(ptr, "the norm term (not separable) is not taken");
    }
  }

  // A controller's terms (quadratic, abs, norm) at `where` (/system/controller, /system/tracking/controller),
  // added into phi.
  void read_controller(const json& c, const std::string& where, Controller<Eigen::Dynamic>& phi) {
    if (!c.is_array()) throw SceneError(where, "expected an array of terms, got " + type_name(c));
    for (std::size_t k = 0; k < c.size(); ++k) {
      const std::string ptr = where + "/" + std::to_string(k);
      require_object(c[k], ptr);
      if (!c[k].contains("type") || !c[k]["type"].is_string())
        throw SceneError(ptr + "/type", "missing term type (quadratic, abs or norm)");
      const std::string type = c[k]["type"].get<std::string>();
      auto nonnegative = [&](const json& j, const std::string& p) {
        const double v = constant(j, p);
        if (v < 0.0) throw SceneError(p, "must be >= 0 (Phi must be convex), got " + format(v));
        return v;
      };
      if (type == "quadratic") {
        check_fields(c[k], ptr, {"type", "weights"});
        if (!c[k].contains("weights")) throw SceneError(ptr, "missing 'weights'");
        const json& w = array_of(c[k]["weights"], ptr + "/weights", static_cast<std::size_t>(n_), "an array");
        for (int i = 0; i < n_; ++i) phi.weights(i) += nonnegative(w[i], ptr + "/weights/" + std::to_string(i));
      } else if (type == "abs") {
        check_fields(c[k], ptr, {"type", "gains"});
        if (!c[k].contains("gains")) throw SceneError(ptr, "missing 'gains'");
        const json& a = array_of(c[k]["gains"], ptr + "/gains", static_cast<std::size_t>(n_), "an array");
        for (int i = 0; i < n_; ++i) phi.gains(i) += nonnegative(a[i], ptr + "/gains/" + std::to_string(i));
      } else if (type == "norm") {
        check_fields(c[k], ptr, {"type", "gain"});
        if (!c[k].contains("gain")) throw SceneError(ptr, "missing 'gain'");
        phi.norm_gain += nonnegative(c[k]["gain"], ptr + "/gain");
      } else {
        throw SceneError(ptr + "/type", "unknown controller term '" + type + "' (expected quadratic, abs or norm)");
      }
    }
  }

  // /system/tracking (docs/tracking.md): the reference q_d(t) with its exact derivatives, Lambda, Phi on
  // sigma, the law (continuous, or a sampled law at a period T_s), the controller's nominal model and its
  // measurement. Run by the tracking scheme, which it selects.
  void tracking(const json& system, LagrangianScene& scene) {
    if (!system.contains("tracking")) return;
    const std::string at = "/system/tracking";
    if (large_) throw large_requirement(at, "tracking is not taken");
    const json& tr = system["tracking"];
    require_object(tr, at);
    check_fields(tr, at, {"reference", "lambda", "controller", "law", "period", "boundary_layer", "band", "nominal", "measurement"});
    if (!scene.constraint_names.empty())
      throw SceneError(at, "tracking is for systems without unilateral constraints (/system/constraints)");
    auto spec = std::make_shared<TrackingSpec>();
    for (const char* field : {"reference", "lambda", "controller"})
      if (!tr.contains(field)) throw SceneError(at, std::string("missing required field '") + field + "'");
    if (tr["reference"].is_object()) {
      way_points(tr["reference"], *spec);
    } else {
      const json& ref = array_of(tr["reference"], at + "/reference", static_cast<std::size_t>(n_),
                                 "an array of expressions in t (q_d), or way points {\"points\": [[t, q...], ...]}");
      std::vector<Node> outs(static_cast<std::size_t>(3 * n_));
      for (int i = 0; i < n_; ++i) {
        const Node qd = expression(ref[i], at + "/reference/" + std::to_string(i), kTime, "a reference (a function of t)");
        const Node vd = graph_.derivative(qd, 0);
        outs[i] = qd;
        outs[n_ + i] = vd;
        outs[2 * n_ + i] = graph_.derivative(vd, 0);
        spec->reference_text.push_back(ref[i].is_string() ? ref[i].get<std::string>() : ref[i].dump());
      }
      spec->reference = std::make_shared<expr::Tape>(expr::Tape::compile(graph_, outs, 1, num_params()));
    }
    spec->lambda = constant_vector(tr["lambda"], at + "/lambda");
    if (spec->lambda.size() != static_cast<std::size_t>(n_))
      throw SceneError(at + "/lambda", "expected " + std::to_string(n_) + " entries (one per coordinate)");
    for (std::size_t i = 0; i < spec->lambda.size(); ++i)
      if (!(spec->lambda[i] > 0.0)) throw SceneError(at + "/lambda/" + std::to_string(i), "must be > 0, got " + format(spec->lambda[i]));
    spec->phi = Controller<Eigen::Dynamic>::zero(n_);
    read_controller(tr["controller"], at + "/controller", spec->phi);
    const std::string law = tr.contains("law") ? (tr["law"].is_string() ? tr["law"].get<std::string>() : "") : "continuous";
    if (law == "implicit")
      spec->sampled = SampledTrackingLaw::kImplicit;
    else if (law == "explicit")
      spec->sampled = SampledTrackingLaw::kExplicit;
    else if (law == "saturated")
      spec->sampled = SampledTrackingLaw::kSaturated;
    else if (law != "continuous")
      throw SceneError(at + "/law", "expected \"continuous\", \"implicit\", \"explicit\" or \"saturated\", got " + brief(tr["law"]));
    if (spec->sampled) {
      if (!tr.contains("period")) throw SceneError(at, "a sampled law (" + law + ") needs 'period', the sampling period T_s");
      spec->period = positive(tr["period"], at + "/period");
    } else {
      for (const char* field : {"period", "band", "measurement"})
        if (tr.contains(field))
          throw SceneError(at + "/" + field, std::string(field) + " belongs to a sampled law (implicit, explicit or saturated)");
    }
    if (spec->sampled == SampledTrackingLaw::kSaturated) {
      if (!tr.contains("boundary_layer")) throw SceneError(at, "the saturated law needs 'boundary_layer', the width phi > 0");
      spec->boundary_layer = positive(tr["boundary_layer"], at + "/boundary_layer");
    } else if (tr.contains("boundary_layer")) {
      throw SceneError(at + "/boundary_layer", "boundary_layer belongs to the saturated law");
    }
    if (tr.contains("band")) spec->band = positive(tr["band"], at + "/band");
    if (tr.contains("measurement")) {
      const json& m = tr["measurement"];
      require_object(m, at + "/measurement");
      check_fields(m, at + "/measurement", {"quantum", "noise", "seed"});
      if (m.contains("quantum")) spec->quantum = positive(m["quantum"], at + "/measurement/quantum");
      if (m.contains("noise")) spec->noise = positive(m["noise"], at + "/measurement/noise");
      if (m.contains("seed")) {
        const json& sd = m["seed"];
        if (!sd.is_number_unsigned() && !(sd.is_number_integer() && sd.get<std::int64_t>() >= 0))
          throw SceneError(at + "/measurement/seed", "expected a non-negative integer, got " + brief(sd));
        spec->seed = sd.get<std::uint64_t>();
      }
    }
    spec->nominal = std::make_shared<const LagrangianScene>(nominal_scene(tr, *spec));
    const Controller<Eigen::Dynamic>& plant = scene.controller;
    if (!spec->sampled && ((plant.gains.array() != 0.0).any() || (plant.weights.array() != 0.0).any() || plant.norm_gain != 0.0))
      throw SceneError(system.contains("controller") ? "/system/controller" : "/system/urdf/friction",
                       "the continuous tracking loop is one inclusion in sigma; the plant's own set-valued terms on v "
                       "(controller, friction) are supported with a sampled law only");
    scene.tracking = std::move(spec);
  }

  // /system/tracking/reference as way points: {"points": [[t, q_1, ..., q_n], ...], "interpolation":
  // "natural-cubic"} (a "csv" file is read into "points" with the scene, read_scene_file). The run's
  // interval must lie within the way points' (the spline is not extrapolated).
  void way_points(const json& ref, TrackingSpec& spec) {
    const std::string at = "/system/tracking/reference";
    check_fields(ref, at, {"points", "interpolation"});
    if (ref.contains("interpolation") && ref["interpolation"] != "natural-cubic")
      throw SceneError(at + "/interpolation",
                       "expected \"natural-cubic\" (C2, q_d'' = 0 at both ends), got " + brief(ref["interpolation"]));
    if (!ref.contains("points")) throw SceneError(at, "missing 'points' (or 'csv' in a scene file): way points [[t, q...], ...]");
    const json& pts = ref["points"];
    if (!pts.is_array()) throw SceneError(at + "/points", "expected an array of [t, q_1, ..., q_n] rows");
    std::vector<double> t;
    Eigen::MatrixXd q(static_cast<Eigen::Index>(pts.size()), n_);
    for (std::size_t j = 0; j < pts.size(); ++j) {
      const std::string ptr = at + "/points/" + std::to_string(j);
      const json& row = array_of(pts[j], ptr, static_cast<std::size_t>(n_ + 1), "a row [t, q_1, ..., q_n]");
      t.push_back(constant(row[0], ptr + "/0"));
      for (int i = 0; i < n_; ++i) q(static_cast<Eigen::Index>(j), i) = constant(row[i + 1], ptr + "/" + std::to_string(i + 1));
    }
    if (const std::string why = CubicSplineReference::problem(t, q); !why.empty()) throw SceneError(at + "/points", why);
    spec.spline = std::make_shared<const CubicSplineReference>(std::move(t), std::move(q));
    const std::string text = "natural cubic spline through " + std::to_string(spec.spline->points()) + " way points, t from " +
                             format(spec.spline->t_first()) + " to " + format(spec.spline->t_last());
    spec.reference_text.assign(static_cast<std::size_t>(n_), text);
  }

  // The controller's model (TrackingSpec::nominal): this document with /system/tracking/nominal's
  // parameters written over its own, and without what the controller does not know (the force F) or
  // does not use (the tracking block, the plant's controller, an exact solution).
  LagrangianScene nominal_scene(const json& tr, TrackingSpec& spec) {
    const std::string at = "/system/tracking/nominal";
    json doc = doc_;
    json& sys = doc["system"];
    for (const char* field : {"tracking", "force", "controller"}) sys.erase(field);
    doc.erase("exact");
    if (doc.contains("integrator")) doc["integrator"].erase("scheme");
    if (tr.contains("nominal")) {
      const json& nm = tr["nominal"];
      require_object(nm, at);
      check_fields(nm, at, {"parameters", "scale"});
      if (nm.contains("scale")) spec.nominal_scale = positive(nm["scale"], at + "/scale");
      if (nm.contains("parameters")) {
        const json& ps = nm["parameters"];
        require_object(ps, at + "/parameters");
        for (const auto& [name, value] : ps.items()) {
          const std::string ptr = at + "/parameters/" + name;
          if (!doc.contains("parameters") || !doc["parameters"].contains(name))
            throw SceneError(ptr, "the nominal model can only change a parameter of /parameters; '" + name + "' is not one");
          if (!value.is_number()) throw SceneError(ptr, "expected a number, got " + brief(value));
          doc["parameters"][name] = value;
          spec.nominal_parameters.emplace_back(name, value.get<double>());
        }
      }
    }
    try {
      return load_scene(doc);
    } catch (const SceneError& e) {
      throw SceneError(at, std::string("the controller's nominal model does not compile: ") + e.what());
    }
  }

  // /system/constraints: unilateral constraints h_i(q) >= 0 with Newton restitution e_i (eq. 8 of
  // Brogliato 2003). The gradients are exact symbolic derivatives.
  void constraints(const json& system, LagrangianScene& scene) {
    if (!system.contains("constraints")) return;
    const json& c = system["constraints"];
    if (!c.is_array())
      throw SceneError("/system/constraints", "expected an array of {\"gap\": h(q), \"restitution\": e}, got " + type_name(c));
    if (c.size() > static_cast<std::size_t>(kMaxLargeContacts))
      throw SceneError("/system/constraints", "more than " + std::to_string(kMaxLargeContacts) + " constraints (got " +
                                                  std::to_string(c.size()) +
                                                  "): the limit of one run, whose memory and step time grow with it");
    std::set<std::string> names;
    for (std::size_t k = 0; k < c.size(); ++k) {
      const std::string ptr = "/system/constraints/" + std::to_string(k);
      require_object(c[k], ptr);
      check_fields(c[k], ptr, {"gap", "restitution", "name"});
      if (!c[k].contains("gap")) throw SceneError(ptr, "missing 'gap' (an expression h(q), >= 0 on the admissible set)");
      const Node h = expression(c[k]["gap"], ptr + "/gap", kPosition, "a gap (h depends on q only)");
      if (graph_.is_constant(h)) throw SceneError(ptr + "/gap", "is constant: a gap h(q) must depend on the coordinates");
      double e = 0.0;
      if (c[k].contains("restitution")) {
        e = constant(c[k]["restitution"], ptr + "/restitution");
        if (!(e >= 0.0 && e <= 1.0))
          throw SceneError(ptr + "/restitution", "must be in [0, 1] (Newton's impact law U+ = -e U-), got " + format(e));
      }
      std::string name = "h" + std::to_string(k + 1);
      if (c[k].contains("name")) {
        if (!c[k]["name"].is_string() || c[k]["name"].get<std::string>().empty())
          throw SceneError(ptr + "/name", "expected a non-empty string");
        name = c[k]["name"].get<std::string>();
      }
      if (!names.insert(name).second) throw SceneError(ptr + "/name", "duplicate constraint name '" + name + "'");
      gaps_.push_back(h);
      // Linear gaps (a constant gradient) allow the large-contact path; beyond the dense limits they are
      // required, and the n derivatives of each gap are not formed (n times m graph nodes).
      gap_forms_.push_back(expr::affine_form(graph_, h));
      // The gap's partial derivatives in the coordinates it reads (the large-contact path's sparse
      // gradient; a linear gap's are its coefficients). Beyond the dense limits the n derivatives of each
      // gap are not formed (n times m graph nodes).
      std::vector<std::pair<int, Node>> partials;
      if (large_ && gap_forms_.back()) {
        for (const auto& [slot, a] : gap_forms_.back()->coefficients) partials.emplace_back(slot - 1, graph_.constant(a));
      } else if (large_) {
        const std::vector<int> read = coordinates_read(h);
        if (static_cast<int>(read.size()) > kMaxDof)
          throw SceneError(ptr + "/gap", "reads " + std::to_string(read.size()) +
                                             " coordinates: a gap on the large-contact path reads at most " + std::to_string(kMaxDof) +
                                             " (a contact joins a few bodies)");
        for (int j : read) partials.emplace_back(j, graph_.derivative(h, 1 + j));
      } else {
        for (int j = 0; j < n_; ++j) {
          gap_gradients_.push_back(graph_.derivative(h, 1 + j));
          const Node d = gap_gradients_.back();
          if (!(graph_.is_constant(d) && graph_.constant_value(d) == 0.0)) partials.emplace_back(j, d);
        }
      }
      gap_partials_.push_back(std::move(partials));
      scene.constraint_names.push_back(name);
      scene.constraint_gaps.push_back(c[k]["gap"].is_string() ? c[k]["gap"].get<std::string>() : c[k]["gap"].dump());
      scene.restitution.push_back(e);
    }
  }

  void integrator(LagrangianScene& scene) {
    if (!doc_.contains("integrator")) throw SceneError("/integrator", "missing required field 'integrator' (h and t_end)");
    const json& in = doc_["integrator"];
    require_object(in, "/integrator");
    check_fields(in, "/integrator",
                 {"scheme", "h", "t_end", "t0", "step_rule", "k1", "k3", "max_steps", "position_correction", "position_update", "theta"});
    // Which scheme, and whether the scene's fields belong to it: the scheme table's row decides (scheme.h).
    const bool constrained = !scene.constraint_names.empty();
    scene.scheme = constrained ? Scheme::kMoreauJean : (scene.tracking ? Scheme::kTracking : Scheme::kAbl);
    if (in.contains("scheme")) {
      if (!in["scheme"].is_string()) throw SceneError("/integrator/scheme", "expected a string");
      const std::string name = in["scheme"].get<std::string>();
      const std::optional<Scheme> named = scheme_from_name(name);
      const std::string expected = scheme_names_for_scenes(SystemType::kLagrangian);
      if (named && traits(*named).system != SystemType::kLagrangian)
        throw SceneError("/integrator/scheme", "the " + name + " scheme is for lure systems; a lagrangian system takes " + expected);
      if (!named || !traits(*named).scene_can_name)
        throw SceneError("/integrator/scheme", "unknown scheme '" + name + "' (expected: " + expected + ")");
      scene.scheme = *named;
      if (large_ && scene.scheme != Scheme::kMoreauJean && scene.scheme != Scheme::kAbl)
        throw large_requirement("/integrator/scheme", "the " + name + " scheme is not taken");
      if (scene.tracking && scene.scheme != Scheme::kTracking)
        throw SceneError("/integrator/scheme", "a scene with /system/tracking runs the tracking scheme, not " + name);
      if (!scene.tracking && scene.scheme == Scheme::kTracking)
        throw SceneError("/integrator/scheme", "the tracking scheme needs /system/tracking (a reference and a controller on sigma)");
      if (constrained && !traits(scene.scheme).contacts)
        throw SceneError("/integrator/scheme",
                         "the abl scheme (0.2) cannot integrate unilateral constraints (/system/constraints): its explicit "
                         "position update has no contact law and would pass through h(q) = 0 silently; use \"moreau-jean\"");
    }
    const SchemeTraits& row = traits(scene.scheme);
    if (in.contains("theta") && !row.theta)
      throw SceneError("/integrator/theta",
                       std::string("theta belongs to the implicit-euler scheme of lure systems; ") + row.name + " takes none");
    MoreauJeanSettings& c = scene.contact_settings;
    for (const char* field : {"position_correction", "position_update"}) {
      if (!in.contains(field)) continue;
      const std::string ptr = std::string("/integrator/") + field;
      if (!row.position_options) throw SceneError(ptr, std::string(field) + " belongs to the moreau-jean scheme");
      const json& f = in[field];
      const std::string value = f.is_string() ? f.get<std::string>() : "";
      if (std::string(field) == "position_correction") {
        if (value != "none" && value != "projection") throw SceneError(ptr, "expected \"none\" or \"projection\", got " + brief(f));
        c.correct_positions = value == "projection";
      } else {
        if (value != "mdi" && value != "standard") throw SceneError(ptr, "expected \"mdi\" or \"standard\", got " + brief(f));
        c.position_update = value == "standard" ? PositionUpdate::kStandard : PositionUpdate::kMdi;
      }
    }
    if (!row.step_rules)
      for (const char* field : {"k1", "k3"})
        if (in.contains(field))
          throw SceneError(std::string("/integrator/") + field,
                           "k1 and k3 belong to the step rules of the abl scheme; " + std::string(row.name) + " uses a fixed step");
    if (!row.norm_term && scene.controller.norm_gain > 0.0) {
      const json& ctl = doc_["system"]["controller"];
      std::string ptr = "/system/controller";
      for (std::size_t k = 0; k < ctl.size(); ++k)
        if (ctl[k].contains("type") && ctl[k]["type"] == "norm") ptr += "/" + std::to_string(k) + "/type";
      throw SceneError(ptr, "the norm controller term is not separable and is not supported by the " + std::string(row.name) +
                                " scheme (use quadratic and abs terms)");
    }
    AblSettings& s = scene.settings;
    read_interval(in, s.h, s.t0, s.t_end);
    if (in.contains("step_rule")) {
      const json& r = in["step_rule"];
      const std::string rule = r.is_string() ? r.get<std::string>() : "";
      if (rule == "fixed")
        s.step_rule = StepRule::kFixed;
      else if (rule == "theorem-4.1")
        s.step_rule = StepRule::kTheorem41;
      else if (rule == "theorem-4.2")
        s.step_rule = StepRule::kTheorem42;
      else
        throw SceneError("/integrator/step_rule", "expected \"fixed\", \"theorem-4.1\" or \"theorem-4.2\", got " + brief(r));
      if (!row.step_rules && s.step_rule != StepRule::kFixed)
        throw SceneError("/integrator/step_rule",
                         "the " + std::string(row.name) + " scheme uses a fixed step; the theorem rules belong to abl");
    }
    // At scale M is constant and C = 0: the rules' h_k is h itself (k3 = 0, eps_k = 0), and a k1 or k3
    // given would change that without being a property of the system.
    for (const char* field : {"k1", "k3"})
      if (large_ && in.contains(field))
        throw large_requirement(std::string("/integrator/") + field, "k1 and k3 are not taken (M constant and C = 0: the rules take h)");
    if (in.contains("k1")) s.k1 = positive(in["k1"], "/integrator/k1");
    if (in.contains("k3")) s.k3 = positive(in["k3"], "/integrator/k3");
    s.max_steps = read_max_steps(in);
    check_step_count(s.t0, s.t_end, s.h, s.max_steps, s.step_rule == StepRule::kFixed);
    if (s.step_rule == StepRule::kTheorem42 && scene.controller.eta() <= 0.0 && !constant_mass_) {
      throw SceneError("/integrator/step_rule",
                       "theorem-4.2 needs eta > 0 in Assumption 4.1: give every coordinate a quadratic controller weight");
    }
  }

  void initial(LagrangianScene& scene) {
    if (!doc_.contains("initial")) throw SceneError("/initial", "missing required field 'initial' (q, and optionally v)");
    const json& in = doc_["initial"];
    require_object(in, "/initial");
    check_fields(in, "/initial", {"q", "v"});
    if (!in.contains("q")) throw SceneError("/initial", "missing required field 'q'");
    scene.q0 = constant_vector(in["q"], "/initial/q");
    scene.v0 = in.contains("v") ? constant_vector(in["v"], "/initial/v") : std::vector<double>(n_, 0.0);
  }

  void exact(LagrangianScene& scene) {
    if (!doc_.contains("exact")) return;
    const json& ex = doc_["exact"];
    require_object(ex, "/exact");
    check_fields(ex, "/exact", {"q", "v", "rest_time", "rest_q", "note"});
    if (ex.contains("q") != ex.contains("v")) throw SceneError("/exact", "give both 'q' and 'v' of the exact solution, or neither");
    if (ex.contains("q")) {
      std::vector<Node> outs;
      for (const char* part : {"q", "v"}) {
        const std::string ptr = std::string("/exact/") + part;
        const json& arr = array_of(ex[part], ptr, static_cast<std::size_t>(n_), "an array of expressions in t");
        for (int i = 0; i < n_; ++i)
          outs.push_back(expression(arr[i], ptr + "/" + std::to_string(i), kTime, "an exact solution (a function of t)"));
      }
      scene.exact_tape = std::make_shared<expr::Tape>(expr::Tape::compile(graph_, outs, 1 + 2 * n_, num_params()));
    }
    if (ex.contains("rest_time")) scene.exact_rest_time = constant(ex["rest_time"], "/exact/rest_time");
    if (ex.contains("rest_q")) scene.exact_rest_q = constant_vector(ex["rest_q"], "/exact/rest_q");
  }

  // Evaluates M, C, g at the initial state: finite, symmetric, positive definite.
  // `params`: the free parameters' values (ParametricLagrangianScene), nullptr when there are none. The
  // tapes are compiled at the first call and kept: a parametric scene checks each binding with them.
  void check_at_initial_state(const LagrangianScene& scene, const double* params) {
    if (large_) return check_large_at_initial_state(scene);
    std::vector<Node> outs;
    for (int i = 0; i < n_ * n_; ++i) outs.push_back(M_[i]);
    for (int i = 0; i < n_; ++i) outs.push_back(g_[i]);
    for (int i = 0; i < n_ * n_; ++i) outs.push_back(C_[i]);
    if (potential_ >= 0) outs.push_back(potential_);
    if (!check_tape_) check_tape_ = expr::Tape::compile(graph_, outs, 1 + 2 * n_, num_params());
    expr::Tape& tape = *check_tape_;
    if (params) static_cast<void>(tape.bind(params));  // the checks ask for finite values, not for the folded bits
    std::vector<double> slots(1 + 2 * n_), values(outs.size()), scratch(tape.scratch_size());
    auto eval_at = [&](const std::vector<double>& q, const std::vector<double>& v) {
      slots[0] = scene.settings.t0;
      for (int i = 0; i < n_; ++i) {
        slots[1 + i] = q[i];
        slots[1 + n_ + i] = v[i];
      }
      tape.eval(slots.data(), values.data(), scratch.data());
    };
    eval_at(scene.q0, scene.v0);
    for (int i = 0; i < n_; ++i)
      for (int j = 0; j < n_; ++j)
        if (!std::isfinite(values[i * n_ + j]))
          throw SceneError("/system/mass/" + std::to_string(i) + "/" + std::to_string(j), "is not finite at the initial state");
    for (int i = 0; i < n_; ++i)
      if (!std::isfinite(values[n_ * n_ + i]))
        throw SceneError(doc_["system"].contains("force") ? "/system/force/" + std::to_string(i) : "/system/potential",
                         "the generalized force grad V + F is not finite at the initial state (component " + std::to_string(i) + ")");
    for (int i = 0; i < n_ * n_; ++i)
      if (!std::isfinite(values[n_ * n_ + n_ + i])) throw SceneError("/system/coriolis", "C(q, v) is not finite at the initial state");
    // V itself enters the reports (the Lagrange-Dirichlet W = kinetic + V): finite where the run starts.
    if (potential_ >= 0 && !std::isfinite(values[2 * n_ * n_ + n_]))
      throw SceneError("/system/potential", "V(q) is not finite at the initial state (" + format(values[2 * n_ * n_ + n_]) + ")");

    // Symmetry: structurally equal entries are; others are compared at the initial state and at a few
    // deterministic points around it.
    std::vector<std::vector<double>> points = {scene.q0};
    for (int p = 1; p <= 6; ++p) {
      std::vector<double> q = scene.q0;
      for (int i = 0; i < n_; ++i) q[i] += std::sin(1.7 * p + 2.3 * i) * 2.0;
      points.push_back(q);
    }
    for (const auto& q : points) {
      eval_at(q, scene.v0);
      for (int i = 0; i < n_; ++i) {
        for (int j = i + 1; j < n_; ++j) {
          if (M_[i * n_ + j] == M_[j * n_ + i]) continue;
          const double a = values[i * n_ + j], b = values[j * n_ + i];
          if (std::abs(a - b) > 1e-12 * (std::abs(a) + std::abs(b)) && std::abs(a - b) > 1e-300) {
            throw SceneError("/system/mass/" + std::to_string(j) + "/" + std::to_string(i),
                             "M is not symmetric: M[" + std::to_string(i) + "][" + std::to_string(j) + "] = " + format(a) + " but M[" +
                                 std::to_string(j) + "][" + std::to_string(i) + "] = " + format(b) +
                                 (q == scene.q0 ? std::string(" at the initial state") : std::string(" at another q")));
          }
        }
      }
    }
    if (!gaps_.empty()) {
      std::vector<Node> cons = gaps_;
      cons.insert(cons.end(), gap_gradients_.begin(), gap_gradients_.end());
      if (!gap_check_tape_) gap_check_tape_ = expr::Tape::compile(graph_, cons, 1 + 2 * n_, num_params());
      expr::Tape& ct = *gap_check_tape_;
      if (params) static_cast<void>(ct.bind(params));
      std::vector<double> cs(1 + 2 * n_, 0.0), cv(cons.size()), cscr(ct.scratch_size());
      for (int i = 0; i < n_; ++i) cs[1 + i] = scene.q0[i];
      ct.eval(cs.data(), cv.data(), cscr.data());
      const int nc = static_cast<int>(gaps_.size());
      for (int i = 0; i < nc; ++i) {
        const std::string ptr = "/system/constraints/" + std::to_string(i) + "/gap";
        if (!std::isfinite(cv[i])) throw SceneError(ptr, "h(q) is not finite at the initial state");
        double norm = 0.0;
        for (int j = 0; j < n_; ++j) {
          const double g = cv[nc + i * n_ + j];
          if (!std::isfinite(g)) throw SceneError(ptr, "the gradient of h is not finite at the initial state");
          norm += g * g;
        }
        if (cv[i] < 0.0)
          throw SceneError("/initial/q", "violates constraint '" + scene.constraint_names[i] + "': h(q0) = " + format(cv[i]) +
                                             " < 0 (the initial position must be admissible, h(q0) >= 0)");
        if (cv[i] == 0.0 && norm == 0.0)
          throw SceneError(ptr, "the gradient of h vanishes at the initial contact (the paper assumes grad h != 0 where h = 0)");
      }
    }
    eval_at(scene.q0, scene.v0);
    Eigen::MatrixXd M(n_, n_);
    for (int i = 0; i < n_; ++i)
      for (int j = 0; j < n_; ++j) M(i, j) = values[std::min(i, j) * n_ + std::max(i, j)];
    if (robot_) {
      RigidBodyData data(robot_->model);
      moreau::mass_matrix(robot_->model, data, scene.q0.data(), M);
      if (!M.allFinite()) throw SceneError("/initial/q", "the robot's M(q) is not finite at the initial state");
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(M, Eigen::EigenvaluesOnly);
    const double lmin = eig.eigenvalues()(0);
    if (!(lmin > 0.0))
      throw SceneError(robot_ ? "/system/urdf" : "/system/mass",
                       "M is not positive definite at the initial state (smallest eigenvalue " + format(lmin) + ")");
    // The kinetic energy E_0 = 1/2 <M v0, v0> must be a number: finite entries can still overflow it
    // (v0 = 1e308), and a run from there fails at its first step with a NaN residual.
    const Eigen::VectorXd v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), n_);
    const double e0 = 0.5 * v0.dot(M * v0);
    if (!std::isfinite(e0))
      throw SceneError("/initial/v", "the kinetic energy 1/2 <M(q0) v0, v0> is not finite at the initial state (" + format(e0) + ")");
  }

  // The wiring of a tape of M, C and g entries (CompiledLagrangian::Source and Sink): input slot 0 is t,
  // 1..n are q and n+1..2n are v; flat index k of [M | C | g] is entry k of M, k - n^2 of C or k - 2n^2 of g.
  expr::Tape::Wiring terms_wiring(const std::vector<std::vector<int>>& targets) const {
    using Place = expr::Tape::Place;
    expr::Tape::Wiring w;
    w.inputs.push_back({CompiledLagrangian::kTime, 0});
    for (int i = 0; i < n_; ++i) w.inputs.push_back({CompiledLagrangian::kPosition, i});
    for (int i = 0; i < n_; ++i) w.inputs.push_back({CompiledLagrangian::kVelocity, i});
    const int nn = n_ * n_;
    for (const auto& flat : targets) {
      auto& places = w.outputs.emplace_back();
      for (int k : flat)
        places.push_back(k < nn       ? Place{CompiledLagrangian::kMass, k}
                         : k < 2 * nn ? Place{CompiledLagrangian::kCoriolis, k - nn}
                                      : Place{CompiledLagrangian::kForce, k - 2 * nn});
    }
    return w;
  }

  // The inputs of a tape of q alone (V, the gaps): q from sources[0]; t and v have no place, so wiring a
  // tape that read them would throw.
  expr::Tape::Wiring position_wiring() const {
    expr::Tape::Wiring w;
    w.inputs.push_back({});
    for (int i = 0; i < n_; ++i) w.inputs.push_back({0, i});
    return w;
  }

  // grad V and F apart (the same nodes that g = grad V + F adds), wired to write grad V to sinks[0] and F
  // to sinks[1] (CompiledLagrangian::split_force_tape).
  void compile_split_force_tape(CompiledLagrangian& c) const {
    std::vector<Node> split = gradient_;
    split.insert(split.end(), force_.begin(), force_.end());
    c.split_force_tape = expr::Tape::compile(graph_, split, 1 + 2 * n_, num_params());
    expr::Tape::Wiring w = terms_wiring({});
    for (int i = 0; i < n_; ++i) w.outputs.push_back({{0, i}});  // grad V
    for (int i = 0; i < n_; ++i) w.outputs.push_back({{1, i}});  // F
    c.split_force_tape.wire(w);
  }

  // V(q) alone, wired to read q from sources[0] and write V to sinks[0][0].
  void compile_potential_tape(CompiledLagrangian& c) const {
    c.has_potential = true;
    c.potential_tape = expr::Tape::compile(graph_, {potential_}, 1 + 2 * n_, num_params());
    expr::Tape::Wiring w = position_wiring();
    w.outputs.push_back({{0, 0}});
    c.potential_tape.wire(w);
  }

  // The coordinates q_j (slots 1 + j) that f reads, increasing: one traversal of f's nodes, marked with a
  // stamp kept between calls, so that the gaps of a large scene cost the size of their expressions and
  // not, each, the size of the graph.
  std::vector<int> coordinates_read(Node f) {
    if (visit_stamp_.size() < graph_.size()) visit_stamp_.resize(graph_.size(), 0);
    ++stamp_;
    std::vector<int> read;
    std::vector<Node> stack{f};
    visit_stamp_[static_cast<std::size_t>(f)] = stamp_;
    while (!stack.empty()) {
      const expr::Graph::Entry e = graph_.entry(stack.back());
      stack.pop_back();
      if (e.op == expr::Op::kVar && e.slot >= 1 && e.slot <= n_) read.push_back(e.slot - 1);
      for (Node child : {e.a, e.b, e.c, e.d})
        if (child >= 0 && visit_stamp_[static_cast<std::size_t>(child)] != stamp_) {
          visit_stamp_[static_cast<std::size_t>(child)] = stamp_;
          stack.push_back(child);
        }
    }
    std::sort(read.begin(), read.end());
    return read;
  }

  // grad V of a potential at scale: V's sum split into its terms (through +, - and unary -), each term
  // differentiated in the coordinates it reads, and each coordinate's partials added. The graph grows by
  // the size of V, not by n derivatives of all of V (n times its size).
  void gradient_by_terms() {
    std::vector<std::vector<Node>> parts(static_cast<std::size_t>(n_));
    std::vector<std::pair<Node, bool>> stack{{potential_, false}};  // (node, negated)
    while (!stack.empty()) {
      const auto [f, negated] = stack.back();
      stack.pop_back();
      const expr::Graph::Entry e = graph_.entry(f);
      if (e.op == Op::kAdd || e.op == Op::kSub) {
        stack.emplace_back(e.a, negated);
        stack.emplace_back(e.b, e.op == Op::kSub ? !negated : negated);
        continue;
      }
      if (e.op == Op::kNeg) {
        stack.emplace_back(e.a, !negated);
        continue;
      }
      const std::vector<int> read = coordinates_read(f);
      if (static_cast<int>(read.size()) > kMaxDof)
        throw large_requirement("/system/potential", "a term of its sum reads " + std::to_string(read.size()) + " coordinates (at most " +
                                                         std::to_string(kMaxDof) + ": a term couples a few coordinates)");
      for (int j : read) {
        const Node d = graph_.derivative(f, 1 + j);
        parts[static_cast<std::size_t>(j)].push_back(negated ? graph_.unary(Op::kNeg, d) : d);
      }
    }
    for (int i = 0; i < n_; ++i) {
      Node sum = graph_.constant(0.0);
      for (Node d : parts[static_cast<std::size_t>(i)]) sum = graph_.binary(Op::kAdd, sum, d);
      g_[static_cast<std::size_t>(i)] = sum;
    }
  }

  // The error for a field that the paths at scale cannot take (a system beyond the dense limits).
  SceneError large_requirement(const std::string& ptr, const std::string& what) const {
    return SceneError(ptr,
                      what + ": a system of more than " + std::to_string(kMaxDof) + " coordinates or " + std::to_string(kMaxConstraints) +
                          " constraints runs on a path at scale: the large-contact path (the moreau-jean scheme: a constant diagonal "
                          "mass, a linear potential, constant forces, gaps of a few coordinates each, no controller) or the large ABL "
                          "path (the abl scheme: a constant mass given by its bands, potential terms of a few coordinates each, constant "
                          "forces, quadratic and abs controller terms, no constraints) (docs/scaling.md)");
  }

  // The system of the large-contact path (large_contact_integrator.h) from the affine forms, when the
  // scene has that structure: M constant and diagonal, C = 0, g = grad V + F constant, every gap linear,
  // no controller, no robot, no tracking, no free parameter. Null otherwise.
  std::shared_ptr<const LargeContactSystem> large_contact_system(const LagrangianScene& scene) const {
    if (robot_ || scene.tracking || num_params() > 0) return nullptr;
    if (!scene.controller.gains.isZero(0.0) || !scene.controller.weights.isZero(0.0) || scene.controller.norm_gain != 0.0) return nullptr;
    auto sys = std::make_shared<LargeContactSystem>();
    sys->mass.resize(n_);
    sys->force.resize(n_);
    if (banded_mass_ && large_ && mass_bands_.size() > 1) return nullptr;
    for (int i = 0; i < n_; ++i) {
      const Node m = !large_        ? M_[static_cast<std::size_t>(i * n_ + i)]
                     : banded_mass_ ? mass_bands_[0][static_cast<std::size_t>(i)]
                                    : mass_diagonal_[static_cast<std::size_t>(i)];
      if (!graph_.is_constant(m) || !graph_.is_constant(g_[static_cast<std::size_t>(i)])) return nullptr;
      sys->mass(i) = graph_.constant_value(m);
      sys->force(i) = graph_.constant_value(g_[static_cast<std::size_t>(i)]);
    }
    if (!large_) {
      for (int i = 0; i < n_; ++i)
        for (int j = 0; j < n_; ++j) {
          const Node m = M_[static_cast<std::size_t>(i * n_ + j)], c = C_[static_cast<std::size_t>(i * n_ + j)];
          if (i != j && !(graph_.is_constant(m) && graph_.constant_value(m) == 0.0)) return nullptr;
          if (!(graph_.is_constant(c) && graph_.constant_value(c) == 0.0)) return nullptr;
        }
    }
    // V(q) = g^T q (+ a constant) is the potential when F = 0 (W of Lemma 3 uses it).
    sys->force_is_potential = !has_force_;  // a constant gradient (given or from V) is that of g^T q
    std::vector<Eigen::Triplet<double>> t;
    const int m = static_cast<int>(gap_forms_.size());
    sys->offsets.setZero(m);
    const bool linear = std::all_of(gap_forms_.begin(), gap_forms_.end(), [](const auto& form) { return form.has_value(); });
    if (linear) {
      for (int i = 0; i < m; ++i) {
        const expr::AffineForm& form = *gap_forms_[static_cast<std::size_t>(i)];
        sys->offsets(i) = form.constant;
        for (const auto& [slot, a] : form.coefficients) t.emplace_back(i, slot - 1, a);
      }
    } else {
      // Nonlinear gaps: their tapes, and the pattern of their gradients (values at q0 below). Position
      // correction is one LCP for linear gaps only: within the dense limits the dense step takes it.
      if (scene.contact_settings.correct_positions) return nullptr;
      for (int i = 0; i < m; ++i)
        for (const auto& [j, node] : gap_partials_[static_cast<std::size_t>(i)]) t.emplace_back(i, j, 1.0);
      sys->nonlinear_gaps = std::make_shared<detail::SparseVectorTapes>(graph_, gaps_, gap_partials_, 1 + 2 * n_);
    }
    sys->gradients.resize(m, n_);
    sys->gradients.setFromTriplets(t.begin(), t.end());
    sys->gradients.makeCompressed();
    if (!linear && static_cast<int>(scene.q0.size()) == n_) {
      Eigen::VectorXd gap;
      std::vector<double> scratch = sys->nonlinear_gaps->make_scratch();
      sys->evaluate(Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), n_), gap, sys->gradients, scratch);
    }
    sys->restitution = scene.restitution;
    // Within the dense limits a system this path does not take (contacts that couple densely, a zero
    // gradient) stays on the dense step; beyond them check_large_at_initial_state reports why.
    if (!large_ && !sys->validate().empty()) return nullptr;
    return sys;
  }

  // check_at_initial_state for the large-contact path: the system's own validation (masses, gradients),
  // finite values, and an admissible initial position.
  void check_large_at_initial_state(const LagrangianScene& scene) {
    if (num_params() > 0) throw large_requirement("/parameters", "free parameters (a campaign's) are not taken");
    if (scene.scheme == Scheme::kAbl) return check_large_abl_at_initial_state(scene);
    // The large-contact path's own requirements, each at its field.
    if (scene.controller.has_quadratic() || scene.controller.has_nonsmooth())
      throw large_requirement("/system/controller", "a controller (dPhi) is not taken with the moreau-jean scheme");
    if (banded_mass_ && mass_bands_.size() > 1)
      throw large_requirement("/system/mass/bands", "the moreau-jean scheme takes a diagonal mass (one band)");
    for (int i = 0; i < n_; ++i)
      if (!graph_.is_constant(gradient_[static_cast<std::size_t>(i)]))
        throw large_requirement(
            doc_["system"].contains("potential_gradient") ? "/system/potential_gradient/" + std::to_string(i) : "/system/potential",
            "is not linear in q (the moreau-jean scheme takes a constant gradient, as gravity's)");
    const std::shared_ptr<const LargeContactSystem> sys = large_contact_system(scene);
    if (!sys && scene.contact_settings.correct_positions)
      throw large_requirement("/integrator/position_correction", "position correction with nonlinear gaps is not taken");
    if (!sys) throw large_requirement("/system", "the system does not have that structure");
    for (int i = 0; i < n_; ++i) {
      if (!(sys->mass(i) > 0.0) || !std::isfinite(sys->mass(i)))
        throw SceneError("/system/mass/diagonal/" + std::to_string(i),
                         "must be a finite positive number (M positive definite), got " + format(sys->mass(i)));
      if (!std::isfinite(sys->force(i)))
        throw SceneError(doc_["system"].contains("force") ? "/system/force/" + std::to_string(i) : "/system/potential",
                         "the generalized force grad V + F is not finite (component " + std::to_string(i) + ")");
    }
    const std::string invalid = sys->validate();
    if (!invalid.empty()) throw SceneError("/system/constraints", invalid);
    const Eigen::VectorXd q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), n_);
    Eigen::VectorXd gaps;
    Eigen::SparseMatrix<double, Eigen::RowMajor> H = sys->gradients;
    std::vector<double> scratch = sys->linear() ? std::vector<double>{} : sys->nonlinear_gaps->make_scratch();
    sys->evaluate(q0, gaps, H, scratch);
    for (int i = 0; i < sys->num_constraints(); ++i) {
      if (!std::isfinite(gaps(i)))
        throw SceneError("/system/constraints/" + std::to_string(i) + "/gap", "h(q) is not finite at the initial state");
      if (gaps(i) < 0.0)
        throw SceneError("/initial/q", "violates constraint '" + scene.constraint_names[static_cast<std::size_t>(i)] +
                                           "': h(q0) = " + format(gaps(i)) + " < 0 (the initial position must be admissible, h(q0) >= 0)");
    }
    const Eigen::VectorXd v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), n_);
    const double e0 = 0.5 * v0.cwiseProduct(v0).dot(sys->mass);
    if (!std::isfinite(e0))
      throw SceneError("/initial/v", "the kinetic energy 1/2 <M v0, v0> is not finite at the initial state (" + format(e0) + ")");
    large_system_ = sys;
  }

  // The system of the large ABL path (large_abl_system.h): M from its bands (beyond the dense limits) or
  // from the dense M's constant entries (within them, when M is constant and sparse, C = 0), Phi's
  // quadratic and abs terms, g = grad V + F as tapes of its components when it is not constant. Null when
  // the scene does not have that structure (within the dense limits it then runs on the dense step).
  std::shared_ptr<LargeAblSystem> large_abl_system(const LagrangianScene& scene) const {
    if (robot_ || scene.tracking || num_params() > 0 || !scene.constraint_names.empty() || scene.scheme != Scheme::kAbl) return nullptr;
    if (scene.controller.norm_gain != 0.0 || scene.settings.k1 || scene.settings.k3) return nullptr;
    auto sys = std::make_shared<LargeAblSystem>();
    std::vector<Eigen::Triplet<double>> t;
    bool constant = true;
    const auto entry = [&](int i, int j, Node e) {
      if (!graph_.is_constant(e)) {
        constant = false;
        return;
      }
      const double value = graph_.constant_value(e);
      if (value != 0.0 || i == j) t.emplace_back(i, j, value);
    };
    if (!large_) {
      for (int i = 0; i < n_; ++i)
        for (int j = 0; j < n_; ++j) {
          entry(i, j, M_[static_cast<std::size_t>(i * n_ + j)]);
          const Node c = C_[static_cast<std::size_t>(i * n_ + j)];
          if (!(graph_.is_constant(c) && graph_.constant_value(c) == 0.0)) return nullptr;
        }
    } else if (banded_mass_) {
      for (std::size_t k = 0; k < mass_bands_.size(); ++k)
        for (int i = 0; i + static_cast<int>(k) < n_; ++i) {
          const Node e = mass_bands_[k][static_cast<std::size_t>(i)];
          entry(i, i + static_cast<int>(k), e);
          if (k > 0) entry(i + static_cast<int>(k), i, e);
        }
    } else {
      for (int i = 0; i < n_; ++i) entry(i, i, mass_diagonal_[static_cast<std::size_t>(i)]);
    }
    if (!constant) return nullptr;
    // g = grad V + F of q alone (a force that reads t or v is not this system's).
    for (int i = 0; i < n_; ++i)
      if (graph_.any_reachable(g_[static_cast<std::size_t>(i)],
                               [this](const expr::Graph::Entry& e) { return e.op == Op::kVar && (e.slot == 0 || e.slot > n_); }))
        return nullptr;
    sys->mass.resize(n_, n_);
    sys->mass.setFromTriplets(t.begin(), t.end());
    sys->mass.makeCompressed();
    if (!large_ && sys->mass.nonZeros() > kMaxMassNonzerosPerCoordinate * n_) return nullptr;
    sys->phi = scene.controller;
    bool constant_g = true;
    for (int i = 0; i < n_ && constant_g; ++i) constant_g = graph_.is_constant(g_[static_cast<std::size_t>(i)]);
    sys->force.setZero(n_);
    if (constant_g) {
      for (int i = 0; i < n_; ++i) sys->force(i) = graph_.constant_value(g_[static_cast<std::size_t>(i)]);
    } else {
      const std::vector<std::vector<std::pair<int, Node>>> no_jacobian(static_cast<std::size_t>(n_));
      sys->gradient = std::make_shared<detail::SparseVectorTapes>(graph_, g_, no_jacobian, 1 + 2 * n_);
    }
    if (!large_ && (!sys->validate().empty() || !(certified_lambda_min(sys->mass) > 0.0))) return nullptr;
    return sys;
  }

  // check_at_initial_state for the large ABL path: the system's validation, M certified positive definite
  // (Assumption 3.1), g(q0) and E_0 finite.
  void check_large_abl_at_initial_state(const LagrangianScene& scene) {
    const std::shared_ptr<LargeAblSystem> sys = large_abl_system(scene);
    if (!sys) throw large_requirement("/system", "the system does not have that structure");
    const std::string mass_ptr = banded_mass_ ? "/system/mass/bands" : "/system/mass/diagonal";
    for (int i = 0; i < n_; ++i)
      if (!(sys->mass.coeff(i, i) > 0.0))
        throw SceneError(mass_ptr + "/" + (banded_mass_ ? "0/" : "") + std::to_string(i),
                         "must be a finite positive number (M positive definite), got " + format(sys->mass.coeff(i, i)));
    if (const std::string invalid = sys->validate(); !invalid.empty()) throw SceneError(mass_ptr, invalid);
    const double lambda = certified_lambda_min(sys->mass);
    if (!(lambda > 0.0))
      throw SceneError(mass_ptr, "M is not positive definite: no Cholesky factor of M - s I for any s > 0 tried (Assumption 3.1)");
    const Eigen::VectorXd q0 = Eigen::Map<const Eigen::VectorXd>(scene.q0.data(), n_);
    Eigen::VectorXd g;
    std::vector<double> scratch = sys->gradient ? sys->gradient->make_scratch() : std::vector<double>{};
    sys->evaluate(q0, g, scratch);
    for (int i = 0; i < n_; ++i)
      if (!std::isfinite(g(i)))
        throw SceneError(doc_["system"].contains("force")                ? "/system/force/" + std::to_string(i)
                         : doc_["system"].contains("potential_gradient") ? "/system/potential_gradient/" + std::to_string(i)
                                                                         : "/system/potential",
                         "the generalized force grad V + F is not finite at the initial state (component " + std::to_string(i) + ")");
    const Eigen::VectorXd v0 = Eigen::Map<const Eigen::VectorXd>(scene.v0.data(), n_);
    const double e0 = 0.5 * v0.dot(sys->mass * v0);
    if (!std::isfinite(e0))
      throw SceneError("/initial/v", "the kinetic energy 1/2 <M v0, v0> is not finite at the initial state (" + format(e0) + ")");
    large_abl_system_ = sys;
  }

  // The compiled scene of the large-contact path: no dense M, C or gap gradients; grad V and F apart
  // (2n constants) and V for the reports' checks, and the system the integrator runs.
  std::shared_ptr<CompiledLagrangian> build_large() {
    auto c = std::make_shared<CompiledLagrangian>();
    c->n = n_;
    c->dense = false;
    c->constant_mass = true;
    c->bandwidth = 0;
    c->num_constraints = static_cast<int>(gaps_.size());
    compile_split_force_tape(*c);
    if (potential_ >= 0) compile_potential_tape(*c);
    if (!gaps_.empty()) {  // the gaps alone (no gradients: the system holds H)
      c->constraint_tape = expr::Tape::compile(graph_, gaps_, 1 + 2 * n_, num_params());
      expr::Tape::Wiring w = position_wiring();
      for (int i = 0; i < c->num_constraints; ++i) w.outputs.push_back({{0, i}});
      c->constraint_tape.wire(w);
    }
    c->large_contacts = large_system_;
    c->large_abl = large_abl_system_;
    if (large_abl_system_) c->bandwidth = large_abl_system_->bandwidth();
    return c;
  }

  // Builds the tapes (step, mass, grad V and F apart, V, the gaps, their Hessians, the parameters' terms)
  // and the constant parts.
  std::shared_ptr<CompiledLagrangian> build() {
    auto c = std::make_shared<CompiledLagrangian>();
    c->n = n_;
    const int nn = n_ * n_;
    c->constant_terms.assign(static_cast<std::size_t>(2 * nn + n_), 0.0);
    std::vector<Node> step_outputs, mass_outputs;
    std::vector<Node> bound_outputs;
    // step_tape output j goes to the flat indices step_targets[j] of [M | C | g] (two for a symmetric
    // pair of M); likewise mass_targets for mass_tape into M. The tapes are wired to them (terms_wiring).
    std::vector<std::vector<int>> step_targets, mass_targets;
    auto place = [&](Node node, std::vector<int> targets, bool is_mass) {
      if (graph_.is_constant(node)) {
        for (int t : targets) c->constant_terms[t] = graph_.constant_value(node);
        return;
      }
      // Free parameters and constants alone: a constant of each binding, set when it is bound (as the
      // folded compile sets a constant here), so that the step tapes are those of the folded compile.
      if (num_params() > 0 && bound_only(node)) {
        bound_outputs.push_back(node);
        c->bound_targets.push_back(std::move(targets));
        return;
      }
      step_outputs.push_back(node);
      step_targets.push_back(targets);
      if (is_mass) {
        mass_outputs.push_back(node);
        mass_targets.push_back(targets);
        c->constant_mass = false;
      }
    };
    for (int i = 0; i < n_; ++i)
      for (int j = i; j < n_; ++j) place(sym(i, j), i == j ? std::vector<int>{i + j * n_} : std::vector<int>{i + j * n_, j + i * n_}, true);
    for (int i = 0; i < n_; ++i)
      for (int j = 0; j < n_; ++j) place(C_[i * n_ + j], {nn + i + j * n_}, false);
    for (int i = 0; i < n_; ++i) place(g_[i], {2 * nn + i}, false);
    // The band of M and C: every flat index of [M | C] that a tape writes or that holds a non-zero constant.
    const auto widen = [&](int flat) {
      const int ij = flat % nn;  // column-major within M or C
      c->bandwidth = std::max(c->bandwidth, std::abs(ij % n_ - ij / n_));
    };
    for (const auto& targets : step_targets)
      for (int t : targets)
        if (t < 2 * nn) widen(t);
    for (const auto& targets : c->bound_targets)  // whatever their values
      for (int t : targets)
        if (t < 2 * nn) widen(t);
    c->bound_terms_tape = expr::Tape::compile(graph_, bound_outputs, 1 + 2 * n_, num_params());
    for (int t = 0; t < 2 * nn; ++t)
      if (c->constant_terms[t] != 0.0) widen(t);
    compile_split_force_tape(*c);
    if (robot_) {
      c->robot = std::make_shared<const RigidBodyModel>(robot_->model);
      c->constant_mass = false;
      c->has_potential = true;  // gravity's, with the scene's own potential added when given
      // M_ij != 0 only where i and j are on one branch; C likewise: the band is the widest such pair.
      for (int j = 0; j < n_; ++j)
        for (int a = j; a >= 0; a = c->robot->bodies[static_cast<std::size_t>(a)].parent) c->bandwidth = std::max(c->bandwidth, j - a);
    }
    c->step_tape = expr::Tape::compile(graph_, step_outputs, 1 + 2 * n_, num_params());
    c->mass_tape = expr::Tape::compile(graph_, mass_outputs, 1 + 2 * n_, num_params());
    c->step_tape.wire(terms_wiring(step_targets));
    c->mass_tape.wire(terms_wiring(mass_targets));
    if (potential_ >= 0) {
      compile_potential_tape(*c);
      std::vector<Node> with_potential = step_outputs;
      with_potential.push_back(potential_);
      c->step_potential_tape = expr::Tape::compile(graph_, with_potential, 1 + 2 * n_, num_params());
      expr::Tape::Wiring terms = terms_wiring(step_targets);
      terms.outputs.push_back({{CompiledLagrangian::kPotential, 0}});
      c->step_potential_tape.wire(terms);
    }
    if (!gaps_.empty()) {
      std::vector<Node> cons = gaps_;
      cons.insert(cons.end(), gap_gradients_.begin(), gap_gradients_.end());
      const int m = static_cast<int>(gaps_.size());
      c->num_constraints = m;
      c->constraint_tape = expr::Tape::compile(graph_, cons, 1 + 2 * n_, num_params());
      expr::Tape::Wiring w = position_wiring();
      for (int i = 0; i < m; ++i) w.outputs.push_back({{0, i}});
      for (int i = 0; i < m; ++i)
        for (int j = 0; j < n_; ++j) w.outputs.push_back({{1, i + j * m}});  // output m + i n + j: H(i, j), column-major
      c->constraint_tape.wire(w);
      if (potential_ >= 0 && !robot_ && n_ <= CompiledLagrangian::kMaxHessianDof) {
        // Exact second derivatives (the graph differentiates symbolically): V's, then each gap's.
        std::vector<Node> hessians;
        auto add_hessian = [&](auto first_derivative) {
          for (int i = 0; i < n_; ++i)
            for (int j = 0; j < n_; ++j) hessians.push_back(graph_.derivative(first_derivative(i), 1 + j));
        };
        add_hessian([&](int i) { return graph_.derivative(potential_, 1 + i); });
        for (std::size_t k = 0; k < gaps_.size(); ++k) add_hessian([&](int i) { return gap_gradients_[k * n_ + i]; });
        c->hessian_tape = expr::Tape::compile(graph_, hessians, 1 + 2 * n_, num_params());
      }
    }
    return c;
  }

  std::vector<std::string> coord_names_, vel_names_;
  std::vector<Node> M_, C_, g_;
  bool diagonal_mass_ = false;                                   // /system/mass given as {"diagonal": [...]}
  bool large_ = false;                                           // beyond the dense limits: the large-contact path
  bool has_force_ = false;                                       // /system/force given
  std::vector<Node> mass_diagonal_;                              // M's diagonal when given so
  std::vector<std::optional<expr::AffineForm>> gap_forms_;       // each gap as an affine form, when it is one
  std::vector<std::vector<std::pair<int, Node>>> gap_partials_;  // per gap: (j, dh/dq_j) for the q_j it reads
  std::vector<std::uint32_t> visit_stamp_;                       // coordinates_read's marks, per graph node
  std::uint32_t stamp_ = 0;
  std::shared_ptr<const LargeContactSystem> large_system_;  // the large-contact path's system (check_large_at_initial_state)
  std::shared_ptr<const LargeAblSystem> large_abl_system_;  // the large ABL path's (check_large_abl_at_initial_state)
  bool banded_mass_ = false;                                // /system/mass given as {"bands": [...]}
  std::vector<std::vector<Node>> mass_bands_;               // its bands (b_k[i] = M(i, i + k))
  std::vector<Node> gradient_, force_;                      // grad V and F alone (constant 0 when absent)
  void enclose_forces(CompiledLagrangian& c, double t0, double t_end) const;
  Node potential_ = -1;
  bool constant_mass_ = true;
  std::vector<Node> gaps_, gap_gradients_;                 // h_i(q) and dh_i/dq_j (row-major)
  std::optional<expr::Tape> check_tape_, gap_check_tape_;  // check_at_initial_state's
  std::vector<double> free_values_;                        // the free parameters' values as the document gives them
  std::shared_ptr<UrdfRobot> robot_;                       // a URDF system's robot (/system/urdf)
};

LagrangianScene LagrangianCompiler::compile() {
  LagrangianScene scene;
  scene.name = read_top_level();
  declare_parameters();
  if (!doc_.contains("system")) throw SceneError("/system", "missing required field 'system'");
  const json& system = doc_["system"];
  require_object(system, "/system");
  if (!system.contains("type") || !system["type"].is_string())
    throw SceneError("/system/type", "missing system type (expected \"lagrangian\")");
  const std::string type = system["type"].get<std::string>();
  // Reached only where a Lagrangian system is required (studies); everything else loads a scene of either
  // kind through Simulation.
  if (type == "lure")
    throw SceneError("/system/type",
                     "studies compare schemes for Lagrangian systems; a Lur'e system (\"lure\") has one scheme: run it instead");
  if (type != "lagrangian") throw SceneError("/system/type", "unknown system type '" + type + "' (expected: lagrangian, lure)");
  check_fields(system, "/system",
               {"type", "coordinates", "mass", "coriolis", "potential", "potential_gradient", "force", "controller", "constraints", "urdf",
                "tracking"});
  if (system.contains("urdf")) urdf(system);
  coordinates(system);
  check_all_parameters();
  scene.n = n_;
  scene.coordinates = coord_names_;
  scene.velocities = vel_names_;
  if (robot_) {
    // M, C and grad V come from the robot model at every step (SceneModel); the expressions add F (and a
    // potential, if the scene gives one) to them.
    M_.assign(static_cast<std::size_t>(n_ * n_), graph_.constant(0.0));
    C_.assign(static_cast<std::size_t>(n_ * n_), graph_.constant(0.0));
    constant_mass_ = false;
    scene.coriolis = CoriolisSource::kChristoffel;
    scene.robot_name = robot_->name;
  } else {
    mass_matrix(system["mass"]);
    for (std::size_t i = 0; i < M_.size(); ++i)  // none when large_: its diagonal is checked constant
      if (!graph_.is_constant(M_[i]) && !(num_params() > 0 && bound_only(M_[i]))) constant_mass_ = false;
    coriolis(system, scene);
  }
  forces(system, scene);
  controller(system, scene);
  joint_friction(system, scene);
  constraints(system, scene);
  joint_limits(system, scene);
  tracking(system, scene);
  initial(scene);
  integrator(scene);
  if (scene.tracking && scene.tracking->spline) {
    const CubicSplineReference& sp = *scene.tracking->spline;
    if (scene.settings.t0 < sp.t_first() || scene.settings.t_end > sp.t_last())
      throw SceneError("/system/tracking/reference/points", "the way points cover t from " + format(sp.t_first()) + " to " +
                                                                format(sp.t_last()) + ", not the run's [" + format(scene.settings.t0) +
                                                                ", " + format(scene.settings.t_end) + "]");
  }
  if (scene.tracking && scene.tracking->sampled) {
    // The plant steps h between samples: T_s a whole number of them, and no longer than the run (so the
    // number of steps per sample is bounded by the run's step count).
    if (scene.tracking->period > scene.settings.t_end - scene.settings.t0)
      throw SceneError("/system/tracking/period", "T_s = " + format(scene.tracking->period) + " is longer than the run's interval [" +
                                                      format(scene.settings.t0) + ", " + format(scene.settings.t_end) + "]");
    const double ratio = scene.tracking->period / scene.settings.h;
    if (!(std::round(ratio) >= 1.0) || std::abs(ratio - std::round(ratio)) > 1e-9 * ratio)
      throw SceneError("/system/tracking/period", "T_s = " + format(scene.tracking->period) +
                                                      " must be a whole number of plant steps h = " + format(scene.settings.h));
  }
  if (const auto every = output_every()) scene.settings.output_every = *every;
  exact(scene);
  check_at_initial_state(scene, free_values_.empty() ? nullptr : free_values_.data());
  std::shared_ptr<CompiledLagrangian> compiled = large_ ? build_large() : build();
  // A dense-size scene with the large-contact structure may run on that path too (run_scene chooses by n).
  if (!large_) {
    compiled->large_contacts = large_contact_system(scene);
    compiled->large_abl = large_abl_system(scene);
  }
  scene.unread_parameters = unread_parameters();
  enclose_forces(*compiled, scene.settings.t0, scene.settings.t_end);
  scene.compiled = std::move(compiled);
  scene.settings.bandwidth = scene.compiled->bandwidth;
  return scene;
}

// Bounds of ||grad V(q)|| over every q and of ||F(t, q, v)|| over every (q, v) and t in [t0, t_end], by
// interval arithmetic over the expressions (expr/interval.h): what proves Assumption 4.1 2)-3) for all
// states. None when an enclosure is unbounded, a free parameter appears, or a robot adds gravity.
void LagrangianCompiler::enclose_forces(CompiledLagrangian& c, double t0, double t_end) const {
  std::vector<expr::Interval> slots(static_cast<std::size_t>(1 + 2 * n_), expr::Interval::everything());
  slots[0] = {t0, t_end};
  const auto norm_bound = [&](const std::vector<Node>& nodes) -> std::optional<double> {
    double sum = 0.0;
    for (const expr::Interval& i : expr::enclose(graph_, nodes, slots)) {
      if (!i.bounded()) return std::nullopt;
      sum += i.magnitude() * i.magnitude();
    }
    return std::sqrt(sum) * (1.0 + 1e-12);  // above the rounding of n squares, their sum and the root
  };
  c.force_bound = norm_bound(force_);
  if (!robot_) c.gradient_bound = norm_bound(gradient_);
}

}  // namespace

LagrangianScene load_scene(const nlohmann::json& doc) {
  LagrangianCompiler compiler(doc);
  return compile_scene([&] { return compiler.compile(); });
}

struct ParametricLagrangianScene::Impl {
  explicit Impl(const nlohmann::json& d) : doc(d), compiler(doc) {}
  const nlohmann::json doc;     // the compiler reads it by reference
  LagrangianCompiler compiler;  // its graph and check tapes serve every binding
  LagrangianScene nominal;      // tapes unbound
  std::size_t num_free = 0;
  // The compiled model and exact-solution tape of the latest binding: bound again in place by the next
  // one when nothing else holds them any more (the previous sample's simulation is gone), instead of
  // copied; bind() sets every value that depends on the parameters, so no earlier binding shows through.
  std::shared_ptr<CompiledLagrangian> spare_compiled;
  std::shared_ptr<expr::Tape> spare_exact;
};

ParametricLagrangianScene::ParametricLagrangianScene(const nlohmann::json& doc, std::vector<std::string> free)
    : impl_(std::make_unique<Impl>(doc)) {
  std::vector<double> values;
  for (const std::string& name : free) {
    const std::string ptr = "/parameters/" + json_pointer_token(name);
    const nlohmann::json::json_pointer jp(ptr);
    if (!doc.contains(jp) || !doc[jp].is_number() || !std::isfinite(doc[jp].get<double>()))
      throw SceneError(ptr, "a free parameter must be a finite number in the scene");
    values.push_back(doc[jp].get<double>());
  }
  impl_->num_free = free.size();
  impl_->compiler.keep_free(std::move(free), values);
  impl_->nominal = compile_scene([&] { return impl_->compiler.compile(); });
  // The nominal scene's tapes stay unbound: bind() binds copies.
  // What the compiler decides from the structure of the expressions must not depend on whether the free
  // parameters are folded in: checked against the scene compiled at the document's values, and for the
  // one decision that depends on a value (whether x^p is smooth everywhere, p a free parameter), refused.
  const LagrangianScene folded = load_scene(doc);
  const LagrangianScene& kept = impl_->nominal;
  const bool same = folded.forces_smooth_everywhere == kept.forces_smooth_everywhere &&
                    folded.force_depends_on_time == kept.force_depends_on_time && folded.has_force == kept.has_force &&
                    folded.compiled->constant_mass == kept.compiled->constant_mass &&
                    folded.compiled->bandwidth == kept.compiled->bandwidth && folded.settings.bandwidth == kept.settings.bandwidth &&
                    folded.scheme == kept.scheme;
  if (!same || impl_->compiler.free_parameter_in_an_exponent())
    throw SceneError("/parameters",
                     "these parameters cannot be left free: what the compiler decides from the expressions' structure "
                     "(smoothness, time dependence, constant mass, band) would depend on their values");
}

ParametricLagrangianScene::~ParametricLagrangianScene() = default;
ParametricLagrangianScene::ParametricLagrangianScene(ParametricLagrangianScene&&) noexcept = default;

const LagrangianScene& ParametricLagrangianScene::nominal() const { return impl_->nominal; }

LagrangianScene ParametricLagrangianScene::bind(const std::vector<double>& values, const std::vector<double>& q0,
                                                const std::vector<double>& v0) {
  const LagrangianScene& base = impl_->nominal;
  if (values.size() != impl_->num_free) throw std::invalid_argument("ParametricLagrangianScene::bind: one value per free parameter");
  for (double v : values)
    if (!std::isfinite(v) || v == 0.0) throw std::invalid_argument("ParametricLagrangianScene::bind: values must be finite and non-zero");
  if (q0.size() != static_cast<std::size_t>(base.n) || v0.size() != static_cast<std::size_t>(base.n))
    throw std::invalid_argument("ParametricLagrangianScene::bind: q0 and v0 need n entries");
  LagrangianScene scene = base;
  if (!impl_->spare_compiled || impl_->spare_compiled.use_count() > 1)
    impl_->spare_compiled = std::make_shared<CompiledLagrangian>(*base.compiled);
  const std::shared_ptr<CompiledLagrangian> compiled = impl_->spare_compiled;
  bool generic = true;
  for (expr::Tape* tape : {&compiled->step_tape, &compiled->mass_tape, &compiled->potential_tape, &compiled->step_potential_tape,
                           &compiled->split_force_tape, &compiled->constraint_tape, &compiled->hessian_tape, &compiled->bound_terms_tape})
    generic = tape->bind(values.data()) && generic;
  // The entries of M, C and g of the parameters alone: constants of this binding.
  if (!compiled->bound_targets.empty()) {
    const expr::Tape& tape = compiled->bound_terms_tape;
    std::vector<double> slots(static_cast<std::size_t>(1 + 2 * base.n), 0.0), out(tape.num_outputs()), scratch(tape.scratch_size());
    tape.eval(slots.data(), out.data(), scratch.data());
    for (std::size_t j = 0; j < out.size(); ++j)
      for (int t : compiled->bound_targets[j]) compiled->constant_terms[static_cast<std::size_t>(t)] = out[j];
  }
  scene.compiled = compiled;
  if (scene.exact_tape) {
    if (!impl_->spare_exact || impl_->spare_exact.use_count() > 1) impl_->spare_exact = std::make_shared<expr::Tape>(*base.exact_tape);
    generic = impl_->spare_exact->bind(values.data()) && generic;
    scene.exact_tape = impl_->spare_exact;
  }
  // The reference of a tracking scene may read the free parameters too. (Its nominal model was compiled
  // at the document's values: a campaign varies the plant, not the controller's model.)
  if (scene.tracking && scene.tracking->reference) {
    auto spec = std::make_shared<TrackingSpec>(*scene.tracking);
    auto tape = std::make_shared<expr::Tape>(*spec->reference);
    generic = tape->bind(values.data()) && generic;
    spec->reference = std::move(tape);
    scene.tracking = std::move(spec);
  }
  if (!generic)
    throw std::invalid_argument(
        "ParametricLagrangianScene::bind: a quantity of the parameters alone is 0 at these values (the full compile "
        "folds it, which can change the sign of a zero)");
  scene.q0 = q0;
  scene.v0 = v0;
  for (std::size_t i = 0; i < q0.size(); ++i)
    if (!std::isfinite(q0[i]) || !std::isfinite(v0[i])) throw SceneError("/initial", "the initial state must be finite");
  compile_scene([&] {
    impl_->compiler.check_binding(scene, values);
    return 0;
  });
  return scene;
}

}  // namespace moreau::scene
