// Fuzzes the expression compiler: any text must parse or fail with an ExpressionError, never crash,
// hang or recurse without bound; what parses must differentiate, compile and evaluate.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "moreau/scene/expression.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace moreau::expr;
  const std::string text(reinterpret_cast<const char*>(data), size);
  Graph g;
  auto resolve = [&](std::string_view name) -> std::optional<Node> {
    if (name == "t") return g.variable(0);
    if (name == "x") return g.variable(1);
    if (name == "y") return g.variable(2);
    if (name == "k") return g.constant(2.5);
    return std::nullopt;
  };
  try {
    const Node f = g.parse(text, resolve);
    std::vector<Node> outs = {f, g.derivative(f, 1), g.derivative(f, 2)};
    outs.push_back(g.derivative(outs[1], 2));
    const Tape tape = Tape::compile(g, outs, 3);
    std::vector<double> scratch(tape.scratch_size()), out(outs.size());
    const double slots[3] = {0.5, -1.25, 3.0};
    tape.eval(slots, out.data(), scratch.data());
    (void)g.to_string(f);
  } catch (const ExpressionError&) {
  }
  return 0;
}
