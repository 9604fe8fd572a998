// The time grid every scheme shares: the interval [t0, t_end], the step h, the cap on the step count and
// how often the observer sees a sample. Each scheme's settings extend it (AblSettings, MoreauJeanSettings,
// LureSettings, RegularizedSettings) with what is its own, so the grid is written once and copied as one
// piece (`grid() = other.grid()`); SteppingDriver reads it through SteppingPlan. Validated where defined
// (Ceres's Solver::Options::IsValid): the scene readers check the fields of a scene file first, with the
// JSON pointer of each, and the integrators assume a grid that is_valid().
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

namespace moreau {

struct TimeGrid {
  double h = 1e-3;                         // the step (fixed rule), or its upper bound (adaptive rules), seconds
  double t0 = 0.0;                         // initial time, seconds
  double t_end = 1.0;                      // final time, seconds
  std::int64_t max_steps = 2'000'000'000;  // the run fails rather than take more steps
  std::int64_t output_every = 1;           // the observer sees every this many steps (and the first and last)

  TimeGrid& grid() { return *this; }
  const TimeGrid& grid() const { return *this; }

  // True when a scheme can run on this grid; otherwise false, with the reason in *why (if given).
  bool is_valid(std::string* why = nullptr) const {
    const auto fail = [&](const char* reason) {
      if (why) *why = reason;
      return false;
    };
    if (!(h > 0.0) || !std::isfinite(h)) return fail("h must be finite and > 0");
    if (!std::isfinite(t0) || !std::isfinite(t_end)) return fail("t0 and t_end must be finite");
    if (!(t_end > t0)) return fail("t_end must be > t0");
    if (max_steps < 1) return fail("max_steps must be >= 1");
    if (output_every < 1) return fail("output_every must be >= 1");
    return true;
  }
};

}  // namespace moreau
