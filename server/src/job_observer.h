// The observer of a job's run: the trajectory rows at the scene's decimation (the run may be sampled
// more finely for streaming), the trajectory row limit, progress, cancellation, and the LCM stream.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

#include "job.h"
#include "lcm_stream.h"
#include "moreau/core/observer.h"
#include "moreau/scene/trajectory_csv.h"

namespace moreau::server {

class JobObserver final : public ForwardingObserver {
 public:
  JobObserver(Job& job, scene::TrajectoryCsvWriter& csv, std::int64_t record_every, std::int64_t engine_every, std::int64_t max_samples,
              StreamObserver* stream, std::function<void()> progress, std::function<void(const Sample&)> sample = nullptr)
      : ForwardingObserver(stream),
        job_(job),
        csv_(csv),
        every_(std::max<std::int64_t>(1, record_every)),
        engine_every_(std::max<std::int64_t>(1, engine_every)),
        max_samples_(max_samples),
        stream_(stream),
        progress_(std::move(progress)),
        sample_(std::move(sample)),
        last_progress_(std::chrono::steady_clock::now()) {}

  void on_sample(const Sample& s) override {
    job_.t_now.store(s.t, std::memory_order_relaxed);
    job_.step_now.store(s.step, std::memory_order_relaxed);
    if (s.step % every_ == 0 || engine_every_ == every_) {
      // A multiple of the decimation, or (when the run is sampled at the decimation) its final state.
      write(s);
    } else {
      // Sampled finer than the decimation for streaming: hold on to it in case it is the final state.
      pending_step_ = s.step;
      pending_t_ = s.t;
      pending_h_ = s.h;
      pending_e_ = s.kinetic_energy;
      pending_q_.assign(s.q, s.q + s.n);
      pending_v_.assign(s.v, s.v + s.n);
      n_ = s.n;
    }
    maybe_sample(s);
    if (stream_) {
      stream_->on_sample(s);
      if (++since_progress_check_ >= 128) {
        since_progress_check_ = 0;
        maybe_progress();
      }
    }
  }

  // Impacts, convergence as it is detected and a detected rest that ended go on to the job's event
  // stream (StreamObserver) as ForwardingObserver passes them.

  bool keep_going(std::int64_t step, double t) override {
    job_.t_now.store(t, std::memory_order_relaxed);
    job_.step_now.store(step, std::memory_order_relaxed);
    maybe_progress();
    return !job_.cancel.load(std::memory_order_relaxed) && !overflow_;
  }

  // Writes the held final state if the run ended on one.
  void finish() {
    if (pending_step_ > last_written_) {
      Sample s{pending_step_, pending_t_, pending_h_, n_, pending_q_.data(), pending_v_.data(), pending_e_};
      write(s);
    }
  }

  bool overflow() const { return overflow_; }
  std::int64_t rows() const { return rows_; }

 private:
  void write(const Sample& s) {
    if (rows_ >= max_samples_) {
      overflow_ = true;
      return;
    }
    csv_.on_sample(s);
    ++rows_;
    last_written_ = s.step;
  }
  void maybe_progress() {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_progress_ >= std::chrono::milliseconds(100)) {
      last_progress_ = now;
      progress_();
    }
  }

  // The state for a live plot at most ten times a second of wall time (the first sample at once): a
  // clock read per recorded state, which costs nothing beside the step that made it.
  void maybe_sample(const Sample& s) {
    if (!sample_) return;
    const auto now = std::chrono::steady_clock::now();
    if (sampled_ && now - last_sample_ < std::chrono::milliseconds(100)) return;
    sampled_ = true;
    last_sample_ = now;
    sample_(s);
  }

  Job& job_;
  scene::TrajectoryCsvWriter& csv_;
  std::int64_t every_, engine_every_, max_samples_;
  StreamObserver* stream_;
  std::function<void()> progress_;
  std::function<void(const Sample&)> sample_;
  std::chrono::steady_clock::time_point last_progress_, last_sample_;
  bool sampled_ = false;
  int since_progress_check_ = 0;
  std::int64_t rows_ = 0, last_written_ = -1;
  bool overflow_ = false;
  std::int64_t pending_step_ = -1;
  double pending_t_ = 0, pending_h_ = 0, pending_e_ = 0;
  int n_ = 0;
  std::vector<double> pending_q_, pending_v_;
};

}  // namespace moreau::server
