// The friction bar of scripts/make-friction-bar.py as a scene document, for any n: an elastic bar fixed
// at one end as n linear finite elements of the 64-node bar's length l = 1/64 (so L = n/64: the system
// grows, its elements and hence its fastest mode stay those of scenes/friction-bar.json; (0.2)'s explicit
// position update amplifies modes with h omega of order 1, and a bar of fixed length L = 1 cut into
// 2000 elements has omega_max about 7000/s), with Coulomb friction at every node,
//
//   M = rhoA l / 6 tridiag(1, 4, 1) (2 on the free end's diagonal),  V = EA / (2 l) sum_i (u_i - u_{i-1})^2,
//   Phi(v) = sum_i c/2 v_i^2 + a |v_i|,  a = mu_f rhoA l g,
//
// released with its first mode's velocity profile (V given as the array of its terms); with pendulum > 0
// every node also carries pendulum * (1 - cos u_i) (a Frenkel-Kontorova chain: a nonlinear grad V). M is given by its bands
// ({"bands": [diagonal, first off-diagonal]}), which every n takes (beyond 64 the large ABL path).
#pragma once

#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

namespace moreau::test_support {

inline nlohmann::json friction_bar_scene(int n, double t_end, double pendulum = 0.0) {
  nlohmann::json coordinates = nlohmann::json::array(), diagonal = nlohmann::json::array(), off = nlohmann::json::array();
  nlohmann::json v0 = nlohmann::json::array();
  nlohmann::json potential = nlohmann::json::array();  // V as its terms (one expression would pass 16384 characters)
  for (int i = 0; i < n; ++i) {
    const std::string u = "u" + std::to_string(i + 1);
    coordinates.push_back(u);
    diagonal.push_back(i == n - 1 ? "2*m6" : "4*m6");
    if (i + 1 < n) off.push_back("m6");
    potential.push_back("k/2*(" + u + " - " + (i ? "u" + std::to_string(i) : std::string("0")) + ")^2");
    if (pendulum > 0.0) potential.push_back("c0*(1 - cos(" + u + "))");
    v0.push_back(std::sin(3.14159265358979323846 * (i + 1) / (2.0 * n)));
  }
  nlohmann::json scene = {{"name", "friction-bar"},
                          {"parameters",
                           {{"L", "nodes/64"},
                            {"nodes", n},
                            {"l", "L/nodes"},
                            {"rhoA", 1},
                            {"EA", 1},
                            {"mu_f", 0.05},
                            {"g", 9.81},
                            {"m6", "rhoA*l/6"},
                            {"k", "EA/l"},
                            {"a", "mu_f*rhoA*l*g"},
                            {"c", 0.15}}},
                          {"system",
                           {{"type", "lagrangian"},
                            {"coordinates", coordinates},
                            {"mass", {{"bands", {diagonal, off}}}},
                            {"potential", potential},
                            {"controller",
                             {{{"type", "quadratic"}, {"weights", std::vector<std::string>(static_cast<std::size_t>(n), "c")}},
                              {{"type", "abs"}, {"gains", std::vector<std::string>(static_cast<std::size_t>(n), "a")}}}}}},
                          {"initial", {{"q", std::vector<double>(static_cast<std::size_t>(n), 0.0)}, {"v", v0}}},
                          {"integrator", {{"scheme", "abl"}, {"h", 1e-3}, {"t_end", t_end}}}};
  if (pendulum > 0.0) scene["parameters"]["c0"] = pendulum;
  return scene;
}

}  // namespace moreau::test_support
