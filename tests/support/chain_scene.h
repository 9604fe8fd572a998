// The n-link planar chain of the benchmarks and tests: build/robots/chain-n.urdf (written by
// scripts/make-chain-urdf.py at build time, MOREAU_CHAIN_DIR) hanging under gravity, bent and moving,
// with the paper's controller on every joint (weights 0.01, gains 0.02) and scheme (0.2) at h = 1e-3.
#pragma once

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace moreau::test_support {

inline std::string chain_urdf_text(int n) {
  std::ifstream in(std::string(MOREAU_CHAIN_DIR) + "/chain-" + std::to_string(n) + ".urdf");
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline nlohmann::json chain_scene(int n, double t_end) {
  nlohmann::json q = nlohmann::json::array(), v = nlohmann::json::array();
  for (int i = 0; i < n; ++i) {
    q.push_back(i == 0 ? -1.2 : 0.3 * std::sin(0.7 * i));
    v.push_back(1.5 * std::cos(0.9 * i));
  }
  return {{"name", "chain"},
          {"system",
           {{"type", "lagrangian"},
            {"urdf", {{"text", chain_urdf_text(n)}, {"gravity", {0.0, -9.81, 0.0}}}},
            {"controller",
             {{{"type", "quadratic"}, {"weights", std::vector<double>(n, 0.01)}},
              {{"type", "abs"}, {"gains", std::vector<double>(n, 0.02)}}}}}},
          {"initial", {{"q", q}, {"v", v}}},
          {"integrator", {{"scheme", "abl"}, {"h", 1e-3}, {"t_end", t_end}}}};
}

}  // namespace moreau::test_support
