// The run bookkeeping every scheme shares (core/include/moreau/core/stepping_driver.h): convergence is
// announced to the observer when the rest reaches the report's window of RunSummary::kMinRestSteps steps,
// withdrawn if the velocity leaves 0.0 again, and the announcements agree with the summary's converged step;
// and ObserverFan (core/observer.h), which hands a run's events to several observers.
#include "moreau/core/stepping_driver.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "moreau/core/abl_integrator.h"
#include "moreau/core/models/oscillator1.h"

namespace moreau {
namespace {

// The rest announcements, with how many samples the observer had seen when each came.
struct RestLog : RunObserver {
  struct Entry {
    bool detected;
    std::int64_t from_step, step;
    double from_t, t;
    std::size_t samples_seen;
  };
  std::vector<Entry> entries;
  std::size_t samples = 0;
  void on_sample(const Sample&) override { ++samples; }
  void on_rest_detected(std::int64_t from_step, double from_t, std::int64_t step, double t) override {
    entries.push_back({true, from_step, step, from_t, t, samples});
  }
  void on_rest_ended(std::int64_t from_step, std::int64_t step, double t) override {
    entries.push_back({false, from_step, step, 0.0, t, samples});
  }
};

// Drives a RunRecorder through steps 1..rest.size()-1 with the given rest flags (rest[0]: the initial
// state), t_k = k / 100, and returns the summary of the run ending at the last step.
RunSummary drive(RunRecorder& rec, const std::vector<bool>& rest) {
  const double x = 0.0;
  const auto state = [](bool at_rest) { return at_rest ? RestState::kAtRest : RestState::kMoving; };
  rec.start(0.0, 0.0, state(rest[0]));
  rec.first_sample(0.0, 0.01, &x, &x, 0.0);
  const auto n = static_cast<std::int64_t>(rest.size()) - 1;
  for (std::int64_t k = 1; k <= n; ++k) {
    rec.step_taken(0.01);
    rec.rest(state(rest[static_cast<std::size_t>(k)]), k, k / 100.0);
    rec.after_step(k, k / 100.0, 0.01, &x, &x, 0.0, 0.0);
  }
  rec.last_sample(n, n / 100.0, 0.01, &x, &x, 0.0, 0.0);
  rec.finish(n, n / 100.0, &x, &x, 0.0);
  return rec.close();
}

std::vector<bool> flags(std::initializer_list<std::pair<int, bool>> runs) {
  std::vector<bool> v;
  for (auto [count, value] : runs) v.insert(v.end(), static_cast<std::size_t>(count), value);
  return v;
}

// RestTracker against the definitions in stepping_driver.h: the solver's statement decides when it is
// given; otherwise 0.0 is a rest unless reached through the subnormal numbers, and any state below the
// smallest normal double that the law does not hold is kBelowNormal.
TEST(RestTracker, ASolversStatementOrAZeroNotReachedByUnderflow) {
  const double tiny = std::numeric_limits<double>::denorm_min(), min_normal = std::numeric_limits<double>::min();
  RestTracker by_values;
  EXPECT_EQ(by_values.update(Vec<2>(1.0, 0.0)), RestState::kMoving);
  EXPECT_EQ(by_values.update(Vec<2>(0.0, 0.0)), RestState::kAtRest);  // a jump to exactly 0.0
  EXPECT_EQ(by_values.update(Vec<2>(0.5 * min_normal, 0.0)), RestState::kBelowNormal);
  EXPECT_EQ(by_values.update(Vec<2>(0.0, 0.0)), RestState::kBelowNormal);  // 0.0 by underflow
  EXPECT_EQ(by_values.update(Vec<2>(min_normal, 0.0)), RestState::kMoving);
  RestTracker by_solver;
  EXPECT_EQ(by_solver.update(Vec<1>(0.0), true), RestState::kAtRest);
  EXPECT_EQ(by_solver.update(Vec<1>(0.0), false), RestState::kBelowNormal);  // 0.0, but the law does not hold it
  EXPECT_EQ(by_solver.update(Vec<1>(tiny), false), RestState::kBelowNormal);
  EXPECT_EQ(by_solver.update(Vec<1>(1e-300), false), RestState::kMoving);
}

// A grid TimeGrid::is_valid refuses ends the run at its start with the reason, whatever the scheme.
TEST(TimeGrid, AnInvalidGridFailsTheRunWithItsReason) {
  std::string why;
  TimeGrid grid;
  EXPECT_TRUE(grid.is_valid(&why));
  grid.output_every = 0;
  EXPECT_FALSE(grid.is_valid(&why));
  EXPECT_EQ(why, "output_every must be >= 1");
  models::Oscillator1 model(1.0, 0.0, 0.0, 1.0, 1.0);
  AblSettings settings;
  settings.t_end = settings.t0;
  AblIntegrator<models::Oscillator1> integrator(model, settings);
  const RunSummary s = integrator.run(Vec<1>(0.0), Vec<1>(1.0));
  EXPECT_EQ(s.status, RunStatus::kFailed);
  EXPECT_NE(s.message.find("invalid time grid: t_end must be > t0"), std::string::npos) << s.message;
}

TEST(RunRecorder, AnnouncesRestAtTheReportsWindowAndWithdrawsItWhenItEnds) {
  constexpr std::int64_t W = RunSummary::kMinRestSteps;
  // Steps 0-4 moving, 5-20 at rest, 21 moving, 22-24 at rest (shorter than the window), 25 moving,
  // 26 to the end at rest.
  const std::vector<bool> rest = flags({{5, false}, {16, true}, {1, false}, {3, true}, {1, false}, {30, true}});
  RestLog log;
  RunRecorder rec(&log, 1, 1);
  const RunSummary s = drive(rec, rest);
  ASSERT_EQ(log.entries.size(), 3u);
  // The rest from step 5 is announced at step 5 + W, before that step's sample (samples 0 .. 4 + W seen).
  EXPECT_TRUE(log.entries[0].detected);
  EXPECT_EQ(log.entries[0].from_step, 5);
  EXPECT_DOUBLE_EQ(log.entries[0].from_t, 0.05);
  EXPECT_EQ(log.entries[0].step, 5 + W);
  EXPECT_EQ(log.entries[0].samples_seen, static_cast<std::size_t>(5 + W));
  // It ends at step 21.
  EXPECT_FALSE(log.entries[1].detected);
  EXPECT_EQ(log.entries[1].from_step, 5);
  EXPECT_EQ(log.entries[1].step, 21);
  EXPECT_DOUBLE_EQ(log.entries[1].t, 0.21);
  // The three steps from 22 are never announced; the final rest from 26 is, and it is the summary's.
  EXPECT_TRUE(log.entries[2].detected);
  EXPECT_EQ(log.entries[2].from_step, 26);
  EXPECT_EQ(log.entries[2].step, 26 + W);
  ASSERT_TRUE(s.converged_step.has_value());
  EXPECT_EQ(*s.converged_step, 26);
  EXPECT_DOUBLE_EQ(*s.converged_time, 0.26);
}

// The samples' numbers (Sample::index) when only the first and the last state are recorded: output_every
// = INT64_MAX, as a study's runs ask, with and without an observer that wants every 4th sample. Reference:
// the definition in observer.h, 0 for the first and ceil(k / output_every) = 1 for the last. (The number of
// the last was once (k + output_every - 1) / output_every, a signed overflow for this output_every.)
TEST(RunRecorder, OnlyTheFirstAndLastStatesWhenOutputEveryIsTheLargestCount) {
  struct Indices : RunObserver {
    std::int64_t stride = 1;
    std::vector<std::pair<std::int64_t, std::int64_t>> seen;  // (step, index)
    void on_sample(const Sample& s) override { seen.emplace_back(s.step, s.index); }
    std::int64_t sample_stride() const override { return stride; }
  };
  for (std::int64_t stride : {1, 4}) {
    Indices log;
    log.stride = stride;
    RunRecorder rec(&log, std::numeric_limits<std::int64_t>::max(), 1);
    drive(rec, std::vector<bool>(601, false));
    ASSERT_EQ(log.seen.size(), 2u) << "stride " << stride;
    EXPECT_EQ(log.seen[0], std::make_pair(std::int64_t{0}, std::int64_t{0}));
    EXPECT_EQ(log.seen[1], std::make_pair(std::int64_t{600}, std::int64_t{1}));
  }
  // An ordinary decimation, for comparison: every 7th of 600 steps, the last (600 = 85 * 7 + 5) numbered 86.
  Indices log;
  RunRecorder rec(&log, 7, 1);
  drive(rec, std::vector<bool>(601, false));
  ASSERT_EQ(log.seen.size(), 87u);
  EXPECT_EQ(log.seen[85], std::make_pair(std::int64_t{595}, std::int64_t{85}));
  EXPECT_EQ(log.seen[86], std::make_pair(std::int64_t{600}, std::int64_t{86}));
}

TEST(RunRecorder, ARestShorterThanTheWindowIsNeitherAnnouncedNorConverged) {
  constexpr auto W = static_cast<int>(RunSummary::kMinRestSteps);
  RestLog log;
  RunRecorder rec(&log, 1, 1);
  // At rest for the last W - 1 steps: the summary's window is not reached, and nothing was announced.
  const RunSummary s = drive(rec, flags({{10, false}, {W - 1, true}}));
  EXPECT_TRUE(log.entries.empty());
  EXPECT_FALSE(s.converged_step.has_value());
  ASSERT_TRUE(s.rest_step.has_value());
  EXPECT_EQ(*s.rest_step, 10);
  // Exactly W steps: announced at the last step, and converged.
  RestLog log2;
  RunRecorder rec2(&log2, 1, 1);
  const RunSummary s2 = drive(rec2, flags({{10, false}, {W + 1, true}}));
  ASSERT_EQ(log2.entries.size(), 1u);
  EXPECT_EQ(log2.entries[0].step, 10 + W);
  ASSERT_TRUE(s2.converged_step.has_value());
  EXPECT_EQ(*s2.converged_step, 10);
}

TEST(RunRecorder, AStateAtRestFromTheStartIsAnnouncedAfterTheWindow) {
  RestLog log;
  RunRecorder rec(&log, 1, 1);
  const RunSummary s = drive(rec, flags({{40, true}}));
  ASSERT_EQ(log.entries.size(), 1u);
  EXPECT_EQ(log.entries[0].from_step, 0);
  EXPECT_EQ(log.entries[0].step, RunSummary::kMinRestSteps);
  ASSERT_TRUE(s.converged_step.has_value());
  EXPECT_EQ(*s.converged_step, 0);
}

// In a real run of the scheme (0.2): the damped relay m v' = -c v - a Sign(v) stops in finitely many
// steps; the announcement comes during the run, at the summary's converged step plus the window, with
// the samples up to then (one per step) and not the rest of the run seen by the observer.
TEST(RunRecorder, AblRunAnnouncesConvergenceWhenItIsDetected) {
  const double m = 2.0, c = 0.5, a = 1.0, v0 = 3.0, h = 1e-3;
  models::Oscillator1 model(m, 0.0, 0.0, c, a);
  AblSettings settings;
  settings.h = h;
  settings.t_end = 8.0;
  RestLog log;
  AblIntegrator<models::Oscillator1> integrator(model, settings);
  const RunSummary s = integrator.run(Vec<1>(0.0), Vec<1>(v0), &log);
  ASSERT_TRUE(s.converged_step.has_value());
  ASSERT_EQ(log.entries.size(), 1u);
  const auto& e = log.entries[0];
  EXPECT_TRUE(e.detected);
  EXPECT_EQ(e.from_step, *s.converged_step);
  EXPECT_EQ(e.from_t, *s.converged_time);
  EXPECT_EQ(e.step, *s.converged_step + RunSummary::kMinRestSteps);
  EXPECT_EQ(e.samples_seen, static_cast<std::size_t>(e.step));
  EXPECT_LT(e.samples_seen, log.samples / 2) << "the relay stops at t* = (m/c) ln(1 + c v0 / a) = 3.67 of 8";
  EXPECT_EQ(log.samples, static_cast<std::size_t>(s.steps) + 1);
}

// RunObserver::sample_stride: an observer that needs every 4th recorded state sees exactly those (by
// Sample::index) and the last, out of the states an observer of every one sees; the numbers are the
// recorded states' own, k / output_every, and the last one's ceil(k / output_every). Checked against
// the definition: recorded states are steps 0, e, 2e, ... and the last step, numbered in order.
TEST(RunRecorder, SampleStrideHandsOutEveryKthRecordedStateAndTheLast) {
  struct Log : RunObserver {
    std::int64_t stride = 1;
    std::vector<std::pair<std::int64_t, std::int64_t>> seen;  // (step, index)
    void on_sample(const Sample& s) override { seen.emplace_back(s.step, s.index); }
    std::int64_t sample_stride() const override { return stride; }
  };
  for (std::int64_t every : {1, 3, 7}) {
    for (std::int64_t steps : {96, 100, 101}) {  // the last step a multiple of every * 4, or of neither
      Log all, fourth;
      fourth.stride = 4;
      for (Log* log : {&all, &fourth}) {
        RunRecorder rec(log, every, 1);
        const double x = 0.0;
        rec.first_sample(0.0, 0.01, &x, &x, 0.0);
        for (std::int64_t k = 1; k <= steps; ++k) rec.after_step(k, k / 100.0, 0.01, &x, &x, 0.0, 0.0);
        rec.last_sample(steps, steps / 100.0, 0.01, &x, &x, 0.0, 0.0);
      }
      std::vector<std::pair<std::int64_t, std::int64_t>> expected_all, expected_fourth;
      std::int64_t number = 0;
      for (std::int64_t k = 0; k <= steps; ++k) {
        if (k % every != 0 && k != steps) continue;
        expected_all.emplace_back(k, number);
        if (number % 4 == 0 || k == steps) expected_fourth.emplace_back(k, number);
        ++number;
      }
      EXPECT_EQ(all.seen, expected_all) << "every " << every << ", " << steps << " steps";
      EXPECT_EQ(fourth.seen, expected_fourth) << "every " << every << ", " << steps << " steps";
    }
  }
  // What a chain and a fan ask for: the states every member needs.
  Log one, four, six;
  four.stride = 4;
  six.stride = 6;
  ObserverFan fan;
  fan.add(&four);
  fan.add(&six);
  EXPECT_EQ(fan.sample_stride(), 2);
  fan.add(&one);
  EXPECT_EQ(fan.sample_stride(), 1);
  EXPECT_EQ(ObserverFan().sample_stride(), 1);
  EXPECT_EQ(ForwardingObserver(&six).sample_stride(), 6);
}

// ObserverFan (core/observer.h): every observer added sees every event of the run, the same as alone.
TEST(ObserverFan, EachObserverSeesWhatItWouldSeeAlone) {
  models::Oscillator1 model(2.0, 0.0, 0.0, 0.5, 1.0);
  AblSettings settings;
  settings.h = 1e-3;
  settings.t_end = 8.0;
  RestLog alone;
  AblIntegrator<models::Oscillator1>(model, settings).run(Vec<1>(0.0), Vec<1>(3.0), &alone);
  ASSERT_EQ(alone.entries.size(), 1u);  // the relay comes to rest once: there is something to pass on

  RestLog first, second;
  ObserverFan fan;
  fan.add(&first);
  fan.add(nullptr);  // ignored
  fan.add(&second);
  AblIntegrator<models::Oscillator1>(model, settings).run(Vec<1>(0.0), Vec<1>(3.0), &fan);
  for (const RestLog* log : {&first, &second}) {
    EXPECT_EQ(log->samples, alone.samples);
    ASSERT_EQ(log->entries.size(), alone.entries.size());
    EXPECT_EQ(log->entries[0].from_step, alone.entries[0].from_step);
    EXPECT_EQ(log->entries[0].step, alone.entries[0].step);
    EXPECT_EQ(log->entries[0].samples_seen, alone.entries[0].samples_seen);
  }
}

// The run stops at the first control point where any observer says stop, and every observer is asked
// at every control point (none is skipped because another already said stop).
TEST(ObserverFan, StopsWhenAnyObserverAsksAndAsksThemAll) {
  struct Stopper : RunObserver {
    std::int64_t stop_at;
    int asked = 0;
    explicit Stopper(std::int64_t at) : stop_at(at) {}
    void on_sample(const Sample&) override {}
    bool keep_going(std::int64_t step, double) override {
      ++asked;
      return step < stop_at;
    }
  };
  models::Oscillator1 model(2.0, 0.0, 0.0, 0.5, 1.0);
  AblSettings settings;
  settings.h = 1e-3;
  settings.t_end = 8.0;
  Stopper early(2 * RunObserver::kControlInterval), never(1 << 30);
  ObserverFan fan;
  fan.add(&early);
  fan.add(&never);
  const RunSummary s = AblIntegrator<models::Oscillator1>(model, settings).run(Vec<1>(0.0), Vec<1>(3.0), &fan);
  EXPECT_EQ(s.status, RunStatus::kCancelled);
  EXPECT_EQ(s.steps, 2 * RunObserver::kControlInterval);
  EXPECT_EQ(early.asked, 2);
  EXPECT_EQ(never.asked, 2);
}

}  // namespace
}  // namespace moreau
