// What the Lagrangian and the Lur'e compilers share: a scene document's parameters, expressions and
// constants, each error a SceneError naming the field's JSON pointer. lagrangian_compiler.cc and
// lure_compiler.cc derive from it; docs/scene-format.md is the format.
#pragma once

#include <Eigen/Dense>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "moreau/expr/expression.h"
#include "moreau/scene/scene.h"

#include "json_checks.h"

namespace moreau::scene::detail {

// A parameter, coordinate or state name: a letter or _, then letters, digits and _ (at most 64).
bool is_identifier(const std::string& s);

// The functions of the expression language: reserved, so no parameter or coordinate takes their name.
const std::set<std::string>& function_names();

// Coordinate and state names (system.coordinates, a URDF robot's joints, a Lur'e system's states) name
// the columns of the trajectory: t, h, the n names, their velocities <name>_dot, energy (the CSV header,
// trajectory_csv.h, and the keys of the JSON trajectory), and the variables of the expressions. So that
// each column and each variable has one meaning, a name may not be
//   - t, h or energy (the trajectory's own columns; t is also the time of the expressions),
//   - a function of the expression language (function_names()),
//   - another coordinate's name (duplicate), or another coordinate's velocity <other>_dot.
// The first name that breaks the rule (in the order given) and why; nullopt when all may be used.
// `what` is "coordinate" or "state", as the message calls them.
struct NameConflict {
  std::size_t index;
  std::string reason;
};
std::optional<NameConflict> column_name_conflict(const std::vector<std::string>& names, const std::string& what);

// What an expression may depend on.
enum Depends : unsigned { kParamsOnly = 0, kTime = 1, kPosition = 2, kVelocity = 4 };

class SceneReader {
 protected:
  using json = nlohmann::json;
  using Node = expr::Node;

  explicit SceneReader(const json& doc) : doc_(doc) {}

  // The document's top level: an object with only the known fields, and its optional name.
  std::string read_top_level();
  // /integrator/h, t0 (default 0) and t_end > t0, in seconds.
  void read_interval(const json& integrator, double& h, double& t0, double& t_end);
  // /integrator/max_steps, kMaxStepsLimit when absent.
  std::int64_t read_max_steps(const json& integrator);
  // /output/every, when given.
  std::optional<std::int64_t> output_every();

  void declare_parameters();
  // Every parameter must evaluate to a finite constant, whether or not anything uses it: a typo or a
  // division by zero in an unused parameter is still an error. Called once the coordinates are known,
  // so that a parameter naming one is told it cannot.
  void check_all_parameters();
  // The parameters no expression of the scene reads (directly, or through a parameter that is read), in
  // name order: the report warns of them. (An override cannot create a parameter: apply_override.)
  std::vector<std::string> unread_parameters() const;
  Node parameter(const std::string& name);
  Node expression(const json& j, const std::string& ptr, unsigned allowed, const std::string& what);
  Node constant_node(const json& j, const std::string& ptr);
  double constant(const json& j, const std::string& ptr) { return graph_.constant_value(constant_node(j, ptr)); }
  double positive(const json& j, const std::string& ptr) {
    const double v = constant(j, ptr);
    if (!(v > 0.0)) throw SceneError(ptr, "must be > 0, got " + format(v));
    return v;
  }
  const json& array_of(const json& j, const std::string& ptr, std::size_t size, const std::string& what) {
    if (!j.is_array()) throw SceneError(ptr, "expected " + what + ", got " + type_name(j));
    if (j.size() != size)
      throw SceneError(ptr, "expected " + std::to_string(size) + " entries (one per coordinate), got " + std::to_string(j.size()));
    return j;
  }
  std::vector<double> constant_vector(const json& j, const std::string& ptr);
  Eigen::MatrixXd constant_matrix(const json& j, const std::string& ptr, int rows, int cols, const std::string& what);
  // A run takes at least one step and at most max_steps. Everything is computed in double before any
  // conversion to an integer: a double at or beyond 2^63 (t_end = 1e300, h = 1e-300) converts to int64
  // with undefined behaviour. For the adaptive rules h is the largest step, so (t_end - t0) / h is a lower
  // bound of their step count: beyond max_steps they could only fail at max_steps.
  void check_step_count(double t0, double t_end, double h, std::int64_t max_steps, bool fixed);

  const json& doc_;
  expr::Graph graph_;
  int n_ = 0;  // coordinates (Lagrangian) or states (Lur'e)
  std::map<std::string, const json*> params_;
  std::map<std::string, Node> param_nodes_;
  std::set<std::string> resolving_;
  std::vector<std::string> resolving_order_;                  // the parameters being resolved, innermost last
  std::set<std::string> read_params_;                         // named by an expression of the scene
  std::map<std::string, std::set<std::string>> param_reads_;  // parameter -> the parameters its value names
  std::map<std::string, int> coord_slot_;                     // a coordinate's variable: 1..n positions, n+1..2n velocities
  // Parameters kept free (ParametricLagrangianScene): parameter k is the variable 1 + 2n + k of the
  // expressions, a named constant of the tapes set when they are bound, never folded in. Anything that
  // needs its value while compiling (a gain, the step, the initial state, another parameter) fails with
  // "must be constant".
  std::vector<std::string> free_params_;
  int num_params() const { return static_cast<int>(free_params_.size()); }
};

// Runs a compiler, turning expression limits and malformed JSON into SceneErrors.
template <class F>
auto compile_scene(F&& compile) -> decltype(compile()) {
  try {
    return compile();
  } catch (const SceneError&) {
    throw;
  } catch (const expr::ExpressionError& e) {
    throw SceneError("/", std::string("expression limit: ") + e.what());
  } catch (const nlohmann::json::exception& e) {
    throw SceneError("/", std::string("malformed scene: ") + e.what());
  }
}

}  // namespace moreau::scene::detail
