// affine_form (linear_form.h): the reachable nodes in increasing index order (a node's operands have
// smaller indices: the graph creates them first), a forward pass that classifies each node and evaluates
// it at x = 0, and a reverse pass that accumulates the adjoints into the variables' coefficients.
#include "moreau/expr/linear_form.h"

#include <algorithm>
#include <unordered_map>

namespace moreau::expr {

std::optional<AffineForm> affine_form(const Graph& graph, Node f) {
  // Reachable nodes, without recursion (a sum of 10,000 terms is a chain 10,000 deep).
  std::vector<Node> nodes, stack{f};
  std::unordered_map<Node, int> index;  // node -> its place in `nodes` after sorting
  index.reserve(64);
  while (!stack.empty()) {
    const Node x = stack.back();
    stack.pop_back();
    if (!index.emplace(x, 0).second) continue;
    nodes.push_back(x);
    const Graph::Entry& e = graph.entry(x);
    for (Node operand : {e.a, e.b, e.c, e.d})
      if (operand >= 0 && !index.count(operand)) stack.push_back(operand);
  }
  std::sort(nodes.begin(), nodes.end());
  for (std::size_t i = 0; i < nodes.size(); ++i) index[nodes[i]] = static_cast<int>(i);

  enum Kind : char { kConstant, kAffine };
  std::vector<char> kind(nodes.size());
  std::vector<double> value(nodes.size());  // at x = 0; for a constant node, its value
  const auto at = [&](Node x) { return static_cast<std::size_t>(index.at(x)); };
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const Graph::Entry& e = graph.entry(nodes[i]);
    switch (e.op) {
      case Op::kConst: kind[i] = kConstant, value[i] = e.value; break;
      case Op::kVar: kind[i] = kAffine, value[i] = 0.0; break;
      case Op::kAdd:
      case Op::kSub: {
        const std::size_t a = at(e.a), b = at(e.b);
        kind[i] = kind[a] == kConstant && kind[b] == kConstant ? kConstant : kAffine;
        value[i] = e.op == Op::kAdd ? value[a] + value[b] : value[a] - value[b];
        break;
      }
      case Op::kNeg: kind[i] = kind[at(e.a)], value[i] = -value[at(e.a)]; break;
      case Op::kMul: {
        const std::size_t a = at(e.a), b = at(e.b);
        if (kind[a] != kConstant && kind[b] != kConstant) return std::nullopt;
        kind[i] = kind[a] == kConstant && kind[b] == kConstant ? kConstant : kAffine;
        value[i] = value[a] * value[b];
        break;
      }
      case Op::kDiv: {
        const std::size_t a = at(e.a), b = at(e.b);
        if (kind[b] != kConstant) return std::nullopt;
        kind[i] = kind[a];
        value[i] = value[a] / value[b];
        break;
      }
      default: return std::nullopt;  // every other operation of a non-constant operand is nonlinear
    }
  }

  // Reverse pass: adjoint of f is 1.
  std::vector<double> adjoint(nodes.size(), 0.0);
  adjoint.back() = 1.0;  // f has the largest index of the nodes it reaches
  std::unordered_map<int, double> coefficient;
  for (std::size_t i = nodes.size(); i-- > 0;) {
    const double g = adjoint[i];
    if (g == 0.0 || kind[i] == kConstant) continue;
    const Graph::Entry& e = graph.entry(nodes[i]);
    switch (e.op) {
      case Op::kVar: coefficient[e.slot] += g; break;
      case Op::kAdd: adjoint[at(e.a)] += g, adjoint[at(e.b)] += g; break;
      case Op::kSub: adjoint[at(e.a)] += g, adjoint[at(e.b)] -= g; break;
      case Op::kNeg: adjoint[at(e.a)] -= g; break;
      case Op::kMul:
        if (kind[at(e.a)] == kConstant)
          adjoint[at(e.b)] += g * value[at(e.a)];
        else
          adjoint[at(e.a)] += g * value[at(e.b)];
        break;
      case Op::kDiv: adjoint[at(e.a)] += g / value[at(e.b)]; break;
      default: break;
    }
  }
  AffineForm form;
  form.constant = value.back();
  for (const auto& [slot, a] : coefficient)
    if (a != 0.0) form.coefficients.emplace_back(slot, a);
  std::sort(form.coefficients.begin(), form.coefficients.end());
  return form;
}

}  // namespace moreau::expr
