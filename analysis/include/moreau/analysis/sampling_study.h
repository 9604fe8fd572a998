// A tracking scene's digital controller over a ladder of sampling periods T_s, for each law asked
// (implicit, explicit, saturated): the tracking error after reaching and the chattering of u against T_s,
// the comparison docs/tracking.md derives (implicit: error O(T_s), no sign change of u under a constant
// perturbation; explicit: u switches at a rate of order 1 / T_s). Each row is one run of the scene with
// /system/tracking/law and /system/tracking/period set, and the plant step h = T_s / r, r the scene's own
// number of plant steps per sample (10 for a scene of the continuous law), so every row integrates the
// plant with the same number of steps per sample.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace moreau::scene {

struct SamplingStudyRow {
  std::string law;
  double period = 0.0, h = 0.0;
  std::string status;  // completed, failed
  std::string message;
  bool reached = false;
  std::optional<double> reaching_time;
  // After reaching (NaN when not reached): max ||e||_inf, RMS e, sign changes of u per second, total
  // variation of u.
  double error_max = 0.0, error_rms = 0.0, sign_changes_per_second = 0.0, total_variation = 0.0;
  // Over the run, whether it reached or not: ||e||_inf at the end, the sign changes of u per second and
  // its total variation, max |u|.
  double error_final = 0.0, run_sign_changes_per_second = 0.0, run_total_variation = 0.0, u_max = 0.0;
  double wall_seconds = 0.0;
};

struct SamplingStudyResult {
  std::string scene;
  std::vector<SamplingStudyRow> rows;
  nlohmann::json to_json() const;
  std::string to_csv() const;
  std::string to_text() const;
};

// Runs the study. Throws SceneError naming the option (--periods, --laws) or the scene field: a scene
// without /system/tracking, an empty ladder or a period that is not positive, an unknown law, the
// saturated law without /system/tracking/boundary_layer.
SamplingStudyResult run_sampling_study(const nlohmann::json& doc, const std::vector<double>& periods, const std::vector<std::string>& laws);

}  // namespace moreau::scene
