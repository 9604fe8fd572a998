// Live state over LCM. A job's worker thread never publishes: its observer appends the states it
// wants to send (one per simulation-time period) to the job's JobStream, which costs a lock and a copy
// of 2n + 4 numbers, and one hub thread per server encodes and publishes them. The integrator thus
// pays almost nothing for streaming (docs/streaming.md has the measured overhead).
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "moreau/core/observer.h"
#include "moreau/core/run_diagnostics.h"
#include "moreau/core/run_summary.h"

namespace lcm {
class LCM;
}

namespace moreau::server {

struct StreamSettings {
  bool enabled = false;
  std::string prefix = "MOREAU";  // channels: <prefix>_STATE_<ID>, <prefix>_EVENT_<ID>, <prefix>_DESC_<ID>
  double period = 1.0 / 64.0;     // simulation seconds between published states
  bool realtime = false;          // pace the job so that simulation time follows wall-clock time
  std::string state_channel, event_channel, description_channel;
};

// What the job's states hold (published as moreau::description_t): names, kind of system, energy.
struct StreamDescription {
  std::string scene, system, energy;
  std::vector<std::string> q_names, v_names;
  double t0 = 0, t_end = 0;
  std::vector<std::string> signal_names;  // Sample::signals, when the scheme has them
};

// "MOREAU_STATE_" + the job id in upper case, and the event and description channels likewise.
void set_channels(StreamSettings& s, const std::string& job_id);

// Microseconds since the Unix epoch.
std::int64_t utime_now();

// The messages of one job, in order, waiting for the hub thread. States are gathered in a buffer of
// the producer's own and handed over in batches (one lock per batch); events, and every state of a
// realtime stream, are handed over at once.
class JobStream {
 public:
  JobStream(std::string job_id, StreamSettings settings, int n, StreamDescription description = {});
  ~JobStream();
  // signals: description().signal_names.size() values (none: nullptr).
  void push_state(std::int64_t step, double t, double h, const double* q, const double* v, double energy, const double* signals);
  void push_event(const char* kind, std::int64_t step, double t, std::string text);
  // Hands the states gathered so far to the hub.
  void flush();
  // No more messages will be pushed: the hub publishes what is left and forgets the stream.
  void close();

  const std::string& job_id() const { return job_id_; }
  const StreamSettings& settings() const { return settings_; }
  const StreamDescription& description() const { return description_; }
  int n() const { return n_; }

 private:
  friend class LcmHub;
  struct Record {
    std::int64_t step;
    double t, h, energy;
    std::int32_t event;  // index into events_, or -1 for a state (values in qv_)
  };
  struct Event {
    std::string kind, text;
  };
  struct Batch {
    std::vector<Record> records;
    std::vector<double> qv;  // 2n + m per state record, in order (q, v, the signals)
    std::vector<Event> events;
    void clear() {
      records.clear();
      qv.clear();
      events.clear();
    }
  };
  // Swaps the pending batch into `out` (cleared first); returns whether the stream is closed.
  bool take(Batch& out);

  static constexpr std::size_t kMaxPending = 1 << 18;  // states held at most; beyond, new ones are dropped
  static constexpr std::size_t kBatch = 64;            // states gathered before they are handed over

  std::string job_id_;
  StreamSettings settings_;
  int n_;
  StreamDescription description_;
  int m_;  // signals per state
  // The hub's own: when it last published the description (never: the epoch).
  std::chrono::steady_clock::time_point described_at_{};
  // The producer's buffer and the shared one on separate cache lines.
  alignas(64) Batch local_;  // the producer's (no lock)
  alignas(64) std::mutex mu_;
  Batch pending_;
  bool closed_ = false;
  std::atomic<std::int64_t> dropped_{0};
};

// Owns the LCM instance and the thread that publishes every job's stream.
class LcmHub {
 public:
  explicit LcmHub(std::string url);  // empty: LCM_DEFAULT_URL, else LCM's default; opened lazily
  ~LcmHub();
  LcmHub(const LcmHub&) = delete;
  LcmHub& operator=(const LcmHub&) = delete;

  // Opens the LCM instance (once). Throws std::runtime_error naming the URL if LCM cannot open it.
  lcm::LCM& open();
  lcm::LCM* get();
  const std::string& url() const { return url_; }

  void add(std::shared_ptr<JobStream> stream);
  // Publishes what every stream holds and joins the thread.
  void stop();

  std::uint64_t published() const { return published_.load(); }
  std::uint64_t dropped() const { return dropped_.load(); }

 private:
  void loop();
  void drain(JobStream& s, JobStream::Batch& batch);
  // Publishes the stream's description when it has not been, or a second has passed since it last was.
  void describe(JobStream& s);

  std::string url_;
  std::mutex open_mu_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::atomic<lcm::LCM*> lcm_ptr_{nullptr};

  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::shared_ptr<JobStream>> streams_;
  bool stopping_ = false;
  std::thread thread_;
  std::vector<std::uint8_t> buffer_;
  std::atomic<std::uint64_t> published_{0}, dropped_{0};
};

// The job-side half: sees the run's samples and pushes one state per period (and the last state).
// With `realtime`, on_sample sleeps so that t - t0 follows the wall clock (waking early if `cancel`
// becomes true).
class StreamObserver final : public RunObserver {
 public:
  StreamObserver(std::shared_ptr<JobStream> stream, double t0, const std::atomic<bool>* cancel);
  // Inline: most samples fall between two publication times and cost one comparison.
  void on_sample(const Sample& s) override {
    last_h_ = s.h;
    if (s.m > 0) last_signals_.assign(s.signals, s.signals + s.m);  // a tracking run's, for the last state
    if (any_ && s.t < next_t_ - 1e-9 * period_ && held_.empty()) return;
    publish_and_advance(s);
  }
  // Events of the run are held until the next sample (the state just after them) and published before
  // that sample's state, in the order they happened: a paced stream shows each at its time.
  // An impact: an "impact" event.
  void on_impact(const ImpactEvent& impact) override;
  // Convergence detected (the report's window of rest reached): a "converged" event; and a detected rest
  // that ended: a "convergence_withdrawn" event.
  void on_rest_detected(std::int64_t from_step, double from_t, std::int64_t step, double t) override;
  void on_rest_ended(std::int64_t from_step, std::int64_t step, double t) override;
  // Impact events a stream publishes at most (a chattering contact could otherwise send one per step);
  // beyond, one "impacts_truncated" event says so.
  static constexpr std::int64_t kMaxImpactEvents = 10000;
  // The first step of the rest a published "converged" event announced and no "convergence_withdrawn"
  // took back, if any: what the run's end has to confirm or withdraw (JobRunner::commit).
  std::optional<std::int64_t> announced_rest() const { return announced_rest_; }
  // Pushes the run's last state (from its summary) if it was not published yet.
  void flush_last(const RunSummary& summary);

 private:
  void publish_and_advance(const Sample& s);
  std::shared_ptr<JobStream> stream_;
  double t0_, period_;
  bool realtime_;
  const std::atomic<bool>* cancel_;
  double next_t_;
  bool any_ = false;
  std::int64_t last_published_step_ = -1;
  std::chrono::steady_clock::time_point wall_start_;
  double last_h_ = 0;                 // the step of the last sample seen (the summary does not carry it)
  std::vector<double> last_signals_;  // likewise its signals
  struct HeldEvent {
    enum class Kind { kImpact, kConverged, kConvergenceWithdrawn };
    Kind kind;
    std::int64_t step;
    double t;
    std::string text;
    std::optional<std::int64_t> rest_from;  // kConverged: the rest it announces; otherwise none
    // The event's kind as the stream names it (docs/streaming.md).
    const char* name() const {
      switch (kind) {
        case Kind::kImpact: return "impact";
        case Kind::kConverged: return "converged";
        case Kind::kConvergenceWithdrawn: return "convergence_withdrawn";
      }
      return "unknown";
    }
  };
  std::vector<HeldEvent> held_;  // since the last sample, in order
  std::int64_t impacts_seen_ = 0;
  std::optional<std::int64_t> announced_rest_;
  bool truncation_said_ = false;
};

}  // namespace moreau::server
