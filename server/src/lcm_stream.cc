#include "lcm_stream.h"

#include <moreau/lcm_url.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include <lcm/lcm-cpp.hpp>
#include <moreau/description_t.hpp>
#include <moreau/job_event_t.hpp>
#include <moreau/state_t.hpp>

#include "moreau/platform/number_text.h"

namespace moreau::server {

void set_channels(StreamSettings& s, const std::string& job_id) {
  std::string upper = job_id;
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  s.state_channel = s.prefix + "_STATE_" + upper;
  s.event_channel = s.prefix + "_EVENT_" + upper;
  s.description_channel = s.prefix + "_DESC_" + upper;
}

std::int64_t utime_now() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// ---- JobStream ----

JobStream::JobStream(std::string job_id, StreamSettings settings, int n, StreamDescription description)
    : job_id_(std::move(job_id)),
      settings_(std::move(settings)),
      n_(n),
      description_(std::move(description)),
      m_(static_cast<int>(description_.signal_names.size())) {
  for (Batch* b : {&local_, &pending_}) {
    b->records.reserve(4 * kBatch);
    b->qv.reserve(4 * kBatch * static_cast<std::size_t>(2 * n + m_));
  }
}

JobStream::~JobStream() = default;

void JobStream::push_state(std::int64_t step, double t, double h, const double* q, const double* v, double energy, const double* signals) {
  local_.records.push_back(Record{step, t, h, energy, -1});
  local_.qv.insert(local_.qv.end(), q, q + n_);
  local_.qv.insert(local_.qv.end(), v, v + n_);
  if (m_ > 0) local_.qv.insert(local_.qv.end(), signals, signals + m_);
  if (local_.records.size() >= kBatch || settings_.realtime) flush();
}

void JobStream::flush() {
  if (local_.records.empty()) return;
  {
    std::lock_guard lock(mu_);
    if (pending_.records.empty() && pending_.events.empty()) {
      std::swap(local_, pending_);  // the usual case: the hub took the last batch
    } else if (pending_.records.size() >= kMaxPending) {
      dropped_.fetch_add(static_cast<std::int64_t>(local_.records.size()), std::memory_order_relaxed);
    } else {
      // Events are only ever in pending_, so these states keep their place after them.
      pending_.records.insert(pending_.records.end(), local_.records.begin(), local_.records.end());
      pending_.qv.insert(pending_.qv.end(), local_.qv.begin(), local_.qv.end());
    }
  }
  local_.clear();
}

void JobStream::push_event(const char* kind, std::int64_t step, double t, std::string text) {
  flush();
  std::lock_guard lock(mu_);
  pending_.events.push_back(Event{kind, std::move(text)});
  pending_.records.push_back(Record{step, t, 0.0, 0.0, static_cast<std::int32_t>(pending_.events.size() - 1)});
}

void JobStream::close() {
  flush();
  std::lock_guard lock(mu_);
  closed_ = true;
}

bool JobStream::take(Batch& out) {
  out.clear();
  std::lock_guard lock(mu_);
  std::swap(out, pending_);
  return closed_;
}

// ---- LcmHub ----

LcmHub::LcmHub(std::string url) : url_(std::move(url)) {
  if (url_.empty()) {
    if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) url_ = env;
  }
}

LcmHub::~LcmHub() { stop(); }

lcm::LCM& LcmHub::open() {
  std::lock_guard lock(open_mu_);
  if (!lcm_) {
    const std::string shown = url_.empty() ? std::string("(LCM's default)") : url_;
    if (const std::string why = lcm_url_problem(url_); !why.empty())
      throw std::runtime_error("cannot open LCM URL '" + shown + "': " + why);
    auto l = std::make_unique<lcm::LCM>(url_);
    if (!l->good()) throw std::runtime_error("cannot open LCM URL '" + shown + "'");
    lcm_ = std::move(l);
    lcm_ptr_.store(lcm_.get());
  }
  return *lcm_;
}

lcm::LCM* LcmHub::get() { return lcm_ptr_.load(); }

void LcmHub::add(std::shared_ptr<JobStream> stream) {
  open();
  std::lock_guard lock(mu_);
  if (!thread_.joinable() && !stopping_) thread_ = std::thread([this] { loop(); });
  streams_.push_back(std::move(stream));
  cv_.notify_one();
}

void LcmHub::stop() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void LcmHub::loop() {
  JobStream::Batch batch;
  std::vector<std::shared_ptr<JobStream>> current;
  while (true) {
    bool stopping = false;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return !streams_.empty() || stopping_; });
      stopping = stopping_;
      current = streams_;
    }
    std::vector<JobStream*> finished;
    for (auto& s : current) {
      const bool closed = s->take(batch);
      // With the stream's first messages (before its first state), then at most once a second with the
      // messages that follow, so never after its last one.
      if (!batch.records.empty()) describe(*s);
      drain(*s, batch);
      // close() comes after the last push, so a closed stream has nothing left once taken.
      if (closed) finished.push_back(s.get());
    }
    if (!finished.empty()) {
      std::lock_guard lock(mu_);
      std::erase_if(streams_, [&](const std::shared_ptr<JobStream>& s) {
        return std::find(finished.begin(), finished.end(), s.get()) != finished.end();
      });
    }
    current.clear();
    if (stopping) {
      std::lock_guard lock(mu_);
      for (auto& s : streams_) {
        s->take(batch);
        if (!batch.records.empty()) describe(*s);
        drain(*s, batch);
      }
      streams_.clear();
      return;
    }
    // Publish about once a millisecond: a paced (realtime) viewer sees states within a millisecond of
    // their wall-clock time, and a fast job's states go out in batches.
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, std::chrono::milliseconds(1), [&] { return stopping_; });
  }
}

void LcmHub::describe(JobStream& s) {
  const auto now = std::chrono::steady_clock::now();
  if (s.described_at_ != std::chrono::steady_clock::time_point{} && now - s.described_at_ < std::chrono::seconds(1)) return;
  lcm::LCM* l = get();
  if (!l) return;
  s.described_at_ = now;
  const StreamDescription& d = s.description();
  moreau::description_t m;
  m.utime = utime_now();
  m.job_id = s.job_id();
  m.scene = d.scene;
  m.system = d.system;
  m.n = s.n();
  m.q_names = d.q_names;
  m.v_names = d.v_names;
  m.q_names.resize(static_cast<std::size_t>(s.n()));  // the message's arrays have n entries
  m.v_names.resize(static_cast<std::size_t>(s.n()));
  m.energy = d.energy;
  m.t0 = d.t0;
  m.t_end = d.t_end;
  m.period = s.settings().period;
  m.state_channel = s.settings().state_channel;
  m.event_channel = s.settings().event_channel;
  m.m = static_cast<std::int32_t>(d.signal_names.size());
  m.signal_names = d.signal_names;
  const int size = m.getEncodedSize();
  buffer_.resize(static_cast<std::size_t>(size));
  m.encode(buffer_.data(), 0, size);
  if (l->publish(s.settings().description_channel, buffer_.data(), static_cast<unsigned>(size)) == 0) published_.fetch_add(1);
}

void LcmHub::drain(JobStream& s, JobStream::Batch& batch) {
  if (batch.records.empty()) return;
  lcm::LCM* l = get();
  if (!l) return;
  dropped_.fetch_add(static_cast<std::uint64_t>(s.dropped_.exchange(0)));
  moreau::state_t state;
  state.job_id = s.job_id();
  state.n = s.n();
  state.m = s.m_;
  moreau::job_event_t event;
  event.job_id = s.job_id();
  const std::size_t n = static_cast<std::size_t>(s.n());
  std::size_t qv_at = 0;
  // utime: when the message is published (within a millisecond of the state for a realtime stream).
  const std::int64_t now = utime_now();
  for (const auto& r : batch.records) {
    int size = 0;
    const std::string* channel = nullptr;
    if (r.event < 0) {
      state.utime = now;
      state.step = r.step;
      state.t = r.t;
      state.h = r.h;
      state.energy = r.energy;
      state.q.assign(batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at), batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at + n));
      state.v.assign(batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at + n),
                     batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at + 2 * n));
      state.signals.assign(batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at + 2 * n),
                           batch.qv.begin() + static_cast<std::ptrdiff_t>(qv_at + 2 * n + static_cast<std::size_t>(s.m_)));
      qv_at += 2 * n + static_cast<std::size_t>(s.m_);
      size = state.getEncodedSize();
      buffer_.resize(static_cast<std::size_t>(size));
      state.encode(buffer_.data(), 0, size);
      channel = &s.settings().state_channel;
    } else {
      const auto& e = batch.events[static_cast<std::size_t>(r.event)];
      event.utime = now;
      event.kind = e.kind;
      event.step = r.step;
      event.t = r.t;
      event.text = e.text;
      size = event.getEncodedSize();
      buffer_.resize(static_cast<std::size_t>(size));
      event.encode(buffer_.data(), 0, size);
      channel = &s.settings().event_channel;
    }
    if (l->publish(*channel, buffer_.data(), static_cast<unsigned>(size)) == 0) published_.fetch_add(1);
  }
  batch.clear();
}

// ---- StreamObserver ----

StreamObserver::StreamObserver(std::shared_ptr<JobStream> stream, double t0, const std::atomic<bool>* cancel)
    : stream_(std::move(stream)),
      t0_(t0),
      period_(stream_->settings().period),
      realtime_(stream_->settings().realtime),
      cancel_(cancel),
      next_t_(t0),
      wall_start_(std::chrono::steady_clock::now()) {}

void StreamObserver::publish_and_advance(const Sample& s) {
  // A state is due at the first sample and at each multiple of the period; impacts since the last sample
  // go out with any sample.
  const bool state_due = !any_ || s.t >= next_t_ - 1e-9 * period_;
  if (realtime_) {
    // Sleep in short slices so that a cancellation is seen within a few milliseconds.
    const auto target =
        wall_start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s.t - t0_));
    while (!(cancel_ && cancel_->load(std::memory_order_relaxed))) {
      const auto now = std::chrono::steady_clock::now();
      if (now >= target) break;
      std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(target - now, std::chrono::milliseconds(5)));
    }
  }
  // A cancelled run publishes nothing more: without this, a paced stream woken by the cancellation
  // would publish its remaining states unpaced until the run reaches its next cancellation check.
  if (cancel_ && cancel_->load(std::memory_order_relaxed)) return;
  for (HeldEvent& e : held_) {
    if (e.kind == HeldEvent::Kind::kConverged) announced_rest_ = e.rest_from;
    if (e.kind == HeldEvent::Kind::kConvergenceWithdrawn) announced_rest_.reset();
    stream_->push_event(e.name(), e.step, e.t, std::move(e.text));
  }
  held_.clear();
  if (impacts_seen_ > kMaxImpactEvents && !truncation_said_) {
    truncation_said_ = true;
    stream_->push_event("impacts_truncated", s.step, s.t,
                        "this stream publishes the first " + std::to_string(kMaxImpactEvents) +
                            " impacts; the report counts them all (contacts.impact_count)");
  }
  if (!state_due) return;
  any_ = true;
  // The next multiple of the period after t (robust to steps that do not divide the period).
  next_t_ = t0_ + period_ * (std::floor((s.t - t0_) / period_ + 1e-9) + 1.0);
  stream_->push_state(s.step, s.t, s.h, s.q, s.v, s.kinetic_energy, s.signals);
  last_published_step_ = s.step;
}

void StreamObserver::on_impact(const ImpactEvent& e) {
  if (++impacts_seen_ > kMaxImpactEvents) return;
  // key=value pairs: a line to read, and fields to parse (docs/streaming.md).
  using platform::shortest;
  const std::string text = "contact=" + std::to_string(e.constraint) + " pre=" + shortest(e.pre) + " post=" + shortest(e.post) +
                           " restitution=" + shortest(e.restitution) + " impulse=" + shortest(e.impulse);
  held_.push_back({HeldEvent::Kind::kImpact, e.step, e.t, text, std::nullopt});
}

void StreamObserver::on_rest_detected(std::int64_t from_step, double from_t, std::int64_t step, double t) {
  const std::string text = "v == 0.0 exactly from step " + std::to_string(from_step) + " (t = " + platform::shortest(from_t) +
                           "), detected at step " + std::to_string(step) + " (t = " + platform::shortest(t) + ") after " +
                           std::to_string(step - from_step) +
                           " steps at rest; final if the rest lasts to the end and the final state is an equilibrium of the "
                           "scheme, else a convergence_withdrawn event follows";
  held_.push_back({HeldEvent::Kind::kConverged, from_step, from_t, text, from_step});
}

void StreamObserver::on_rest_ended(std::int64_t from_step, std::int64_t step, double t) {
  const std::string text = "v != 0 at step " + std::to_string(step) + " (t = " + platform::shortest(t) + "): the rest from step " +
                           std::to_string(from_step) + " ended, the run is no longer converged";
  held_.push_back({HeldEvent::Kind::kConvergenceWithdrawn, step, t, text, std::nullopt});
}

void StreamObserver::flush_last(const RunSummary& summary) {
  const auto n = static_cast<std::size_t>(stream_->n());
  // A failed run's summary has no energy for its last state: the last periodic state stands.
  if (summary.status == RunStatus::kFailed || summary.status == RunStatus::kCancelled) return;
  if (summary.steps == last_published_step_ || summary.q_final.size() != n || summary.v_final.size() != n) return;
  if (last_signals_.size() != stream_->description().signal_names.size()) return;  // no sample of the run seen
  stream_->push_state(summary.steps, summary.t_final, last_h_, summary.q_final.data(), summary.v_final.data(), summary.energy_final,
                      last_signals_.data());
  last_published_step_ = summary.steps;
}

}  // namespace moreau::server
