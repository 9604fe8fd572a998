// Interval enclosures (expr/interval.h) against independent evaluations: every value of the expression at
// many points of the input box (dense sampling, and the box's corners and the known extrema of sin and
// cos) must lie inside the enclosure, and the enclosure must be tight where the exact range is known.
#include "moreau/expr/interval.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

namespace moreau::expr {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The enclosure of `text` in x (slot 0) and y (slot 1) over the given boxes, and a check that the
// expression's value (by std:: functions, not by the graph) at `samples` random points is inside it.
template <class F>
Interval CheckedEnclosure(const std::string& text, Interval x, Interval y, F value, int samples = 20000) {
  Graph g;
  const Node f = g.parse(text, [&](std::string_view name) -> std::optional<Node> {
    if (name == "x") return g.variable(0);
    if (name == "y") return g.variable(1);
    return std::nullopt;
  });
  const Interval e = enclose(g, {f}, {x, y})[0];
  std::mt19937_64 rng(7);
  const auto pick = [&](const Interval& i) {
    const double lo = std::isfinite(i.lo) ? i.lo : -1e6, hi = std::isfinite(i.hi) ? i.hi : 1e6;
    return std::uniform_real_distribution<double>(lo, hi)(rng);
  };
  for (int k = 0; k < samples; ++k) {
    const double a = pick(x), b = pick(y), v = value(a, b);
    EXPECT_LE(e.lo, v) << text << " at " << a << ", " << b;
    EXPECT_GE(e.hi, v) << text << " at " << a << ", " << b;
  }
  return e;
}

TEST(Interval, SineAndCosineOverAnyRangeAreWithinMinusOneAndOne) {
  const Interval all =
      CheckedEnclosure("0.45*sin(x)", Interval::everything(), Interval::everything(), [](double a, double) { return 0.45 * std::sin(a); });
  EXPECT_LE(all.hi, 0.45 * (1 + 1e-15));
  EXPECT_GE(all.hi, 0.45);
  const Interval c = CheckedEnclosure("cos(x)", {0.1, 1.0}, {}, [](double a, double) { return std::cos(a); });
  EXPECT_NEAR(c.lo, std::cos(1.0), 1e-14);  // no extremum inside: the ends
  EXPECT_NEAR(c.hi, std::cos(0.1), 1e-14);
  const Interval s = CheckedEnclosure("sin(x)", {1.0, 2.0}, {}, [](double a, double) { return std::sin(a); });
  EXPECT_EQ(s.hi, 1.0);  // pi/2 inside
  EXPECT_NEAR(s.lo, std::sin(1.0), 1e-14);
  const Interval far = CheckedEnclosure("cos(x)", {1e6 * kPi - 0.5, 1e6 * kPi + 0.5}, {}, [](double a, double) { return std::cos(a); });
  EXPECT_EQ(far.hi, 1.0);  // 1e6 pi is a maximum of cos (an even multiple of pi)
}

TEST(Interval, PolynomialsProductsAndMonotoneFunctions) {
  CheckedEnclosure("x^2 - 3*x*y + y^3", {-2.0, 1.5}, {-1.0, 3.0}, [](double a, double b) { return a * a - 3 * a * b + b * b * b; });
  CheckedEnclosure("exp(-x^2)*atan(y) + tanh(x*y)", {-3.0, 3.0}, {-10.0, 10.0},
                   [](double a, double b) { return std::exp(-a * a) * std::atan(b) + std::tanh(a * b); });
  CheckedEnclosure("abs(x) + min(x, y) - max(x, 2*y) + cosh(y) - sinh(x)", {-2.0, 2.0}, {-1.0, 1.0},
                   [](double a, double b) { return std::abs(a) + std::min(a, b) - std::max(a, 2 * b) + std::cosh(b) - std::sinh(a); });
  const Interval sq = CheckedEnclosure("x^2", {-2.0, 1.0}, {}, [](double a, double) { return a * a; });
  EXPECT_EQ(sq.lo, 0.0);
  EXPECT_NEAR(sq.hi, 4.0, 1e-14);
}

TEST(Interval, WhatCannotBeBoundedIsEverything) {
  Graph g;
  const Node x = g.variable(0);
  const Node y = g.variable(1);
  const std::vector<Interval> e = enclose(g, {g.binary(Op::kMul, x, y), g.unary(Op::kExp, x), g.binary(Op::kDiv, g.constant(1.0), x)},
                                          {Interval::everything(), {0.0, 1.0}});
  EXPECT_FALSE(e[0].bounded());  // x * y with x unbounded
  EXPECT_FALSE(e[1].bounded());  // exp of an unbounded input
  EXPECT_FALSE(e[2].bounded());  // 1 / x with 0 in range
  // A slot beyond those given is unbounded.
  EXPECT_FALSE(enclose(g, {g.variable(5)}, {})[0].bounded());
}

}  // namespace
}  // namespace moreau::expr
