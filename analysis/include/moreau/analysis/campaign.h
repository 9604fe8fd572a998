// Robustness campaigns: one scene run over many sampled values of its uncertain inputs, with a verdict.
//
// A campaign spec (docs/campaigns.md) names a scene, its uncertain inputs (any scene path, each with a
// distribution or a grid), a sampler (Monte Carlo, Latin hypercube, Sobol, full grid) with a seed, and a
// number of samples. Sample i's values depend only on the spec and i (never on the worker or the order
// in which samples run), so any split of the index range over processes or threads gives the same
// samples. Each sample's record (its inputs and outcomes) is one JSON line; the summary gives the success
// rate with its Wilson interval (labelled by what it assumes: independent samples), quantiles of the
// convergence time and of the final error, the worst samples and Spearman rank correlations of each
// outcome with each input; with the spec's "sensitivity", the samples are Saltelli's design and the
// summary adds each outcome's Sobol indices (sensitivity.h) and which inputs matter by which measure.
//
// Files of a campaign directory:
//   campaign.json       the spec as run (a directory holds one campaign: another spec is refused)
//   samples.jsonl       one record per finished sample, in the order they finished (a run on one machine)
//   parts/B-E.jsonl     the same for the samples B to E-1 of a task (.partial while it runs)
//   samples.csv         the same records as a table
//   summary.json/.txt   once every sample is present (run_campaign, or collect_campaign)
// A stopped run leaves samples.jsonl and samples.csv as they were after the last finished sample; the
// next run skips what is there (a line cut short by a kill is dropped and recomputed).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/scene/scene.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {

// A distribution of one uncertain input, drawn by the inverse of its CDF from u in [0, 1).
struct InputDistribution {
  enum class Kind { kUniform, kNormal, kLogUniform, kDiscrete, kGrid };
  Kind kind = Kind::kUniform;
  double low = 0.0, high = 0.0;        // uniform, log-uniform, grid; the truncation bounds of a normal
  double mean = 0.0, stddev = 0.0;     // normal
  std::vector<nlohmann::json> values;  // discrete (equally likely); a grid's points

  // The value at u in [0, 1): low + u (high - low); exp of the same in log; the truncated normal's
  // quantile Phi^-1(Phi(a) + u (Phi(b) - Phi(a))) (a, b the standardized bounds); values[floor(u n)].
  nlohmann::json at(double u) const;
  bool numeric() const { return kind != Kind::kDiscrete || all_numbers_; }
  bool all_numbers_ = true;  // discrete values are all numbers
};

struct CampaignInput {
  std::string path;  // a JSON pointer into the scene (/parameters/m2, /initial/q/0)
  InputDistribution distribution;
};

enum class Sampler { kMonteCarlo, kLatinHypercube, kSobol, kGrid };

// Largest number of samples in one campaign: about 10 GB of JSON Lines at 1 kB per record.
inline constexpr std::int64_t kMaxCampaignSamples = 10'000'000;
// The Latin hypercube keeps one permutation of the samples per input in memory (4 bytes per sample and
// input): it is limited to this many samples.
inline constexpr std::int64_t kMaxLatinHypercubeSamples = 2'000'000;
// Worker threads of one run at most.
inline constexpr int kMaxCampaignWorkers = 1024;
// Uncertain inputs at most (Sobol's table has more; a campaign over more inputs is not a robustness check).
inline constexpr int kMaxCampaignInputs = 64;
// A campaign's name: 1 to 64 of [A-Za-z0-9._-]. It goes into Slurm job names and batch scripts, file
// names and messages, where any other character (a space, a newline, a quote, '$', '#') could be read as
// an option or a command; the spec reader refuses other names at /name.
inline constexpr std::size_t kMaxCampaignNameLength = 64;
bool is_campaign_name(const std::string& name);

// The identity of a campaign spec: FNV-1a (64-bit) of the canonical JSON text of its document (the spec
// with its scene inlined), as 16 lowercase hex digits. Canonical: nlohmann's compact dump (object keys
// sorted) after every number that is a whole double below 2^53 in magnitude is written as an integer, so
// that two documents equal as JSON values (1 and 1.0) have one hash. Every record carries it.
std::string campaign_spec_hash(const nlohmann::json& document);

// Variance-based sensitivity (sensitivity.h; the spec's "sensitivity": {"method": "sobol", "base_samples":
// N}): the samples are Saltelli's design of N rows over the base sampler (Monte Carlo or Sobol) in
// [0, 1)^(2k), N (k + 2) samples in all, and the summary gives first-order and total Sobol indices with
// bootstrap intervals. Sample i is block i mod (k + 2) of row i / (k + 2) (saltelli_place).
struct CampaignSobol {
  std::int64_t base_samples = 0;  // N
  int resamples = 100;            // bootstrap resamples of the rows (SALib's default)
};

struct CampaignSpec {
  std::string name;
  nlohmann::json scene;  // the scene document the samples override
  std::vector<CampaignInput> inputs;
  Sampler sampler = Sampler::kMonteCarlo;
  std::uint64_t seed = 0;
  std::int64_t samples = 0;
  // The target set: a sample succeeds when it converged (the report's definition) and, with a target,
  // its final q lies within `tolerance` (Euclidean distance) of target_q.
  std::vector<double> target_q;
  // Parameters the nominal scene declares and no expression reads (a likely typo; a sample's inputs only
  // set values): what `moreau campaign` warns of.
  std::vector<std::string> unread_parameters;
  double target_tolerance = 0.0;
  // A tracking scene's success (the spec's "tracking": {"error", "after"}): completed, with
  // ||e||_inf <= error at every recorded state from t = after on (docs/tracking.md); no convergence asked.
  std::optional<double> tracking_error, tracking_after;
  // The two inputs (indices into `inputs`) whose plane the success map shows: the spec's "map", else the
  // first two numeric inputs; -1 when there are not two.
  std::array<int, 2> map_inputs{-1, -1};
  // Whether each record carries the run's whole report (about 4 kB for the manipulator); false keeps the
  // records to their outcomes (about 300 bytes), for campaigns of millions of samples.
  bool full_report = true;
  std::optional<CampaignSobol> sobol;  // the spec's "sensitivity"
  nlohmann::json document;             // the spec as given, with the scene inlined: what campaign.json stores
  std::string hash;                    // campaign_spec_hash(document): the "spec_hash" of every record

  // Validates a spec. `base_dir` resolves a scene given as a file path. Throws SceneError naming the
  // field (a JSON pointer into the spec) and what is wrong.
  static CampaignSpec from_json(const nlohmann::json& spec, const std::string& base_dir);
  static CampaignSpec from_file(const std::string& path);
};

// The design: sample i's point in [0, 1)^d, and its input values.
class CampaignDesign {
 public:
  explicit CampaignDesign(const CampaignSpec& spec);
  std::vector<double> unit_point(std::int64_t i) const;
  std::vector<nlohmann::json> values(std::int64_t i) const;

 private:
  const CampaignSpec& spec_;
  std::vector<std::vector<std::uint32_t>> strata_;  // Latin hypercube: the stratum of sample i per input
};

// What the summary and the figures use of one record: a few numbers, so that a million samples take
// tens of megabytes (the records themselves stay on disk).
struct CampaignOutcome {
  std::int64_t index = 0;
  int failure_class = 0;  // 3 invalid, 2 failed run, 1 did not succeed, 0 succeeded
  bool success = false, converged = false, hypothesis_failed = false;
  double converged_time = 0, target_distance = 0, max_abs_q = 0;  // NaN: none
  std::vector<double> inputs;                                     // per input; NaN: not a number
};

// Runs the samples of one campaign, one at a time (one runner per worker thread).
//
// Compiled once: when every input is a parameter (/parameters/NAME, a number in the scene) or a
// coordinate of the initial state (/initial/q/K, /initial/v/K) of a Lagrangian scene, the runner compiles
// the scene once with those parameters free (ParametricLagrangianScene) and binds each sample's values,
// which computes what compiling the scene with them computes (scene.h says why, bit for bit). A sample
// it cannot take so (a value that is not a finite number, a parameter at 0, an initial state the checks
// refuse: the full compile names the error) is compiled in full. The first sample a runner binds is also
// compiled in full and the two records compared (their wall times aside); if they differ in anything the
// runner compiles every sample in full from then on (compiles_once() turns false).
// Otherwise each sample's values are written into one scene document the runner keeps (every sample
// writes every input's path, distinct and not nested, so nothing of the sample before remains) and the
// document is compiled.
class CampaignSampleRunner {
 public:
  enum class Compile { kOnceWhenPossible, kEverySample };
  // `max_steps`: a caller's step limit on each run (a server's); a sample that needs more fails at it
  // and is recorded as failed.
  CampaignSampleRunner(const CampaignSpec& spec, const CampaignDesign& design, std::optional<std::int64_t> max_steps = std::nullopt,
                       Compile compile = Compile::kOnceWhenPossible);
  ~CampaignSampleRunner();
  // Sample i's record. Never throws for a bad sample: an invalid scene or a failed run is recorded as
  // such, with the field and the reason.
  nlohmann::json run(std::int64_t i);
  // Whether samples are bound to the scene compiled once (see above).
  bool compiles_once() const { return parametric_ != nullptr; }

 private:
  // The record of sample i without its wall time: from the document with the values written in, or
  // from the scene compiled once (nullopt: this sample needs the full compile).
  nlohmann::json run_compiled(std::int64_t i, const std::vector<nlohmann::json>& values);
  std::optional<nlohmann::json> run_bound(std::int64_t i, const std::vector<nlohmann::json>& values);
  nlohmann::json record_of(std::int64_t i, const std::vector<nlohmann::json>& values, const Simulation& sim) const;
  // What every record of sample i starts with, run or not: {"index": i, "inputs": {path: value, ...},
  // "spec_hash": the spec's hash}: what identifies it as sample i of this campaign (resume and collect
  // refuse a record whose hash or inputs differ from the spec's).
  nlohmann::json record_head(std::int64_t i, const std::vector<nlohmann::json>& values) const;

  const CampaignSpec& spec_;
  const CampaignDesign& design_;
  std::optional<std::int64_t> max_steps_;
  nlohmann::json doc_;
  std::vector<nlohmann::json::json_pointer> paths_;
  // Compiled once: the scene, and where each input goes (a free parameter k, q0[k] or v0[k]).
  struct Target {
    enum Kind { kParameter, kInitialQ, kInitialV } kind;
    int index;
  };
  std::unique_ptr<ParametricLagrangianScene> parametric_;
  std::vector<Target> targets_;
  bool checked_ = false;  // the first bound sample has been compared with its full compile
};

// The summary of a campaign's records (all of them, each index once).
nlohmann::json summarize_campaign(const CampaignSpec& spec, const std::vector<nlohmann::json>& records);
std::string format_campaign_summary(const nlohmann::json& summary);

struct CampaignRunOptions {
  int workers = 1;
  std::int64_t begin = 0, end = -1;  // the index range [begin, end) (end < 0: every sample)
  // A task of a split campaign (a Slurm array task, a Kubernetes pod): its records go to its own part
  // file, parts/<begin>-<end>.jsonl.partial, renamed to parts/<begin>-<end>.jsonl when the range is done,
  // and the summary is left to collect_campaign. Otherwise: samples.jsonl and samples.csv, and the summary
  // once every sample is present.
  bool part = false;
  const std::atomic<bool>* stop = nullptr;  // set (e.g. by SIGINT) to stop after the samples running now
  std::optional<std::int64_t> max_steps;    // per sample (CampaignSampleRunner)
  // The bytes the files this run writes may take on disk (0: no limit): samples.jsonl and samples.csv,
  // or a task's own part file, counting what earlier runs of the campaign left in them; a record that
  // would pass it ends the run with std::runtime_error, the records before it kept.
  std::int64_t max_bytes = 0;
  // The integration steps the campaign may take (0: no limit), counting the steps of the records already
  // in the files this run reads (a campaign resumed after a restart) and those of every sample it runs:
  // once the count reaches the limit with samples still to run, the run ends with std::runtime_error
  // ("reached the limit of N integration steps"), the records so far kept. No sample starts once the
  // count has reached the limit; samples running then finish and are recorded (each bounded by max_steps).
  std::int64_t max_total_steps = 0;
  std::function<void(std::int64_t done, std::int64_t total)> progress;  // after each sample, from one thread
};

struct CampaignRunResult {
  std::int64_t ran = 0;      // samples computed by this run
  std::int64_t steps = 0;    // integration steps of those samples
  std::int64_t skipped = 0;  // already in the directory
  bool stopped = false;      // stopped before every sample of the range was done
  bool summarized = false;   // every sample present: summary.json written
};

// The integration steps a campaign's samples can take, bounded sample by sample: sample i's bound is
// ceil((t_end - t0) / h) of its own integrator settings, its inputs applied (an input may be an integrator
// setting, or a parameter the settings' expressions use), capped by its max_steps and by `cap` (a caller's
// per-run limit: the runner stops a sample there). A sample whose settings are invalid runs no step (0).
// For the adaptive step rules h is the largest step, so the bound is their least count: a run may take
// more, up to its max_steps (CampaignRunOptions::max_total_steps holds a run to a total whatever the
// samples take).
struct CampaignStepBound {
  std::int64_t base = 0;             // the scene without the inputs: ceil((t_end - t0) / h), capped
  bool inputs_change_steps = false;  // some input is an integrator setting, or a parameter they may use
  std::int64_t largest = 0;          // the largest bound of one sample
  std::int64_t largest_sample = -1;  // the first sample with it
  std::int64_t total = 0;            // the sum over the samples (saturating), or the part summed when it passed stop_above
  bool stopped = false;              // the sum passed stop_above and was not finished
  int input = -1;                    // when inputs change steps: the input whose value alone raises largest_sample's bound most
};
CampaignStepBound campaign_step_bound(const CampaignSpec& spec, std::optional<std::int64_t> cap = std::nullopt,
                                      std::int64_t stop_above = std::numeric_limits<std::int64_t>::max());

// Runs the campaign's samples in the range that the directory does not hold yet, appending each record as
// it finishes, and writes the summary when every sample is present. Throws std::runtime_error (a
// directory that holds another campaign, an unreadable record, a record that is not this campaign's)
// naming the file (and the line).
//
// Every record read (resume, --collect, the figures, a Slurm resubmission's count) must be one of this
// campaign's: its spec_hash equal to the spec's, its inputs exactly those the sampler draws for its index
// (compared as JSON values: the doubles are written with round-trip precision), and its success what its
// own status, convergence and target distance make it. Otherwise the error is "'FILE' line N: ..." and
// nothing is run or summarized: a foreign or edited record never enters a summary.
CampaignRunResult run_campaign(const CampaignSpec& spec, const std::string& dir, const CampaignRunOptions& options);

// Makes `dir` the campaign's directory: writes campaign.json, or checks that the one there is this spec's
// (else std::runtime_error: the directory holds a different campaign).
void claim_campaign_directory(const CampaignSpec& spec, const std::string& dir);

// Task k of `tasks` takes the contiguous block [k N / tasks, (k + 1) N / tasks) of the N samples.
std::pair<std::int64_t, std::int64_t> task_range(std::int64_t samples, std::int64_t task, std::int64_t tasks);
// How many samples of each task's block have no record in the directory yet (a part cut short by a
// killed task counts its complete records).
std::vector<std::int64_t> missing_per_task(const std::string& dir, const CampaignSpec& spec, std::int64_t tasks);

// The outcomes of every record in a campaign directory, by index (a cut record is an error).
std::vector<CampaignOutcome> read_campaign_outcomes(const CampaignSpec& spec, const std::string& dir);

// Reads every record of a campaign directory, checks that each sample is present exactly once, writes
// summary.json and summary.txt and returns the summary. Throws std::runtime_error naming what is missing,
// duplicated or malformed.
nlohmann::json collect_campaign(const std::string& dir);

// Statistics the summary uses, for tests.
struct WilsonInterval {
  double low, high;
};
WilsonInterval wilson_interval(std::int64_t successes, std::int64_t n, double z = 1.959963984540054);
// The q-quantile of sorted values, linear between order statistics (Hyndman and Fan's type 7).
double quantile_sorted(const std::vector<double>& sorted, double q);
// Spearman's rank correlation (average ranks for ties); nullopt when either side is constant or n < 3.
std::optional<double> spearman(const std::vector<double>& x, const std::vector<double>& y);

}  // namespace moreau::scene
