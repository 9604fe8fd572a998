// The arithmetic of expressions that is not a single IEEE operation or a libm call: shared by constant
// folding and the interpreter (expression.cc); the native code (native_tape.cc) calls sign_of and
// select_le_of and does min_of and max_of with minsd and maxsd, tested equal. Folding, the interpreter and
// the native code must give bit for bit the same values.
#pragma once

namespace moreau::expr::arithmetic {

inline double sign_of(double x) {
  // sign(0) = 0 (abs is differentiated to 0 at the kink); NaN stays NaN.
  return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : (x == 0.0 ? 0.0 : x));
}
// std::min / std::max semantics: the first argument wins ties and unordered (NaN) comparisons.
inline double min_of(double a, double b) { return b < a ? b : a; }
inline double max_of(double a, double b) { return a < b ? b : a; }
// Chooses like min_of: c where min(a, b) would pick a, d where it would pick b.
inline double select_le_of(double a, double b, double c, double d) { return b < a ? d : c; }

}  // namespace moreau::expr::arithmetic
