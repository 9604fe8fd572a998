// Robustness campaigns (analysis/include/moreau/analysis/campaign.h): the samplers against their defining
// properties (Sobol's known first points and stratification, one Latin-hypercube point per stratum,
// order-independent Monte Carlo), the distributions' inverse CDFs against closed forms, the statistics
// against hand-computed values, the spec's errors, and the campaign directory: the same records however
// the samples are split, a stop and a killed write resumed without loss or duplicates.
#include "moreau/analysis/campaign.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <fstream>
#include <map>
#include <numeric>
#include <set>
#include <sstream>

#include "moreau/scene/scene.h"
#include "support/one_dof_tracking.h"
#include "support/scratch_dir.h"

namespace moreau::scene {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using ::testing::HasSubstr;

std::string source_path(const std::string& rel) { return std::string(MOREAU_SOURCE_DIR) + "/" + rel; }

// The forced relay (scenes/forced-relay.json, 1-DOF, rests at t* = m v0 / (a - f)) with uncertain f
// and v0: cheap samples, an outcome that depends on them in a known way.
json relay_spec(const std::string& sampler, std::int64_t samples) {
  json scene = read_scene_file(source_path("scenes/forced-relay.json"));
  scene["integrator"]["t_end"] = 1.0;
  scene.erase("exact");
  return {{"name", "relay"},
          {"scene", scene},
          {"inputs",
           {{{"path", "/parameters/f"}, {"distribution", {{"type", "uniform"}, {"low", 0.0}, {"high", 1.0}}}},
            {{"path", "parameters.v0"}, {"distribution", {{"type", "log-uniform"}, {"low", 0.1}, {"high", 2.0}}}}}},
          {"sampler", sampler},
          {"samples", samples},
          {"seed", 7}};
}

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(moreau::test_support::scratch_dir()) / name;
  fs::remove_all(d);
  return d;
}

// ---- samplers ----

TEST(CampaignSampler, SobolGivesTheKnownFirstPointsAndStratifiesEveryInput) {
  json spec = relay_spec("sobol", 64);
  const CampaignSpec s = CampaignSpec::from_json(spec, "");
  const CampaignDesign design(s);
  // The 2-D Sobol sequence from its origin (Bratley and Fox's Gray-code order).
  const double expected[][2] = {{0.0, 0.0}, {0.5, 0.5}, {0.75, 0.25}, {0.25, 0.75}, {0.375, 0.375}, {0.875, 0.875}};
  for (int i = 0; i < 6; ++i) {
    const auto u = design.unit_point(i);
    EXPECT_EQ(u[0], expected[i][0]) << i;
    EXPECT_EQ(u[1], expected[i][1]) << i;
  }
  // Any 2^m consecutive points from index 0: each input's interval [0, 1) cut in 2^m equal strata holds
  // one point each (every Sobol coordinate is a (0, m, 1)-net).
  for (int m = 1; m <= 6; ++m) {
    const int n = 1 << m;
    for (int d = 0; d < 2; ++d) {
      std::set<int> strata;
      for (int i = 0; i < n; ++i) strata.insert(static_cast<int>(design.unit_point(i)[d] * n));
      EXPECT_EQ(static_cast<int>(strata.size()), n) << "m = " << m << ", input " << d;
    }
  }
}

TEST(CampaignSampler, LatinHypercubePutsOnePointInEachStratumOfEveryInput) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("latin-hypercube", 500), "");
  const CampaignDesign design(s);
  for (int d = 0; d < 2; ++d) {
    std::set<int> strata;
    for (int i = 0; i < 500; ++i) {
      const double u = design.unit_point(i)[d];
      ASSERT_GE(u, 0.0);
      ASSERT_LT(u, 1.0);
      strata.insert(static_cast<int>(u * 500));
    }
    EXPECT_EQ(strata.size(), 500u) << "input " << d;
  }
  // Another seed, another design.
  json other = relay_spec("latin-hypercube", 500);
  other["seed"] = 8;
  const CampaignSpec s2 = CampaignSpec::from_json(other, "");
  EXPECT_NE(CampaignDesign(s2).unit_point(0), design.unit_point(0));
}

TEST(CampaignSampler, MonteCarloDependsOnlyOnTheSeedAndTheIndex) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("monte-carlo", 20000), "");
  const CampaignDesign a(s), b(s);
  // Any order, any design object: the same point.
  EXPECT_EQ(a.unit_point(12345), b.unit_point(12345));
  EXPECT_EQ(a.unit_point(7), b.unit_point(7));
  EXPECT_NE(a.unit_point(7), a.unit_point(8));
  // Uniform on [0, 1): the mean of 20000 draws is 1/2 within 5 standard errors (1/sqrt(12 n)), and the
  // two inputs are uncorrelated within 5 standard errors (1/sqrt(n)).
  double m0 = 0, m1 = 0, c = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const auto u = a.unit_point(i);
    m0 += u[0];
    m1 += u[1];
    c += (u[0] - 0.5) * (u[1] - 0.5);
  }
  EXPECT_NEAR(m0 / n, 0.5, 5.0 / std::sqrt(12.0 * n));
  EXPECT_NEAR(m1 / n, 0.5, 5.0 / std::sqrt(12.0 * n));
  EXPECT_NEAR(12.0 * c / n, 0.0, 5.0 / std::sqrt(n));
}

TEST(CampaignSampler, GridIsTheProductWithTheLastInputFastest) {
  json spec = relay_spec("grid", 0);
  spec.erase("samples");
  spec["inputs"][0]["distribution"] = {{"type", "grid"}, {"low", 0.0}, {"high", 1.0}, {"count", 3}};
  spec["inputs"][1]["distribution"] = {{"type", "discrete"}, {"values", {0.5, 1.5}}};
  const CampaignSpec s = CampaignSpec::from_json(spec, "");
  ASSERT_EQ(s.samples, 6);
  const CampaignDesign d(s);
  const double f[] = {0.0, 0.0, 0.5, 0.5, 1.0, 1.0}, v[] = {0.5, 1.5, 0.5, 1.5, 0.5, 1.5};
  for (int i = 0; i < 6; ++i) {
    const auto x = d.values(i);
    EXPECT_EQ(x[0].get<double>(), f[i]) << i;
    EXPECT_EQ(x[1].get<double>(), v[i]) << i;
  }
  spec["samples"] = 7;
  EXPECT_THROW(CampaignSpec::from_json(spec, ""), SceneError);
}

// ---- distributions ----

TEST(CampaignDistribution, InverseCdfsAgreeWithClosedForms) {
  InputDistribution u;
  u.kind = InputDistribution::Kind::kUniform;
  u.low = -2;
  u.high = 6;
  EXPECT_EQ(u.at(0.25).get<double>(), 0.0);
  InputDistribution lu;
  lu.kind = InputDistribution::Kind::kLogUniform;
  lu.low = 0.01;
  lu.high = 100;
  EXPECT_NEAR(lu.at(0.5).get<double>(), 1.0, 1e-12);  // the geometric mean
  EXPECT_NEAR(lu.at(0.75).get<double>(), 10.0, 1e-12);
  InputDistribution n;
  n.kind = InputDistribution::Kind::kNormal;
  n.mean = 3;
  n.stddev = 0.5;
  n.low = 2;
  n.high = 4;
  EXPECT_NEAR(n.at(0.5).get<double>(), 3.0, 1e-12);  // symmetric bounds: the median is the mean
  // Truncated at mean +- 2 sigma: Phi(2) = 0.97724986805182079; u = 1 maps to the upper bound, and the
  // quantile of u = (0.84134474606854293 - Phi(-2)) / (Phi(2) - Phi(-2)) is mean + sigma.
  const double phi2 = 0.97724986805182079, phi1 = 0.84134474606854293;
  EXPECT_NEAR(n.at((phi1 - (1 - phi2)) / (2 * phi2 - 1)).get<double>(), 3.5, 1e-9);
  EXPECT_LE(n.at(0.999999999).get<double>(), 4.0);
  EXPECT_GE(n.at(0.0).get<double>(), 2.0);
}

// ---- statistics ----

TEST(CampaignStatistics, WilsonQuantilesAndSpearmanAgainstHandComputedValues) {
  // k = n: the interval is [n / (n + z^2), 1]; k = 0: [0, z^2 / (n + z^2)].
  const double z = 1.959963984540054;
  EXPECT_NEAR(wilson_interval(256, 256).low, 256 / (256 + z * z), 1e-15);
  EXPECT_DOUBLE_EQ(wilson_interval(256, 256).high, 1.0);
  EXPECT_NEAR(wilson_interval(0, 10).high, z * z / (10 + z * z), 1e-15);
  // 8 of 10: (p + z^2/2n)/(1 + z^2/n) -+ z/(1 + z^2/n) sqrt(p(1-p)/n + z^2/4n^2) = 0.49016 .. 0.94332.
  EXPECT_NEAR(wilson_interval(8, 10).low, 0.4901624, 1e-6);
  EXPECT_NEAR(wilson_interval(8, 10).high, 0.9433178, 1e-6);
  // Type 7 quantiles (numpy's default): [1, 2, 3, 4] -> median 2.5, first quartile 1.75.
  EXPECT_DOUBLE_EQ(quantile_sorted({1, 2, 3, 4}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(quantile_sorted({1, 2, 3, 4}, 0.25), 1.75);
  EXPECT_DOUBLE_EQ(quantile_sorted({1, 2, 3, 4}, 1.0), 4.0);
  // Spearman: 1 - 6 sum d^2 / (n (n^2 - 1)) without ties; any monotone map gives +-1; ties take the
  // average rank (x = 1, 2, 2, 3 has ranks 1, 2.5, 2.5, 4).
  EXPECT_NEAR(*spearman({1, 2, 3, 4, 5}, {2, 1, 4, 3, 5}), 0.8, 1e-15);
  EXPECT_NEAR(*spearman({1, 2, 3, 4, 5}, {1, 8, 27, 64, 125}), 1.0, 1e-15);
  EXPECT_NEAR(*spearman({1, 2, 3, 4, 5}, {5, 4, 3, 2, 1}), -1.0, 1e-15);
  // Ties: Pearson of ranks (1, 2.5, 2.5, 4) and (1, 2, 3, 4) = 4.5 / sqrt(4.5 * 5) = 0.9486833.
  EXPECT_NEAR(*spearman({1, 2, 2, 3}, {1, 2, 3, 4}), 4.5 / std::sqrt(4.5 * 5.0), 1e-15);
  EXPECT_FALSE(spearman({1, 1, 1}, {1, 2, 3}).has_value());
}

// ---- the spec's errors ----

TEST(CampaignSpec, EveryBadFieldIsNamed) {
  struct Case {
    const char* what;
    std::function<void(json&)> edit;
    const char* pointer;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"unknown path", [](json& s) { s["inputs"][0]["path"] = "/parameters/nope"; }, "/inputs/0/path", "nothing at"},
      // An array index beyond size_t: nlohmann::json's contains() threw instead of answering (the campaign
      // fuzzer's find: the process aborted).
      {"array index past size_t", [](json& s) { s["inputs"][0]["path"] = "/initial/q/66666666666666666666666666666666"; }, "/inputs/0/path",
       "nothing at"},
      {"inverted bounds", [](json& s) { s["inputs"][0]["distribution"]["low"] = 2.0; }, "/inputs/0/distribution/high", "inverted"},
      {"non-finite", [](json& s) { s["inputs"][1]["distribution"]["high"] = std::numeric_limits<double>::infinity(); },
       "/inputs/1/distribution/high", "finite"},
      {"log of zero", [](json& s) { s["inputs"][1]["distribution"]["low"] = 0.0; }, "/inputs/1/distribution/low", "low > 0"},
      {"zero samples", [](json& s) { s["samples"] = 0; }, "/samples", ">= 1"},
      {"too many samples", [](json& s) { s["samples"] = kMaxCampaignSamples + 1; }, "/samples", "limit"},
      {"unknown sampler", [](json& s) { s["sampler"] = "halton"; }, "/sampler", "unknown sampler"},
      {"unknown distribution", [](json& s) { s["inputs"][0]["distribution"]["type"] = "beta"; }, "/inputs/0/distribution/type", "unknown"},
      {"unknown field", [](json& s) { s["sample"] = 3; }, "/sample", "unknown field"},
      {"duplicate input", [](json& s) { s["inputs"][1]["path"] = "/parameters/f"; }, "/inputs/1/path", "already"},
      {"bad scene", [](json& s) { s["scene"]["integrator"]["h"] = -1; }, "/scene/integrator/h", ""},
      {"normal without mass",
       [](json& s) {
         s["inputs"][0]["distribution"] = {{"type", "normal"}, {"mean", 0}, {"std", 1e-3}, {"low", 5}, {"high", 6}};
       },
       "/inputs/0/distribution/low", "no probability"},
      {"target size",
       [](json& s) {
         s["target"] = {{"q", {1, 2}}, {"tolerance", 0.1}};
       },
       "/target/q", "1 numbers"},
      {"map of a non-input",
       [](json& s) {
         s["map"] = {"/parameters/f", "/parameters/m"};
       },
       "/map/1", "not one of the inputs"},
      {"map of one input twice",
       [](json& s) {
         s["map"] = {"/parameters/f", "parameters.f"};
       },
       "/map/1", "same input"},
      {"full_report not a boolean", [](json& s) { s["full_report"] = "no"; }, "/full_report", "true or false"},
      {"name not a string", [](json& s) { s["name"] = 5; }, "/name", "expected a string"},
      // Names are data (they reach Slurm's batch script and command lines): 1 to 64 of [A-Za-z0-9._-].
      {"name with a newline", [](json& s) { s["name"] = "x\ntouch FILE\n#"; }, "/name", "is not a campaign name"},
      {"name with spaces", [](json& s) { s["name"] = "a --output=/tmp/x --wrap=true"; }, "/name", "is not a campaign name"},
      {"name with a dollar", [](json& s) { s["name"] = "$(touch x)"; }, "/name", "is not a campaign name"},
      {"empty name", [](json& s) { s["name"] = ""; }, "/name", "is not a campaign name"},
      {"name of 65 characters", [](json& s) { s["name"] = std::string(65, 'a'); }, "/name", "is not a campaign name"},
      {"overlapping inputs", [](json& s) { s["inputs"][1]["path"] = "/parameters"; }, "/inputs/1/path", "overlap"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    json spec = relay_spec("monte-carlo", 10);
    c.edit(spec);
    try {
      CampaignSpec::from_json(spec, "");
      ADD_FAILURE() << "accepted";
    } catch (const SceneError& e) {
      EXPECT_EQ(e.pointer(), c.pointer) << e.what();
      EXPECT_THAT(e.reason(), HasSubstr(c.reason));
    }
  }
}

// The longest name and every allowed character are taken as they are.
TEST(CampaignSpec, NamesOfTheSafeSetAreKept) {
  for (const std::string& name : {std::string(64, 'z'), std::string("Relay_2.v-3"), std::string("-"), std::string("campaign")}) {
    json spec = relay_spec("monte-carlo", 4);
    spec["name"] = name;
    EXPECT_EQ(CampaignSpec::from_json(spec, "").name, name);
  }
  json unnamed = relay_spec("monte-carlo", 4);
  unnamed.erase("name");
  EXPECT_EQ(CampaignSpec::from_json(unnamed, "").name, "campaign");
}

// FNV-1a (64 bits), written out here from its definition, checked against the published test vectors.
std::string fnv1a64(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

// The spec's hash is FNV-1a of its document's compact JSON text (keys sorted), whole doubles written as
// integers: documents equal as JSON values have one hash, any other change gives another.
TEST(CampaignSpec, TheHashIsFnv1aOfTheCanonicalDocument) {
  ASSERT_EQ(fnv1a64(""), "cbf29ce484222325");
  ASSERT_EQ(fnv1a64("a"), "af63dc4c8601ec8c");
  ASSERT_EQ(fnv1a64("foobar"), "85944171f73967e8");
  // A document of integers, strings and non-whole doubles is its own canonical form.
  const json doc = {{"b", 1}, {"a", {{"y", "text"}, {"x", 0.25}}}, {"c", {1, 2, 3}}};
  EXPECT_EQ(campaign_spec_hash(doc), fnv1a64(R"({"a":{"x":0.25,"y":"text"},"b":1,"c":[1,2,3]})"));
  json as_doubles = doc;
  as_doubles["b"] = 1.0;
  as_doubles["c"] = {1.0, 2.0, 3.0};
  EXPECT_EQ(campaign_spec_hash(as_doubles), campaign_spec_hash(doc));
  json other = doc;
  other["a"]["x"] = 0.5;
  EXPECT_NE(campaign_spec_hash(other), campaign_spec_hash(doc));
  // A spec's hash is that of its document (the scene inlined), and every record carries it.
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 4), "");
  EXPECT_EQ(s.hash, campaign_spec_hash(s.document));
  EXPECT_EQ(s.hash.size(), 16u);
  const CampaignDesign design(s);
  EXPECT_EQ(CampaignSampleRunner(s, design).run(2)["spec_hash"], s.hash);
  json reseeded = relay_spec("sobol", 4);
  reseeded["seed"] = 8;
  EXPECT_NE(CampaignSpec::from_json(reseeded, "").hash, s.hash);
}

// ---- the steps of the samples ----

// Each sample's bound is ceil((t_end - t0) / h) of its own settings: inputs on t_end, on h, or on a
// parameter h is an expression of change it; others do not. Reference: the step counts by hand.
TEST(CampaignSteps, EachSampleIsBoundedByItsOwnSettings) {
  // The relay at h = 1e-3 over [0, 1]: 1000 steps; f and v0 do not touch the settings.
  const CampaignSpec plain = CampaignSpec::from_json(relay_spec("sobol", 8), "");
  CampaignStepBound b = campaign_step_bound(plain);
  EXPECT_FALSE(b.inputs_change_steps);
  EXPECT_EQ(b.base, 1000);
  EXPECT_EQ(b.total, 8000);
  EXPECT_EQ(b.input, -1);
  // The issue's case: a 50-step scene whose 8 samples each set t_end = 2000: 2,000,000 steps each.
  json raised = relay_spec("monte-carlo", 8);
  raised["scene"]["integrator"]["t_end"] = 0.05;
  raised["inputs"].push_back({{"path", "/integrator/t_end"}, {"distribution", {{"type", "discrete"}, {"values", {2000.0}}}}});
  b = campaign_step_bound(CampaignSpec::from_json(raised, ""));
  EXPECT_TRUE(b.inputs_change_steps);
  EXPECT_EQ(b.base, 50);
  EXPECT_EQ(b.largest, 2'000'000);
  EXPECT_EQ(b.total, 16'000'000);
  EXPECT_EQ(b.input, 2);
  EXPECT_FALSE(b.stopped);
  // Capped by a caller's per-run limit (the runner stops a sample there), and summed no further than asked.
  b = campaign_step_bound(CampaignSpec::from_json(raised, ""), 100'000);
  EXPECT_EQ(b.largest, 100'000);
  EXPECT_EQ(b.total, 800'000);
  b = campaign_step_bound(CampaignSpec::from_json(raised, ""), std::nullopt, 3'000'000);
  EXPECT_TRUE(b.stopped);
  EXPECT_GT(b.total, 3'000'000);
  // A grid over t_end and h: 0.5 / 1e-3, 0.5 / 1e-4, 2 / 1e-3, 2 / 1e-4; h = 10 is longer than the
  // interval (an invalid sample: no step).
  json grid = relay_spec("grid", 0);
  grid.erase("samples");
  grid["inputs"] = {{{"path", "/integrator/t_end"}, {"distribution", {{"type", "discrete"}, {"values", {0.5, 2.0}}}}},
                    {{"path", "integrator.h"}, {"distribution", {{"type", "discrete"}, {"values", {1e-3, 1e-4, 10.0}}}}}};
  b = campaign_step_bound(CampaignSpec::from_json(grid, ""));
  EXPECT_EQ(b.largest, 20'000);
  EXPECT_EQ(b.largest_sample, 4);  // t_end = 2, h = 1e-4
  EXPECT_EQ(b.total, 500 + 5'000 + 0 + 2'000 + 20'000 + 0);
  EXPECT_EQ(b.input, 1);  // h alone makes sample 4's 10,000 steps; t_end alone 2000
  // h an expression of a parameter: the parameter's input changes the steps.
  json param = relay_spec("grid", 0);
  param.erase("samples");
  param["scene"]["parameters"]["dt"] = 1e-3;
  param["scene"]["integrator"]["h"] = "dt";
  param["inputs"] = {{{"path", "/parameters/dt"}, {"distribution", {{"type", "discrete"}, {"values", {1e-3, 1e-5}}}}}};
  b = campaign_step_bound(CampaignSpec::from_json(param, ""));
  EXPECT_TRUE(b.inputs_change_steps);
  EXPECT_EQ(b.total, 1000 + 100'000);
  EXPECT_EQ(b.input, 0);
}

// ---- the campaign directory ----

// Every record of a campaign directory (samples.jsonl and the parts), by index.
std::map<std::int64_t, json> records_of(const fs::path& dir) {
  std::map<std::int64_t, json> r;
  std::vector<fs::path> files = {dir / "samples.jsonl"};
  if (fs::is_directory(dir / "parts"))
    for (const auto& e : fs::directory_iterator(dir / "parts")) files.push_back(e.path());
  std::string all;
  for (const auto& f : files) {
    std::ifstream in(f);
    all.append(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::istringstream in(all);
  for (std::string line; std::getline(in, line);) {
    json j = json::parse(line);
    const auto i = j["index"].get<std::int64_t>();
    EXPECT_EQ(r.count(i), 0u) << "sample " << i << " twice";
    // What depends on the machine's clock, not on the sample.
    j.erase("wall_seconds");
    j["report"].erase("wall_seconds");
    j["report"].erase("phase_seconds");
    r[i] = j;
  }
  return r;
}

TEST(CampaignRun, TheSameRecordsHoweverTheSamplesAreSplit) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("latin-hypercube", 60), "");
  const fs::path one = fresh_dir("split1"), two = fresh_dir("split2");
  CampaignRunOptions all;
  all.workers = 2;
  const CampaignRunResult r1 = run_campaign(s, one.string(), all);
  EXPECT_EQ(r1.ran, 60);
  EXPECT_TRUE(r1.summarized);
  // Three ranges as tasks (each its own part file), one worker, out of order, then collected.
  for (auto [b, e] : {std::pair{40, 60}, std::pair{0, 15}, std::pair{15, 40}}) {
    CampaignRunOptions part;
    part.begin = b;
    part.end = e;
    part.part = true;
    const CampaignRunResult r = run_campaign(s, two.string(), part);
    EXPECT_EQ(r.ran, e - b);
    EXPECT_FALSE(r.summarized);
    EXPECT_TRUE(fs::exists(two / "parts" / (std::to_string(b) + "-" + std::to_string(e) + ".jsonl")));
  }
  const json collected = collect_campaign(two.string());
  const auto a = records_of(one), b = records_of(two);
  ASSERT_EQ(a.size(), 60u);
  EXPECT_EQ(a, b);
  EXPECT_EQ(read_scene_file((one / "summary.json").string()), collected);
  // A task run again on its complete block (a requeue, a resubmission) computes nothing and leaves its
  // part as it was.
  const fs::path part = two / "parts" / "15-40.jsonl";
  const auto size = fs::file_size(part);
  CampaignRunOptions again;
  again.begin = 15;
  again.end = 40;
  again.part = true;
  const CampaignRunResult r3 = run_campaign(s, two.string(), again);
  EXPECT_EQ(r3.ran, 0);
  EXPECT_EQ(r3.skipped, 25);
  EXPECT_EQ(fs::file_size(part), size);
  EXPECT_FALSE(fs::exists(two / "parts" / "15-40.jsonl.partial"));
  EXPECT_EQ(records_of(two), a);
  // The relay rests at t* = m v0 / (a - f) (m = 1.5, a = 2): success exactly when t* <= 1 - window.
  for (const auto& [i, r] : a) {
    const double f = r["inputs"]["/parameters/f"], v0 = r["inputs"]["/parameters/v0"];
    const double t_stop = 1.5 * v0 / (2.0 - f);
    if (t_stop < 0.95) {
      EXPECT_TRUE(r["success"].get<bool>()) << i;
      EXPECT_NEAR(r["converged_time"].get<double>(), t_stop, 2e-3) << i;
    } else if (t_stop > 1.0) {
      EXPECT_FALSE(r["success"].get<bool>()) << i;
    }
  }
  const json summary = read_scene_file((one / "summary.json").string());
  // The success rate's sensitivity: a larger v0 stops later, so fails more: negative rank correlation.
  EXPECT_LT(summary["sensitivity"]["inputs"][1]["success"].get<double>(), 0.0);
  EXPECT_GT(summary["sensitivity"]["inputs"][1]["converged_time"].get<double>(), 0.9);
  // The CSV: a header and one row per sample.
  std::ifstream csv(one / "samples.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_THAT(header, HasSubstr("index,\"/parameters/f\",\"/parameters/v0\",status,success"));
  std::size_t rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  EXPECT_EQ(rows, 60u);
  fs::remove_all(one);
  fs::remove_all(two);
}

// The summary against values computed here, independently of the campaign's code: which samples succeed
// from the relay's closed form (it rests at t* = m v0 / (a - f), m = 1.5, a = 2; success when t* <= 1
// minus the report's rest window, so samples with t* in [0.95, 1] are left undecided here), the Wilson
// interval in its textbook form (k + z^2/2) / (n + z^2) +- z / (n + z^2) sqrt(k (n - k) / n + z^2 / 4), and
// Spearman's rho of v0 with the convergence time from ranks computed here (Pearson's r of the ranks).
TEST(CampaignRun, TheSummaryIsWhatTheClosedFormsGive) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("monte-carlo", 120), "");
  const fs::path dir = fresh_dir("closed-form-summary");
  CampaignRunOptions all;
  all.workers = 2;
  ASSERT_EQ(run_campaign(s, dir.string(), all).ran, 120);
  const auto records = records_of(dir);
  ASSERT_EQ(records.size(), 120u);
  std::int64_t sure = 0, undecided = 0;
  std::vector<double> v0s, times;
  for (const auto& [i, r] : records) {
    const double f = r["inputs"]["/parameters/f"], v0 = r["inputs"]["/parameters/v0"];
    const double t_stop = 1.5 * v0 / (2.0 - f);
    if (t_stop < 0.95) {
      ++sure;
    } else if (t_stop <= 1.0) {
      ++undecided;
    }
    if (r["converged_time"].is_number()) {
      v0s.push_back(v0);
      times.push_back(r["converged_time"].get<double>());
      EXPECT_NEAR(times.back(), t_stop, 2e-3) << i;
    }
  }
  const json summary = read_scene_file((dir / "summary.json").string());
  const std::int64_t n = summary["samples"], k = summary["successes"];
  EXPECT_EQ(n, 120);
  EXPECT_GE(k, sure);
  EXPECT_LE(k, sure + undecided);
  EXPECT_GT(sure, 10);  // the test says something: both outcomes occur
  EXPECT_LT(sure, 120 - 10);
  const double z = 1.959963984540054, nn = static_cast<double>(n), kk = static_cast<double>(k);
  const double center = (kk + z * z / 2.0) / (nn + z * z);
  const double half = z / (nn + z * z) * std::sqrt(kk * (nn - kk) / nn + z * z / 4.0);
  EXPECT_NEAR(summary["success_rate_95"]["low"].get<double>(), std::max(0.0, center - half), 1e-12);
  EXPECT_NEAR(summary["success_rate_95"]["high"].get<double>(), std::min(1.0, center + half), 1e-12);
  EXPECT_DOUBLE_EQ(summary["success_rate"].get<double>(), kk / nn);
  // Ranks, ties sharing their average rank (rest times are multiples of h, so they tie), then Pearson's r
  // of the ranks.
  const auto ranks = [](const std::vector<double>& x) {
    std::vector<std::size_t> order(x.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return x[a] < x[b]; });
    std::vector<double> r(x.size());
    for (std::size_t p = 0; p < order.size();) {
      std::size_t q = p;
      while (q + 1 < order.size() && x[order[q + 1]] == x[order[p]]) ++q;
      for (std::size_t j = p; j <= q; ++j) r[order[j]] = (static_cast<double>(p + 1) + static_cast<double>(q + 1)) / 2.0;
      p = q + 1;
    }
    return r;
  };
  const std::vector<double> rx = ranks(v0s), ry = ranks(times);
  const double m = (static_cast<double>(rx.size()) + 1.0) / 2.0;  // the mean rank, ties or not
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t j = 0; j < rx.size(); ++j) {
    sxy += (rx[j] - m) * (ry[j] - m);
    sxx += (rx[j] - m) * (rx[j] - m);
    syy += (ry[j] - m) * (ry[j] - m);
  }
  ASSERT_GE(rx.size(), 3u);
  const json& v0_row = summary["sensitivity"]["inputs"][1];
  ASSERT_EQ(v0_row["input"], "/parameters/v0");
  EXPECT_NEAR(v0_row["converged_time"].get<double>(), sxy / std::sqrt(sxx * syy), 1e-12);
  fs::remove_all(dir);
}

// A task completes its part by linking X.jsonl to X.jsonl.partial, then removing the .partial: another
// task or a collection that lists the directory in between sees both names for one file. Each record
// is read once, and a task reads only the parts that can hold its own samples.
// A tracking campaign: the 1-DOF plant m x'' = u + D0 (F = -D0) under the implicit digital controller,
// over plant masses m and perturbations D0, with the controller's model the document's m = 2. Once e's
// transient has passed (Lambda = 3: exp(-3 * 8) at t = 8), the sampled loop sits at its fixed point
// (docs/tracking.md, exact for a constant perturbation whatever the plant's mass, since the plant does not
// accelerate there): u = -D0, sigma = D0 T_s / m^ and e = D0 T_s / (m^ Lambda), with m^ = 2 the model's
// mass. So a sample succeeds exactly when D0 T_s / (2 Lambda) <= E.
TEST(CampaignRun, ATrackingCampaignSucceedsWhereTheFixedPointErrorIsWithinTheTarget) {
  json scene = moreau::test_support::one_dof_tracking("-D0", "0.5*t", {{"law", "implicit"}, {"period", 1e-3}}, 1e-4, 9.0, 0.2, 0.0, 8.0);
  scene["parameters"]["D0"] = 1.0;
  const double E = 5e-4, Ts = 1e-3, lambda = 3.0, model_mass = 2.0;
  const json spec = {{"name", "tracking"},
                     {"scene", scene},
                     {"inputs",
                      {{{"path", "/parameters/m"}, {"distribution", {{"type", "uniform"}, {"low", 1.5}, {"high", 2.5}}}},
                       {{"path", "/parameters/D0"}, {"distribution", {{"type", "uniform"}, {"low", 0.5}, {"high", 5.0}}}}}},
                     {"tracking", {{"error", E}, {"after", 8.0}}},
                     {"sampler", "latin-hypercube"},
                     {"samples", 24},
                     {"seed", 3}};
  const CampaignSpec s = CampaignSpec::from_json(spec, "");
  const fs::path dir = fresh_dir("tracking-campaign");
  CampaignRunOptions all;
  all.workers = 2;
  ASSERT_EQ(run_campaign(s, dir.string(), all).ran, 24);
  int successes = 0, margin = 0;
  for (const auto& [i, r] : records_of(dir)) {
    const double D0 = r["inputs"]["/parameters/D0"];
    const double fixed_point = D0 * Ts / (model_mass * lambda);
    ASSERT_TRUE(r["tracking_error"].is_number()) << r.dump();
    EXPECT_NEAR(r["tracking_error"].get<double>(), fixed_point, 1e-9) << i;
    if (std::abs(fixed_point - E) < 1e-8) continue;  // too close to call: not asserted
    ++margin;
    EXPECT_EQ(r["success"].get<bool>(), fixed_point <= E) << i;
    successes += fixed_point <= E;
  }
  EXPECT_GT(successes, 3);  // both outcomes occur
  EXPECT_LT(successes, margin - 3);
  const json summary = read_scene_file((dir / "summary.json").string());
  EXPECT_EQ(summary["successes"].get<int>(), successes);
}

TEST(CampaignRun, APartSeenUnderBothItsNamesIsReadOnce) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 30), "");
  const fs::path dir = fresh_dir("two-names");
  for (auto [b, e] : {std::pair{0, 10}, std::pair{10, 20}}) {
    CampaignRunOptions part;
    part.begin = b;
    part.end = e;
    part.part = true;
    ASSERT_EQ(run_campaign(s, dir.string(), part).ran, e - b);
  }
  // The moment between the link and the removal, held still.
  ASSERT_EQ(::link((dir / "parts" / "0-10.jsonl").c_str(), (dir / "parts" / "0-10.jsonl.partial").c_str()), 0);
  EXPECT_EQ(missing_per_task(dir.string(), s, 3), (std::vector<std::int64_t>{0, 0, 10}));
  EXPECT_EQ(read_campaign_outcomes(s, dir.string()).size(), 20u);
  CampaignRunOptions last;
  last.begin = 20;
  last.end = 30;
  last.part = true;
  // A part that cannot hold samples 20 to 29 is not read by their task (only a collection checks it).
  std::ofstream(dir / "parts" / "5-8.jsonl") << "not a record\n";
  EXPECT_EQ(run_campaign(s, dir.string(), last).ran, 10);
  try {
    collect_campaign(dir.string());
    ADD_FAILURE() << "a part that is not records was collected";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("5-8.jsonl' line 1 is not a sample record"));
  }
  fs::remove(dir / "parts" / "5-8.jsonl");
  // Collected with both names still there: the summary of the same campaign run whole.
  const json collected = collect_campaign(dir.string());
  const fs::path whole = fresh_dir("two-names-whole");
  ASSERT_TRUE(run_campaign(s, whole.string(), CampaignRunOptions{}).summarized);
  EXPECT_EQ(collected, read_scene_file((whole / "summary.json").string()));
  fs::remove_all(dir);
  fs::remove_all(whole);
}

// The byte limit is on the files as they are on disk, not on what one run adds: a campaign stopped and
// resumed (as a restarted server resumes it) under the same limit stops when the files, with what the
// first run wrote, reach it, and keeps the records that fit. Reference: the sizes of samples.jsonl and
// samples.csv, read from the file system.
TEST(CampaignRun, TheByteLimitCountsWhatEarlierRunsWrote) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 50), "");
  const fs::path dir = fresh_dir("bytes-resumed");
  auto on_disk = [&] { return static_cast<std::int64_t>(fs::file_size(dir / "samples.jsonl") + fs::file_size(dir / "samples.csv")); };
  std::atomic<bool> stop{false};
  CampaignRunOptions first;
  first.workers = 1;
  first.stop = &stop;
  first.progress = [&](std::int64_t done, std::int64_t) {
    if (done == 20) stop = true;
  };
  ASSERT_EQ(run_campaign(s, dir.string(), first).ran, 20);
  const std::int64_t after_first = on_disk();
  // Room for about five more records and rows (the first twenty took after_first bytes).
  CampaignRunOptions resumed;
  resumed.workers = 1;
  resumed.max_bytes = after_first + 5 * after_first / 20;
  try {
    run_campaign(s, dir.string(), resumed);
    ADD_FAILURE() << "the resumed run wrote 30 more records under a limit with room for about 5";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("reached the limit of " + std::to_string(resumed.max_bytes) + " bytes"));
  }
  EXPECT_LE(on_disk(), resumed.max_bytes);
  const auto rows = read_campaign_outcomes(s, dir.string());
  EXPECT_GE(rows.size(), 23u);  // the records that fit were kept
  EXPECT_LE(rows.size(), 27u);
  fs::remove_all(dir);
}

TEST(CampaignRun, AStopAndAKilledWriteResumeWithoutLossOrDuplicates) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 50), "");
  const fs::path ref = fresh_dir("ref"), dir = fresh_dir("resume");
  run_campaign(s, ref.string(), CampaignRunOptions{});
  // Stopped after 12 samples (as Ctrl-C does): what finished is kept, no summary yet.
  std::atomic<bool> stop{false};
  CampaignRunOptions o;
  o.stop = &stop;
  o.progress = [&](std::int64_t done, std::int64_t) {
    if (done == 12) stop = true;
  };
  const CampaignRunResult r1 = run_campaign(s, dir.string(), o);
  EXPECT_TRUE(r1.stopped);
  EXPECT_EQ(r1.ran, 12);
  EXPECT_FALSE(fs::exists(dir / "summary.json"));
  EXPECT_THROW(collect_campaign(dir.string()), std::runtime_error);
  // A task killed while writing its 13th record: half a line at the end.
  {
    std::ofstream out(dir / "samples.jsonl", std::ios::app);
    out << "{\"index\": 13, \"inputs\": {\"/param";
  }
  try {
    collect_campaign(dir.string());
    ADD_FAILURE() << "a cut record was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("samples.jsonl' line 13 is cut short"));
  }
  const CampaignRunResult r2 = run_campaign(s, dir.string(), CampaignRunOptions{});
  EXPECT_EQ(r2.skipped, 12);
  EXPECT_EQ(r2.ran, 38);
  EXPECT_TRUE(r2.summarized);
  EXPECT_EQ(records_of(dir), records_of(ref));
  EXPECT_EQ(collect_campaign(dir.string()), read_scene_file((ref / "summary.json").string()));
  // Running it again computes nothing.
  EXPECT_EQ(run_campaign(s, dir.string(), CampaignRunOptions{}).ran, 0);
  // A duplicated record is refused by name.
  {
    std::ifstream in(dir / "samples.jsonl");
    std::string first;
    std::getline(in, first);
    std::ofstream(dir / "samples.jsonl", std::ios::app) << first << "\n";
  }
  try {
    collect_campaign(dir.string());
    ADD_FAILURE() << "a duplicated record was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("is present twice"));
  }
  // Two writers of one records file: the second is refused while the first holds it.
  {
    const fs::path busy = fresh_dir("busy");
    CampaignRunOptions task;
    task.begin = 0;
    task.end = 10;
    task.part = true;
    fs::create_directories(busy / "parts");
    const int fd = ::open((busy / "parts" / "0-10.jsonl.partial").c_str(), O_WRONLY | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(::flock(fd, LOCK_EX), 0);
    try {
      run_campaign(s, busy.string(), task);
      ADD_FAILURE() << "a second writer was let in";
    } catch (const std::runtime_error& e) {
      EXPECT_THAT(e.what(), HasSubstr("is being written by another process"));
    }
    ::close(fd);
    EXPECT_EQ(run_campaign(s, busy.string(), task).ran, 10);
  }
  // A different campaign in the same directory is refused, and nothing there changes.
  json other = relay_spec("sobol", 51);
  try {
    run_campaign(CampaignSpec::from_json(other, ""), dir.string(), CampaignRunOptions{});
    ADD_FAILURE() << "another campaign was run in the directory";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("holds a different campaign"));
  }
  fs::remove_all(ref);
  fs::remove_all(dir);
}

// A run stops once its count of integration steps (the records already there, then each finished
// sample) reaches CampaignRunOptions::max_total_steps, keeping its records; run again under the same
// limit it runs nothing more; without it, it finishes. Reference: every relay sample takes 1000 steps,
// so a limit of 10,500 lets ceil(10500 / 1000) = 11 samples start.
TEST(CampaignRun, TheStepLimitStopsTheRunAndCountsWhatEarlierRunsRan) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 30), "");
  const fs::path dir = fresh_dir("step-limit");
  CampaignRunOptions limited;
  limited.workers = 1;
  limited.max_total_steps = 10'500;
  try {
    run_campaign(s, dir.string(), limited);
    ADD_FAILURE() << "30 samples of 1000 steps ran under a limit of 10500 steps";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("reached the limit of 10500 integration steps"));
  }
  auto records = records_of(dir);
  for (const auto& [i, r] : records) ASSERT_EQ(r["steps"], 1000) << i;
  EXPECT_EQ(records.size(), 11u);
  EXPECT_FALSE(fs::exists(dir / "summary.json"));
  // Resumed under the same limit: the 11,000 steps of the records count, nothing more runs.
  EXPECT_THROW(run_campaign(s, dir.string(), limited), std::runtime_error);
  EXPECT_EQ(records_of(dir).size(), 11u);
  // A limit the whole campaign fits in (30,000 steps) lets it finish.
  limited.max_total_steps = 30'000;
  const CampaignRunResult r = run_campaign(s, dir.string(), limited);
  EXPECT_EQ(r.ran, 19);
  EXPECT_TRUE(r.summarized);
  fs::remove_all(dir);
}

// A record is sample i of this campaign only if it carries the spec's hash, the inputs the sampler draws
// for i (exactly: one ulp off is another input) and the success its own fields make. Resume, --collect,
// the outcomes the figures read and a Slurm resubmission's count all refuse an edited or a foreign record,
// naming the file and the line; the genuine records, put back, are taken again.
TEST(CampaignRun, EditedOrForeignRecordsAreRefusedNamingTheFileAndLine) {
  const CampaignSpec s = CampaignSpec::from_json(relay_spec("sobol", 12), "");
  // Another campaign with the same samples (Sobol ignores the seed) but another spec: its records differ
  // from these by their spec_hash alone.
  json other_doc = relay_spec("sobol", 12);
  other_doc["description"] = "another campaign";
  const CampaignSpec other = CampaignSpec::from_json(other_doc, "");
  ASSERT_NE(other.hash, s.hash);
  const fs::path dir = fresh_dir("edited"), foreign = fresh_dir("foreign");
  CampaignRunOptions one;
  one.workers = 1;  // line k + 1 holds sample k
  ASSERT_TRUE(run_campaign(s, dir.string(), one).summarized);
  ASSERT_TRUE(run_campaign(other, foreign.string(), one).summarized);
  const json summary = read_scene_file((dir / "summary.json").string());
  auto lines_of = [](const fs::path& file) {
    std::vector<std::string> lines;
    std::ifstream in(file);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    return lines;
  };
  const std::vector<std::string> genuine = lines_of(dir / "samples.jsonl"), theirs = lines_of(foreign / "samples.jsonl");
  ASSERT_EQ(genuine.size(), 12u);
  ASSERT_EQ(json::parse(genuine[6])["inputs"], json::parse(theirs[6])["inputs"]);
  auto write = [&](const std::vector<std::string>& lines) {
    std::ofstream out(dir / "samples.jsonl", std::ios::trunc);
    for (const std::string& l : lines) out << l << "\n";
  };
  struct Edit {
    const char* what;
    std::size_t line;  // 1-based
    std::function<std::string(json)> edit;
    const char* phrase;
  };
  const std::vector<Edit> edits = {
      {"an input changed", 3,
       [](json r) {
         r["inputs"]["/parameters/f"] = r["inputs"]["/parameters/f"].get<double>() + 0.125;
         return r.dump();
       },
       "input /parameters/f"},
      {"an input one ulp off", 4,
       [](json r) {
         r["inputs"]["/parameters/v0"] = std::nextafter(r["inputs"]["/parameters/v0"].get<double>(), 10.0);
         return r.dump();
       },
       "input /parameters/v0"},
      {"success flipped", 5,
       [](json r) {
         r["success"] = !r["success"].get<bool>();
         return r.dump();
       },
       "its success is"},
      {"another sample's index", 6,
       [](json r) {
         r["index"] = 7;
         return r.dump();
       },
       "sample 7's input"},
      {"another campaign's record", 7, [&](json) { return theirs[6]; }, "spec_hash"},
      {"no spec_hash", 2,
       [](json r) {
         r.erase("spec_hash");
         return r.dump();
       },
       "no spec_hash"},
  };
  for (const Edit& e : edits) {
    SCOPED_TRACE(e.what);
    std::vector<std::string> lines = genuine;
    lines[e.line - 1] = e.edit(json::parse(lines[e.line - 1]));
    write(lines);
    const std::string where = "samples.jsonl' line " + std::to_string(e.line) + " is not a record of this campaign";
    const std::vector<std::pair<const char*, std::function<void()>>> readers = {
        {"collect", [&] { collect_campaign(dir.string()); }},
        {"resume", [&] { run_campaign(s, dir.string(), one); }},
        {"outcomes", [&] { read_campaign_outcomes(s, dir.string()); }},
        {"missing per task", [&] { missing_per_task(dir.string(), s, 3); }}};
    for (const auto& [name, read] : readers) {
      SCOPED_TRACE(name);
      try {
        read();
        ADD_FAILURE() << "the record was taken";
      } catch (const std::runtime_error& err) {
        EXPECT_THAT(err.what(), HasSubstr(where));
        EXPECT_THAT(err.what(), HasSubstr(e.phrase));
      }
    }
    EXPECT_EQ(read_scene_file((dir / "summary.json").string()), summary) << "the summary was rewritten";
  }
  write(genuine);
  EXPECT_EQ(collect_campaign(dir.string()), summary);
  fs::remove_all(dir);
  fs::remove_all(foreign);
}

std::size_t resident_bytes() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stoul(line.substr(6)) * 1024;
  return 0;
}

// Records go to disk as samples finish and nothing of a finished sample stays in memory: over 100,000
// samples (of 10 steps each, records without the full report) resident memory after the first 10,000
// grows by less than 4 MB (keeping about 50 bytes or more per sample would exceed it; a record is about
// 300).
TEST(CampaignRun, MemoryStaysFlatOverAHundredThousandSamples) {
  json spec = relay_spec("monte-carlo", 100000);
  spec["scene"]["integrator"]["t_end"] = 0.01;
  spec["full_report"] = false;
  const CampaignSpec s = CampaignSpec::from_json(spec, "");
  const fs::path dir = fresh_dir("memory");
  std::size_t at_10k = 0, peak = 0;
  CampaignRunOptions o;
  o.workers = 2;
  o.progress = [&](std::int64_t done, std::int64_t) {
    if (done % 1000 != 0) return;
    const std::size_t rss = resident_bytes();
    if (done == 10000) at_10k = rss;
    if (done >= 10000) peak = std::max(peak, rss);
  };
  const CampaignRunResult r = run_campaign(s, dir.string(), o);
  ASSERT_EQ(r.ran, 100000);
  ASSERT_TRUE(r.summarized);
  ASSERT_GT(at_10k, 0u);
  EXPECT_LT(peak - at_10k, std::size_t{4} << 20) << "resident memory at 10,000 samples " << at_10k << " bytes, peak after " << peak;
  EXPECT_EQ(read_scene_file((dir / "summary.json").string())["samples"], 100000);
  fs::remove_all(dir);
}

// ---- compiled once ----

// A record without its wall times, the only fields two runs of one sample may differ in.
json without_times(json r) {
  r.erase("wall_seconds");
  if (r.contains("report")) {
    r["report"].erase("wall_seconds");
    r["report"].erase("phase_seconds");
  }
  return r;
}

// Every sample of `spec`, bound to the scene compiled once and compiled in full from its document: the
// same record (full report included), field for field and to the last bit.
void expect_bound_equals_compiled(const json& spec_doc, bool compiles_once) {
  const CampaignSpec spec = CampaignSpec::from_json(spec_doc, "");
  const CampaignDesign design(spec);
  CampaignSampleRunner once(spec, design), every(spec, design, std::nullopt, CampaignSampleRunner::Compile::kEverySample);
  EXPECT_EQ(once.compiles_once(), compiles_once);
  EXPECT_FALSE(every.compiles_once());
  for (std::int64_t i = 0; i < spec.samples; ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(without_times(once.run(i)), without_times(every.run(i)));
  }
  EXPECT_EQ(once.compiles_once(), compiles_once) << "the first bound sample differed from its full compile";
}

TEST(CampaignCompileOnce, TheShippedCampaignsSamplesAreThoseOfTheFullCompile) {
  json spec = read_scene_file(source_path("campaigns/manipulator-robust.json"));
  json scene = read_scene_file(source_path("scenes/manipulator-fig6.4.json"));
  scene["integrator"]["t_end"] = 3.0;
  spec["scene"] = scene;
  spec["samples"] = 24;
  expect_bound_equals_compiled(spec, true);
}

// A bound sample's run does the work of the scene compiled with its values: the tapes the run evaluates
// have as many instructions (the paper's manipulator, the shipped campaign's three masses free).
TEST(CampaignCompileOnce, ABoundSceneEvaluatesNoMoreInstructionsThanTheFoldedCompile) {
  json scene = read_scene_file(source_path("scenes/manipulator-fig6.4.json"));
  ParametricLagrangianScene parametric(scene, {"m1", "m2", "I"});
  json folded_doc = scene;
  folded_doc["parameters"]["m1"] = 1.1;
  folded_doc["parameters"]["m2"] = 0.9;
  folded_doc["parameters"]["I"] = 0.11;
  const LagrangianScene folded = load_scene(folded_doc);
  const LagrangianScene bound = parametric.bind({1.1, 0.9, 0.11}, folded.q0, folded.v0);
  const CompiledLagrangian &f = *folded.compiled, &b = *bound.compiled;
  EXPECT_EQ(b.step_tape.num_instructions(), f.step_tape.num_instructions());
  EXPECT_EQ(b.mass_tape.num_instructions(), f.mass_tape.num_instructions());
  EXPECT_EQ(b.potential_tape.num_instructions(), f.potential_tape.num_instructions());
  EXPECT_EQ(b.step_potential_tape.num_instructions(), f.step_potential_tape.num_instructions());
  EXPECT_EQ(b.split_force_tape.num_instructions(), f.split_force_tape.num_instructions());
  EXPECT_GT(f.step_tape.num_instructions(), 0u);
}

TEST(CampaignCompileOnce, SpecialValuesAndInvalidSamplesGoThroughTheFullCompile) {
  // Masses at 1 and at 0 (the graph rewrites 1 * x and folds 0 * x), a negative mass (M not positive
  // definite: an invalid sample, named as the full compile names it), and initial positions.
  json scene = read_scene_file(source_path("scenes/manipulator-fig6.4.json"));
  scene["integrator"]["t_end"] = 1.0;
  json spec = {{"scene", scene},
               {"inputs",
                {{{"path", "/parameters/m1"}, {"distribution", {{"type", "discrete"}, {"values", {-0.5, 0.9, 1.0}}}}},
                 {{"path", "/parameters/m2"}, {"distribution", {{"type", "discrete"}, {"values", {0.0, 1.0, 2.0}}}}},
                 {{"path", "/initial/q/1"}, {"distribution", {{"type", "grid"}, {"low", -1}, {"high", 1}, {"count", 2}}}}}},
               {"sampler", "grid"}};
  expect_bound_equals_compiled(spec, true);
  // V = k (x^2 + 1)^(p/2): k free, or p too. Whether x^p is smooth everywhere (Assumption 3.3 in the
  // report) depends on p's value, so a free p makes the runner compile every sample.
  json pow_scene = {{"name", "pow-potential"},
                    {"parameters", {{"m", 1.0}, {"k", 0.5}, {"p", 3.0}}},
                    {"system",
                     {{"type", "lagrangian"},
                      {"coordinates", {"x"}},
                      {"mass", {{"m"}}},
                      {"potential", "k*(x^2 + 1)^(p/2)"},
                      {"controller", {{{"type", "quadratic"}, {"weights", {1}}}, {{"type", "abs"}, {"gains", {1}}}}}}},
                    {"initial", {{"q", {1.0}}, {"v", {0.5}}}},
                    {"integrator", {{"h", 1e-3}, {"t_end", 1.0}}}};
  json pow_spec = {{"scene", pow_scene},
                   {"inputs",
                    {{{"path", "/parameters/p"}, {"distribution", {{"type", "discrete"}, {"values", {2.0, 3.0, 4.0, 2.5}}}}},
                     {{"path", "/parameters/k"}, {"distribution", {{"type", "grid"}, {"low", 0.1}, {"high", 0.7}, {"count", 3}}}}}},
                   {"sampler", "grid"}};
  expect_bound_equals_compiled(pow_spec, false);
  pow_spec["inputs"].erase(0);
  expect_bound_equals_compiled(pow_spec, true);
  pow_spec["scene"]["parameters"]["p"] = 4.0;  // the exponent 2: x^2 becomes x*x
  expect_bound_equals_compiled(pow_spec, true);
}

TEST(CampaignCompileOnce, AParameterTheCompilerNeedsAsANumberIsCompiledForEverySample) {
  // The damped relay's t_stop is computed from m, and its controller weight is c: neither can be free.
  json scene = read_scene_file(source_path("scenes/damped-relay.json"));
  scene.erase("exact");
  for (const char* path : {"/parameters/m", "/parameters/c"}) {
    SCOPED_TRACE(path);
    json spec = {
        {"scene", scene}, {"inputs", {{{"path", path}, {"distribution", {{"type", "uniform"}, {"low", 1}, {"high", 3}}}}}}, {"samples", 6}};
    expect_bound_equals_compiled(spec, false);
  }
  // An input that is neither a parameter nor an initial coordinate.
  json spec = {{"scene", scene},
               {"inputs", {{{"path", "/integrator/h"}, {"distribution", {{"type", "discrete"}, {"values", {1e-3, 2e-3}}}}}}},
               {"sampler", "grid"}};
  expect_bound_equals_compiled(spec, false);
}

}  // namespace
}  // namespace moreau::scene
