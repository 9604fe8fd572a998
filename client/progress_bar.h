// A progress bar on stderr for runs longer than a second, redrawn at most ten times a second. It only
// uses the integrator's periodic keep_going() call, never a per-step hook.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "moreau/core/observer.h"

namespace moreau::cli {

class ProgressBar : public RunObserver {
 public:
  using Clock = std::chrono::steady_clock;
  ProgressBar(double t0, double t_end, bool enabled) : t0_(t0), t_end_(t_end), enabled_(enabled), start_(Clock::now()) {}
  ~ProgressBar() override { finish(); }
  void on_sample(const Sample&) override {}
  bool keep_going(std::int64_t step, double t) override {
    if (!enabled_) return true;
    const double elapsed = std::chrono::duration<double>(Clock::now() - start_).count();
    if (elapsed < 1.0 || elapsed - last_draw_ < 0.1) return true;
    last_draw_ = elapsed;
    const double frac = std::clamp((t - t0_) / (t_end_ - t0_), 0.0, 1.0);
    const int width = 40, filled = static_cast<int>(frac * width);
    std::fprintf(stderr, "\r[%.*s%*s] %5.1f%%  t = %-10.4g step %lld  %.1f s", filled, "########################################",
                 width - filled, "", 100.0 * frac, t, static_cast<long long>(step), elapsed);
    std::fflush(stderr);
    drawn_ = true;
    return true;
  }
  // Clears the bar (a terminal line) once the run is over.
  void finish() {
    if (drawn_) std::fprintf(stderr, "\r%*s\r", 100, "");
    drawn_ = false;
  }

 private:
  double t0_, t_end_;
  bool enabled_;
  Clock::time_point start_;
  double last_draw_ = 0.0;
  bool drawn_ = false;
};

}  // namespace moreau::cli
