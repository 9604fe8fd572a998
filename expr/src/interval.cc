#include "moreau/expr/interval.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace moreau::expr {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPi = 3.14159265358979323846;

double down(double x) { return std::nextafter(std::nextafter(x, -kInf), -kInf); }
double up(double x) { return std::nextafter(std::nextafter(x, kInf), kInf); }

// The enclosure [lo, hi] widened outward by two ulps; anything NaN (inf - inf, 0 * inf) encloses nothing
// usable, so everything.
Interval widened(double lo, double hi) {
  if (std::isnan(lo) || std::isnan(hi)) return Interval::everything();
  return {down(lo), up(hi)};
}

Interval mul(const Interval& a, const Interval& b) {
  const double p[] = {a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi};
  for (double x : p)
    if (std::isnan(x)) return Interval::everything();
  return widened(*std::min_element(p, p + 4), *std::max_element(p, p + 4));
}

// A function that decreases on (-inf, 0] and increases on [0, inf) with its minimum f(0) (x^2, x^(2k),
// cosh).
template <class F>
Interval even(const Interval& a, F f) {
  if (a.lo >= 0.0) return widened(f(a.lo), f(a.hi));
  if (a.hi <= 0.0) return widened(f(a.hi), f(a.lo));
  // The minimum f(0) is exact for the functions used here (0 * 0, pow(0, 2k), cosh(0) = 1): not widened.
  return {f(0.0), widened(f(0.0), std::max(f(a.lo), f(a.hi))).hi};
}

// sin over a bounded interval narrower than 2 pi: its values at the ends, and 1 (-1) when a maximum
// (minimum) pi/2 + 2 k pi (-pi/2 + 2 k pi) may lie inside. The test is widened by a relative 1e-12 so
// that rounding in x / (2 pi) can only include an extremum that is not there, never miss one.
Interval sine(const Interval& a, double shift) {
  if (!a.bounded() || a.hi - a.lo >= 2.0 * kPi) return {-1.0, 1.0};
  const double lo = a.lo + shift, hi = a.hi + shift;  // cos x = sin(x + pi/2)
  const auto contains = [&](double phase) {           // some x = phase + 2 k pi in [lo, hi]?
    const double slack = 1e-12 * std::max({1.0, std::abs(lo), std::abs(hi)});
    const double k = std::ceil((lo - slack - phase) / (2.0 * kPi));
    return phase + 2.0 * kPi * k <= hi + slack;
  };
  // lo + shift is rounded by at most ulp(lo)/2 and sin is 1-Lipschitz: widen by that absolutely.
  const double shift_error = shift == 0.0 ? 0.0 : 2.3e-16 * std::max({1.0, std::abs(lo), std::abs(hi)});
  const double from = std::min(std::sin(lo), std::sin(hi)), to = std::max(std::sin(lo), std::sin(hi));
  Interval r = widened(from - shift_error, to + shift_error);
  if (contains(kPi / 2.0)) r.hi = 1.0;
  if (contains(-kPi / 2.0)) r.lo = -1.0;
  r.lo = std::max(r.lo, -1.0);
  r.hi = std::min(r.hi, 1.0);
  return r;
}

class Encloser {
 public:
  Encloser(const Graph& graph, const std::vector<Interval>& slots) : g_(graph), slots_(slots) {}

  Interval of(Node n) {
    if (auto it = memo_.find(n); it != memo_.end()) return it->second;
    // Operands first, without recursion: the graph may be deep (kMaxDepth bounds parsing, not derivatives).
    std::vector<Node> stack{n};
    while (!stack.empty()) {
      const Node top = stack.back();
      if (memo_.count(top)) {
        stack.pop_back();
        continue;
      }
      const Graph::Entry& e = g_.entry(top);
      bool ready = true;
      for (Node operand : {e.a, e.b, e.c, e.d})
        if (operand >= 0 && !memo_.count(operand)) {
          stack.push_back(operand);
          ready = false;
        }
      if (!ready) continue;
      memo_[top] = compute(e);
      stack.pop_back();
    }
    return memo_.at(n);
  }

 private:
  Interval compute(const Graph::Entry& e) {
    const auto operand = [&](Node x) { return memo_.at(x); };
    switch (e.op) {
      case Op::kConst: return Interval::point(e.value);
      case Op::kVar:
        return e.slot >= 0 && static_cast<std::size_t>(e.slot) < slots_.size() ? slots_[static_cast<std::size_t>(e.slot)]
                                                                               : Interval::everything();
      case Op::kAdd: {
        const Interval a = operand(e.a), b = operand(e.b);
        return widened(a.lo + b.lo, a.hi + b.hi);
      }
      case Op::kSub: {
        const Interval a = operand(e.a), b = operand(e.b);
        return widened(a.lo - b.hi, a.hi - b.lo);
      }
      case Op::kMul: return mul(operand(e.a), operand(e.b));
      case Op::kDiv: {
        const Interval b = operand(e.b);
        if (b.lo <= 0.0 && b.hi >= 0.0) return Interval::everything();
        return mul(operand(e.a), widened(1.0 / b.hi, 1.0 / b.lo));
      }
      case Op::kNeg: {
        const Interval a = operand(e.a);
        return {-a.hi, -a.lo};
      }
      case Op::kSquare: return even(operand(e.a), [](double x) { return x * x; });
      case Op::kPow: {
        const Graph::Entry& exponent = g_.entry(e.b);
        if (exponent.op != Op::kConst || exponent.value != std::floor(exponent.value) || exponent.value < 0.0 || exponent.value > 64.0)
          return Interval::everything();
        const double p = exponent.value;
        const Interval a = operand(e.a);
        const auto f = [p](double x) { return std::pow(x, p); };
        if (static_cast<long>(p) % 2 == 0) return even(a, f);
        return widened(f(a.lo), f(a.hi));  // odd: increasing
      }
      case Op::kSin: return sine(operand(e.a), 0.0);
      case Op::kCos: return sine(operand(e.a), kPi / 2.0);
      case Op::kAtan: {
        const Interval a = operand(e.a);
        Interval r = widened(std::atan(a.lo), std::atan(a.hi));
        r.lo = std::max(r.lo, -kPi / 2.0 - 1e-15);
        r.hi = std::min(r.hi, kPi / 2.0 + 1e-15);
        return r;
      }
      case Op::kTanh: {
        const Interval a = operand(e.a);
        Interval r = widened(std::tanh(a.lo), std::tanh(a.hi));
        r.lo = std::max(r.lo, -1.0);
        r.hi = std::min(r.hi, 1.0);
        return r;
      }
      case Op::kSinh: {
        const Interval a = operand(e.a);
        return widened(std::sinh(a.lo), std::sinh(a.hi));
      }
      case Op::kExp: {
        const Interval a = operand(e.a);
        Interval r = widened(std::exp(a.lo), std::exp(a.hi));
        r.lo = std::max(r.lo, 0.0);
        return r;
      }
      case Op::kCosh: return even(operand(e.a), [](double x) { return std::cosh(x); });
      case Op::kAbs: {
        const Interval a = operand(e.a);
        if (a.lo >= 0.0) return a;
        if (a.hi <= 0.0) return {-a.hi, -a.lo};
        return {0.0, std::max(-a.lo, a.hi)};
      }
      case Op::kMin: {
        const Interval a = operand(e.a), b = operand(e.b);
        return {std::min(a.lo, b.lo), std::min(a.hi, b.hi)};
      }
      case Op::kMax: {
        const Interval a = operand(e.a), b = operand(e.b);
        return {std::max(a.lo, b.lo), std::max(a.hi, b.hi)};
      }
      case Op::kSign: {
        const Interval a = operand(e.a);
        if (a.lo > 0.0) return Interval::point(1.0);
        if (a.hi < 0.0) return Interval::point(-1.0);
        return {-1.0, 1.0};
      }
      case Op::kSelectLe: {  // c or d, whichever the comparison picks: their union
        const Interval c = operand(e.c), d = operand(e.d);
        return {std::min(c.lo, d.lo), std::max(c.hi, d.hi)};
      }
      default: return Interval::everything();  // tan, asin, acos, atan2, log, sqrt, ...: not enclosed here
    }
  }

  const Graph& g_;
  const std::vector<Interval>& slots_;
  std::unordered_map<Node, Interval> memo_;
};

}  // namespace

double Interval::magnitude() const { return std::max(std::abs(lo), std::abs(hi)); }

std::vector<Interval> enclose(const Graph& graph, const std::vector<Node>& outputs, const std::vector<Interval>& slots) {
  Encloser encloser(graph, slots);
  std::vector<Interval> out;
  out.reserve(outputs.size());
  for (Node n : outputs) out.push_back(encloser.of(n));
  return out;
}

}  // namespace moreau::expr
