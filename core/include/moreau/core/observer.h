// How a run hands its states out without knowing where they go (recorder, CSV writer, LCM publisher,
// progress bar, cancellation). The integrator calls on_sample() only every `output_every` steps (and at
// the first and last state), or only every sample_stride()-th of these recorded states where the
// observer asks for fewer, keep_going() every kControlInterval steps, on_impact() once per impact and
// on_rest_detected()/on_rest_ended() once per rest: the hot loop never makes a virtual call per step.
#pragma once

#include <cstdint>
#include <numeric>
#include <vector>

namespace moreau {

struct ImpactEvent;  // run_diagnostics.h

struct Sample {
  std::int64_t step;      // k
  double t;               // t_k
  double h;               // the step that led to this state, t_k - t_{k-1} (step 0: the nominal h)
  int n;                  // degrees of freedom
  const double* q;        // Q^k, n values
  const double* v;        // V^k, n values
  double kinetic_energy;  // E_k = 1/2 <M(Q^k) V^k, V^k>
  // D_k = sum_{j < k} h_j <xi_j, V^{j+1}>, xi_j in dPhi(V^{j+1}): the work done so far against the
  // set-valued controller and friction (RunSummary::dissipated_work); 0 where the scheme does not track it.
  double dissipated_work = 0.0;
  // The recorded state's number: 0 for the first, k / output_every for a state recorded at step k, and
  // one more than the one before it for the last state when it falls between (ceil(k / output_every)).
  // An observer with a sample_stride() above 1 sees only the numbers that are multiples of it, and the last.
  std::int64_t index = 0;
  // What a scheme computes beside the state, named by the run (a tracking run: q_d, e, sigma and u per
  // coordinate, Simulation::signal_names); none for most schemes.
  int m = 0;
  const double* signals = nullptr;
};

class RunObserver {
 public:
  // 256 steps take at most about 15 ms even at n = 64 coordinates (56 us per step), so a cancellation
  // is seen within 50 ms of wall time; one virtual call per 256 steps costs nothing measurable.
  static constexpr std::int64_t kControlInterval = 256;
  virtual ~RunObserver() = default;
  virtual void on_sample(const Sample& sample) = 0;
  // Which recorded states this observer needs: those whose Sample::index is a multiple of the stride, and
  // the last (asked once, when the run starts). An observer that checks only every kth recorded state and
  // passes nothing on says k, and the run skips the virtual call for the others: a JSON scene run with no
  // output would otherwise pay one call per step for its sampled checks.
  virtual std::int64_t sample_stride() const { return 1; }
  // Return false to cancel the run (it then ends with RunStatus::kCancelled).
  virtual bool keep_going(std::int64_t /*step*/, double /*t*/) { return true; }
  // An impact of a unilateral contact (the Moreau-Jean scheme): called from the integrating thread for
  // every impacting contact, in the step that carries it, before that step's sample; also beyond the
  // ContactDiagnostics' record limit. Impacts are rare: a virtual call each costs nothing per step.
  virtual void on_impact(const ImpactEvent& /*impact*/) {}
  // Convergence as it is detected (RunRecorder::rest): the velocity has been exactly 0.0 from step
  // `from_step` (time from_t) through step `step` (time t), RunSummary::kMinRestSteps steps, the window the
  // report's definition of converged asks for. The report counts the run as converged only if this rest
  // lasts to the end and the final state passes the scheme's equilibrium test, so the detection is
  // provisional: on_rest_ended() follows if the velocity leaves 0.0 again. Each is called at most once per
  // rest, from the integrating thread: no virtual call per step.
  virtual void on_rest_detected(std::int64_t /*from_step*/, double /*from_t*/, std::int64_t /*step*/, double /*t*/) {}
  // A rest announced by on_rest_detected() ended: the velocity is nonzero at step `step` (time t).
  virtual void on_rest_ended(std::int64_t /*from_step*/, std::int64_t /*step*/, double /*t*/) {}
};

// An observer that passes every event on to `next` (which may be null): one that acts on some events
// derives from it and overrides only those, so that an event added to RunObserver reaches `next`
// without every forwarding observer having to learn it.
class ForwardingObserver : public RunObserver {
 public:
  explicit ForwardingObserver(RunObserver* next) : next_(next) {}
  void on_sample(const Sample& sample) override {
    if (next_) next_->on_sample(sample);
  }
  bool keep_going(std::int64_t step, double t) override { return !next_ || next_->keep_going(step, t); }
  // Forwarding alone needs what `next` needs; none when there is no next.
  std::int64_t sample_stride() const override { return next_ ? next_->sample_stride() : 1; }
  void on_impact(const ImpactEvent& impact) override {
    if (next_) next_->on_impact(impact);
  }
  void on_rest_detected(std::int64_t from_step, double from_t, std::int64_t step, double t) override {
    if (next_) next_->on_rest_detected(from_step, from_t, step, t);
  }
  void on_rest_ended(std::int64_t from_step, std::int64_t step, double t) override {
    if (next_) next_->on_rest_ended(from_step, step, t);
  }

 protected:
  RunObserver* next() const { return next_; }

 private:
  RunObserver* next_;
};

// Runs several observers as one: each event goes to every observer added, in the order added; the run
// goes on while all of them say keep_going (each is asked, so each sees the control point).
class ObserverFan : public RunObserver {
 public:
  void add(RunObserver* o) {
    if (o) observers_.push_back(o);
  }
  void on_sample(const Sample& s) override {
    for (auto* o : observers_) o->on_sample(s);
  }
  // Every state any of them needs.
  std::int64_t sample_stride() const override {
    std::int64_t stride = 0;
    for (auto* o : observers_) stride = std::gcd(stride, o->sample_stride());
    return stride > 0 ? stride : 1;
  }
  bool keep_going(std::int64_t step, double t) override {
    bool go = true;
    for (auto* o : observers_) go = o->keep_going(step, t) && go;
    return go;
  }
  void on_impact(const ImpactEvent& e) override {
    for (auto* o : observers_) o->on_impact(e);
  }
  void on_rest_detected(std::int64_t from_step, double from_t, std::int64_t step, double t) override {
    for (auto* o : observers_) o->on_rest_detected(from_step, from_t, step, t);
  }
  void on_rest_ended(std::int64_t from_step, std::int64_t step, double t) override {
    for (auto* o : observers_) o->on_rest_ended(from_step, step, t);
  }

 private:
  std::vector<RunObserver*> observers_;
};

}  // namespace moreau
