// The parts of a scene document both compilers read: parameters, expressions, constants, step counts.
#include "scene_reader.h"

#include <algorithm>
#include <cmath>
#include <string_view>

#include "moreau/core/stepping_driver.h"

namespace moreau::scene::detail {

using expr::Node;
using nlohmann::json;

bool is_identifier(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  if (!(std::isalpha(static_cast<unsigned char>(s[0])) || s[0] == '_')) return false;
  for (char c : s)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_')) return false;
  return true;
}

const std::set<std::string>& function_names() {
  static const std::set<std::string> names = {"sin",  "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh",
                                              "tanh", "exp", "log", "sqrt", "abs",  "min",  "max",   "pow"};
  return names;
}

std::optional<NameConflict> column_name_conflict(const std::vector<std::string>& names, const std::string& what) {
  static const std::map<std::string, std::string> kColumns = {{"t", "the time"}, {"h", "the step size"}, {"energy", "the energy"}};
  std::map<std::string, std::size_t> first;  // name -> index of its first use
  for (std::size_t i = 0; i < names.size(); ++i) first.emplace(names[i], i);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const std::string& q = names[i];
    if (const auto c = kColumns.find(q); c != kColumns.end())
      return NameConflict{i, "'" + q + "' is reserved: the trajectory has its own column '" + q + "' (" + c->second + ")"};
    if (function_names().count(q)) return NameConflict{i, "'" + q + "' is reserved (a function of the expression language)"};
    if (first.at(q) != i) return NameConflict{i, "duplicate name '" + q + "'"};
    // q == <other>_dot: the velocity of the other names the same column and the same variable.
    constexpr std::string_view kDot = "_dot";
    if (q.size() > kDot.size() && q.compare(q.size() - kDot.size(), kDot.size(), kDot) == 0) {
      const std::string base = q.substr(0, q.size() - kDot.size());
      if (first.count(base))
        return NameConflict{i, "'" + q + "' is the name of the velocity of " + what + " '" + base +
                                   "' (its column in the trajectory and its name in expressions): give this " + what + " another name"};
    }
  }
  return std::nullopt;
}

std::string SceneReader::read_top_level() {
  require_object(doc_, "");
  check_fields(doc_, "", {"name", "description", "parameters", "system", "initial", "integrator", "output", "exact", "units"});
  std::string name;
  if (doc_.contains("name")) {
    if (!doc_["name"].is_string()) throw SceneError("/name", "expected a string, got " + type_name(doc_["name"]));
    name = doc_["name"].get<std::string>();
  }
  return name;
}

void SceneReader::read_interval(const json& in, double& h, double& t0, double& t_end) {
  if (!in.contains("h")) throw SceneError("/integrator", "missing required field 'h'");
  if (!in.contains("t_end")) throw SceneError("/integrator", "missing required field 't_end'");
  h = positive(in["h"], "/integrator/h");
  t0 = in.contains("t0") ? constant(in["t0"], "/integrator/t0") : 0.0;
  t_end = constant(in["t_end"], "/integrator/t_end");
  if (!(t_end > t0)) throw SceneError("/integrator/t_end", "must be > t0 (" + format(t0) + "), got " + format(t_end));
}

std::int64_t SceneReader::read_max_steps(const json& in) {
  if (!in.contains("max_steps")) return kMaxStepsLimit;
  const double m = positive(in["max_steps"], "/integrator/max_steps");
  if (m != std::floor(m) || m > static_cast<double>(kMaxStepsLimit))
    throw SceneError("/integrator/max_steps", "must be a whole number <= " + std::to_string(kMaxStepsLimit));
  return static_cast<std::int64_t>(m);
}

std::optional<std::int64_t> SceneReader::output_every() {
  if (!doc_.contains("output")) return std::nullopt;
  const json& o = doc_["output"];
  require_object(o, "/output");
  check_fields(o, "/output", {"every"});
  if (!o.contains("every")) return std::nullopt;
  const double e = positive(o["every"], "/output/every");
  if (e != std::floor(e) || e > 1e15) throw SceneError("/output/every", "must be a whole number >= 1");
  return static_cast<std::int64_t>(e);
}

void SceneReader::declare_parameters() {
  if (!doc_.contains("parameters")) return;
  const json& p = doc_["parameters"];
  require_object(p, "/parameters");
  for (auto it = p.begin(); it != p.end(); ++it) {
    const std::string ptr = "/parameters/" + json_pointer_token(it.key());
    if (!is_identifier(it.key())) throw SceneError(ptr, "'" + it.key() + "' is not a valid name");
    if (function_names().count(it.key()) || it.key() == "t")
      throw SceneError(ptr, "'" + it.key() + "' is reserved (a function name or the time t)");
    params_[it.key()] = &it.value();
  }
}

// Every parameter must evaluate to a finite constant, whether or not anything uses it: a typo or a
// division by zero in an unused parameter is still an error. Called once the coordinates are known,
// so that a parameter naming one is told it cannot.
void SceneReader::check_all_parameters() {
  for (const auto& entry : params_) parameter(entry.first);
}

std::vector<std::string> SceneReader::unread_parameters() const {
  // Read: named by an expression of the scene, or by a parameter that is read.
  std::set<std::string> read = read_params_;
  std::vector<std::string> pending(read.begin(), read.end());
  while (!pending.empty()) {
    const std::string name = pending.back();
    pending.pop_back();
    if (auto it = param_reads_.find(name); it != param_reads_.end())
      for (const std::string& other : it->second)
        if (read.insert(other).second) pending.push_back(other);
  }
  std::vector<std::string> unread;
  for (const auto& entry : params_)
    if (!read.count(entry.first)) unread.push_back(entry.first);
  return unread;
}

Node SceneReader::parameter(const std::string& name) {
  if (auto it = param_nodes_.find(name); it != param_nodes_.end()) return it->second;
  if (auto it = std::find(free_params_.begin(), free_params_.end(), name); it != free_params_.end()) {
    if (n_ <= 0) throw SceneError("/parameters/" + json_pointer_token(name), "a free parameter is read before the coordinates are known");
    const Node node = graph_.variable(1 + 2 * n_ + static_cast<int>(it - free_params_.begin()));
    param_nodes_[name] = node;
    return node;
  }
  if (resolving_.count(name)) throw SceneError("/parameters/" + json_pointer_token(name), "parameter '" + name + "' depends on itself");
  resolving_.insert(name);
  resolving_order_.push_back(name);
  const Node node = constant_node(*params_.at(name), "/parameters/" + json_pointer_token(name));
  resolving_order_.pop_back();
  resolving_.erase(name);
  param_nodes_[name] = node;
  return node;
}

Node SceneReader::expression(const json& j, const std::string& ptr, unsigned allowed, const std::string& what) {
  if (j.is_number()) {
    const double value = j.get<double>();
    if (!std::isfinite(value)) throw SceneError(ptr, "not a finite number");
    return graph_.constant(value);
  }
  if (!j.is_string()) throw SceneError(ptr, "expected a number or an expression string, got " + type_name(j));
  const std::string text = j.get<std::string>();
  std::string disallowed;
  auto resolve = [&](std::string_view name_view) -> std::optional<Node> {
    const std::string name(name_view);
    if (name == "t") {
      if (allowed & kTime) return graph_.variable(0);
      disallowed = name;
      return std::nullopt;
    }
    if (auto it = coord_slot_.find(name); it != coord_slot_.end()) {
      const bool is_velocity = it->second > n_;
      if ((is_velocity && (allowed & kVelocity)) || (!is_velocity && (allowed & kPosition))) return graph_.variable(it->second);
      disallowed = name;
      return std::nullopt;
    }
    if (params_.count(name)) {
      // Who reads it: an expression of the scene, or the parameter being resolved (unread_parameters).
      if (resolving_order_.empty())
        read_params_.insert(name);
      else
        param_reads_[resolving_order_.back()].insert(name);
      return parameter(name);
    }
    return std::nullopt;
  };
  try {
    return graph_.parse(text, resolve);
  } catch (const SceneError&) {
    throw;
  } catch (const expr::ExpressionError& e) {
    if (!disallowed.empty()) {
      throw SceneError(ptr, "'" + disallowed + "' cannot appear in " + what + " (in '" + text + "')");
    }
    throw SceneError(ptr, std::string(e.what()) + " at character " + std::to_string(e.position()) + " of '" + utf8_prefix(text, 200) + "'");
  }
}

Node SceneReader::constant_node(const json& j, const std::string& ptr) {
  const Node node = expression(j, ptr, kParamsOnly, "a constant (parameters only)");
  if (!graph_.is_constant(node)) throw SceneError(ptr, "must be constant");
  if (!std::isfinite(graph_.constant_value(node))) throw SceneError(ptr, "evaluates to a non-finite value");
  return node;
}

std::vector<double> SceneReader::constant_vector(const json& j, const std::string& ptr) {
  array_of(j, ptr, static_cast<std::size_t>(n_), "an array of " + std::to_string(n_) + " numbers");
  std::vector<double> out;
  for (int i = 0; i < n_; ++i) out.push_back(constant(j[i], ptr + "/" + std::to_string(i)));
  return out;
}

Eigen::MatrixXd SceneReader::constant_matrix(const json& j, const std::string& ptr, int rows, int cols, const std::string& what) {
  if (!j.is_array() || j.empty() || !j[0].is_array())
    throw SceneError(ptr, "expected " + what + " as an array of rows, got " + type_name(j));
  if (rows >= 0 && j.size() != static_cast<std::size_t>(rows))
    throw SceneError(ptr, "expected " + std::to_string(rows) + " rows (" + what + "), got " + std::to_string(j.size()));
  const int r = static_cast<int>(j.size());
  if (r > kMaxDof) throw SceneError(ptr, "more than " + std::to_string(kMaxDof) + " rows");
  const int c = cols >= 0 ? cols : static_cast<int>(j[0].size());
  if (c == 0 || c > kMaxDof) throw SceneError(ptr + "/0", "expected between 1 and " + std::to_string(kMaxDof) + " columns");
  Eigen::MatrixXd M(r, c);
  for (int i = 0; i < r; ++i) {
    const std::string row = ptr + "/" + std::to_string(i);
    if (!j[i].is_array()) throw SceneError(row, "expected a row (an array of numbers), got " + type_name(j[i]));
    if (j[i].size() != static_cast<std::size_t>(c))
      throw SceneError(row, "expected " + std::to_string(c) + " entries (" + what + "), got " + std::to_string(j[i].size()));
    for (int k = 0; k < c; ++k) M(i, k) = constant(j[i][k], row + "/" + std::to_string(k));
  }
  return M;
}

// A run takes at least one step and at most max_steps. Everything is computed in double before any
// conversion to an integer: a double at or beyond 2^63 (t_end = 1e300, h = 1e-300) converts to int64
// with undefined behaviour. For the adaptive rules h is the largest step, so (t_end - t0) / h is a lower
// bound of their step count: beyond max_steps they could only fail at max_steps.
void SceneReader::check_step_count(double t0, double t_end, double h, std::int64_t max_steps, bool fixed) {
  const double span = t_end - t0;
  if (!std::isfinite(span))
    throw SceneError("/integrator/t_end", "t_end - t0 overflows a double (t0 = " + format(t0) + ", t_end = " + format(t_end) + ")");
  const double ratio = span / h;  // > 0: h > 0 and t_end > t0 are checked; +inf when h is tiny
  // Within round-off of one step, the run takes one step of h (fixed_step_count); beyond it, none of
  // size h fits and a fixed run would take none at all once h exceeds the interval 1e9 times.
  if (ratio < 1.0 - 1e-9)
    throw SceneError("/integrator/h", "h = " + format(h) + " is longer than the interval [" + format(t0) + ", " + format(t_end) +
                                          "]: the run would not take a single step of h");
  const double steps = ratio > 9e18 ? ratio : static_cast<double>(fixed_step_count(t0, t_end, h));
  if (steps > static_cast<double>(max_steps)) {
    throw SceneError("/integrator/h", "h = " + format(h) + " over [" + format(t0) + ", " + format(t_end) + "] needs " +
                                          (fixed ? "" : "at least ") + format(steps) + " steps, more than the limit of " +
                                          std::to_string(max_steps));
  }
}

}  // namespace moreau::scene::detail
