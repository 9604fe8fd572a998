// affine_form against the graph's own symbolic derivatives and the tape's values (independent code paths).
#include "moreau/expr/linear_form.h"

#include <gtest/gtest.h>

#include <string>

namespace moreau::expr {
namespace {

// Names x0..x9 are slots 0..9; r and m are constants.
Node parse(Graph& g, const std::string& text) {
  return g.parse(text, [&](std::string_view name) -> std::optional<Node> {
    if (name == "r") return g.constant(0.05);
    if (name == "m") return g.constant(3.0);
    if (name.size() == 2 && name[0] == 'x') return g.variable(name[1] - '0');
    return std::nullopt;
  });
}

TEST(AffineForm, AgreesWithTheSymbolicDerivativesAndTheValueAtZero) {
  for (const std::string text :
       {"x1 - x0 - 2*r", "x3", "-x2 + 4", "m*9.81*(x0 + x1 + x2)", "(x4 - x1)/m + r*x1 - 7", "x1 - (x1 - x2)", "2*(x0 - 3*(x5 + 1))/4"}) {
    Graph g;
    const Node f = parse(g, text);
    const auto form = affine_form(g, f);
    ASSERT_TRUE(form) << text;
    Tape tape = Tape::compile(g, {f}, 10);
    std::vector<double> slots(10, 0.0), out(1), scratch(tape.scratch_size());
    tape.eval(slots.data(), out.data(), scratch.data());
    EXPECT_DOUBLE_EQ(form->constant, out[0]) << text;
    for (int slot = 0; slot < 10; ++slot) {
      const Node d = g.derivative(f, slot);
      ASSERT_TRUE(g.is_constant(d)) << text;
      double a = 0.0;
      for (const auto& [s, c] : form->coefficients)
        if (s == slot) a = c;
      EXPECT_DOUBLE_EQ(a, g.constant_value(d)) << text << ", slot " << slot;
    }
  }
}

TEST(AffineForm, SaysNotAffineForNonlinearExpressions) {
  for (const std::string text : {"x0*x1", "x0^2", "sin(x0)", "1/x0", "abs(x1 - x0)", "sqrt(x0 + 1) - 1", "min(x0, x1)", "x0/(x1 + 1)"}) {
    Graph g;
    EXPECT_FALSE(affine_form(g, parse(g, text))) << text;
  }
}

TEST(AffineForm, ReadsASumOfTwentyThousandTermsWithoutRecursion) {
  Graph g;
  Node sum = g.constant(0.0);
  for (int k = 0; k < 20000; ++k) sum = g.binary(Op::kAdd, sum, g.binary(Op::kMul, g.constant(k + 1.0), g.variable(k % 10)));
  const auto form = affine_form(g, sum);
  ASSERT_TRUE(form);
  ASSERT_EQ(form->coefficients.size(), 10u);
  // a_j = sum of (k + 1) over k = j mod 10: 2000 terms j + 1, j + 11, ...: 2000 (j + 1) + 10 * 1999000.
  for (int j = 0; j < 10; ++j) EXPECT_EQ(form->coefficients[j].second, 2000.0 * (j + 1) + 10.0 * 1999000.0) << j;
}

}  // namespace
}  // namespace moreau::expr
