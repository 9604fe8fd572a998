// A campaign's part in variance-based sensitivity (docs/campaigns.md, "Sobol indices"): the spec's
// "sensitivity" option, Saltelli's design over the base sampler, the Sobol indices in the summary, and
// what the success rate's Wilson interval assumes of the design. Internal to moreau_campaign: campaign.cc
// calls these where it reads the spec, draws a sample and writes the summary.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/analysis/campaign.h"

namespace moreau::scene::campaign_detail {

// Reads spec["sensitivity"] (present) into s.sobol and sets s.samples to N (k + 2), given s.inputs and
// s.sampler. Throws SceneError at the field: an unknown method, N out of range, a base sampler that is not
// monte-carlo or sobol, a "samples" other than N (k + 2).
void read_campaign_sensitivity(const nlohmann::json& spec, CampaignSpec& s);

// What the Wilson interval assumes and whether the design meets it: {"assumes", "valid_for_design",
// "design"} (the design's reason), merged into the summary's "success_rate_95".
nlohmann::json success_interval_assumptions(const CampaignSpec& spec);

// The summary's "sobol": each outcome's indices, from the outcomes of every sample in index order, and
// `spearman_inputs`, the summary's rank correlations (its "sensitivity"/"inputs").
nlohmann::json summarize_campaign_sobol(const CampaignSpec& spec, const std::vector<CampaignOutcome>& rows,
                                        const nlohmann::json& spearman_inputs);

// The text of the interval's note (after the success line) and of "sobol" (before the worst samples).
std::string format_success_interval_note(const nlohmann::json& summary);
std::string format_campaign_sobol(const nlohmann::json& summary);

}  // namespace moreau::scene::campaign_detail
