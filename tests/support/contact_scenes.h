// The contact scenes at scale of the benchmarks and tests (docs/scaling.md), as
// scripts/make-contact-scene.py writes them: a stack of N balls on a floor, a Newton's cradle and a
// granular column, masses given as {"diagonal": [...]}, linear gaps (the column's between balls nonlinear). The radius is a power of two,
// so positions and gaps are exact binary numbers and touching contacts have gap 0.0.
#pragma once

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace moreau::test_support {

inline constexpr double kBallRadius = 0.0625;

// "y12": a name and a number (appended, not "y" + std::to_string: GCC 12 warns wrongly of an overlap there).
inline std::string indexed(const char* name, int i) { return std::string(name).append(std::to_string(i)); }

// The scene of balls with a diagonal mass: its parts, the potential's gradient omitted when null.
inline nlohmann::json balls_scene(const char* name, nlohmann::json parameters, nlohmann::json coords, nlohmann::json mass,
                                  nlohmann::json gradient, nlohmann::json cons, nlohmann::json q0, nlohmann::json v0, double t_end) {
  nlohmann::json system = {{"type", "lagrangian"}, {"coordinates", std::move(coords)}, {"mass", {{"diagonal", std::move(mass)}}}};
  if (!gradient.is_null()) system["potential_gradient"] = std::move(gradient);
  system["constraints"] = std::move(cons);
  return {{"name", name},
          {"parameters", std::move(parameters)},
          {"system", std::move(system)},
          {"initial", {{"q", std::move(q0)}, {"v", std::move(v0)}}},
          {"integrator", {{"scheme", "moreau-jean"}, {"h", 1e-3}, {"t_end", t_end}}}};
}

// N balls on a floor under gravity, each gap opened by `drop` (0: resting, every contact closed). With
// `varied_masses`, every third ball (the second, the fifth, ...) has mass 2 m.
inline nlohmann::json stack_scene(int n, double drop, double t_end, double e = 0.5, bool varied_masses = false) {
  using nlohmann::json;
  json coords = json::array(), mass = json::array(), grad = json::array(), cons = json::array(), q0 = json::array();
  for (int i = 0; i < n; ++i) {
    const bool heavy = varied_masses && i % 3 == 1;
    coords.push_back(indexed("y", i + 1));
    mass.push_back(heavy ? "2*m" : "m");
    grad.push_back(heavy ? "2*m*g" : "m*g");
    q0.push_back(kBallRadius + i * (2 * kBallRadius + drop) + drop);
    cons.push_back({{"name", indexed("c", i + 1)},
                    {"gap", i == 0 ? std::string("y1 - r") : indexed("y", i + 1) + " - " + indexed("y", i) + " - 2*r"},
                    {"restitution", "e"}});
  }
  return balls_scene("stack", {{"m", 1}, {"g", 9.81}, {"r", kBallRadius}, {"e", e}}, coords, mass, grad, cons, q0,
                     std::vector<int>(static_cast<std::size_t>(n), 0), t_end);
}

// N balls of mass 1 on a line, `gap` apart (0: touching), the first at v0 = 1, restitution e.
inline nlohmann::json cradle_scene(int n, double gap, double t_end, double e = 1.0) {
  using nlohmann::json;
  json coords = json::array(), mass = json::array(), cons = json::array(), q0 = json::array(), v0 = json::array();
  for (int i = 0; i < n; ++i) {
    coords.push_back(indexed("x", i + 1));
    mass.push_back("m");
    q0.push_back(i * (2 * kBallRadius + gap));
    v0.push_back(i == 0 ? 1 : 0);
    if (i + 1 < n) cons.push_back({{"gap", indexed("x", i + 2) + " - " + indexed("x", i + 1) + " - 2*r"}, {"restitution", e}});
  }
  return balls_scene("cradle", {{"m", 1}, {"r", kBallRadius}}, coords, mass, nullptr, cons, q0, v0, t_end);
}

// A granular column (scripts/make-contact-scene.py column): N balls (x_i, y_i) in a tube of width 3r,
// dropped in a zigzag, each gap opened by `drop`; floor under the first, both walls for each, the distance
// between neighbours minus 2r; contacts ball by ball (left_i, right_i, c_i).
inline nlohmann::json column_scene(int n, double drop, double t_end, double e = 0.5) {
  using nlohmann::json;
  const double r = kBallRadius, width = 3 * kBallRadius;
  json coords = json::array(), mass = json::array(), grad = json::array(), q0 = json::array();
  json cons = json::array({{{"name", "floor"}, {"gap", "y1 - r"}, {"restitution", "e"}}});
  for (int i = 1; i <= n; ++i) {
    const std::string x = indexed("x", i), y = indexed("y", i);
    coords.push_back(x);
    coords.push_back(y);
    mass.push_back("m");
    mass.push_back("m");
    grad.push_back("0");
    grad.push_back("m*g");
    q0.push_back(i % 2 == 1 ? r : width - r);
    q0.push_back(r + drop + (i - 1) * (std::sqrt(3.0) * r + drop));
    cons.push_back({{"name", indexed("left", i)}, {"gap", x + " - r"}, {"restitution", "e"}});
    cons.push_back({{"name", indexed("right", i)}, {"gap", "w - r - " + x}, {"restitution", "e"}});
    if (i < n) {
      const std::string x2 = indexed("x", i + 1), y2 = indexed("y", i + 1);
      cons.push_back({{"name", indexed("c", i)},
                      {"gap", "sqrt((" + x2 + " - " + x + ")^2 + (" + y2 + " - " + y + ")^2) - 2*r"},
                      {"restitution", "e"}});
    }
  }
  return balls_scene("column", {{"m", 1}, {"g", 9.81}, {"r", r}, {"w", width}, {"e", e}}, coords, mass, grad, cons, q0,
                     std::vector<int>(static_cast<std::size_t>(2 * n), 0), t_end);
}

}  // namespace moreau::test_support
