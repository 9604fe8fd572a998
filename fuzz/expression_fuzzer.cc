// Fuzzes the expression compiler: any text must parse or fail with an ExpressionError, never crash,
// hang or recurse without bound; what parses must differentiate, compile and evaluate, its native code
// (plain and wired to arrays) computing bit for bit what the interpreter computes.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "moreau/expr/expression.h"

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
    Tape tape = Tape::compile(g, outs, 3);
    std::vector<double> scratch(tape.scratch_size()), out(outs.size());
    const double slots[3] = {0.5, -1.25, 3.0};
    tape.eval(slots, out.data(), scratch.data());
    // The native code (where there is some) and the interpreter, from the same registers, bit for bit.
    std::vector<double> interpreted = scratch;
    tape.run(scratch.data());
    tape.run_interpreted(interpreted.data());
    if (std::memcmp(scratch.data(), interpreted.data(), scratch.size() * sizeof(double)) != 0) __builtin_trap();
    // Wired to arrays (inputs read from slots, outputs written to wired_out): the interpreter's outputs.
    Tape::Wiring wiring;
    for (std::int32_t k = 0; k < 3; ++k) wiring.inputs.push_back({0, k});
    for (std::int32_t j = 0; j < static_cast<std::int32_t>(outs.size()); ++j) wiring.outputs.push_back({{0, j}});
    tape.wire(wiring);
    std::vector<double> wired_out(outs.size()), wired_scratch(tape.scratch_size());
    tape.load_constants(wired_scratch.data());
    const double* sources[] = {slots};
    double* sinks[] = {wired_out.data()};
    tape.run_wired(wired_scratch.data(), sources, sinks);
    for (std::size_t j = 0; j < outs.size(); ++j)
      if (std::memcmp(&wired_out[j], &interpreted[static_cast<std::size_t>(tape.output_register(j))], sizeof(double)) != 0)
        __builtin_trap();
    (void)g.to_string(f);
  } catch (const ExpressionError&) {
  }
  return 0;
}
