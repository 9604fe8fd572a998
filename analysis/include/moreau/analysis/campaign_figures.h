// The figures of a robustness campaign (campaign.h) as render/ figures: the one bridge between campaigns
// and render/, used by `moreau campaign` (after the summary, and by --collect) and by moreau.campaign in
// Python.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "moreau/render/figure.h"
#include "moreau/analysis/campaign.h"
#include "moreau/analysis/figure_kind.h"

namespace moreau::scene {

// By kind, in the order of CampaignFigure:
//   kConvergenceCdf ("convergence-cdf"): the fraction of all samples converged by time t (an empirical
//       CDF that levels off at the fraction that converged), t from the convergence times;
//   kInputs ("inputs"): one panel per numeric input (at most 8), the input against the convergence time:
//       successes, samples that converged off the target (at their convergence time) and samples that
//       never converged (at t_end) apart;
//   kSuccessMap ("success-map"): the plane of the two map inputs, successes and the others apart (a map
//       all on one side says so in its title).
// Axes name the inputs in words with the scene's units (/parameters/m1 -> "m1", /initial/q/0 -> "initial
// x1 [m]"), time as "t [s]"; success has one colour in every figure.
// A figure without data to draw (no sample converged; fewer than two numeric inputs) is left out.
// `t_end` is the scene's end time.
std::vector<std::pair<CampaignFigure, render::Figure>> campaign_figures(const CampaignSpec& spec,
                                                                        const std::vector<CampaignOutcome>& outcomes, double t_end);

// DIR/figures/<name>.png for the campaign in DIR, every sample of which is present: the figures above,
// from DIR/campaign.json and its records. Returns the paths written, in that order.
std::vector<std::string> write_campaign_figures(const std::string& dir);

}  // namespace moreau::scene
