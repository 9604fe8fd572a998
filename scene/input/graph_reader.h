// Reading a maximal monotone graph (a Lur'e feedback, Brogliato 2003 Fig. 3) from its JSON object.
#pragma once

#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "moreau/core/maximal_monotone_graph.h"

namespace moreau::scene::detail {

// How the scene turns a JSON value into a number (a literal, or an expression of the parameters),
// throwing SceneError at `pointer` when it cannot.
using ConstantReader = std::function<double(const nlohmann::json& value, const std::string& pointer)>;

// The graph of `f` (relay, coulomb, saturation, dead_zone, complementarity, mos, adhesive or graph),
// and its type in `type`. Throws SceneError naming the field (under `ptr`) that is missing, out of range
// or makes the graph non-monotone or overflow.
MonotoneGraph read_feedback_graph(const nlohmann::json& f, const std::string& ptr, std::string& type, const ConstantReader& constant);

}  // namespace moreau::scene::detail
