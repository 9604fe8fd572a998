// Studies (see study.h). Each run is the scene's variant for a scheme and h (scene_variant), run by
// run_scene: the study builds no integrator of its own.
#include "moreau/analysis/study.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "moreau/platform/number_text.h"
#include "moreau/platform/text_columns.h"
#include "moreau/scene/guarantees.h"
#include "moreau/scene/json_number.h"
#include "moreau/scene/scene_model.h"

namespace moreau::scene {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Samples a run at the common times by linear interpolation between consecutive samples, and counts
// velocity sign changes after `chatter_from`.
class GridSampler : public RunObserver {
 public:
  GridSampler(const std::vector<double>& grid, int n, double chatter_from, const std::atomic<bool>* cancel)
      : grid_(grid),
        n_(n),
        chatter_from_(chatter_from),
        cancel_(cancel),
        q_(grid.size() * n, kNaN),
        v_(grid.size() * n, kNaN),
        prev_q_(n),
        prev_v_(n),
        last_sign_(n, 0) {}

  bool keep_going(std::int64_t, double) override { return !(cancel_ && cancel_->load(std::memory_order_relaxed)); }

  void on_sample(const Sample& s) override {
    if (have_prev_) {
      while (next_ < grid_.size() && grid_[next_] <= s.t) {
        const double g = grid_[next_];
        const double w = s.t > prev_t_ ? (g - prev_t_) / (s.t - prev_t_) : 1.0;
        for (int i = 0; i < n_; ++i) {
          q_[next_ * n_ + i] = prev_q_[i] + w * (s.q[i] - prev_q_[i]);
          v_[next_ * n_ + i] = prev_v_[i] + w * (s.v[i] - prev_v_[i]);
        }
        ++next_;
      }
    } else {
      while (next_ < grid_.size() && grid_[next_] <= s.t) {
        for (int i = 0; i < n_; ++i) {
          q_[next_ * n_ + i] = s.q[i];
          v_[next_ * n_ + i] = s.v[i];
        }
        ++next_;
      }
    }
    if (s.t > chatter_from_) {
      for (int i = 0; i < n_; ++i) {
        const int sign = s.v[i] > 0.0 ? 1 : (s.v[i] < 0.0 ? -1 : 0);
        if (sign != 0 && last_sign_[i] != 0 && sign != last_sign_[i]) ++sign_changes_;
        if (sign != 0) last_sign_[i] = sign;
        amplitude_ = std::max(amplitude_, std::abs(s.v[i]));
      }
    }
    prev_t_ = s.t;
    for (int i = 0; i < n_; ++i) {
      prev_q_[i] = s.q[i];
      prev_v_[i] = s.v[i];
    }
    have_prev_ = true;
  }

  const std::vector<double>& q() const { return q_; }
  const std::vector<double>& v() const { return v_; }
  std::int64_t sign_changes() const { return sign_changes_; }
  double amplitude() const { return amplitude_; }

 private:
  const std::vector<double>& grid_;
  int n_;
  double chatter_from_;
  const std::atomic<bool>* cancel_;
  std::vector<double> q_, v_;
  std::vector<double> prev_q_, prev_v_;
  std::vector<int> last_sign_;
  std::size_t next_ = 0;
  double prev_t_ = 0.0;
  bool have_prev_ = false;
  std::int64_t sign_changes_ = 0;
  double amplitude_ = 0.0;
};

// The observer of a timed run: sees no sample (the run samples only its first and last state) and
// checks for cancellation every RunObserver::kControlInterval steps.
class CancelCheck : public RunObserver {
 public:
  explicit CancelCheck(const std::atomic<bool>* cancel) : cancel_(cancel) {}
  void on_sample(const Sample&) override {}
  bool keep_going(std::int64_t, double) override { return !cancel_->load(std::memory_order_relaxed); }

 private:
  const std::atomic<bool>* cancel_;
};

// The scene as `scheme` integrates it at step h, with the study's regularization for the regularized peer.
LagrangianScene variant(const LagrangianScene& scene, Scheme scheme, double h, const StudySettings& st) {
  LagrangianScene at = scene_variant(scene, scheme, h);
  at.regularization = st.regularization;
  at.regularization_epsilon = st.epsilon;
  return at;
}

// output_every: 1 for the runs whose every state is sampled, a huge value for timed runs. `checked`: a
// run whose guarantees the study reports (the error runs and the reference), with the checks `moreau run`
// makes at the recorded states for the schemes whose row says so.
RunSummary run_scheme(const LagrangianScene& scene, Scheme scheme, double h, const StudySettings& st, RunObserver* observer,
                      std::int64_t output_every = 1, bool checked = false) {
  LagrangianScene at = variant(scene, scheme, h, st);
  at.settings.output_every = output_every;
  RunSummary s = run_scene(at, observer, nullptr, checked);
  if (s.status == RunStatus::kCancelled && st.cancel && st.cancel->load()) throw StudyCancelled();
  return s;
}

// The guarantees section of a study run, as `moreau run` writes it for the same scene, scheme and h;
// none for a scheme without recorded-state checks (the regularized peer, which no theorem covers).
nlohmann::json run_guarantees(const LagrangianScene& scene, Scheme scheme, double h, const RunSummary& s, const StudySettings& st) {
  if (!traits(scheme).recorded_state_checks) return nlohmann::json::array();
  return guarantees_json(lagrangian_guarantees(variant(scene, scheme, h, st), s));
}

void check_cancel(const StudySettings& st) {
  if (st.cancel && st.cancel->load()) throw StudyCancelled();
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double slope(const std::vector<double>& h, const std::vector<double>& e) {
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  int m = 0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    if (!(e[i] > 0.0) || !std::isfinite(e[i])) continue;
    const double x = std::log10(h[i]), y = std::log10(e[i]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
    ++m;
  }
  if (m < 2) return kNaN;
  const double den = m * sxx - sx * sx;
  return den == 0.0 ? kNaN : (m * sxy - sx * sy) / den;
}

nlohmann::json num(double v) { return finite_or_null(v); }

// Numbers in messages: 10 significant digits.
std::string fmt(double v) { return platform::significant(v, 10); }

// Largest --eval-points and --repeats: the bounds POST /v1/studies has (docs/api.md).
constexpr int kMaxEvalPoints = 100000;
constexpr int kMaxRepeats = 20;

std::vector<std::string> scheme_names(const std::vector<Scheme>& schemes) {
  std::vector<std::string> names;
  for (const Scheme s : schemes) names.push_back(scheme_name(s));
  return names;
}

// A scheme a study compares, by name (the table's study_compares column).
std::optional<Scheme> study_scheme_from_name(std::string_view name) {
  const std::optional<Scheme> s = scheme_from_name(name);
  if (s && traits(*s).study_compares) return s;
  return std::nullopt;
}

// "abl, explicit, regularized": the schemes a study compares, for messages.
std::string study_scheme_list() {
  std::string out;
  for (const SchemeTraits& t : all_schemes())
    if (t.study_compares) out += (out.empty() ? "" : ", ") + std::string(t.name);
  return out;
}

// A scheme name in a stored study result (StudyResult::from_json).
Scheme scheme_in(const nlohmann::json& v) {
  const std::optional<Scheme> s = study_scheme_from_name(v.get<std::string>());
  if (!s) throw std::invalid_argument("not a study result: unknown scheme " + v.dump());
  return *s;
}

}  // namespace

std::vector<Scheme> parse_study_schemes(const std::string& text) {
  std::vector<Scheme> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    if (item.empty()) continue;
    const std::optional<Scheme> s = study_scheme_from_name(item);
    if (!s) throw SceneError("--schemes", "unknown scheme '" + item + "' (expected " + study_scheme_list() + ")");
    if (std::find(out.begin(), out.end(), *s) != out.end()) throw SceneError("--schemes", "scheme '" + item + "' given twice");
    out.push_back(*s);
  }
  if (out.empty()) throw SceneError("--schemes", "expected at least one scheme");
  return out;
}

std::vector<double> parse_ladder(const std::string& text) {
  std::vector<double> out;
  auto number = [&](const std::string& s) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || *end != '\0' || !std::isfinite(v) || !(v > 0.0))
      throw SceneError("--h", "'" + s + "' is not a positive finite step size");
    return v;
  };
  if (text.find(':') != std::string::npos) {
    std::stringstream ss(text);
    std::string a, b, c;
    std::getline(ss, a, ':');
    std::getline(ss, b, ':');
    std::getline(ss, c, ':');
    const double hi = number(a), lo = number(b);
    char* end = nullptr;
    const long count = std::strtol(c.c_str(), &end, 10);
    if (c.empty() || *end != '\0' || count < 2 || count > 100)
      throw SceneError("--h", "a ladder is FIRST:LAST:COUNT with 2 <= COUNT <= 100, got '" + text + "'");
    for (long i = 0; i < count; ++i) {
      const double h = std::pow(10.0, std::log10(hi) + (std::log10(lo) - std::log10(hi)) * i / (count - 1));
      // Between two positive finite ends, but pow can round to 0 or inf at the ends of the double range.
      if (!std::isfinite(h) || !(h > 0.0))
        throw SceneError("--h", "the ladder '" + text + "' gives the step size " + fmt(h) + ", not a positive finite one");
      out.push_back(h);
    }
  } else {
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) out.push_back(number(item));
  }
  if (out.empty()) throw SceneError("--h", "empty ladder");
  return out;
}

void check_study_settings(const LagrangianScene& scene, const StudySettings& st) {
  if (!scene.constraint_names.empty())
    throw SceneError("/system/constraints", "studies compare abl, explicit and regularized, which do not integrate unilateral constraints");
  if (st.h.empty()) throw SceneError("--h", "empty ladder");
  if (st.schemes.empty()) throw SceneError("--schemes", "expected at least one scheme");
  if (st.eval_points < 2 || st.eval_points > kMaxEvalPoints)
    throw SceneError("--eval-points",
                     "must be between 2 and " + std::to_string(kMaxEvalPoints) + ", got " + std::to_string(st.eval_points));
  if (st.repeats < 1 || st.repeats > kMaxRepeats)
    throw SceneError("--repeats", "must be between 1 and " + std::to_string(kMaxRepeats) + ", got " + std::to_string(st.repeats));
  if (!(st.epsilon > 0.0) || !std::isfinite(st.epsilon))
    throw SceneError("--epsilon", "must be a positive finite number, got " + fmt(st.epsilon));
  // Every run's h as the scene's own h is checked at load: positive and finite, at least one step over
  // [t0, t_end], and a step count within /integrator/max_steps, computed in double before any integer
  // conversion (a double at or beyond 2^63 converts to int64 with undefined behaviour). A NaN h would
  // put NaN in every error of the table.
  const double t0 = scene.settings.t0, t_end = scene.settings.t_end, span = t_end - t0;
  const std::int64_t limit = scene.settings.max_steps;
  const std::string interval = "[" + fmt(t0) + ", " + fmt(t_end) + "]";
  auto check_h = [&](double h, const std::string& option, const std::string& what) {
    if (!std::isfinite(h) || !(h > 0.0)) throw SceneError(option, what + " = " + fmt(h) + " is not a positive finite step size");
    const double ratio = span / h;
    if (ratio < 1.0 - 1e-9)
      throw SceneError(option,
                       what + " = " + fmt(h) + " is longer than the interval " + interval + ": a run would not take a single step of h");
    const double steps = ratio > 9e18 ? ratio : static_cast<double>(fixed_step_count(t0, t_end, h));
    if (steps > static_cast<double>(limit))
      throw SceneError(option, what + " = " + fmt(h) + " over " + interval + " needs " + fmt(steps) + " steps, more than the limit of " +
                                   std::to_string(limit) + " (/integrator/max_steps)");
  };
  for (double h : st.h) check_h(h, "--h", "h");
  if (st.reference_h) {
    check_h(*st.reference_h, "--reference-h", "the reference h");
  } else if (!scene.exact_tape) {
    check_h(*std::min_element(st.h.begin(), st.h.end()) / 10.0, "--reference-h",
            "the scene has no exact solution, and the default reference h = min h / 10");
  }
}

StudyResult run_study(const LagrangianScene& scene, const StudySettings& st) {
  const auto start = Clock::now();
  check_study_settings(scene, st);
  const int n = scene.n;
  const double t0 = scene.settings.t0, t_end = scene.settings.t_end;
  std::vector<double> grid(static_cast<std::size_t>(st.eval_points));
  for (int j = 0; j < st.eval_points; ++j) grid[j] = j + 1 == st.eval_points ? t_end : t0 + (t_end - t0) * j / (st.eval_points - 1);

  StudyResult result;
  result.scene = scene.name;
  std::vector<double> ref_q(grid.size() * n), ref_v(grid.size() * n);
  if (scene.exact_tape && !st.reference_h) {
    result.reference = "exact solution";
    std::vector<double> slots(1 + 2 * n, 0.0), out(2 * n), scratch(scene.exact_tape->scratch_size());
    for (std::size_t j = 0; j < grid.size(); ++j) {
      slots[0] = grid[j];
      scene.exact_tape->eval(slots.data(), out.data(), scratch.data());
      for (int i = 0; i < n; ++i) {
        ref_q[j * n + i] = out[i];
        ref_v[j * n + i] = out[n + i];
      }
      // The closed form is the reference of every error: a NaN or an infinity in it would be one in
      // every row of the table.
      for (int i = 0; i < 2 * n; ++i) {
        if (!std::isfinite(out[i]))
          throw SceneError(std::string(i < n ? "/exact/q/" : "/exact/v/") + std::to_string(i % n),
                           "the exact solution is not finite at t = " + fmt(grid[j]) + " (" + fmt(out[i]) +
                               "), one of the study's common times in [t0, t_end]");
      }
    }
    result.reference_converged_time = scene.exact_rest_time;
  } else {
    const double h_ref = st.reference_h ? *st.reference_h : *std::min_element(st.h.begin(), st.h.end()) / 10.0;
    result.reference = "abl at h = " + platform::significant(h_ref, 6);
    GridSampler sampler(grid, n, std::numeric_limits<double>::infinity(), st.cancel);
    const RunSummary ref = run_scheme(scene, Scheme::kAbl, h_ref, st, &sampler, 1, true);
    if (ref.status != RunStatus::kCompleted) throw SceneError("--reference", "the reference run failed: " + ref.message);
    ref_q = sampler.q();
    ref_v = sampler.v();
    result.reference_converged_time = ref.converged_time;
    result.reference_guarantees = run_guarantees(scene, Scheme::kAbl, h_ref, ref, st);
  }
  const double chatter_from = result.reference_converged_time.value_or(std::numeric_limits<double>::infinity());

  const std::size_t rows_total = st.schemes.size() * st.h.size();
  std::optional<CancelCheck> cancel_check;
  if (st.cancel) cancel_check.emplace(st.cancel);
  for (const Scheme scheme : st.schemes) {
    std::vector<double> hs, eq, ev;
    for (double h : st.h) {
      check_cancel(st);
      StudyRow row;
      row.scheme = scheme;
      row.h = h;
      // The error run, which is also the warm-up of the timed runs.
      // Chattering is measured once the run has had five of its own steps past the reference's
      // convergence time: a first-order scheme arrives O(h) late.
      GridSampler sampler(grid, n, chatter_from + 5.0 * h, st.cancel);
      if (st.on_row_start) st.on_row_start(scheme, h);
      const RunSummary s = run_scheme(scene, scheme, h, st, &sampler, 1, true);
      row.status = to_string(s.status);
      row.message = s.message;
      row.steps = s.steps;
      row.converged_time = s.converged_time;
      double qmax = 0, qsum = 0, vmax = 0, vsum = 0;
      for (std::size_t j = 0; j < grid.size(); ++j) {
        double dq = 0, dv = 0;
        for (int i = 0; i < n; ++i) {
          dq += std::pow(sampler.q()[j * n + i] - ref_q[j * n + i], 2);
          dv += std::pow(sampler.v()[j * n + i] - ref_v[j * n + i], 2);
        }
        qmax = std::max(qmax, std::sqrt(dq));
        vmax = std::max(vmax, std::sqrt(dv));
        qsum += dq;
        vsum += dv;
        if (!std::isfinite(dq) || !std::isfinite(dv)) qmax = vmax = qsum = vsum = kNaN;
      }
      const bool ok = s.status == RunStatus::kCompleted;
      row.q_max_error = ok ? qmax : kNaN;
      row.v_max_error = ok ? vmax : kNaN;
      row.q_l2_error = ok ? std::sqrt(qsum / grid.size()) : kNaN;
      row.v_l2_error = ok ? std::sqrt(vsum / grid.size()) : kNaN;
      const std::size_t last = grid.size() - 1;
      double fe = 0;
      for (int i = 0; i < n; ++i)
        fe += std::pow(sampler.q()[last * n + i] - ref_q[last * n + i], 2) + std::pow(sampler.v()[last * n + i] - ref_v[last * n + i], 2);
      row.final_error = ok ? std::sqrt(fe) : kNaN;
      if (row.converged_time && result.reference_converged_time)
        row.converged_time_error = std::abs(*row.converged_time - *result.reference_converged_time);
      row.chatter_sign_changes = sampler.sign_changes();
      row.chatter_amplitude = sampler.amplitude();
      row.guarantees = run_guarantees(scene, scheme, h, s, st);

      // Timed runs: no sampling (at most a cancellation check every kControlInterval steps), the minimum
      // over repeats, a single one when it is long.
      if (ok) {
        double best = std::numeric_limits<double>::infinity();
        for (int r = 0; r < std::max(1, st.repeats); ++r) {
          const auto t_run = Clock::now();
          const RunSummary timed =
              run_scheme(scene, scheme, h, st, cancel_check ? &*cancel_check : nullptr, std::numeric_limits<std::int64_t>::max());
          const double secs = seconds_since(t_run);
          best = std::min(best, secs);
          ++row.timed_runs;
          if (secs > st.single_run_seconds || timed.status != RunStatus::kCompleted) break;
        }
        row.wall_seconds = best;
      }
      hs.push_back(h);
      eq.push_back(row.q_max_error);
      ev.push_back(row.v_max_error);
      result.rows.push_back(row);
      if (st.on_row) st.on_row(result.rows.size(), rows_total);
    }
    StudyResult::Order order = order_theory(scene, scheme);
    order.q_max = slope(hs, eq);
    order.v_max = slope(hs, ev);
    result.orders.push_back(order);
  }
  result.wall_seconds = seconds_since(start);
  return result;
}

StudySettings study_settings_from_json(const nlohmann::json& j, const std::string& pointer) {
  StudySettings st;
  st.h = parse_ladder("1e-1:1e-5:9");
  if (j.is_null()) return st;
  if (!j.is_object())
    throw SceneError(pointer, "expected an object {h?, schemes?, reference_h?, epsilon?, regularization?, eval_points?, repeats?}");
  auto positive = [&](const nlohmann::json& v, const std::string& ptr) {
    if (!v.is_number() || !std::isfinite(v.get<double>()) || !(v.get<double>() > 0.0))
      throw SceneError(ptr, "expected a positive finite number");
    return v.get<double>();
  };
  auto integer = [&](const nlohmann::json& v, const std::string& ptr, long lo, long hi) {
    if (!v.is_number_integer() || v.get<long>() < lo || v.get<long>() > hi)
      throw SceneError(ptr, "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return static_cast<int>(v.get<long>());
  };
  for (const auto& [key, v] : j.items()) {
    const std::string ptr = pointer + "/" + key;
    if (key == "h") {
      if (v.is_string()) {
        try {
          st.h = parse_ladder(v.get<std::string>());
        } catch (const SceneError& e) {
          throw SceneError(ptr, e.reason());
        }
      } else if (v.is_array()) {
        if (v.empty() || v.size() > 100) throw SceneError(ptr, "expected 1 to 100 step sizes");
        st.h.clear();
        for (std::size_t i = 0; i < v.size(); ++i) st.h.push_back(positive(v[i], ptr + "/" + std::to_string(i)));
      } else {
        throw SceneError(ptr, "expected a ladder \"FIRST:LAST:COUNT\", a list \"h1,h2\" or an array of step sizes");
      }
    } else if (key == "schemes") {
      std::vector<std::string> names;
      if (v.is_string()) {
        std::stringstream ss(v.get<std::string>());
        for (std::string item; std::getline(ss, item, ',');)
          if (!item.empty()) names.push_back(item);
      } else if (v.is_array()) {
        for (std::size_t i = 0; i < v.size(); ++i) {
          if (!v[i].is_string()) throw SceneError(ptr + "/" + std::to_string(i), "expected a scheme name");
          names.push_back(v[i].get<std::string>());
        }
      } else {
        throw SceneError(ptr, "expected an array of scheme names or a comma list");
      }
      if (names.empty()) throw SceneError(ptr, "expected at least one scheme");
      st.schemes.clear();
      for (std::size_t i = 0; i < names.size(); ++i) {
        const auto& s = names[i];
        const std::optional<Scheme> scheme = study_scheme_from_name(s);
        if (!scheme)
          throw SceneError(v.is_array() ? ptr + "/" + std::to_string(i) : ptr,
                           "unknown scheme '" + s + "' (expected " + study_scheme_list() + ")");
        if (std::count(names.begin(), names.end(), s) > 1) throw SceneError(ptr, "scheme '" + s + "' given twice");
        st.schemes.push_back(*scheme);
      }
    } else if (key == "reference_h") {
      st.reference_h = positive(v, ptr);
    } else if (key == "epsilon") {
      st.epsilon = positive(v, ptr);
    } else if (key == "regularization") {
      const std::optional<Regularization> kind = v.is_string() ? regularization_from_name(v.get<std::string>()) : std::nullopt;
      if (!kind) throw SceneError(ptr, "expected \"tanh\" or \"saturation\"");
      st.regularization = *kind;
    } else if (key == "eval_points") {
      st.eval_points = integer(v, ptr, 2, 100000);
    } else if (key == "repeats") {
      st.repeats = integer(v, ptr, 1, 20);
    } else {
      throw SceneError(ptr, "unknown field (expected h, schemes, reference_h, epsilon, regularization, eval_points, repeats)");
    }
  }
  return st;
}

nlohmann::json study_settings_to_json(const StudySettings& st) {
  nlohmann::json j = {{"h", st.h},
                      {"schemes", scheme_names(st.schemes)},
                      {"epsilon", st.epsilon},
                      {"regularization", to_string(st.regularization)},
                      {"eval_points", st.eval_points},
                      {"repeats", st.repeats}};
  if (st.reference_h) j["reference_h"] = *st.reference_h;
  return j;
}

std::int64_t study_planned_steps(const LagrangianScene& scene, const StudySettings& st) {
  const double span = scene.settings.t_end - scene.settings.t0;
  constexpr double kCap = 9e18;
  double total = 0.0;
  const double runs = 1.0 + std::max(1, st.repeats);
  for (double h : st.h) total += static_cast<double>(st.schemes.size()) * runs * std::ceil(span / h);
  const double h_ref = st.reference_h ? *st.reference_h : *std::min_element(st.h.begin(), st.h.end()) / 10.0;
  if (!scene.exact_tape || st.reference_h) total += std::ceil(span / h_ref);
  // In double until here: the cast is defined only below 2^63 (NaN, from an h check_study_settings
  // would refuse, maps to the cap too).
  return total < kCap ? static_cast<std::int64_t>(total) : static_cast<std::int64_t>(kCap);
}

nlohmann::json StudyResult::to_json() const {
  nlohmann::json j;
  j["scene"] = scene;
  j["reference"] = reference;
  j["reference_converged_time"] = reference_converged_time ? num(*reference_converged_time) : nlohmann::json(nullptr);
  j["reference_guarantees"] = reference_guarantees;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : rows) {
    j["rows"].push_back({{"scheme", scheme_name(r.scheme)},
                         {"h", r.h},
                         {"status", r.status},
                         {"message", r.message},
                         {"steps", r.steps},
                         {"wall_seconds", num(r.wall_seconds)},
                         {"timed_runs", r.timed_runs},
                         {"q_max_error", num(r.q_max_error)},
                         {"q_l2_error", num(r.q_l2_error)},
                         {"v_max_error", num(r.v_max_error)},
                         {"v_l2_error", num(r.v_l2_error)},
                         {"final_error", num(r.final_error)},
                         {"converged_time", r.converged_time ? num(*r.converged_time) : nlohmann::json(nullptr)},
                         {"converged_time_error", r.converged_time_error ? num(*r.converged_time_error) : nlohmann::json(nullptr)},
                         {"chatter_sign_changes", r.chatter_sign_changes},
                         {"chatter_amplitude", num(r.chatter_amplitude)},
                         {"guarantees", r.guarantees}});
  }
  j["orders"] = nlohmann::json::array();
  for (const auto& o : orders)
    j["orders"].push_back({{"scheme", scheme_name(o.scheme)},
                           {"q_max", num(o.q_max)},
                           {"v_max", num(o.v_max)},
                           {"theory", o.theory},
                           {"theory_order", o.theory_order ? num(*o.theory_order) : nlohmann::json(nullptr)},
                           {"theory_note", o.theory_note}});
  j["wall_seconds"] = wall_seconds;
  return j;
}

StudyResult::Order order_theory(const LagrangianScene& scene, Scheme scheme) {
  StudyResult::Order o;
  o.scheme = scheme;
  if (!traits(scheme).theorems_4_1_to_4_3) {
    o.theory_note = std::string("no theorem of the papers covers the ") + scheme_name(scheme) + " scheme: only the measured order";
    return o;
  }
  if (scene.compiled && scene.compiled->constant_mass) {
    o.theory = "Remark 5.1";
    o.theory_order = 1.0;
    o.theory_note = "M is constant (no entry depends on q): order 1 (the paper states it and refers to its [9] for the proof)";
    return o;
  }
  o.theory_note =
      "M depends on q: Theorem 5.2 (order 1/2) needs Assumption 5.2 (local hypo-monotonicity of M^{-1}(q) dPhi), which is "
      "not checked (the paper says it fails for its own section 6 robot), so no theorem applies; only the measured order";
  return o;
}

StudyResult StudyResult::from_json(const nlohmann::json& j) {
  auto number = [](const nlohmann::json& v) { return number_or_nan(v); };
  auto optional = [](const nlohmann::json& v) { return v.is_number() ? std::optional<double>(v.get<double>()) : std::nullopt; };
  if (!j.is_object() || !j.contains("rows") || !j["rows"].is_array() || !j.contains("orders") || !j["orders"].is_array())
    throw std::invalid_argument("not a study result: expected an object with rows and orders");
  try {
    StudyResult r;
    r.scene = j.at("scene").get<std::string>();
    r.reference = j.at("reference").get<std::string>();
    r.reference_converged_time = optional(j.value("reference_converged_time", nlohmann::json()));
    r.reference_guarantees = j.value("reference_guarantees", nlohmann::json());
    for (const auto& x : j["rows"]) {
      StudyRow row;
      row.scheme = scheme_in(x.at("scheme"));
      row.h = x.at("h").get<double>();
      row.status = x.at("status").get<std::string>();
      row.message = x.value("message", "");
      row.steps = x.at("steps").get<std::int64_t>();
      row.wall_seconds = number(x.at("wall_seconds"));
      row.timed_runs = x.value("timed_runs", 0);
      row.q_max_error = number(x.at("q_max_error"));
      row.q_l2_error = number(x.at("q_l2_error"));
      row.v_max_error = number(x.at("v_max_error"));
      row.v_l2_error = number(x.at("v_l2_error"));
      row.final_error = number(x.at("final_error"));
      row.converged_time = optional(x.at("converged_time"));
      row.converged_time_error = optional(x.at("converged_time_error"));
      row.chatter_sign_changes = x.at("chatter_sign_changes").get<std::int64_t>();
      row.chatter_amplitude = number(x.at("chatter_amplitude"));
      row.guarantees = x.value("guarantees", nlohmann::json::array());
      r.rows.push_back(row);
    }
    for (const auto& x : j["orders"]) {
      StudyResult::Order o;
      o.scheme = scheme_in(x.at("scheme"));
      o.q_max = number(x.at("q_max"));
      o.v_max = number(x.at("v_max"));
      o.theory = x.value("theory", "none");
      o.theory_order = optional(x.value("theory_order", nlohmann::json()));
      o.theory_note = x.value("theory_note", "");
      r.orders.push_back(o);
    }
    r.wall_seconds = number(j.at("wall_seconds"));
    return r;
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("not a study result: ") + e.what());
  }
}

std::string StudyResult::to_csv() const {
  std::ostringstream os;
  os << "scheme,h,status,steps,wall_seconds,q_max_error,q_l2_error,v_max_error,v_l2_error,final_error,"
        "converged_time,converged_time_error,chatter_sign_changes,chatter_amplitude\n";
  // Each number in shortest round-trip form (it reads back bit for bit); a value that is not a number
  // (the errors of a failed row) is an empty cell, as JSON has null.
  auto cell = [](double v) { return std::isfinite(v) ? platform::shortest(v) : std::string(); };
  auto opt = [&](const std::optional<double>& v) { return v ? cell(*v) : std::string(); };
  for (const auto& r : rows) {
    os << scheme_name(r.scheme) << ',' << cell(r.h) << ',' << r.status << ',' << r.steps << ',' << cell(r.wall_seconds) << ','
       << cell(r.q_max_error) << ',' << cell(r.q_l2_error) << ',' << cell(r.v_max_error) << ',' << cell(r.v_l2_error) << ','
       << cell(r.final_error) << ',' << opt(r.converged_time) << ',' << opt(r.converged_time_error) << ',' << r.chatter_sign_changes << ','
       << cell(r.chatter_amplitude) << '\n';
  }
  return os.str();
}

namespace {

// The guarantees of a study in a few lines: per scheme and theorem, at which h each verdict came out, with
// the first failing (or unchecked) hypothesis and its numbers; the JSON has every row's whole section.
std::string guarantees_summary_text(const StudyResult& r) {
  std::ostringstream os;
  os << "  guarantees  of each run above (every row's full section is in the JSON):\n";
  auto h_text = [](double h) { return platform::significant(h, 3); };
  // The first hypothesis of `g` (one guarantee's JSON) with verdict `v`, as "name: detail".
  auto first_with = [](const nlohmann::json& g, const std::string& v) {
    for (const auto& x : g.value("hypotheses", nlohmann::json::array()))
      if (x.value("verdict", "") == v)
        return x.value("hypothesis", "") + (x.value("detail", "").empty() ? "" : ": " + x.value("detail", ""));
    return std::string();
  };
  std::vector<Scheme> schemes;
  for (const StudyRow& row : r.rows)
    if (std::find(schemes.begin(), schemes.end(), row.scheme) == schemes.end()) schemes.push_back(row.scheme);
  for (const Scheme scheme : schemes) {
    std::vector<std::string> results;  // in order of first appearance
    for (const StudyRow& row : r.rows)
      if (row.scheme == scheme)
        for (const auto& g : row.guarantees)
          if (std::find(results.begin(), results.end(), g.value("result", "")) == results.end()) results.push_back(g.value("result", ""));
    if (results.empty()) {
      os << "    " << scheme_name(scheme) << ": no theorem of the papers covers this scheme\n";
      continue;
    }
    for (const std::string& result : results) {
      std::vector<std::pair<std::string, std::vector<std::string>>> by_verdict;  // verdict -> h values
      std::string relied, first_detail;
      for (const StudyRow& row : r.rows) {
        if (row.scheme != scheme) continue;
        for (const auto& g : row.guarantees) {
          if (g.value("result", "") != result) continue;
          const std::string v = g.value("verdict", "");
          if (g.value("relied_on", false)) relied = " (relied on)";
          auto it = std::find_if(by_verdict.begin(), by_verdict.end(), [&](const auto& p) { return p.first == v; });
          if (it == by_verdict.end()) it = by_verdict.insert(by_verdict.end(), {v, {}});
          it->second.push_back(h_text(row.h));
          if (first_detail.empty() && v != "holds") first_detail = "at h = " + h_text(row.h) + ", " + v + ": " + first_with(g, v);
        }
      }
      os << "    " << scheme_name(scheme) << ": " << result << relied << ":";
      for (std::size_t i = 0; i < by_verdict.size(); ++i) {
        os << (i ? ";" : "") << " " << by_verdict[i].first << " at h =";
        for (std::size_t k = 0; k < by_verdict[i].second.size(); ++k) os << (k ? ", " : " ") << by_verdict[i].second[k];
      }
      os << "\n";
      if (!first_detail.empty()) os << "        first " << first_detail << "\n";
    }
  }
  if (r.reference_guarantees.is_array() && !r.reference_guarantees.empty()) {
    os << "    reference (" << r.reference << "):";
    bool first = true;
    for (const auto& g : r.reference_guarantees) {
      os << (first ? " " : "; ") << g.value("result", "") << " " << g.value("verdict", "");
      first = false;
    }
    os << "\n";
  }
  return os.str();
}

}  // namespace

std::string StudyResult::to_text() const {
  std::ostringstream os;
  // A table for people: columns padded to a width, numbers to a few significant digits (platform's
  // formatter); a value that is not a number (the errors of a failed row, an order fitted from fewer than
  // two points) is shown as "-".
  const auto left = platform::pad_right;  // text, aligned on its first character
  const auto right = platform::pad_left;  // numbers, aligned on their last digit
  const auto g4 = [](double v) { return std::isfinite(v) ? platform::significant(v, 4) : std::string("-"); };
  const auto fixed3 = [](double v) { return std::isfinite(v) ? platform::fixed(v, 3) : std::string("-"); };
  os << "Study of " << scene << " against the " << reference << "\n";
  os << "  " << left("scheme", 11) << " " << left("h", 9) << " " << left("status", 10) << " " << right("steps", 10) << " "
     << right("wall [s]", 11) << " " << right("q max err", 11) << " " << right("v max err", 11) << " " << right("final err", 11) << " "
     << right("chatter", 8) << " " << right("t_conv", 10) << "\n";
  for (const auto& r : rows) {
    const std::string conv =
        r.converged_time && std::isfinite(*r.converged_time) ? platform::significant(*r.converged_time, 4) : std::string("-");
    os << "  " << left(scheme_name(r.scheme), 11) << " " << left(platform::significant(r.h, 3), 9) << " " << left(r.status, 10) << " "
       << right(std::to_string(r.steps), 10) << " " << right(g4(r.wall_seconds), 11) << " " << right(g4(r.q_max_error), 11) << " "
       << right(g4(r.v_max_error), 11) << " " << right(g4(r.final_error), 11) << " " << right(std::to_string(r.chatter_sign_changes), 8)
       << " " << right(conv, 10) << "\n";
  }
  for (const auto& o : orders) {
    os << "  order of " << left(scheme_name(o.scheme), 11) << " q: " << fixed3(o.q_max) << "   v: " << fixed3(o.v_max) << "   (measured)\n";
    os << "              theory: " << (o.theory_order ? o.theory + ", order " + fixed3(*o.theory_order) : o.theory) << "; " << o.theory_note
       << "\n";
  }
  os << guarantees_summary_text(*this);
  os << "  study wall time " << platform::fixed(wall_seconds, 2) << " s\n";
  return os.str();
}

}  // namespace moreau::scene
