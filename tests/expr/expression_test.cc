#include "moreau/expr/expression.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <tuple>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace moreau::expr {
namespace {

// A graph with the variables x, y, z (slots 0, 1, 2) and a few named constants, as the scene compiler
// resolves coordinates and parameters.
class ExprTest : public ::testing::Test {
 public:
  ExprTest() {
    resolve_ = [this](std::string_view name) -> std::optional<Node> {
      if (name == "x") return g_.variable(0);
      if (name == "y") return g_.variable(1);
      if (name == "z") return g_.variable(2);
      if (auto it = params_.find(std::string(name)); it != params_.end()) return g_.constant(it->second);
      return std::nullopt;
    };
  }

  Node parse(std::string_view text) { return g_.parse(text, resolve_); }

  // Value of `n` at (x, y, z), through a compiled tape.
  double eval(Node n, double x = 0.0, double y = 0.0, double z = 0.0) const {
    Tape tape = Tape::compile(g_, {n}, 3);
    std::vector<double> scratch(tape.scratch_size());
    const double slots[3] = {x, y, z};
    double out = 0.0;
    tape.eval(slots, &out, scratch.data());
    return out;
  }
  double eval(std::string_view text, double x = 0.0, double y = 0.0, double z = 0.0) { return eval(parse(text), x, y, z); }

  // Throws and returns the error, so the test can look at message and position.
  ExpressionError parse_error(std::string_view text) {
    try {
      parse(text);
    } catch (const ExpressionError& e) {
      return e;
    }
    ADD_FAILURE() << "no error for '" << text << "'";
    return ExpressionError("", 0);
  }

  // Central finite difference of `n` in variable `slot`: the reference for the symbolic derivative.
  double finite_difference(Node n, int slot, std::array<double, 3> p) const {
    const auto k = static_cast<std::size_t>(slot);
    const double h = 1e-6 * std::max(1.0, std::fabs(p[k]));
    std::array<double, 3> lo = p, hi = p;
    lo[k] -= h;
    hi[k] += h;
    return (eval(n, hi[0], hi[1], hi[2]) - eval(n, lo[0], lo[1], lo[2])) / (2.0 * h);
  }

  Graph g_;
  std::map<std::string, double> params_{{"a", 2.0}, {"b", 0.5}, {"m2", 1.5}, {"g", 9.81}};
  Graph::Resolver resolve_;
};

// ---------------------------------------------------------------------------------------------------------
// Parsing and precedence.

TEST_F(ExprTest, PrecedenceAndAssociativity) {
  EXPECT_EQ(eval("2^3^2"), 512.0);  // right-associative
  EXPECT_EQ(eval("-2^2"), -4.0);    // ^ binds tighter than unary minus
  EXPECT_EQ(eval("1-2-3"), -4.0);   // left-associative
  EXPECT_EQ(eval("8/4/2"), 1.0);
  EXPECT_EQ(eval("2+3*4"), 14.0);
  EXPECT_EQ(eval("(2+3)*4"), 20.0);
  EXPECT_EQ(eval("2*-3"), -6.0);
  EXPECT_EQ(eval("2^-1"), 0.5);
  EXPECT_EQ(eval("--2"), 2.0);
  EXPECT_EQ(eval("+3"), 3.0);
  EXPECT_EQ(eval("-x^2", 3.0), -9.0);
  EXPECT_EQ(eval("(-x)^2", 3.0), 9.0);
  EXPECT_EQ(eval("2^x^y", 3.0, 2.0), 512.0);
  EXPECT_EQ(eval("x-y-z", 1.0, 2.0, 3.0), -4.0);
  EXPECT_EQ(eval("x/y/z", 8.0, 4.0, 2.0), 1.0);
  EXPECT_EQ(eval("x - -y", 1.0, 2.0), 3.0);
  EXPECT_EQ(eval(" \t2\n*\r( x +1 ) ", 1.0), 4.0);
  EXPECT_EQ(eval("sin (0)"), 0.0);
}

// Assumption 3.3 is concluded from the operations alone: C-infinity on all of R^k or not. Each case says why
// (a pole, a branch point, a kink, a domain edge).
TEST_F(ExprTest, SmoothEverywhereIsDecidedByTheOperations) {
  for (const char* smooth : {"sin(x)*y^2 + cos(z)", "exp(-x^2)*atan(y)", "tanh(x) - sinh(y)*cosh(z)", "x^3 - 2*x", "-x", "0.5*x*y", "3"})
    EXPECT_TRUE(g_.smooth_everywhere(parse(smooth))) << smooth;
  for (const char* not_smooth :
       {"x/y",                                                                              // pole at y = 0
        "1/(1 + x^2)",                                                                      // smooth, but a division is not analysed
        "sqrt(x)",                                                                          // not Lipschitz at 0
        "log(x)", "tan(x)", "asin(x)", "acos(x)", "atan2(x, y)", "x^0.5", "x^(-1)", "x^y",  // non-integer, negative or variable exponents
        "abs(x)", "min(x, y)", "max(x, 0)"})
    EXPECT_FALSE(g_.smooth_everywhere(parse(not_smooth))) << not_smooth;
  // Derivatives keep what they are built of: d/dx abs(x) = sign(x) is not smooth; d/dx sin(x)^2 is.
  EXPECT_FALSE(g_.smooth_everywhere(g_.derivative(parse("abs(x)"), 0)));
  EXPECT_TRUE(g_.smooth_everywhere(g_.derivative(parse("sin(x)^2"), 0)));
}

TEST_F(ExprTest, Numbers) {
  EXPECT_EQ(eval("1"), 1.0);
  EXPECT_EQ(eval("1.5"), 1.5);
  EXPECT_EQ(eval(".5"), 0.5);
  EXPECT_EQ(eval("1."), 1.0);
  EXPECT_EQ(eval("1e-3"), 1e-3);
  EXPECT_EQ(eval("2.5E+4"), 2.5e4);
  EXPECT_EQ(eval("1e2"), 100.0);
  EXPECT_EQ(eval("0.1"), 0.1);  // correctly rounded
  EXPECT_EQ(eval("1.7976931348623157e308"), 1.7976931348623157e308);
  EXPECT_EQ(eval("4.9e-324"), 4.9e-324);
  EXPECT_EQ(eval("1e-400"), 0.0);  // underflow rounds to zero, like the C++ literal
  EXPECT_EQ(eval("0.0000001e-330"), 0.0);
}

TEST_F(ExprTest, FunctionValuesMatchCmath) {
  struct Case {
    const char* text;
    double (*f)(double);
    std::vector<double> points;
  };
  const std::vector<Case> cases = {
      {"sin(x)", [](double v) { return std::sin(v); }, {-2.0, 0.0, 0.3, 7.5}},
      {"cos(x)", [](double v) { return std::cos(v); }, {-2.0, 0.0, 0.3, 7.5}},
      {"tan(x)", [](double v) { return std::tan(v); }, {-1.0, 0.0, 0.3, 1.4}},
      {"asin(x)", [](double v) { return std::asin(v); }, {-0.9, 0.0, 0.3, 1.0}},
      {"acos(x)", [](double v) { return std::acos(v); }, {-0.9, 0.0, 0.3, 1.0}},
      {"atan(x)", [](double v) { return std::atan(v); }, {-5.0, 0.0, 0.3, 100.0}},
      {"sinh(x)", [](double v) { return std::sinh(v); }, {-2.0, 0.0, 0.3, 5.0}},
      {"cosh(x)", [](double v) { return std::cosh(v); }, {-2.0, 0.0, 0.3, 5.0}},
      {"tanh(x)", [](double v) { return std::tanh(v); }, {-2.0, 0.0, 0.3, 5.0}},
      {"exp(x)", [](double v) { return std::exp(v); }, {-2.0, 0.0, 0.3, 5.0}},
      {"log(x)", [](double v) { return std::log(v); }, {1e-3, 0.3, 1.0, 50.0}},
      {"sqrt(x)", [](double v) { return std::sqrt(v); }, {0.0, 0.3, 2.0, 50.0}},
      {"abs(x)", [](double v) { return std::fabs(v); }, {-2.0, 0.0, 0.3}},
  };
  for (const Case& c : cases) {
    const Node n = parse(c.text);
    for (double p : c.points) {
      EXPECT_EQ(eval(n, p), c.f(p)) << c.text << " at " << p;
    }
  }
  for (double p : {-1.5, 0.0, 0.25, 3.0}) {
    for (double q : {-2.0, 0.0, 0.5}) {
      EXPECT_EQ(eval("atan2(x, y)", p, q), std::atan2(p, q));
      EXPECT_EQ(eval("min(x, y)", p, q), std::min(p, q));
      EXPECT_EQ(eval("max(x, y)", p, q), std::max(p, q));
    }
  }
  for (double p : {0.5, 1.0, 2.5}) {
    for (double q : {-1.5, 0.0, 0.5, 3.0, 7.0}) {
      EXPECT_EQ(eval("pow(x, y)", p, q), std::pow(p, q));
      EXPECT_EQ(eval("x^y", p, q), std::pow(p, q));
    }
  }
  EXPECT_TRUE(std::isnan(eval("sqrt(x)", -1.0)));
  EXPECT_TRUE(std::isinf(eval("1/x", 0.0)));
}

TEST_F(ExprTest, ConstantFoldingUsesTheSameFunctions) {
  // A folded constant has exactly the value the tape computes for the same operation at run time.
  const char* functions[] = {"sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "abs"};
  for (const char* f : functions) {
    const Node folded = parse(std::string(f) + "(0.37)");
    ASSERT_TRUE(g_.is_constant(folded)) << f;
    EXPECT_EQ(g_.constant_value(folded), eval(std::string(f) + "(x)", 0.37)) << f;
  }
  EXPECT_EQ(g_.constant_value(parse("atan2(0.3, -0.7)")), std::atan2(0.3, -0.7));
  EXPECT_EQ(g_.constant_value(parse("1.3^0.7")), std::pow(1.3, 0.7));
  EXPECT_EQ(g_.constant_value(parse("min(2, -1)")), -1.0);
  EXPECT_EQ(g_.constant_value(parse("max(2, -1)")), 2.0);
}

// ---------------------------------------------------------------------------------------------------------
// Simplification and hash-consing.

TEST_F(ExprTest, ConstantFolding) {
  const Node n = parse("2*3+1");
  ASSERT_TRUE(g_.is_constant(n));
  EXPECT_EQ(g_.constant_value(n), 7.0);
  EXPECT_EQ(g_.constant_value(parse("a*b + g")), 2.0 * 0.5 + 9.81);
  EXPECT_FALSE(g_.is_constant(parse("x")));
  EXPECT_FALSE(g_.is_constant(parse("x + 1")));
  EXPECT_THROW(g_.constant_value(parse("x")), std::logic_error);
}

TEST_F(ExprTest, Identities) {
  const Node x = parse("x");
  EXPECT_EQ(parse("x + 0"), x);
  EXPECT_EQ(parse("0 + x"), x);
  EXPECT_EQ(parse("x - 0"), x);
  EXPECT_EQ(parse("0 - x"), parse("-x"));
  EXPECT_EQ(parse("x * 1"), x);
  EXPECT_EQ(parse("1 * x"), x);
  EXPECT_EQ(parse("x / 1"), x);
  EXPECT_EQ(parse("--x"), x);
  EXPECT_EQ(parse("x^1"), x);
  EXPECT_EQ(parse("pow(x, 1)"), x);
  for (const char* zero : {"x * 0", "0 * x", "0 / x", "x - x", "sin(x) - sin(x)", "x*y - y*x"}) {
    const Node n = parse(zero);
    ASSERT_TRUE(g_.is_constant(n)) << zero;
    EXPECT_EQ(g_.constant_value(n), 0.0) << zero;
  }
  for (const char* one : {"x^0", "pow(x, 0)", "1^x"}) {
    const Node n = parse(one);
    ASSERT_TRUE(g_.is_constant(n)) << one;
    EXPECT_EQ(g_.constant_value(n), 1.0) << one;
  }
  EXPECT_EQ(g_.entry(parse("x^2")).op, Op::kSquare);
  EXPECT_EQ(parse("pow(x, 2)"), parse("x^2"));
  EXPECT_EQ(g_.entry(parse("x^3")).op, Op::kPow);
  EXPECT_EQ(g_.entry(parse("x^2")).a, x);
}

TEST_F(ExprTest, HashConsing) {
  const Node sum = parse("sin(x)+sin(x)");
  EXPECT_EQ(g_.size(), 3u);  // x, sin(x), and the sum
  EXPECT_EQ(g_.entry(sum).a, g_.entry(sum).b);
  const std::size_t before = g_.size();
  EXPECT_EQ(parse("sin(x) + sin(x)"), sum);
  EXPECT_EQ(g_.size(), before);
  EXPECT_EQ(parse("x*y"), parse("y*x"));  // commutative operands are ordered
  EXPECT_EQ(parse("x+y"), parse("y+x"));
  EXPECT_NE(parse("x-y"), parse("y-x"));
  EXPECT_NE(parse("x/y"), parse("y/x"));
  EXPECT_EQ(g_.constant(1.5), g_.constant(1.5));
  EXPECT_NE(g_.constant(0.0), g_.constant(-0.0));  // distinct bits, distinct behaviour under 1/x
  EXPECT_EQ(g_.variable(7), g_.variable(7));
}

TEST_F(ExprTest, CopiedGraphsHaveIndependentIndices) {
  const Node sx = parse("sin(x)");
  Graph copy = g_;
  // New nodes in each graph get the same index but mean different things; neither may see the other's.
  const Node in_original = g_.unary(Op::kCos, sx);
  const Node in_copy = copy.unary(Op::kExp, sx);
  EXPECT_EQ(in_original, in_copy);
  EXPECT_EQ(g_.entry(in_original).op, Op::kCos);
  EXPECT_EQ(copy.entry(in_copy).op, Op::kExp);
  EXPECT_EQ(g_.unary(Op::kExp, sx), in_copy + 1);
  EXPECT_EQ(copy.unary(Op::kCos, sx), in_copy + 1);
  EXPECT_EQ(copy.unary(Op::kSin, copy.variable(0)), sx);  // existing nodes are still shared in the copy

  Graph assigned;
  assigned = copy;
  EXPECT_EQ(assigned.unary(Op::kExp, sx), in_copy);
  EXPECT_EQ(assigned.size(), copy.size());

  Graph moved = std::move(assigned);
  EXPECT_EQ(moved.unary(Op::kExp, sx), in_copy);
  EXPECT_EQ(moved.size(), copy.size());
}

TEST_F(ExprTest, ToString) {
  EXPECT_EQ(g_.to_string(parse("x + 2*y")), "(x0+(2*x1))");
  EXPECT_EQ(g_.to_string(parse("sin(x)^2 - atan2(y, 1.5)")), "((sin(x0)^2)-atan2(x1, 1.5))");
  EXPECT_EQ(g_.to_string(parse("-x / 3")), "((-x0)/3)");
  EXPECT_EQ(g_.to_string(parse("x^y^z")), "(x0^(x1^x2))");
  EXPECT_EQ(g_.to_string(parse("-2.5")), "(-2.5)");
  EXPECT_EQ(g_.to_string(parse("0.1")), "0.1");
  const Node n = parse("min(x, y) * abs(z)");
  EXPECT_EQ(g_.to_string(n, [](int slot) { return std::string(1, "xyz"[slot]); }), "(min(x, y)*abs(z))");
  EXPECT_EQ(g_.to_string(g_.derivative(parse("min(x, y)"), 0)), "(x0 <= x1 ? 1 : 0)");
  EXPECT_EQ(g_.to_string(g_.derivative(parse("abs(x)"), 0)), "sign(x0)");
}

// ---------------------------------------------------------------------------------------------------------
// Derivatives.

TEST_F(ExprTest, EveryDerivativeRuleMatchesFiniteDifferences) {
  struct Case {
    const char* text;
    std::vector<std::array<double, 3>> points;
  };
  const std::vector<std::array<double, 3>> general = {{0.3, 0.7, -0.4}, {-1.1, 0.2, 0.9}, {2.0, -1.3, 0.5}};
  const std::vector<std::array<double, 3>> positive = {{0.3, 0.7, 0.4}, {1.1, 0.2, 0.9}, {2.0, 1.3, 0.5}};
  const std::vector<std::array<double, 3>> unit = {{0.3, 0.7, -0.4}, {-0.8, 0.2, 0.9}, {0.55, -0.6, 0.5}};
  const std::vector<Case> cases = {
      {"x + y", general},
      {"x - y", general},
      {"x * y", general},
      {"x / y", general},
      {"y / x", general},
      {"-x", general},
      {"x^2", general},
      {"x^3", general},
      {"x^-2", general},
      {"x^2.5", positive},
      {"x^y", positive},
      {"y^x", positive},
      {"x^x", positive},
      {"pow(x, a*b)", positive},
      {"a^x", general},
      {"x^(y*z)", positive},
      {"sin(x)", general},
      {"cos(x)", general},
      {"tan(x)", general},
      {"asin(x)", unit},
      {"acos(x)", unit},
      {"atan(x)", general},
      {"atan2(x, y)", general},
      {"atan2(y, x)", general},
      {"atan2(x*y, x+2)", general},
      {"sinh(x)", general},
      {"cosh(x)", general},
      {"tanh(x)", general},
      {"exp(x)", general},
      {"log(x)", positive},
      {"sqrt(x)", positive},
      {"abs(x)", general},
      {"abs(x*y)", general},
      {"min(x, y)", general},
      {"max(x, y)", general},
      {"min(y, x)", general},
      {"max(x*x, y)", general},
      {"min(x, 2*x)", positive},
      {"sin(x*y)^2 / (1 + exp(-x))", general},
      {"sqrt(x^2 + y^2 + z^2)", general},
      {"log(cosh(x*y)) * atan(z - x)", general},
      {"tan(x)*tan(x) + tan(x)", general},
      {"sin(cos(sin(x*y)))", general},
      {"exp(sin(x))^cos(y)", general},
      {"a*x^2 + b*x + g", general},
  };
  for (const Case& c : cases) {
    const Node f = parse(c.text);
    for (int slot = 0; slot < 3; ++slot) {
      const Node df = g_.derivative(f, slot);
      if (!g_.depends_on(f, slot)) {
        EXPECT_TRUE(g_.is_constant(df)) << c.text;
      }
      for (const auto& p : c.points) {
        const double exact = eval(df, p[0], p[1], p[2]);
        const double fd = finite_difference(f, slot, p);
        EXPECT_NEAR(exact, fd, 1e-6 * std::max(1.0, std::fabs(fd)))
            << "d/d"
            << "xyz"[slot] << " " << c.text << " at (" << p[0] << ", " << p[1] << ", " << p[2] << ")";
      }
    }
  }
}

TEST_F(ExprTest, SecondDerivatives) {
  const Node f = parse("sin(x)*exp(y) + x^3*y");
  const Node fx = g_.derivative(f, 0);
  const Node fxy = g_.derivative(fx, 1);
  const Node fyx = g_.derivative(g_.derivative(f, 1), 0);
  for (const auto& p : std::vector<std::array<double, 3>>{{0.3, 0.7, 0.0}, {-1.2, 0.4, 0.0}}) {
    const double expected = std::cos(p[0]) * std::exp(p[1]) + 3.0 * p[0] * p[0];
    EXPECT_NEAR(eval(fxy, p[0], p[1]), expected, 1e-12);
    EXPECT_NEAR(eval(fyx, p[0], p[1]), expected, 1e-12);
  }
  // d^2/dx^2 sin(x) is literally -sin(x).
  EXPECT_EQ(g_.derivative(g_.derivative(parse("sin(x)"), 0), 0), parse("-sin(x)"));
}

TEST_F(ExprTest, DerivativeOfExpressionNotInTheVariableIsConstantZero) {
  for (const char* text : {"sin(x)*x", "exp(x^2)/(1+x)", "atan2(x, 2)", "min(x, 3)", "a*b", "7"}) {
    const Node d = g_.derivative(parse(text), 1);
    ASSERT_TRUE(g_.is_constant(d)) << text;
    EXPECT_EQ(g_.constant_value(d), 0.0) << text;
  }
  // A constant mass matrix entry has constant zero derivatives in every coordinate.
  const Node m = parse("m2 + a*b^2");
  for (int slot = 0; slot < 3; ++slot) {
    EXPECT_TRUE(g_.is_constant(g_.derivative(m, slot)));
  }
  // An expression that only seems to depend on x.
  const Node d = g_.derivative(parse("x*y - y*x + z"), 0);
  ASSERT_TRUE(g_.is_constant(d));
  EXPECT_EQ(g_.constant_value(d), 0.0);
}

TEST_F(ExprTest, SimpleDerivativesAreSimplified) {
  const Node x = parse("x");
  const Node dx = g_.derivative(x, 0);
  ASSERT_TRUE(g_.is_constant(dx));
  EXPECT_EQ(g_.constant_value(dx), 1.0);
  EXPECT_EQ(g_.derivative(parse("sin(x)"), 0), parse("cos(x)"));
  EXPECT_EQ(g_.derivative(parse("cos(x)"), 0), parse("-sin(x)"));
  EXPECT_EQ(g_.derivative(parse("exp(x)"), 0), parse("exp(x)"));
  EXPECT_EQ(g_.derivative(parse("x^2"), 0), parse("2*x"));
  EXPECT_EQ(g_.derivative(parse("x^3"), 0), parse("3*x^2"));
  EXPECT_EQ(g_.derivative(parse("x*y"), 0), parse("y"));
  EXPECT_EQ(g_.derivative(parse("log(x)"), 0), parse("1/x"));
  EXPECT_EQ(g_.derivative(parse("a*x + b"), 0), parse("a"));
}

TEST_F(ExprTest, PiecewiseDerivativesAtKinks) {
  // abs'(0) = sign(0) = 0.
  EXPECT_EQ(eval(g_.derivative(parse("abs(x)"), 0), 0.0), 0.0);
  EXPECT_EQ(eval(g_.derivative(parse("abs(x)"), 0), -2.0), -1.0);
  // Ties: the derivative of the first argument.
  EXPECT_EQ(eval(g_.derivative(parse("min(x, y)"), 0), 1.0, 1.0), 1.0);
  EXPECT_EQ(eval(g_.derivative(parse("min(x, y)"), 1), 1.0, 1.0), 0.0);
  EXPECT_EQ(eval(g_.derivative(parse("max(x, y)"), 0), 1.0, 1.0), 1.0);
  EXPECT_EQ(eval(g_.derivative(parse("max(x, y)"), 1), 1.0, 1.0), 0.0);
  EXPECT_EQ(eval(g_.derivative(parse("min(2*x, y)"), 0), 1.0, 2.0), 2.0);
  EXPECT_EQ(eval(g_.derivative(parse("max(2*x, y)"), 1), 1.0, 3.0), 1.0);
  // Second derivative through the select.
  const Node d2 = g_.derivative(g_.derivative(parse("min(x^2, y)"), 0), 0);
  EXPECT_EQ(eval(d2, 1.0, 5.0), 2.0);
  EXPECT_EQ(eval(d2, 3.0, 5.0), 0.0);
  EXPECT_EQ(eval(g_.derivative(g_.derivative(parse("abs(x)"), 0), 0), 0.5), 0.0);
}

TEST_F(ExprTest, RobotManipulatorMassMatrix) {
  // Two-link arm: M12 = m2*b*cos(th2) with m2 and b parameters that resolve to constants.
  Graph g;
  const std::map<std::string, double> params{{"m1", 2.0}, {"m2", 1.5}, {"a", 0.8}, {"b", 0.6}, {"I1", 0.1}};
  Graph::Resolver resolve = [&](std::string_view name) -> std::optional<Node> {
    if (name == "th1") return g.variable(0);
    if (name == "th2") return g.variable(1);
    if (auto it = params.find(std::string(name)); it != params.end()) return g.constant(it->second);
    return std::nullopt;
  };
  const Node m12 = g.parse("m2*b*cos(th2)", resolve);
  const Node dm12 = g.derivative(m12, 1);
  EXPECT_EQ(dm12, g.parse("-m2*b*sin(th2)", resolve));
  ASSERT_TRUE(g.is_constant(g.derivative(m12, 0)));
  EXPECT_EQ(g.constant_value(g.derivative(m12, 0)), 0.0);

  const Node m11 = g.parse("I1 + m1*a^2/4 + m2*(a^2 + b^2 + 2*a*b*cos(th2))", resolve);
  const Node m22 = g.parse("m2*b^2", resolve);
  EXPECT_TRUE(g.is_constant(g.derivative(m22, 1)));
  std::vector<Node> outputs{m11, m12, m22};
  for (Node m : {m11, m12, m22}) {
    for (int k = 0; k < 2; ++k) outputs.push_back(g.derivative(m, k));
  }
  const Tape tape = Tape::compile(g, outputs, 2);
  std::vector<double> scratch(tape.scratch_size());
  std::vector<double> out(tape.num_outputs());
  const double q[2] = {0.4, -1.1};
  tape.eval(q, out.data(), scratch.data());
  const double c2 = std::cos(q[1]), s2 = std::sin(q[1]);
  EXPECT_NEAR(out[0], 0.1 + 2.0 * 0.64 / 4 + 1.5 * (0.64 + 0.36 + 2 * 0.8 * 0.6 * c2), 1e-14);
  EXPECT_NEAR(out[1], 1.5 * 0.6 * c2, 1e-15);
  EXPECT_NEAR(out[2], 1.5 * 0.36, 1e-15);
  EXPECT_EQ(out[3], 0.0);
  EXPECT_NEAR(out[4], -1.5 * 2 * 0.8 * 0.6 * s2, 1e-14);
  EXPECT_EQ(out[5], 0.0);
  EXPECT_NEAR(out[6], -1.5 * 0.6 * s2, 1e-15);
  EXPECT_EQ(out[7], 0.0);
  EXPECT_EQ(out[8], 0.0);
}

// ---------------------------------------------------------------------------------------------------------
// Errors and limits.

// Parameters bound into a tape (Tape::bind) against the reference: the same expressions with the
// parameters folded in as constants, compiled afresh. Values and first derivatives in x must agree to the
// bit at every point, for parameter values that trigger the builders' rewrites (1, -1, 2) and others.
// The expressions of x, y (inputs 0 and 1) and the parameters a, b twice: in `folded` with a and b as
// constants, in `free` as the parameters 0 and 1 (slots 2 and 3 of a tape with 2 inputs).
struct FoldedAndFree {
  explicit FoldedAndFree(const std::array<double, 2>& ab)
      : fold([this, ab](std::string_view name) -> std::optional<Node> {
          if (name == "x") return folded.variable(0);
          if (name == "y") return folded.variable(1);
          if (name == "a") return folded.constant(ab[0]);
          if (name == "b") return folded.constant(ab[1]);
          return std::nullopt;
        }),
        keep([this](std::string_view name) -> std::optional<Node> {
          if (name == "x") return free.variable(0);
          if (name == "y") return free.variable(1);
          if (name == "a") return free.variable(2);
          if (name == "b") return free.variable(3);
          return std::nullopt;
        }) {}
  FoldedAndFree(const FoldedAndFree&) = delete;
  FoldedAndFree& operator=(const FoldedAndFree&) = delete;
  Graph folded, free;
  Graph::Resolver fold, keep;
};

TEST(TapeBind, BoundParametersComputeWhatFoldedConstantsCompute) {
  const std::vector<std::string> texts = {"a + b",
                                          "a*b*cos(x)",
                                          "-a*b*sin(x)*y",
                                          "a*x^2 + b*y",
                                          "(a + b)*x / (b - 3)",
                                          "x^a",
                                          "a^2*sin(x)^2",
                                          "exp(-a*x)*cos(b*y)",
                                          "sqrt(a*a + x*x)",
                                          "atan2(a*y, b + x)",
                                          "min(a*x, b) - max(y, a)",
                                          "abs(a - x)*b",
                                          "a - a + b*x",
                                          "sin(a)*cos(a)*x",
                                          "-(a*(-x))",
                                          "2*a*b*cos(x)*y - 0.5*b^2*sin(y)"};
  const std::vector<std::array<double, 2>> bindings = {{1.0, 0.5}, {-1.0, 2.0}, {2.0, -1.0}, {0.3, 1e-3}, {-7.25, 3.0}, {1e5, -2.5e-4}};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (const auto& ab : bindings) {
    // The reference: a and b folded in; bound: a and b parameters.
    FoldedAndFree g(ab);
    Graph &folded = g.folded, &free = g.free;
    const Graph::Resolver &fold = g.fold, &keep = g.keep;
    std::vector<Node> out_folded, out_free;
    for (const auto& t : texts) {
      const Node f = folded.parse(t, fold), k = free.parse(t, keep);
      out_folded.insert(out_folded.end(), {f, folded.derivative(f, 0), folded.derivative(f, 1)});
      out_free.insert(out_free.end(), {k, free.derivative(k, 0), free.derivative(k, 1)});
    }
    const Tape reference = Tape::compile(folded, out_folded, 2);
    Tape bound = Tape::compile(free, out_free, 2, 2);
    EXPECT_EQ(bound.num_params(), 2);
    // bind() says where a node of the parameters alone is 0 (a - 1 in the derivative of x^a at a = 1,
    // b - 3 at b = 3): there the graph may fold differently; these expressions still agree (x^0 and
    // pow(x, 0) are both 1, and x / 0 is not folded).
    EXPECT_EQ(bound.bind(ab.data()), ab[0] != 1.0 && ab[1] != 3.0) << "a = " << ab[0] << ", b = " << ab[1];
    // eval() does the folded tape's work: each expression with its derivatives takes no more instructions,
    // where no value makes the graph rewrite (0, 1, -1 and 2 do: 1*x = x, x^2 = x*x; a bound tape keeps the
    // multiplication, with the same bits). Across expressions the folded graph also shares nodes that are
    // equal by value only ((-a)*b and -(a*b) fold to one constant), which a bound tape computes apart.
    const auto rewrites = [](double v) { return v == 0.0 || v == 1.0 || v == -1.0 || v == 2.0; };
    if (!rewrites(ab[0]) && !rewrites(ab[1]) && !rewrites(ab[1] - 3.0)) {
      for (std::size_t t = 0; t < texts.size(); ++t) {
        const std::vector<Node> f(out_folded.begin() + 3 * t, out_folded.begin() + 3 * t + 3),
            k(out_free.begin() + 3 * t, out_free.begin() + 3 * t + 3);
        EXPECT_LE(Tape::compile(free, k, 2, 2).num_instructions(), Tape::compile(folded, f, 2).num_instructions())
            << texts[t] << " with a = " << ab[0] << ", b = " << ab[1];
      }
    }
    std::vector<double> want(out_folded.size()), got(out_free.size()), s1(reference.scratch_size()), s2(bound.scratch_size());
    for (int p = 0; p < 50; ++p) {
      const double slots[2] = {u(rng), u(rng)};
      reference.eval(slots, want.data(), s1.data());
      bound.eval(slots, got.data(), s2.data());
      for (std::size_t j = 0; j < want.size(); ++j) {
        SCOPED_TRACE(texts[j / 3] + (j % 3 ? " d/d" + std::string(j % 3 == 1 ? "x" : "y") : std::string()) +
                     " with a = " + std::to_string(ab[0]) + ", b = " + std::to_string(ab[1]));
        if (std::isnan(want[j])) {
          EXPECT_TRUE(std::isnan(got[j]));
        } else {
          EXPECT_EQ(std::bit_cast<std::uint64_t>(got[j]), std::bit_cast<std::uint64_t>(want[j])) << got[j] << " vs " << want[j];
        }
      }
    }
  }
  // Unbound parameters are NaN, not stale values.
  Graph g;
  const Node n = g.binary(Op::kMul, g.variable(0), g.variable(1));
  Tape t = Tape::compile(g, {n}, 1, 1);
  const double x = 2.0;
  double out = 0.0;
  std::vector<double> scratch(t.scratch_size());
  t.eval(&x, &out, scratch.data());
  EXPECT_TRUE(std::isnan(out));
  const double p = 3.0;
  EXPECT_TRUE(t.bind(&p));
  t.eval(&x, &out, scratch.data());
  EXPECT_EQ(out, 6.0);
}

// The same against random expressions in one tape with their first and second derivatives, so that the
// compiler's rewrites for bound factors and its sharing of nodes that became equal meet deep graphs,
// signs on every side and subexpressions common to many outputs. Reference: the expressions with the
// parameters folded in, compiled afresh; bit for bit at 20 points, for three bindings.
TEST(TapeBind, RandomExpressionsWithSecondDerivativesComputeWhatFoldedConstantsCompute) {
  std::mt19937_64 rng(2026);
  std::function<std::string(int)> random_text = [&](int depth) -> std::string {
    static const char* leaves[] = {"x", "y", "a", "b", "2", "0.5", "-a", "-x"};
    if (depth == 0 || rng() % 4 == 0) return leaves[rng() % 8];
    const std::string l = random_text(depth - 1), r = random_text(depth - 1);
    switch (rng() % 9) {
      case 0: return "(" + l + " + " + r + ")";
      case 1: return "(" + l + " - " + r + ")";
      case 2:
      case 3: return "(" + l + "*" + r + ")";
      case 4: return "-(" + l + ")";
      case 5: return "sin(" + l + ")";
      case 6: return "cos(" + l + ")";
      case 7: return "(" + l + ")^2";
      default: return "(" + l + "*(-" + r + "))";
    }
  };
  std::vector<std::string> texts;
  for (int i = 0; i < 120; ++i) texts.push_back(random_text(5));
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (const std::array<double, 2> ab : {std::array<double, 2>{0.3, -1.7}, {-2.5, 0.125}, {1.0, -1.0}}) {
    FoldedAndFree g(ab);
    Graph &folded = g.folded, &free = g.free;
    const Graph::Resolver &fold = g.fold, &keep = g.keep;
    std::vector<Node> out_folded, out_free;
    for (const auto& t : texts) {
      for (auto [g, resolve, out] : {std::tuple{&folded, &fold, &out_folded}, std::tuple{&free, &keep, &out_free}}) {
        const Node f = g->parse(t, *resolve), fx = g->derivative(f, 0), fy = g->derivative(f, 1);
        out->insert(out->end(), {f, fx, fy, g->derivative(fx, 0), g->derivative(fx, 1), g->derivative(fy, 1)});
      }
    }
    const Tape reference = Tape::compile(folded, out_folded, 2);
    Tape bound = Tape::compile(free, out_free, 2, 2);
    // At a = 1, b = -1 the node -a - b is 0: the folded graph turns 0 * u into the constant 0 where the
    // bound tape computes -0. bind() says so, and callers compile such values in full.
    if (!bound.bind(ab.data())) {
      EXPECT_EQ(ab, (std::array<double, 2>{1.0, -1.0}));
      continue;
    }
    std::vector<double> want(out_folded.size()), got(out_free.size()), s1(reference.scratch_size()), s2(bound.scratch_size());
    int compared = 0;
    for (int p = 0; p < 20; ++p) {
      const double slots[2] = {u(rng), u(rng)};
      reference.eval(slots, want.data(), s1.data());
      bound.eval(slots, got.data(), s2.data());
      for (std::size_t j = 0; j < want.size(); ++j) {
        if (std::isnan(want[j])) {
          EXPECT_TRUE(std::isnan(got[j])) << texts[j / 6] << " output " << j % 6;
          continue;
        }
        ++compared;
        EXPECT_EQ(std::bit_cast<std::uint64_t>(got[j]), std::bit_cast<std::uint64_t>(want[j]))
            << texts[j / 6] << " output " << j % 6 << " with a = " << ab[0] << ", b = " << ab[1] << ": " << got[j] << " vs " << want[j];
      }
    }
    EXPECT_GT(compared, 10000);
  }
}

TEST_F(ExprTest, ErrorMessagesAndPositions) {
  struct Case {
    std::string text;
    std::string message;
    std::size_t position;
  };
  const std::vector<Case> cases = {
      {"(1+2", "expected ')'", 4},
      {"sin(x", "expected ')'", 5},
      {"(1 2)", "expected ')'", 3},
      {"1 # 2", "unexpected character '#'", 2},
      {"x + $", "unexpected character '$'", 4},
      {"(x]", "unexpected character ']'", 2},
      {"sinn(x)", "unknown function 'sinn'", 0},
      {"2 * foo(1)", "unknown function 'foo'", 4},
      {"atan2(x)", "atan2 takes 2 arguments, got 1", 0},
      {"1 + pow(x)", "pow takes 2 arguments, got 1", 4},
      {"sin(x, y)", "sin takes 1 argument, got 2", 0},
      {"min(x, y, z)", "min takes 2 arguments, got 3", 0},
      {"exp()", "exp takes 1 argument, got 0", 0},
      {"", "empty expression", 0},
      {" \t\n", "empty expression", 0},
      {"1 2", "trailing input after expression", 2},
      {"x)", "trailing input after expression", 1},
      {"2x", "trailing input after expression", 1},
      {"x + foo", "unknown name 'foo'", 4},
      {"1+", "unexpected end of expression", 2},
      {"1+*2", "expected a number, a name or '(' but found '*'", 2},
      {"()", "expected a number, a name or '(' but found ')'", 1},
      {"1e400", "number out of range '1e400'", 0},
      {"x + 123456789e305", "number out of range '123456789e305'", 4},
      {"1e", "malformed number: expected digits in the exponent", 2},
      {"1e+", "malformed number: expected digits in the exponent", 3},
      {".", "malformed number: expected a digit", 0},
      {"x\xff", "unexpected byte 0xFF", 1},
      {"\xc3\xa9", "unexpected byte 0xC3", 0},
      {std::string("x\0y", 3), "unexpected byte 0x00", 1},
      {"x + \x01", "unexpected byte 0x01", 4},
  };
  for (const Case& c : cases) {
    const ExpressionError e = parse_error(c.text);
    EXPECT_EQ(std::string(e.what()), c.message) << "'" << c.text << "'";
    EXPECT_EQ(e.position(), c.position) << "'" << c.text << "'";
  }
}

TEST_F(ExprTest, NestingLimit) {
  auto nested = [](int depth) { return std::string(depth, '(') + "x" + std::string(depth, ')'); };
  EXPECT_EQ(parse(nested(kMaxDepth)), parse("x"));
  const ExpressionError e = parse_error(nested(kMaxDepth + 1));
  EXPECT_EQ(std::string(e.what()), "nesting deeper than 128");
  EXPECT_EQ(e.position(), static_cast<std::size_t>(kMaxDepth));
  // Every kind of recursion counts: unary signs, exponents and function calls.
  EXPECT_EQ(std::string(parse_error(std::string(200, '-') + "x").what()), "nesting deeper than 128");
  std::string tower = "2";
  for (int i = 0; i < 200; ++i) tower += "^2";
  EXPECT_EQ(std::string(parse_error(tower).what()), "nesting deeper than 128");
  std::string calls;
  for (int i = 0; i < 200; ++i) calls += "sin(";
  EXPECT_EQ(std::string(parse_error(calls + "x" + std::string(200, ')')).what()), "nesting deeper than 128");
  // Unbalanced and very deep input: rejected quickly, without deep recursion.
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(std::string(parse_error(std::string(10000, '(')).what()), "nesting deeper than 128");
  EXPECT_EQ(std::string(parse_error(nested(100000)).what()), "expression longer than 16384 characters");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

TEST_F(ExprTest, LengthLimit) {
  // "1+1+...+1" of exactly kMaxTextLength characters (the left-deep sum needs no recursion at all).
  std::string text = "1";
  while (text.size() + 2 <= kMaxTextLength) text += "+1";
  text += std::string(kMaxTextLength - text.size(), ' ');
  ASSERT_EQ(text.size(), kMaxTextLength);
  EXPECT_EQ(g_.constant_value(parse(text)), static_cast<double>(kMaxTextLength / 2));
  const ExpressionError e = parse_error(text + " ");
  EXPECT_EQ(std::string(e.what()), "expression longer than 16384 characters");
  EXPECT_EQ(e.position(), kMaxTextLength);
}

TEST_F(ExprTest, NodeLimit) {
  Graph g;
  for (std::size_t i = 0; i < kMaxNodes; ++i) g.constant(static_cast<double>(i));
  EXPECT_EQ(g.size(), kMaxNodes);
  g.constant(5.0);  // existing nodes can still be found
  try {
    g.constant(-1.0);
    FAIL() << "no error past kMaxNodes";
  } catch (const ExpressionError& e) {
    EXPECT_EQ(e.position(), 0u);
    EXPECT_EQ(std::string(e.what()), "expression graph larger than 1000000 nodes");
  }
}

TEST_F(ExprTest, BadArgumentsToTheBuilders) {
  EXPECT_THROW(g_.variable(-1), std::invalid_argument);
  EXPECT_THROW(g_.unary(Op::kSin, 12345), std::out_of_range);
  EXPECT_THROW(g_.unary(Op::kAdd, parse("x")), std::invalid_argument);
  EXPECT_THROW(g_.binary(Op::kSin, parse("x"), parse("y")), std::invalid_argument);
  EXPECT_THROW(Tape::compile(g_, {parse("z")}, 2), std::invalid_argument);
  Graph::Resolver bad = [](std::string_view) -> std::optional<Node> { return Node{999}; };
  EXPECT_THROW(g_.parse("q", bad), ExpressionError);
  EXPECT_THROW(g_.parse("q", Graph::Resolver{}), ExpressionError);
}

TEST_F(ExprTest, RandomInputNeverCrashes) {
  // Random token soup and random bytes: every input either parses (and then evaluates and differentiates)
  // or throws ExpressionError.
  const std::vector<std::string> tokens = {"x", "y",    "1",      ".5",   "2e3",  "(",    ")", "+", "-", "*",    "/", "^",
                                           ",", "sin(", "atan2(", "min(", "pow(", "abs(", " ", "a", "#", "\xfe", "e"};
  std::mt19937 rng(12345);
  int parsed = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string text;
    const int n = std::uniform_int_distribution<int>(0, 30)(rng);
    for (int k = 0; k < n; ++k) {
      if (i % 4 == 0) {
        text += static_cast<char>(std::uniform_int_distribution<int>(0, 255)(rng));
      } else {
        text += tokens[std::uniform_int_distribution<std::size_t>(0, tokens.size() - 1)(rng)];
      }
    }
    try {
      const Node f = parse(text);
      const Node df = g_.derivative(f, 0);
      (void)eval(f, 0.3, 0.6);
      (void)eval(df, 0.3, 0.6);
      (void)g_.to_string(df);
      ++parsed;
    } catch (const ExpressionError&) {
    }
  }
  EXPECT_GT(parsed, 100);
}

TEST(ExprDeepGraph, TraversalsAreIterative) {
  // A chain far deeper than the parser allows, built with the builders: derivative, depends_on, to_string
  // and Tape::compile must not recurse on it.
  Graph g;
  const Node x = g.variable(0);
  Node f = x;
  for (int i = 0; i < 100000; ++i) f = g.binary(Op::kAdd, g.unary(Op::kSin, f), x);
  EXPECT_TRUE(g.depends_on(f, 0));
  EXPECT_FALSE(g.depends_on(f, 1));
  const Node df = g.derivative(f, 0);
  EXPECT_FALSE(g.is_constant(df));
  EXPECT_TRUE(g.is_constant(g.derivative(f, 1)));
  EXPECT_GT(g.to_string(f).size(), 100000u);
  const Tape tape = Tape::compile(g, {f, df}, 1);
  std::vector<double> scratch(tape.scratch_size());
  double out[2];
  const double slot = 0.1;
  tape.eval(&slot, out, scratch.data());
  EXPECT_TRUE(std::isfinite(out[0]));
  EXPECT_TRUE(std::isfinite(out[1]));
}

// ---------------------------------------------------------------------------------------------------------
// Tapes.

TEST_F(ExprTest, TapeSharesSubexpressionsAcrossOutputs) {
  const Node f1 = parse("sin(x)*y");
  const Node f2 = parse("sin(x) + y");
  const Node f3 = parse("sin(x)");
  const Tape tape = Tape::compile(g_, {f1, f2, f3}, 3);
  EXPECT_EQ(tape.num_outputs(), 3u);
  EXPECT_EQ(tape.num_instructions(), 3u);  // sin(x), the product and the sum; x and y are copied in bulk
  EXPECT_EQ(tape.scratch_size(), 5u);      // one register per node
  std::vector<double> scratch(tape.scratch_size());
  double out[3];
  const double slots[3] = {0.5, 2.0, 0.0};
  tape.eval(slots, out, scratch.data());
  EXPECT_EQ(out[0], std::sin(0.5) * 2.0);
  EXPECT_EQ(out[1], std::sin(0.5) + 2.0);
  EXPECT_EQ(out[2], std::sin(0.5));
}

TEST_F(ExprTest, FusedSinCosMatchesSinAndCos) {
  // sin(u) and cos(u) of the same argument are computed by one instruction; the values must be exactly
  // those of std::sin and std::cos, which constant folding uses.
  const Node u = parse("x*y");
  const Node s = g_.unary(Op::kSin, u);
  const Node c = g_.unary(Op::kCos, u);
  const Tape tape = Tape::compile(g_, {c, parse("x"), s, g_.binary(Op::kMul, s, c)}, 3);
  EXPECT_EQ(tape.num_outputs(), 4u);
  std::vector<double> scratch(tape.scratch_size());
  std::mt19937_64 rng(7);
  std::vector<double> points = {
      0.0,    -0.0,     1e-300,    5e-324, 0.785398163397448, 1.5707963267948966, 3.141592653589793, -2.5, 100.0, 1e5, 1e10, 1e22, 1e300,
      -1e300, INFINITY, -INFINITY, NAN};
  for (int i = 0; i < 2000; ++i) {
    points.push_back(std::ldexp(std::uniform_real_distribution<double>(-1.0, 1.0)(rng), i % 80 - 20));
  }
  for (double p : points) {
    const double slots[3] = {p, 1.0, 0.0};
    double out[4];
    tape.eval(slots, out, scratch.data());
    const double es = std::sin(p), ec = std::cos(p);
    if (std::isnan(es)) {
      EXPECT_TRUE(std::isnan(out[2])) << p;
      EXPECT_TRUE(std::isnan(out[0])) << p;
      continue;
    }
    EXPECT_EQ(std::bit_cast<std::uint64_t>(out[2]), std::bit_cast<std::uint64_t>(es)) << p;
    EXPECT_EQ(std::bit_cast<std::uint64_t>(out[0]), std::bit_cast<std::uint64_t>(ec)) << p;
    EXPECT_EQ(out[1], p);
    EXPECT_EQ(out[3], es * ec) << p;
  }
}

TEST_F(ExprTest, TapeWithRepeatedConstantAndVariableOutputs) {
  const Node f = parse("x*y + exp(z)");
  const Node c = parse("a*b");
  const Node y = parse("y");
  const Tape tape = Tape::compile(g_, {f, c, f, y, c}, 3);
  EXPECT_EQ(tape.num_outputs(), 5u);
  std::vector<double> scratch(tape.scratch_size());
  double out[5];
  const double slots[3] = {1.5, -2.0, 0.25};
  tape.eval(slots, out, scratch.data());
  const double expected = 1.5 * -2.0 + std::exp(0.25);
  EXPECT_EQ(out[0], expected);
  EXPECT_EQ(out[2], expected);
  EXPECT_EQ(out[1], 1.0);
  EXPECT_EQ(out[4], 1.0);
  EXPECT_EQ(out[3], -2.0);
  // The same tape serves other inputs with a fresh or reused scratch buffer.
  const double other[3] = {2.0, 3.0, 0.0};
  tape.eval(other, out, scratch.data());
  EXPECT_EQ(out[0], 7.0);

  const Tape empty = Tape::compile(g_, {}, 3);
  EXPECT_EQ(empty.num_outputs(), 0u);
  EXPECT_EQ(empty.scratch_size(), 0u);
  empty.eval(slots, nullptr, nullptr);
  const Tape def;
  EXPECT_EQ(def.num_instructions(), 0u);
}

// The parts of eval() that the scene's step runs (scene_model.h: the constants loaded once, the inputs
// written into their registers, run(), the outputs read from theirs, one scratch reused at every step)
// against eval() itself with a scratch of its own, bit for bit: with a bound parameter p, a constant
// output, an input that is an output, sin and cos of one angle, and a slot the tape does not read.
TEST_F(ExprTest, TapePartsComputeWhatEvalComputes) {
  const Node p = g_.variable(3);  // the tape's parameter (slots 0-2 are its inputs)
  const Node f = g_.binary(Op::kAdd, g_.binary(Op::kMul, p, parse("cos(x)*y")), parse("sin(x)"));
  const std::vector<Node> outputs = {f, g_.derivative(f, 0), parse("a*b"), parse("y"), g_.derivative(f, 1)};
  Tape tape = Tape::compile(g_, outputs, 3, 1);
  const double param = -1.75;
  ASSERT_TRUE(tape.bind(&param));
  ASSERT_EQ(tape.input_register(2), -1);  // z appears in no output
  const std::int32_t rx = tape.input_register(0), ry = tape.input_register(1);
  ASSERT_GE(rx, 0);
  ASSERT_GE(ry, 0);
  ASSERT_NE(rx, ry);
  std::vector<double> resident(tape.scratch_size(), 0.0), fresh(tape.scratch_size());
  tape.load_constants(resident.data());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  for (int k = 0; k < 200; ++k) {
    const double slots[3] = {u(rng), u(rng), u(rng)};
    std::vector<double> want(outputs.size());
    std::fill(fresh.begin(), fresh.end(), std::nan(""));  // eval() must not depend on what the scratch held
    tape.eval(slots, want.data(), fresh.data());
    resident[static_cast<std::size_t>(rx)] = slots[0];
    resident[static_cast<std::size_t>(ry)] = slots[1];
    tape.run(resident.data());
    for (std::size_t j = 0; j < outputs.size(); ++j) {
      const double got = resident[static_cast<std::size_t>(tape.output_register(j))];
      EXPECT_EQ(std::bit_cast<std::uint64_t>(got), std::bit_cast<std::uint64_t>(want[j])) << "output " << j << " at step " << k;
    }
    // Independent reference for the first output: the same expression in C++.
    EXPECT_EQ(want[0], param * (std::cos(slots[0]) * slots[1]) + std::sin(slots[0]));
  }
}

TEST_F(ExprTest, TapeIsTopologicallyOrderedForDeepSharing) {
  // x1 = x0*x0, x2 = x1*x1, ...: exponential as a tree, linear as a DAG and as a tape.
  Node f = parse("x");
  for (int i = 0; i < 40; ++i) f = g_.binary(Op::kMul, g_.binary(Op::kAdd, f, g_.constant(0.5)), f);
  const Tape tape = Tape::compile(g_, {f}, 1);
  EXPECT_EQ(tape.num_instructions(), 80u);
  const Node df = g_.derivative(f, 0);
  EXPECT_LT(g_.size(), 1000u);
  (void)eval(df, 0.1);
  // Printed as a tree, it would have about 2^40 characters: the text is cut off.
  const std::string text = g_.to_string(f);
  EXPECT_LT(text.size(), 2u << 20);
  EXPECT_EQ(text.substr(text.size() - 3), "...");
}

// ---------------------------------------------------------------------------------------------------------
// Native code (native_tape.cc) against the interpreter: every register bit for bit, NaNs included.

// Runs `tape` natively and interpreted from the same scratch (its constants, the inputs `slots`, every
// other register a poisoned NaN) and compares every register. Returns the number of registers compared.
int expect_native_matches_interpreter(const Tape& tape, const std::vector<double>& slots, const std::string& what) {
  const double poison = std::bit_cast<double>(std::uint64_t{0x7ff4'dead'beef'0001});
  std::vector<double> native(tape.scratch_size(), poison);
  tape.load_constants(native.data());
  for (std::size_t k = 0; k < slots.size(); ++k)
    if (const std::int32_t r = tape.input_register(static_cast<int>(k)); r >= 0) native[static_cast<std::size_t>(r)] = slots[k];
  std::vector<double> interpreted = native;
  tape.run(native.data());
  tape.run_interpreted(interpreted.data());
  int mismatches = 0;
  for (std::size_t r = 0; r < native.size(); ++r) {
    const auto a = std::bit_cast<std::uint64_t>(native[r]), b = std::bit_cast<std::uint64_t>(interpreted[r]);
    if (a != b && ++mismatches <= 3)
      ADD_FAILURE() << what << ": register " << r << " native " << native[r] << " (0x" << std::hex << a << ") interpreted "
                    << interpreted[r] << " (0x" << b << std::dec << ")";
  }
  return static_cast<int>(native.size());
}

// The values where implementations part ways: signed zeros, subnormals, the largest and smallest
// normals, infinities, NaNs of both signs, the kinks of abs, min and max (ties), the edges of asin's and
// log's domains, arguments where sin and cos need their long argument reduction.
const std::vector<double>& special_values() {
  static const std::vector<double> v = {0.0,
                                        -0.0,
                                        1.0,
                                        -1.0,
                                        0.5,
                                        -2.5,
                                        2.0,
                                        3.0,
                                        1e-310,
                                        -4.9e-324,
                                        2.2250738585072014e-308,
                                        1.7976931348623157e308,
                                        -1e300,
                                        710.5,
                                        -745.5,
                                        1e22,
                                        -6.283185307179586,
                                        std::numeric_limits<double>::infinity(),
                                        -std::numeric_limits<double>::infinity(),
                                        std::numeric_limits<double>::quiet_NaN(),
                                        -std::numeric_limits<double>::quiet_NaN()};
  return v;
}

TEST_F(ExprTest, NativeCodeComputesEveryOperationAsTheInterpreterDoesAtSpecialValues) {
  struct Case {
    std::string name;
    std::vector<Node> outputs;
  };
  std::vector<Case> cases;
  for (const char* text : {"sin(x)",  "cos(x)", "tan(x)", "asin(x)",   "acos(x)",     "atan(x)",   "sinh(x)",  "cosh(x)",
                           "tanh(x)", "exp(x)", "log(x)", "sqrt(x)",   "abs(x)",      "-x",        "x^2",      "x + y",
                           "x - y",   "x*y",    "x/y",    "pow(x, y)", "atan2(x, y)", "min(x, y)", "max(x, y)"})
    cases.push_back({text, {parse(text)}});
  cases.push_back({"sign(x), the derivative of abs(x)", {g_.derivative(parse("abs(x)"), 0)}});
  cases.push_back({"select, the derivative of min(x*y, y - x)", {g_.derivative(parse("min(x*y, y - x)"), 0)}});
  cases.push_back({"sin(x) and cos(x) fused", {parse("sin(x)"), parse("cos(x)")}});
  for (const Case& c : cases) {
    const Tape tape = Tape::compile(g_, c.outputs, 3);
#if defined(__x86_64__) && defined(__linux__)
    ASSERT_TRUE(tape.native()) << c.name << ": x86-64 Linux compiles every tape to native code";
#endif
    ASSERT_GT(tape.num_instructions(), 0u) << c.name;
    int compared = 0;
    for (double x : special_values())
      for (double y : special_values())
        compared +=
            expect_native_matches_interpreter(tape, {x, y, 0.0}, c.name + " at x = " + std::to_string(x) + ", y = " + std::to_string(y));
    EXPECT_GT(compared, 400) << c.name;
  }
}

// x^p with p a parameter: bind() switches the interpreter between x*x (p = 2) and pow; the native code,
// compiled before any bind, must follow.
TEST(TapeNative, PowerOfABoundParameterFollowsEveryBind) {
  Graph g;
  const Node x = g.variable(0), p = g.variable(1);  // one input, one parameter
  const Node f = g.binary(Op::kPow, x, p);
  Tape tape = Tape::compile(g, {f, g.derivative(f, 0)}, 1, 1);
  for (const double value : {2.0, 3.0, 2.0, 0.5, -2.0, 2.0}) {
    ASSERT_TRUE(tape.bind(&value));
    for (double xv : special_values())
      expect_native_matches_interpreter(tape, {xv}, "x^p with p = " + std::to_string(value) + " at x = " + std::to_string(xv));
    // And against C++ itself: x*x for p = 2 (the graph's own rewrite of x^2), pow otherwise.
    std::vector<double> scratch(tape.scratch_size()), out(2);
    const double xv = 1.1;
    tape.eval(&xv, out.data(), scratch.data());
    EXPECT_EQ(out[0], value == 2.0 ? xv * xv : std::pow(xv, value)) << "p = " << value;
  }
}

// Random expressions over every operation the scene format has, with their first and second derivatives
// (which bring sign, select, squares, fused sines and cosines and long shared chains), at random points.
TEST(TapeNative, RandomExpressionsWithDerivativesComputeWhatTheInterpreterComputes) {
  std::mt19937_64 rng(2027);
  std::function<std::string(int)> random_text = [&](int depth) -> std::string {
    static const char* leaves[] = {"x", "y", "z", "a", "2", "0.5", "-x", "3"};
    if (depth == 0 || rng() % 5 == 0) return leaves[rng() % 8];
    const std::string l = random_text(depth - 1), r = random_text(depth - 1);
    switch (rng() % 20) {
      case 0: return "(" + l + " + " + r + ")";
      case 1: return "(" + l + " - " + r + ")";
      case 2: return "(" + l + "*" + r + ")";
      case 3: return "(" + l + ")/(" + r + ")";
      case 4: return "-(" + l + ")";
      case 5: return "sin(" + l + ")";
      case 6: return "cos(" + l + ")";
      case 7: return "(" + l + ")^2";
      case 8: return "(" + l + ")^a";
      case 9: return "sqrt(abs(" + l + "))";
      case 10: return "log(1 + (" + l + ")^2)";
      case 11: return "exp(" + l + ")";
      case 12: return "tan(" + l + ")";
      case 13: return "atan2(" + l + ", " + r + ")";
      case 14: return "min(" + l + ", " + r + ")";
      case 15: return "max(" + l + ", " + r + ")";
      case 16: return "abs(" + l + ")";
      case 17: return "tanh(" + l + ")*cosh(" + r + ")";
      case 18: return "atan(" + l + ") + asin(sin(" + r + "))";
      default: return "pow(abs(" + l + "), " + r + ")";
    }
  };
  Graph g;
  const Node a = g.variable(3);  // a parameter
  auto resolve = [&](std::string_view name) -> std::optional<Node> {
    if (name == "x") return g.variable(0);
    if (name == "y") return g.variable(1);
    if (name == "z") return g.variable(2);
    if (name == "a") return a;
    return std::nullopt;
  };
  std::vector<Node> outputs;
  for (int i = 0; i < 150; ++i) {
    const Node f = g.parse(random_text(5), resolve);
    const Node fx = g.derivative(f, 0), fy = g.derivative(f, 1);
    outputs.insert(outputs.end(), {f, fx, fy, g.derivative(fx, 0), g.derivative(fx, 2)});
  }
  Tape tape = Tape::compile(g, outputs, 3, 1);
#if defined(__x86_64__) && defined(__linux__)
  ASSERT_TRUE(tape.native());
#endif
  EXPECT_GT(tape.num_instructions(), 3000u);  // a long tape: every kind of instruction, many times
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (const double param : {2.0, -1.5, 0.75}) {
    // bind() says false when a node of the parameter alone is 0 (then the folded tape could differ from
    // this one in the sign of a zero): the native code and the interpreter agree whatever it says.
    static_cast<void>(tape.bind(&param));
    for (int k = 0; k < 40; ++k)
      expect_native_matches_interpreter(tape, {u(rng), u(rng), u(rng)}, "a = " + std::to_string(param) + ", point " + std::to_string(k));
    for (double v : special_values())
      expect_native_matches_interpreter(tape, {v, -v, 0.5 * v}, "a = " + std::to_string(param) + " at " + std::to_string(v));
  }
}

// A copy of a tape shares its native code; both keep working when the original is gone.
TEST(TapeNative, CopiesShareTheCodeAndOutliveTheOriginal) {
  Graph g;
  const Node f = g.binary(Op::kMul, g.unary(Op::kSin, g.variable(0)), g.variable(1));
  std::optional<Tape> original = Tape::compile(g, {f}, 2);
  const Tape copy = *original;
  original.reset();
  std::vector<double> scratch(copy.scratch_size());
  const double slots[2] = {0.7, -3.0};
  double out = 0.0;
  copy.eval(slots, &out, scratch.data());
  EXPECT_EQ(out, std::sin(0.7) * -3.0);
  EXPECT_EQ(copy.native(), Tape::compile(g, {f}, 2).native());
}

// run_wired() reads its inputs from the caller's arrays and writes every output to each of its places: the
// same bits as the interpreter's registers, for random expressions with their derivatives (a long tape,
// calls between register-held values), outputs that are inputs or constants, and an output with two
// places; the sinks' other entries are left alone.
TEST(TapeNative, WiredRunsWriteWhatTheInterpreterComputesWhereTheWiringSays) {
  std::mt19937_64 rng(77);
  Graph g;
  auto resolve = [&](std::string_view name) -> std::optional<Node> {
    if (name == "t") return g.variable(0);
    if (name == "x") return g.variable(1);
    if (name == "y") return g.variable(2);
    if (name == "a") return g.variable(3);  // a parameter
    return std::nullopt;
  };
  std::vector<Node> outputs = {g.parse("y", resolve), g.parse("2.5", resolve), g.parse("a*a", resolve)};
  const char* texts[] = {"sin(x)*cos(x)*y - t", "x^2*sin(y) + min(x, y)/max(t, 0.5)", "exp(-x*x)*atan2(y, x) + sqrt(abs(y))",
                         "cos(x + y)*(1 + y^a)", "-(a*sin(t))*(-y) + tanh(x)*log(1 + y*y)"};
  for (const char* text : texts) {
    const Node f = g.parse(text, resolve);
    outputs.insert(outputs.end(), {f, g.derivative(f, 1), g.derivative(f, 2), g.derivative(g.derivative(f, 1), 2)});
  }
  Tape tape = Tape::compile(g, outputs, 3, 1);
  const double a = 1.5;
  ASSERT_TRUE(tape.bind(&a));
  // Sources: {t}, {x, y} (reversed: y at 0, x at 1). Sinks: two arrays; output j at sink j % 2, index j / 2,
  // and output 3 also at the end of sink 0.
  Tape::Wiring wiring;
  wiring.inputs = {{0, 0}, {1, 1}, {1, 0}};
  const int m = static_cast<int>(outputs.size());
  const int sink_size = m / 2 + 2;
  for (int j = 0; j < m; ++j) wiring.outputs.push_back({{j % 2, j / 2}});
  wiring.outputs[3].push_back({0, sink_size - 1});
  tape.wire(wiring);
#if defined(__x86_64__) && defined(__linux__)
  ASSERT_TRUE(tape.native());
#endif
  std::vector<double> scratch(tape.scratch_size()), reference(tape.scratch_size());
  tape.load_constants(scratch.data());
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::vector<std::array<double, 3>> points;
  for (int k = 0; k < 100; ++k) points.push_back({u(rng), u(rng), u(rng)});
  for (double v : special_values()) points.push_back({v, -v, 0.25 * v});
  for (const auto& [t, x, y] : points) {
    const double time[] = {t}, position[] = {y, x};
    const double* sources[] = {time, position};
    const double untouched = -123.0;
    std::vector<double> sink0(static_cast<std::size_t>(sink_size), untouched), sink1(static_cast<std::size_t>(sink_size), untouched);
    double* sinks[] = {sink0.data(), sink1.data()};
    tape.run_wired(scratch.data(), sources, sinks);
    std::fill(reference.begin(), reference.end(), std::nan(""));
    tape.load_constants(reference.data());
    const double slots[] = {t, x, y};
    for (int k = 0; k < 3; ++k)
      if (const std::int32_t r = tape.input_register(k); r >= 0) reference[static_cast<std::size_t>(r)] = slots[k];
    tape.run_interpreted(reference.data());
    for (int j = 0; j < m; ++j) {
      const double want = reference[static_cast<std::size_t>(tape.output_register(static_cast<std::size_t>(j)))];
      const double got = (j % 2 == 0 ? sink0 : sink1)[static_cast<std::size_t>(j / 2)];
      EXPECT_EQ(std::bit_cast<std::uint64_t>(got), std::bit_cast<std::uint64_t>(want))
          << "output " << j << " at t = " << t << ", x = " << x << ", y = " << y;
    }
    EXPECT_EQ(std::bit_cast<std::uint64_t>(sink0.back()), std::bit_cast<std::uint64_t>(sink1[1]));  // output 3's two places
    EXPECT_EQ(std::bit_cast<std::uint64_t>(sink0[0]), std::bit_cast<std::uint64_t>(y));             // output 0 is the input y
    EXPECT_EQ(sink1[0], 2.5);                                                                       // output 1 is a constant
    EXPECT_EQ(sink0[1], 2.25);                                                                      // output 2, a*a, is bound
    EXPECT_EQ(sink1[sink_size - 1], untouched);                                                     // written by nothing
  }
}

// Names for the wired tapes' tests: x is slot 0, y slot 1.
auto resolve_x_y(Graph& g) {
  return [&g](std::string_view name) -> std::optional<Node> {
    if (name == "x") return g.variable(0);
    if (name == "y") return g.variable(1);
    return std::nullopt;
  };
}

// A wired tape that calls nothing (its code keeps the caller's pointers where they came, and pushes nothing).
TEST(TapeNative, WiredArithmeticWithoutCallsWritesWhatTheInterpreterComputes) {
  Graph g;
  const auto resolve = resolve_x_y(g);
  const std::vector<Node> outputs = {g.parse("x*y - 0.5*x", resolve), g.parse("min(x, y)/max(x, 1)", resolve),
                                     g.parse("-sqrt(abs(x))*y^2", resolve)};
  Tape tape = Tape::compile(g, outputs, 2);
  tape.wire({{{0, 0}, {0, 1}}, {{{0, 0}}, {{0, 1}}, {{0, 2}}}});
  std::vector<double> scratch(tape.scratch_size()), reference(tape.scratch_size());
  tape.load_constants(scratch.data());
  for (double x : special_values())
    for (double y : special_values()) {
      const double in[] = {x, y};
      double out[3] = {};
      const double* sources[] = {in};
      double* sinks[] = {out};
      tape.run_wired(scratch.data(), sources, sinks);
      tape.load_constants(reference.data());
      for (int k = 0; k < 2; ++k) reference[static_cast<std::size_t>(tape.input_register(k))] = in[k];
      tape.run_interpreted(reference.data());
      for (std::size_t j = 0; j < 3; ++j)
        EXPECT_EQ(std::bit_cast<std::uint64_t>(out[j]),
                  std::bit_cast<std::uint64_t>(reference[static_cast<std::size_t>(tape.output_register(j))]))
            << "output " << j << " at x = " << x << ", y = " << y;
    }
}

// A wired tape without instructions (outputs that are inputs or constants: a contact whose gap is a
// coordinate and whose gradient is constant) runs native code too, which copies each input and constant to
// its places: the values the wiring names, bit for bit (NaN payloads and signed zeros included), and
// nothing else.
TEST(TapeNative, WiredTapeWithoutInstructionsCopiesInputsAndConstants) {
  Graph g;
  const auto resolve = resolve_x_y(g);
  const std::vector<Node> outputs = {g.parse("y", resolve), g.parse("1", resolve), g.parse("x", resolve), g.parse("2.5", resolve)};
  Tape tape = Tape::compile(g, outputs, 2);
  ASSERT_EQ(tape.num_instructions(), 0u);
  // Output 0 to two places, the others to one; sink index 4 is written by nothing.
  tape.wire({{{0, 0}, {0, 1}}, {{{0, 0}, {0, 3}}, {{0, 1}}, {{0, 2}}, {{0, 5}}}});
#if defined(__x86_64__) && defined(__linux__)
  ASSERT_TRUE(tape.native_wired()) << "a wired tape is compiled to native code even without instructions";
#endif
  std::vector<double> scratch(tape.scratch_size());
  tape.load_constants(scratch.data());
  for (double x : special_values())
    for (double y : special_values()) {
      const double in[] = {x, y};
      double out[6] = {-7.0, -7.0, -7.0, -7.0, -7.0, -7.0};
      const double* sources[] = {in};
      double* sinks[] = {out};
      tape.run_wired(scratch.data(), sources, sinks);
      EXPECT_EQ(std::bit_cast<std::uint64_t>(out[0]), std::bit_cast<std::uint64_t>(y));
      EXPECT_EQ(std::bit_cast<std::uint64_t>(out[3]), std::bit_cast<std::uint64_t>(y));
      EXPECT_EQ(out[1], 1.0);
      EXPECT_EQ(std::bit_cast<std::uint64_t>(out[2]), std::bit_cast<std::uint64_t>(x));
      EXPECT_EQ(out[5], 2.5);
      EXPECT_EQ(out[4], -7.0);
    }
}

TEST(TapeNative, WiringMustPlaceEveryInputTheTapeReads) {
  Graph g;
  Tape tape = Tape::compile(g, {g.binary(Op::kMul, g.variable(0), g.variable(2))}, 3);
  Tape::Wiring wiring;
  wiring.inputs = {{0, 0}};  // slot 2 has no place
  wiring.outputs = {{{0, 0}}};
  EXPECT_THROW(tape.wire(wiring), std::invalid_argument);
  wiring.inputs = {{0, 0}, {}, {0, 1}};  // slot 1 is not read: it needs none
  wiring.outputs = {};
  EXPECT_THROW(tape.wire(wiring), std::invalid_argument);  // and the output needs its places
  wiring.outputs = {{{0, 0}}};
  EXPECT_NO_THROW(tape.wire(wiring));
}

}  // namespace
}  // namespace moreau::expr
