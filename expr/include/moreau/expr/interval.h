// Interval bounds of an expression over boxes of its inputs: for every input in its interval the value
// lies in the returned interval (a sound enclosure, Moore's interval arithmetic). Used to prove a
// hypothesis "for all states" (e.g. Assumption 4.1 2)-3): sup ||grad V(q)|| over all q) rather than only on
// the states a run visited. Every result is widened outward by two ulps at each operation, which covers
// the rounding of the operation itself and libm's error in sin, cos, exp, ... (within 1 ulp in glibc);
// the enclosure may be wide (the dependency problem: x - x is [-w, w], not 0) but never too narrow. An
// operation whose enclosure is not finite (x * y with x unbounded, exp of an unbounded input) gives
// [-inf, inf]: nothing is proved then. Ops outside the list below (tan, asin, acos, atan2, log, sqrt,
// division by an interval containing 0, non-integer powers) give [-inf, inf] too.
#pragma once

#include <limits>
#include <vector>

#include "moreau/expr/expression.h"

namespace moreau::expr {

struct Interval {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();

  static Interval everything() { return {}; }
  static Interval point(double x) { return {x, x}; }
  bool bounded() const { return lo > -std::numeric_limits<double>::infinity() && hi < std::numeric_limits<double>::infinity(); }
  // max |x| over the interval (+inf when unbounded).
  double magnitude() const;
};

// Enclosures of the nodes `outputs` of `graph` when variable slot s lies in slots[s] (a slot beyond the
// vector is unbounded). Linear in the number of nodes reachable from the outputs.
std::vector<Interval> enclose(const Graph& graph, const std::vector<Node>& outputs, const std::vector<Interval>& slots);

}  // namespace moreau::expr
