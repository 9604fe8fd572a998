// Studies: how accurate is a scheme for the time it costs, and at what order does it converge.
//
// A study runs one scene over a ladder of step sizes and schemes (abl, explicit, regularized) and, for
// each run, measures
//  - the wall time, by the protocol of DiffEqDevTools' WorkPrecisionSet: one warm-up run, then timed runs
//    with no observer attached (error computation is kept out of them), the minimum over `repeats` runs,
//    or a single timed run when one takes longer than `single_run_seconds`;
//  - the errors against a reference, at `eval_points` common times spread evenly over [t0, t_end]: max
//    over time and L2 norm over time (sqrt of the time average of the squared Euclidean norm) of q and of v,
//    the final-state error, and the error of the finite-step convergence time where both have one. A run's
//    state at a common time is linearly interpolated between its two neighbouring samples (every step is
//    sampled in the error run);
//  - the guarantees section of that run (guarantees.h), and of a numerical reference;
//  - chattering: from five of the run's steps after the reference's convergence time (a first-order
//    scheme arrives O(h) late), the number of sign changes of the velocity components and their
//    largest magnitude. The implicit scheme shows none (Acary and Brogliato 2010).
// The reference is the scene's exact solution when it carries one (`/exact/q`, `/exact/v`), else an abl
// run at `reference_h` (default: the smallest h of the ladder divided by 10), stated in the result.
// The order of each scheme is the least-squares slope of log(error) against log(h).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/scene/scene.h"

namespace moreau::scene {

struct StudySettings {
  std::vector<double> h;  // the ladder
  // Schemes of the table (scheme.h) whose row says a study compares them.
  std::vector<Scheme> schemes = {Scheme::kAbl, Scheme::kExplicit, Scheme::kRegularized};
  std::optional<double> reference_h;  // force a numerical reference at this h
  double epsilon = 1e-3;              // width of the regularized sign
  Regularization regularization = Regularization::kTanh;
  int eval_points = 1000;
  int repeats = 3;
  double single_run_seconds = 2.0;
  // When set, run_study checks it between runs and every RunObserver::kControlInterval steps inside
  // them, and throws StudyCancelled once it is true.
  const std::atomic<bool>* cancel = nullptr;
  // Called after each row of the table, with the rows done and the rows planned.
  std::function<void(std::size_t done, std::size_t total)> on_row;
  // Called when a row's first run is about to start (after the cancellation check between rows), so that
  // a caller can act while that run integrates.
  std::function<void(Scheme scheme, double h)> on_row_start;
};

// Thrown by run_study when StudySettings::cancel became true.
class StudyCancelled : public std::runtime_error {
 public:
  StudyCancelled() : std::runtime_error("study cancelled") {}
};

// The study settings of a request body (POST /v1/studies: {"h", "schemes", "reference_h", "epsilon",
// "regularization", "eval_points", "repeats"}), validated; SceneError pointers are `pointer` + "/field".
// h is a ladder string ("1e-1:1e-5:9", "1e-2,1e-3") or an array of positive numbers; schemes a comma
// string or an array. Absent fields keep StudySettings' defaults (and the ladder "1e-1:1e-5:9").
StudySettings study_settings_from_json(const nlohmann::json& j, const std::string& pointer);
// The settings as study_settings_from_json reads them (h as an array), every field given.
nlohmann::json study_settings_to_json(const StudySettings& settings);

// An upper estimate of the integration steps a study takes: for each scheme and h, ceil(T / h) for the
// error run and each timed run, plus the reference run (adaptive step rules can take more; each run is
// still bounded by the scene's /integrator/max_steps).
std::int64_t study_planned_steps(const LagrangianScene& scene, const StudySettings& settings);

struct StudyRow {
  Scheme scheme = Scheme::kAbl;
  double h = 0.0;
  std::string status;  // completed, failed
  std::string message;
  std::int64_t steps = 0;
  double wall_seconds = 0.0;
  int timed_runs = 0;
  double q_max_error = 0.0, q_l2_error = 0.0, v_max_error = 0.0, v_l2_error = 0.0, final_error = 0.0;
  std::optional<double> converged_time;
  std::optional<double> converged_time_error;
  std::int64_t chatter_sign_changes = 0;
  double chatter_amplitude = 0.0;
  // The guarantees section of the row's error run (guarantees_json: each theorem its claims rest on, its
  // hypotheses, verdicts and numbers), as a run report has it; empty for the regularized peer, which no
  // theorem of the papers covers.
  nlohmann::json guarantees = nlohmann::json::array();
};

struct StudyResult {
  std::string scene;
  std::string reference;  // "exact solution" or "abl at h = ..."
  std::optional<double> reference_converged_time;
  // The reference run's guarantees when the reference is numerical (null for an exact solution).
  nlohmann::json reference_guarantees;
  std::vector<StudyRow> rows;
  struct Order {
    Scheme scheme = Scheme::kAbl;
    double q_max = 0.0, v_max = 0.0;  // fitted slopes (NaN with fewer than two usable points)
    // What the papers say about this scheme's order on this scene (order_theory()): the result that
    // applies and the order it promises, or "none" with why. The measured slopes above are what was seen.
    std::string theory = "none";
    std::optional<double> theory_order;
    std::string theory_note;
  };
  std::vector<Order> orders;
  double wall_seconds = 0.0;

  nlohmann::json to_json() const;
  std::string to_csv() const;
  std::string to_text() const;
  // Reads what to_json() wrote (null numbers become NaN or absent optionals). Throws
  // std::invalid_argument on a document of another shape.
  static StudyResult from_json(const nlohmann::json& j);
};

// The order the papers promise for `scheme` on `scene`: for the scheme (0.2) with a constant M, Remark 5.1
// (order 1); with M depending on q, Theorem 5.2 (order 1/2) only under Assumption 5.2, which is not
// checked, so "none" (the paper says it fails for its own section 6 robot); for the other schemes, none.
StudyResult::Order order_theory(const LagrangianScene& scene, Scheme scheme);

// Parses a ladder "1e-1:1e-5:9" (log-spaced, both ends included) or a list "1e-2,5e-3,1e-3".
std::vector<double> parse_ladder(const std::string& text);
// A comma list of study schemes ("abl,explicit,regularized"). Throws SceneError at --schemes for an
// unknown or repeated name, or an empty list.
std::vector<Scheme> parse_study_schemes(const std::string& text);

// Checks settings against the scene without running anything; run_study calls it first. Throws
// SceneError naming the option (--h, --reference-h, --schemes, --eval-points, --repeats, --epsilon) or the
// scene field: a scene with constraints; an empty ladder; an h (or the reference h, given or the default
// min h / 10 of a scene without an exact solution) that is not positive and finite, longer than
// [t0, t_end], or needing more steps than /integrator/max_steps; an unknown scheme; eval_points outside
// [2, 100000], repeats outside [1, 20], epsilon not positive and finite.
void check_study_settings(const LagrangianScene& scene, const StudySettings& settings);

// Runs the study. Throws SceneError for bad settings (check_study_settings) and for an exact solution
// that is not finite at one of the common times (at /exact/q/i or /exact/v/i), and StudyCancelled when
// settings.cancel turns true.
StudyResult run_study(const LagrangianScene& scene, const StudySettings& settings);

}  // namespace moreau::scene
