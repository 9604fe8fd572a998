#include "moreau/analysis/sampling_study.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>

#include "moreau/platform/number_text.h"
#include "moreau/platform/text_columns.h"
#include "moreau/scene/json_number.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

SamplingStudyResult run_sampling_study(const nlohmann::json& doc, const std::vector<double>& periods,
                                       const std::vector<std::string>& laws) {
  const LagrangianScene base = load_scene(doc);
  if (!base.tracking) throw SceneError("/system/tracking", "a sampling study needs a tracking scene (/system/tracking)");
  if (periods.empty()) throw SceneError("--periods", "give at least one sampling period");
  for (double p : periods)
    if (!(p > 0.0) || !std::isfinite(p)) throw SceneError("--periods", "every period must be finite and > 0, got " + platform::shortest(p));
  if (laws.empty()) throw SceneError("--laws", "give at least one law (implicit, explicit, saturated)");
  for (const std::string& law : laws) {
    if (law != "implicit" && law != "explicit" && law != "saturated")
      throw SceneError("--laws", "unknown law '" + law + "' (expected implicit, explicit or saturated)");
    if (law == "saturated" && !(base.tracking->boundary_layer > 0.0))
      throw SceneError("/system/tracking/boundary_layer", "the saturated law needs the scene's boundary_layer");
  }
  // Plant steps per sample: the scene's own, or 10 for a scene of the continuous law.
  const double per_sample = base.tracking->sampled ? std::round(base.tracking->period / base.settings.h) : 10.0;
  SamplingStudyResult result;
  result.scene = base.name;
  for (const std::string& law : laws) {
    for (double period : periods) {
      SamplingStudyRow row;
      row.law = law;
      row.period = period;
      row.h = period / per_sample;
      nlohmann::json d = doc;
      d["system"]["tracking"]["law"] = law;
      d["system"]["tracking"]["period"] = period;
      d["integrator"]["h"] = row.h;
      if (law != "saturated") d["system"]["tracking"].erase("boundary_layer");
      const auto start = std::chrono::steady_clock::now();
      const LagrangianScene sc = load_scene(d);
      const RunSummary s = run_scene(sc, nullptr);
      row.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      row.status = s.status == RunStatus::kCompleted ? "completed" : "failed";
      row.message = s.message;
      const double nan = std::numeric_limits<double>::quiet_NaN();
      row.error_max = row.error_rms = row.sign_changes_per_second = row.total_variation = nan;
      if (s.tracking) {
        const TrackingSummary& t = *s.tracking;
        row.reached = t.reached;
        row.u_max = t.u_max;
        row.error_final = t.error_final;
        row.run_total_variation = t.run_total_variation;
        row.run_sign_changes_per_second = static_cast<double>(t.run_sign_changes) / (sc.settings.t_end - sc.settings.t0);
        if (t.reached) {
          row.reaching_time = t.reaching_time;
          row.error_max = t.error_max;
          row.error_rms = t.error_rms;
          row.sign_changes_per_second = t.sign_changes_per_second;
          row.total_variation = t.total_variation;
        }
      }
      result.rows.push_back(row);
    }
  }
  return result;
}

nlohmann::json SamplingStudyResult::to_json() const {
  nlohmann::json rows_json = nlohmann::json::array();
  for (const auto& r : rows) {
    rows_json.push_back({{"law", r.law},
                         {"period", r.period},
                         {"h", r.h},
                         {"status", r.status},
                         {"message", r.message},
                         {"reached", r.reached},
                         {"reaching_time", r.reaching_time ? finite_or_null(*r.reaching_time) : nlohmann::json(nullptr)},
                         {"error_max", finite_or_null(r.error_max)},
                         {"error_rms", finite_or_null(r.error_rms)},
                         {"sign_changes_per_second", finite_or_null(r.sign_changes_per_second)},
                         {"total_variation", finite_or_null(r.total_variation)},
                         {"error_final", finite_or_null(r.error_final)},
                         {"run_sign_changes_per_second", finite_or_null(r.run_sign_changes_per_second)},
                         {"run_total_variation", finite_or_null(r.run_total_variation)},
                         {"u_max", finite_or_null(r.u_max)},
                         {"wall_seconds", finite_or_null(r.wall_seconds)}});
  }
  return {{"scene", scene}, {"rows", rows_json}};
}

std::string SamplingStudyResult::to_csv() const {
  std::ostringstream os;
  os << "law,period,h,status,reached,reaching_time,error_max,error_rms,sign_changes_per_second,total_variation,error_final,"
        "run_sign_changes_per_second,run_total_variation,u_max,wall_seconds\n";
  for (const auto& r : rows) {
    os << r.law << "," << platform::shortest(r.period) << "," << platform::shortest(r.h) << "," << r.status << "," << (r.reached ? 1 : 0)
       << "," << (r.reaching_time ? platform::shortest(*r.reaching_time) : "nan");
    for (double v : {r.error_max, r.error_rms, r.sign_changes_per_second, r.total_variation, r.error_final, r.run_sign_changes_per_second,
                     r.run_total_variation, r.u_max, r.wall_seconds})
      os << "," << platform::shortest(v);
    os << "\n";
  }
  return os.str();
}

std::string SamplingStudyResult::to_text() const {
  using platform::pad_left;
  using platform::pad_right;
  const auto g4 = [](double v) { return std::isfinite(v) ? platform::significant(v, 4) : std::string("-"); };
  std::ostringstream os;
  os << "Sampling study of " << scene << ": the digital controller against its period T_s\n";
  os << "  " << pad_right("law", 10) << " " << pad_right("T_s", 9) << " " << pad_right("status", 10) << " " << pad_left("t_reach", 10)
     << " " << pad_left("RMS e*", 11) << " " << pad_left("final |e|", 11) << " " << pad_left("sign ch./s", 11) << " "
     << pad_left("TV(u)", 11) << " " << pad_left("max |u|", 11) << "\n";
  for (const auto& r : rows) {
    os << "  " << pad_right(r.law, 10) << " " << pad_right(platform::significant(r.period, 3), 9) << " " << pad_right(r.status, 10) << " "
       << pad_left(r.reaching_time ? g4(*r.reaching_time) : "-", 10) << " " << pad_left(g4(r.error_rms), 11) << " "
       << pad_left(g4(r.error_final), 11) << " " << pad_left(g4(r.run_sign_changes_per_second), 11) << " "
       << pad_left(g4(r.run_total_variation), 11) << " " << pad_left(g4(r.u_max), 11) << "\n";
    if (!r.message.empty()) os << "    " << r.message << "\n";
  }
  os << "  (* after reaching; the other columns over the whole run: sign changes of u per second and its total variation)\n";
  return os.str();
}

}  // namespace moreau::scene
