// The exact decision of condition (ii) of strict positive realness, G(jw) + G(jw)^H > 0 for every real w,
// for absolute_stability.cc: the Popov function's numerator N(s) = P(s) d(-s) + P(-s)^T d(s) from the
// exact resolvent, q(w^2) = det N(jw), its positive roots by a Sturm sequence (the crossings) and one exact
// definiteness test of N(jw) between each two (docs/second-paper.md, "Exact deciders"). A translation unit
// of its own: its rational arithmetic is what made absolute_stability.cc the largest unit of the build.
#pragma once

#include <vector>

#include "lti_exact.h"
#include "moreau/core/verdict.h"

namespace moreau::lti_exact {

// The exact decision of (ii) (see the header): N(s) = P(s) d(-s) + P(-s)^T d(s), q(w^2) = det N(jw).
struct ExactFrequency {
  Verdict verdict = Verdict::kNotChecked;
  std::vector<double> crossings;
  double witness_omega = -1.0;
  bool witness_singular = false;     // Phi(jw) singular there (a crossing where Phi only touches 0)
  bool witness_beyond_last = false;  // the witness lies beyond the last crossing (high frequency)
  Rational witness_w;                // the exact frequency checked
  bool witness_value_exact = false;  // SISO: the value below is Phi(jw) rounded once
  double witness_value = 0.0;
  int degree = 0;  // of q
};

ExactFrequency exact_frequency(const Matrix& A, const Matrix& B, const Matrix& C, const Resolvent& res, double wc);

}  // namespace moreau::lti_exact
