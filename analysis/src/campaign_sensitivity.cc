#include "campaign_sensitivity.h"

#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <sstream>

#include "moreau/analysis/sensitivity.h"
#include "moreau/platform/number_text.h"

namespace moreau::scene::campaign_detail {
using json = nlohmann::json;

namespace {

// An input matters when its index's interval lies above this share of the outcome's variance.
constexpr double kImportanceThreshold = 0.05;
constexpr int kMaxResamples = 10000;
// The bootstrap's stream: the spec's seed mixed with this and the outcome's number.
constexpr std::uint64_t kBootstrapStream = 0x424f4f54;

std::string brief(const json& j) {
  std::string s = j.dump(-1, ' ', false, json::error_handler_t::replace);
  return s.size() > 60 ? s.substr(0, 57) + "..." : s;
}

const char* sampler_name(Sampler s) {
  switch (s) {
    case Sampler::kMonteCarlo: return "monte-carlo";
    case Sampler::kLatinHypercube: return "latin-hypercube";
    case Sampler::kSobol: return "sobol";
    case Sampler::kGrid: return "grid";
  }
  return "";
}

// The outcomes whose indices the summary gives, as the rank correlations name them.
struct Outcome {
  const char* key;
  const char* label;
  double (*get)(const CampaignOutcome&);
};
const Outcome kOutcomes[] = {{"success", "success", [](const CampaignOutcome& r) { return r.success ? 1.0 : 0.0; }},
                             {"converged_time", "convergence time", [](const CampaignOutcome& r) { return r.converged_time; }},
                             {"target_distance", "target distance", [](const CampaignOutcome& r) { return r.target_distance; }},
                             {"max_abs_q", "max |q|", [](const CampaignOutcome& r) { return r.max_abs_q; }}};

json interval(const SobolInterval& v) { return {{"estimate", v.estimate}, {"low", v.low()}, {"high", v.high()}}; }

}  // namespace

void read_campaign_sensitivity(const json& spec, CampaignSpec& s) {
  const json& d = spec["sensitivity"];
  const std::string ptr = "/sensitivity";
  if (!d.is_object()) throw SceneError(ptr, "expected {\"method\": \"sobol\", \"base_samples\": N}, got " + brief(d));
  for (const auto& item : d.items()) {
    const std::string& key = item.key();
    if (key != "method" && key != "base_samples" && key != "resamples")
      throw SceneError(ptr + "/" + json_pointer_token(key), "unknown field '" + key + "'");
  }
  if (!d.contains("method")) throw SceneError(ptr, "missing 'method'");
  if (d["method"] != "sobol") throw SceneError(ptr + "/method", "unknown method " + brief(d["method"]) + " (sobol)");
  const auto k = static_cast<std::int64_t>(s.inputs.size());
  if (!d.contains("base_samples")) throw SceneError(ptr, "missing 'base_samples'");
  const json& n = d["base_samples"];
  const std::int64_t most = kMaxCampaignSamples / (k + 2);
  if (!n.is_number_integer() || (n.is_number_unsigned() && n.get<std::uint64_t>() > static_cast<std::uint64_t>(most)) ||
      n.get<std::int64_t>() < 2 || n.get<std::int64_t>() > most)
    throw SceneError(ptr + "/base_samples", "expected a whole number of rows in [2, " + std::to_string(most) +
                                                "] (the design has N (k + 2) = N " + std::to_string(k + 2) + " samples, at most " +
                                                std::to_string(kMaxCampaignSamples) + "), got " + brief(n));
  CampaignSobol sobol;
  sobol.base_samples = n.get<std::int64_t>();
  if (d.contains("resamples")) {
    const json& r = d["resamples"];
    if (!r.is_number_integer() || r.get<std::int64_t>() < 2 || r.get<std::int64_t>() > kMaxResamples)
      throw SceneError(ptr + "/resamples", "expected a whole number of bootstrap resamples in [2, " + std::to_string(kMaxResamples) + "]");
    sobol.resamples = static_cast<int>(r.get<std::int64_t>());
  }
  if (s.sampler != Sampler::kMonteCarlo && s.sampler != Sampler::kSobol)
    throw SceneError("/sampler", std::string("Saltelli's design (the spec's sensitivity) draws its rows with monte-carlo or sobol, not ") +
                                     sampler_name(s.sampler));
  const std::int64_t total = saltelli_points(sobol.base_samples, static_cast<int>(k));
  if (spec.contains("samples") && spec["samples"] != total)
    throw SceneError("/samples", "Saltelli's design of " + std::to_string(sobol.base_samples) + " rows over " + std::to_string(k) +
                                     " inputs has " + std::to_string(total) + " samples; leave 'samples' out or give that number");
  s.samples = total;
  s.sobol = sobol;
}

json success_interval_assumptions(const CampaignSpec& spec) {
  json a = {{"assumes", "independent samples"}, {"valid_for_design", false}};
  if (spec.sobol) {
    a["design"] = "Saltelli's design shares coordinates among the k + 2 samples of each row, so its samples are not independent";
  } else {
    switch (spec.sampler) {
      case Sampler::kMonteCarlo:
        a["valid_for_design"] = true;
        a["design"] = "the Monte Carlo samples are independent draws";
        break;
      case Sampler::kLatinHypercube:
        a["design"] =
            "the Latin hypercube's samples are stratified, not independent (Owen 1997 bounds the variance of its success rate by that of "
            "n - 1 independent samples)";
        break;
      case Sampler::kSobol:
        a["design"] =
            "the Sobol points are a deterministic sequence (not scrambled): the rate is a quasi-Monte Carlo estimate whose error no "
            "sampling interval bounds";
        break;
      case Sampler::kGrid: a["design"] = "a grid's points are not random: the rate is the fraction of the grid that succeeded"; break;
    }
  }
  return a;
}

json summarize_campaign_sobol(const CampaignSpec& spec, const std::vector<CampaignOutcome>& rows, const json& spearman_inputs) {
  const int k = static_cast<int>(spec.inputs.size());
  const std::int64_t n = spec.sobol->base_samples, per_row = k + 2;
  json out = {{"method",
               "Saltelli's design; first-order index S: Saltelli et al. (2010) estimator (b); total index ST: Jansen (1999); "
               "intervals: bootstrap of the rows (normal approximation, as SALib)"},
              {"base_sampler", sampler_name(spec.sampler)},
              {"base_samples", n},
              {"confidence", 0.95},
              {"resamples", spec.sobol->resamples},
              {"threshold", kImportanceThreshold}};
  bool complete = static_cast<std::int64_t>(rows.size()) == n * per_row;
  for (std::size_t i = 0; complete && i < rows.size(); ++i) complete = rows[i].index == static_cast<std::int64_t>(i);
  if (!complete) {
    out["outcomes"] = nullptr;
    out["why"] = "not every sample of the design is present";
    return out;
  }
  // The A and B points of a Monte Carlo base are 2N independent draws: the success rate's interval there.
  if (spec.sampler == Sampler::kMonteCarlo) {
    std::int64_t successes = 0;
    for (std::int64_t j = 0; j < n; ++j)
      successes += rows[static_cast<std::size_t>(j * per_row)].success + rows[static_cast<std::size_t>(j * per_row + k + 1)].success;
    const WilsonInterval w = wilson_interval(successes, 2 * n);
    out["success_rate_ab"] = {
        {"samples", 2 * n}, {"successes", successes}, {"rate", static_cast<double>(successes) / static_cast<double>(2 * n)},
        {"low", w.low},     {"high", w.high},         {"method", "Wilson score interval over the A and B points (independent draws)"}};
  }
  std::vector<std::string> names;
  for (const CampaignInput& in : spec.inputs) names.push_back(in.path);
  json outcomes = json::array();
  std::uint64_t stream = 0;
  for (const Outcome& o : kOutcomes) {
    ++stream;
    if (std::string(o.key) == "target_distance" && spec.target_q.empty()) continue;
    // The rows where every sample has the outcome (a run that did not converge has no convergence time).
    std::vector<double> y;
    y.reserve(rows.size());
    std::int64_t used = 0;
    for (std::int64_t j = 0; j < n; ++j) {
      bool all = true;
      for (std::int64_t b = 0; b < per_row && all; ++b) all = std::isfinite(o.get(rows[static_cast<std::size_t>(j * per_row + b)]));
      if (!all) continue;
      ++used;
      for (std::int64_t b = 0; b < per_row; ++b) y.push_back(o.get(rows[static_cast<std::size_t>(j * per_row + b)]));
    }
    json entry = {{"outcome", o.key}, {"rows", used}};
    if (used < n)
      entry["note"] =
          "over the rows where every sample has the outcome: the indices of the outcome restricted to them, not a "
          "decomposition of its variance over the inputs' whole distribution";
    if (used < 2) {
      entry["indices"] = nullptr;
      entry["why"] = "fewer than 2 rows where every sample has the outcome";
      outcomes.push_back(entry);
      continue;
    }
    SobolOptions options;
    options.resamples = spec.sobol->resamples;
    options.seed = spec.seed ^ (kBootstrapStream + stream);
    const SobolIndices r = sobol_indices(y, k, options);
    entry["mean"] = r.mean;
    entry["variance"] = r.variance;
    if (!r.defined) {
      entry["indices"] = nullptr;
      entry["why"] = "the outcome is constant over the A and B points: no variance to share";
      outcomes.push_back(entry);
      continue;
    }
    // The rank correlation of each input with this outcome, where the summary has one.
    std::map<std::string, double> rho;
    for (const json& row : spearman_inputs)
      if (row.contains(o.key) && row[o.key].is_number()) rho[row["input"].get<std::string>()] = row[o.key].get<double>();
    std::vector<std::optional<double>> ranks;
    json inputs = json::array();
    for (int i = 0; i < k; ++i) {
      const auto ii = static_cast<std::size_t>(i);
      const auto it = rho.find(names[ii]);
      ranks.push_back(it == rho.end() ? std::nullopt : std::optional<double>(it->second));
      inputs.push_back({{"input", names[ii]},
                        {"first_order", interval(r.first[ii])},
                        {"total", interval(r.total[ii])},
                        {"interaction", interval(r.interaction[ii])}});
    }
    entry["indices"] = inputs;
    entry["verdict"] = describe_importance(names, input_importance(r, ranks, kImportanceThreshold), kImportanceThreshold);
    outcomes.push_back(entry);
  }
  out["outcomes"] = outcomes;
  return out;
}

std::string format_success_interval_note(const json& summary) {
  const json& w = summary["success_rate_95"];
  if (!w.contains("valid_for_design") || w["valid_for_design"].get<bool>()) return "";
  std::string s = "  the interval does not hold for this design: " + w["design"].get<std::string>() + "\n";
  if (summary.contains("sobol") && summary["sobol"].contains("success_rate_ab")) {
    const json& ab = summary["sobol"]["success_rate_ab"];
    const auto percent = [](const json& rate) { return platform::fixed(100.0 * rate.get<double>(), 2) + "%"; };
    s += "  over its " + std::to_string(ab["samples"].get<std::int64_t>()) + " A and B points, independent draws: " + percent(ab["rate"]) +
         ", 95% Wilson interval [" + percent(ab["low"]) + ", " + percent(ab["high"]) + "]\n";
  }
  return s;
}

std::string format_campaign_sobol(const json& summary) {
  if (!summary.contains("sobol")) return "";
  const json& s = summary["sobol"];
  std::ostringstream o;
  o << "  Sobol indices (Saltelli's design, " << s["base_samples"].get<std::int64_t>() << " rows of "
    << s["base_sampler"].get<std::string>() << "; first order S: Saltelli et al. 2010, total ST: Jansen 1999; 95% bootstrap intervals):\n";
  if (!s["outcomes"].is_array()) {
    o << "    not computed: " << s.value("why", "") << "\n";
    return o.str();
  }
  for (const json& e : s["outcomes"]) {
    const std::string key = e["outcome"];
    const char* label = key.c_str();
    for (const Outcome& out : kOutcomes)
      if (key == out.key) label = out.label;
    o << "    " << label << " (" << e["rows"].get<std::int64_t>() << " of " << s["base_samples"].get<std::int64_t>() << " rows):";
    if (!e["indices"].is_array()) {
      o << " " << e.value("why", "") << "\n";
      continue;
    }
    o << "\n";
    for (const json& in : e["indices"]) {
      const json &f = in["first_order"], &t = in["total"];
      const auto f3 = [](const json& v) { return platform::fixed(v.get<double>(), 3); };
      o << "      " << in["input"].get<std::string>() << ": S " << f3(f["estimate"]) << " [" << f3(f["low"]) << ", " << f3(f["high"])
        << "]  ST " << f3(t["estimate"]) << " [" << f3(t["low"]) << ", " << f3(t["high"]) << "]\n";
    }
    o << "      matter " << e["verdict"].get<std::string>() << "\n";
  }
  return o.str();
}

}  // namespace moreau::scene::campaign_detail
