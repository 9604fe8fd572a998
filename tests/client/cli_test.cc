// The `moreau` command end to end, as a user runs it: the report (text and JSON), the trajectory CSV,
// overrides, exit codes and error messages for bad scenes, and figures.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <csignal>
#include <chrono>
#include <thread>
#include <set>
#include <tuple>
#include <cctype>
#include <vector>

#include <nlohmann/json.hpp>

#include "support/sanitizers.h"
#include "support/scratch_dir.h"

namespace {

struct Result {
  int status;
  std::string out;  // stdout and stderr together
};

// Runs a shell command line; its exit status (-1 for a signal) and its output.
Result Shell(const std::string& cmd) {
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  std::array<char, 4096> buf{};
  while (std::size_t n = std::fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int rc = pclose(pipe);
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, out};
}

Result Moreau(const std::string& args) { return Shell(std::string(MOREAU_BINARY) + " " + args + " 2>&1"); }

const std::string kScene = std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator.json";

TEST(Cli, RunPrintsAReadableReport) {
  const Result r = Moreau("run " + kScene);
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* part : {"completed: 10000 steps", "v == 0.0 exactly from step", "equilibrium", "energy", "solver", "wall time"})
    EXPECT_NE(r.out.find(part), std::string::npos) << part << "\n" << r.out;
}

// moreau inspect: a URDF scene's joints, links and masses as the URDF gives them (scenes/robots/
// kuka-iiwa14.urdf), its constraints, scheme and solver, without running it; an invalid one exits 2.
TEST(Cli, InspectShowsTheRobotWithoutRunningIt) {
  const Result r = Moreau("inspect " + std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-joint-limit.json");
  ASSERT_EQ(r.status, 0) << r.out;
  for (const char* part : {"7 coordinates from URDF robot 'iiwa14'", "iiwa_joint_2      revolute  iiwa_link_2       iiwa_link_1", "6.35",
                           "constraints  14", "iiwa_joint_7_upper: 3.05432619099 - iiwa_joint_7 >= 0, e = 0.5", "scheme       moreau-jean"})
    EXPECT_NE(r.out.find(part), std::string::npos) << part << "\n" << r.out;
  EXPECT_EQ(r.out.find("wall time"), std::string::npos) << "inspect must not run the scene";
  const Result banded = Moreau("inspect " + std::string(MOREAU_SOURCE_DIR) + "/scenes/friction-bar.json");
  EXPECT_NE(banded.out.find("the large ABL path (large_abl_integrator.h): constant sparse M (190 nonzeros, bandwidth 1)"),
            std::string::npos)
      << banded.out;
  const Result bad = Moreau("inspect " + std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-controller.json --set system.urdf.gravity=[0]");
  EXPECT_EQ(bad.status, 2) << bad.out;
  EXPECT_NE(bad.out.find("/system/urdf/gravity"), std::string::npos) << bad.out;
}

// The issue's example: the manipulator at h = 1 with a large initial velocity breaks (4.2) of Theorem 4.1
// from its first step (tests/scene/guarantees_test.cc computes r_0 from the paper's closed forms). Without
// --strict the run completes with a warning; with it, exit status 3. The default scene satisfies (4.2)
// at every step and passes --strict.
TEST(Cli, StrictFailsWhenARelieduponHypothesisFails) {
  const std::string bad = "run " + kScene + " --set integrator.h=1 --set 'initial.v=[10,10]' --set integrator.t_end=20";
  const Result warn = Moreau(bad);
  EXPECT_EQ(warn.status, 0) << warn.out;
  EXPECT_NE(warn.out.find("moreau: warning: Theorem 4.1: (4.2)"), std::string::npos) << warn.out;
  EXPECT_NE(warn.out.find("fails at"), std::string::npos) << warn.out;
  const Result strict = Moreau(bad + " --strict");
  EXPECT_EQ(strict.status, 3) << strict.out;
  EXPECT_NE(strict.out.find("moreau: error: Theorem 4.1"), std::string::npos) << strict.out;
  const Result good = Moreau("run " + kScene + " --strict");
  EXPECT_EQ(good.status, 0) << good.out;
  EXPECT_EQ(good.out.find("moreau: warning"), std::string::npos) << good.out;
}

TEST(Cli, JsonReportHasTheDocumentedFields) {
  const Result r = Moreau("run " + kScene + " --json");
  ASSERT_EQ(r.status, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* key :
       {"steps", "t_final", "converged_step", "converged_time", "final", "energy_nonincreasing", "equilibrium", "solver", "wall_seconds"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["steps"], 10000);
  EXPECT_DOUBLE_EQ(j["t_final"].get<double>(), 10.0);
  ASSERT_TRUE(j["converged_step"].is_number_integer());
  EXPECT_EQ(j["final"]["v"], nlohmann::json({0.0, 0.0}));
  EXPECT_TRUE(j["equilibrium"].contains("residual") && j["equilibrium"].contains("interior"));
  EXPECT_TRUE(j["solver"].contains("max_iterations") && j["solver"].contains("max_residual"));
}

TEST(Cli, TrajectoryCsvAndOverrides) {
  const std::string csv = moreau::test_support::scratch_dir() + "/traj.csv";
  const Result r = Moreau("run " + kScene + " --set integrator.h=1e-2 --set integrator.t_end=2 --set 'initial.v=[0,1]' --out " + csv);
  ASSERT_EQ(r.status, 0) << r.out;
  std::ifstream in(csv);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "t,h,x1,th2,x1_dot,th2_dot,energy");
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first.rfind("0,0.01,3,-1,0,1,", 0), 0u) << first;
  int rows = 1;
  for (std::string line; std::getline(in, line);) ++rows;
  EXPECT_EQ(rows, 201);  // t = 0, 0.01, ..., 2
}

TEST(Cli, BadSceneNamesTheFieldAndExitsWith2) {
  Result r = Moreau("run " + kScene + " --set integrator.h=0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("/integrator/h: must be > 0"), std::string::npos) << r.out;
  r = Moreau("run " + kScene + " --set 'system.mass.0.1=cos(th3)'");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("/system/mass/0/1: unknown name 'th3'"), std::string::npos) << r.out;
  r = Moreau("run /nonexistent.json");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.out.find("cannot open"), std::string::npos) << r.out;
}

// A URDF file nested 40,000 elements deep made `moreau run` and `moreau inspect` die of a stack overflow
// (exit 139) in the recursive XML parsers: now both refuse it, naming the field and the depth, with exit 2.
TEST(Cli, DeeplyNestedUrdfFileIsRefusedWithExit2) {
  const std::filesystem::path dir = moreau::test_support::scratch_dir();
  {
    std::ofstream urdf(dir / "deep.urdf");
    urdf << "<robot name=\"r\">";
    for (int k = 0; k < 40000; ++k) urdf << "<a>";
    for (int k = 0; k < 40000; ++k) urdf << "</a>";
    urdf << "</robot>\n";
    std::ofstream scene(dir / "deep.json");
    scene
        << R"({"system": {"type": "lagrangian", "urdf": {"file": "deep.urdf"}}, "initial": {"q": [0]}, "integrator": {"h": 0.01, "t_end": 1}})";
  }
  for (const char* command : {"run", "inspect"}) {
    const Result r = Moreau(std::string(command) + " " + (dir / "deep.json").string());
    EXPECT_EQ(r.status, 2) << command << ": " << r.out;
    EXPECT_NE(r.out.find("/system/urdf/text: elements nested deeper than 64 levels (line 1)"), std::string::npos)
        << command << ": " << r.out;
  }
}

TEST(Cli, FiguresArePngOfTheRequestedSize) {
  const std::string png = moreau::test_support::scratch_dir() + "/state.png";
  const std::string svg = moreau::test_support::scratch_dir() + "/energy.svg";
  const Result r = Moreau("run " + kScene + " --figure " + png + " --figure energy=" + svg + " --size 800x600");
  ASSERT_EQ(r.status, 0) << r.out;
  std::ifstream in(png, std::ios::binary);
  std::array<unsigned char, 24> head{};
  in.read(reinterpret_cast<char*>(head.data()), head.size());
  ASSERT_EQ(head[1], 'P');
  const auto be32 = [&](int at) { return (head[at] << 24) | (head[at + 1] << 16) | (head[at + 2] << 8) | head[at + 3]; };
  EXPECT_EQ(be32(16), 800);
  EXPECT_EQ(be32(20), 600);
  std::ifstream s(svg);
  std::stringstream ss;
  ss << s.rdbuf();
  EXPECT_NE(ss.str().find("<svg"), std::string::npos);
}

TEST(Cli, StudyWritesTheTableAndBothFigures) {
  const std::string dir = moreau::test_support::scratch_dir();
  const Result r = Moreau("study " + std::string(MOREAU_SOURCE_DIR) +
                          "/scenes/damped-relay.json --h 1e-2:1e-3:2 --schemes abl,explicit --repeats 1 --csv " + dir +
                          "/study.csv --work " + dir + "/work.png --order " + dir + "/order.png");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("against the exact solution"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("order of abl"), std::string::npos) << r.out;
  std::ifstream csv(dir + "/study.csv");
  std::string line;
  int lines = 0;
  while (std::getline(csv, line)) ++lines;
  EXPECT_EQ(lines, 5) << "a header and 2 schemes x 2 step sizes";
  for (const char* png : {"/work.png", "/order.png"}) {
    std::ifstream in(dir + png, std::ios::binary);
    char head[8] = {};
    in.read(head, 8);
    EXPECT_EQ(std::string(head + 1, 3), "PNG") << png;
  }
  const Result bad = Moreau("study " + std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json --schemes abl,rk4");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.out.find("unknown scheme 'rk4'"), std::string::npos) << bad.out;
}

// A parameter the scene declares and no expression reads (a likely typo) is a warning on stderr from every
// command that reads the scene: run, study and campaign.
TEST(Cli, AnUnreadParameterIsAWarningFromRunStudyAndCampaign) {
  const std::string dir = moreau::test_support::scratch_dir() + "/unread";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  nlohmann::json doc;
  {
    std::ifstream in(std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json");
    doc = nlohmann::json::parse(in);
  }
  doc["parameters"]["velocty"] = 1.0;
  const std::string scene = dir + "/scene.json";
  std::ofstream(scene) << doc.dump();
  const char* warning = "warning: parameter 'velocty' is not read by any expression of the scene";
  const Result run = Moreau("run " + scene);
  ASSERT_EQ(run.status, 0) << run.out;
  EXPECT_NE(run.out.find(std::string("moreau: ") + warning), std::string::npos) << run.out;
  const Result study = Moreau("study " + scene + " --h 1e-2:1e-3:2 --schemes abl --repeats 1");
  ASSERT_EQ(study.status, 0) << study.out;
  EXPECT_NE(study.out.find(std::string("moreau study: ") + warning), std::string::npos) << study.out;
  const Result campaign = Moreau("campaign --scene " + scene + " --vary parameters.v0=1:2:2 --quiet --out " + dir + "/campaign");
  ASSERT_EQ(campaign.status, 0) << campaign.out;
  EXPECT_NE(campaign.out.find(std::string("moreau campaign: ") + warning), std::string::npos) << campaign.out;
  // A parameter that is read gives none.
  const Result clean = Moreau("run " + std::string(MOREAU_SOURCE_DIR) + "/scenes/damped-relay.json");
  EXPECT_EQ(clean.out.find("warning: parameter"), std::string::npos) << clean.out;
  std::filesystem::remove_all(dir);
}

TEST(Cli, PlotReadsTheCsvBack) {
  const std::string csv = moreau::test_support::scratch_dir() + "/p.csv";
  ASSERT_EQ(Moreau("run " + kScene + " --out " + csv).status, 0);
  const Result r = Moreau("plot " + csv + " --kind phase -o " + moreau::test_support::scratch_dir() + "/phase.png");
  EXPECT_EQ(r.status, 0) << r.out;
  const Result bad = Moreau("plot " + kScene + " -o /tmp/x.png");
  EXPECT_EQ(bad.status, 2);
  EXPECT_NE(bad.out.find("not a Moreau trajectory"), std::string::npos) << bad.out;
}

// `moreau run --out` writes what the CSV's columns are beside it (<csv>-metadata.json), so a plot of the
// bare CSV is the run's own figure: a Lur'e state x, its output y = C x, the switching line, the storage
// W, units, impacts and the converged time, byte for byte what `moreau run --figure` draws from the scene.
TEST(Cli, PlotOfABareCsvIsTheRunsOwnFigure) {
  const std::string dir = moreau::test_support::scratch_dir() + "/bare-csv";
  std::filesystem::create_directories(dir);
  auto read = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::pair<std::string, std::vector<std::string>> runs[] = {
      {"lure-relay-2state", {"state", "phase", "energy"}}, {"bouncing-ball-e0.5", {"state", "phase"}}, {"manipulator", {"state"}}};
  for (const auto& [scene, kinds] : runs) {
    const std::string csv = dir + "/" + scene + ".csv";
    std::string figures;
    for (const std::string& kind : kinds) figures += " --figure " + kind + "=" + dir + "/" + scene + "-run-" + kind + ".svg";
    const Result run = Moreau("run " + std::string(MOREAU_SOURCE_DIR) + "/scenes/" + scene + ".json --out " + csv + figures);
    ASSERT_EQ(run.status, 0) << run.out;
    ASSERT_TRUE(std::filesystem::exists(csv + "-metadata.json"));
    for (const std::string& kind : kinds) {
      const std::string plotted = dir + "/" + scene + "-plot-" + kind + ".svg";
      const Result plot = Moreau("plot " + csv + " --kind " + kind + " -o " + plotted);
      ASSERT_EQ(plot.status, 0) << plot.out;
      const std::string drawn = read(plotted);
      EXPECT_FALSE(drawn.empty());
      EXPECT_EQ(drawn, read(dir + "/" + scene + "-run-" + kind + ".svg")) << scene << " " << kind;
    }
  }
  EXPECT_NE(read(dir + "/lure-relay-2state-plot-state.svg").find("Output y = C x"), std::string::npos);
  // A metadata file that does not fit its CSV is refused, naming the field.
  {
    std::ofstream bad(dir + "/lure-relay-2state.csv-metadata.json", std::ios::trunc);
    bad << R"({"moreau:figures": {"q_units": ["m", "m", "m"]}})";
  }
  const Result bad = Moreau("plot " + dir + "/lure-relay-2state.csv -o " + dir + "/bad.svg");
  EXPECT_EQ(bad.status, 2) << bad.out;
  EXPECT_NE(bad.out.find("at /moreau:figures/q_units: 3 units for the CSV's 2 columns"), std::string::npos) << bad.out;
  {
    std::ofstream deep(dir + "/lure-relay-2state.csv-metadata.json", std::ios::trunc);
    deep << std::string(100000, '[');
  }
  const Result nested = Moreau("plot " + dir + "/lure-relay-2state.csv -o " + dir + "/bad.svg");
  EXPECT_EQ(nested.status, 2) << nested.out;
  EXPECT_NE(nested.out.find("nest"), std::string::npos) << nested.out;
  std::filesystem::remove_all(dir);
}

}  // namespace

namespace {
// A run longer than a second draws a progress bar on stderr (forced on, since the test's stderr is not
// a terminal), and clears it at the end.
TEST(Cli, ProgressBarForLongRuns) {
  const Result r = Moreau("run " + kScene + " --set integrator.h=1e-7 --set integrator.t_end=4 --progress always");
  ASSERT_EQ(r.status, 0) << r.out.substr(0, 2000);
  EXPECT_NE(r.out.find("%  t = "), std::string::npos) << r.out.substr(0, 2000);
  const Result quiet = Moreau("run " + kScene + " --progress always");
  EXPECT_EQ(quiet.out.find("%  t = "), std::string::npos) << "a short run draws no bar";
}
}  // namespace

namespace {
std::size_t count_lines(const std::string& path) {
  std::ifstream in(path);
  return static_cast<std::size_t>(std::count(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>(), '\n'));
}

// moreau campaign: the shipped campaign runs and prints its verdict; Ctrl-C (SIGINT) stops a long one
// cleanly (exit 130, every finished sample kept), and the same command finishes it without recomputing
// or duplicating a sample; --collect checks it and prints the same summary.
TEST(Cli, CampaignRunsStopsOnCtrlCAndResumes) {
  const std::string shipped_dir = moreau::test_support::scratch_dir() + "/campaign-shipped";
  const Result shipped = Moreau("campaign " + std::string(MOREAU_SOURCE_DIR) + "/campaigns/manipulator-robust.json --out " + shipped_dir);
  ASSERT_EQ(shipped.status, 0) << shipped.out;
  EXPECT_NE(shipped.out.find("manipulator-robust: "), std::string::npos) << shipped.out;
  EXPECT_NE(shipped.out.find("95% Wilson interval"), std::string::npos) << shipped.out;
  EXPECT_EQ(count_lines(shipped_dir + "/samples.jsonl"), 256u);

  // 2000 samples of the manipulator at t_end = 10 on one thread: about 2 s, long enough to interrupt.
  const std::string dir = moreau::test_support::scratch_dir() + "/campaign-stop";
  const std::string spec = moreau::test_support::scratch_dir() + "/campaign-stop.json";
  nlohmann::json s = nlohmann::json::parse(std::ifstream(std::string(MOREAU_SOURCE_DIR) + "/campaigns/manipulator-robust.json"));
  s["scene"] = std::string(MOREAU_SOURCE_DIR) + "/scenes/manipulator-fig6.4.json";
  s["samples"] = 2000;
  std::ofstream(spec) << s.dump();
  const std::string log = dir + ".log";
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    execl(MOREAU_BINARY, MOREAU_BINARY, "campaign", spec.c_str(), "--out", dir.c_str(), "-j", "1", "--quiet", static_cast<char*>(nullptr));
    _exit(127);
  }
  // Wait for the state we need (20 finished samples), never for a fixed time.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (count_lines(dir + "/samples.jsonl") < 20 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(kill(pid, SIGINT), 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  std::ifstream log_in(log);
  const std::string out((std::istreambuf_iterator<char>(log_in)), std::istreambuf_iterator<char>());
  const std::size_t kept = count_lines(dir + "/samples.jsonl");
  if (kept == 2000) GTEST_SKIP() << "the campaign finished before the interrupt arrived";
  ASSERT_TRUE(WIFEXITED(status)) << out;
  EXPECT_EQ(WEXITSTATUS(status), 130) << out;
  EXPECT_NE(out.find("stopped; every finished sample is kept"), std::string::npos) << out;
  EXPECT_GE(kept, 20u);
  EXPECT_FALSE(std::filesystem::exists(dir + "/summary.json"));

  const Result resumed = Moreau("campaign " + spec + " --out " + dir + " -j 2 --quiet");
  ASSERT_EQ(resumed.status, 0) << resumed.out;
  EXPECT_NE(resumed.out.find(std::to_string(2000 - kept) + " run in"), std::string::npos) << resumed.out;
  EXPECT_NE(resumed.out.find(std::to_string(kept) + " already done"), std::string::npos) << resumed.out;
  std::set<long long> indices;
  std::ifstream records(dir + "/samples.jsonl");
  for (std::string line; std::getline(records, line);)
    EXPECT_TRUE(indices.insert(nlohmann::json::parse(line)["index"].get<long long>()).second);
  EXPECT_EQ(indices.size(), 2000u);
  EXPECT_EQ(*indices.rbegin(), 1999);
  const Result collected = Moreau("campaign --collect " + dir);
  ASSERT_EQ(collected.status, 0) << collected.out;
  EXPECT_NE(resumed.out.find(collected.out), std::string::npos) << "the same summary\n" << collected.out << "\n" << resumed.out;
}

// A parameter sweep is the grid campaign over its --vary lists: split over three tasks and collected, it
// has every point of the grid once (the last list varying fastest), each with the values a single run
// given the same overrides has, and the same final state; a missing part is an error.
TEST(Cli, SweepIsAGridCampaignOverTasks) {
  const std::string dir = moreau::test_support::scratch_dir() + "/sweep";
  std::filesystem::remove_all(dir);
  const std::string sweep =
      "campaign --scene " + kScene + " --vary parameters.g=0:9.81:4 --vary 'initial.v=[0,1];[1,0]' --set integrator.t_end=2 --out " + dir;
  for (int i = 0; i < 3; ++i) {
    const Result r = Moreau(sweep + " --quiet --task " + std::to_string(i) + "/3");
    ASSERT_EQ(r.status, 0) << r.out;
  }
  const Result collected = Moreau("campaign --collect " + dir);
  ASSERT_EQ(collected.status, 0) << collected.out;
  EXPECT_NE(collected.out.find("of 8 samples"), std::string::npos) << collected.out;
  // The grid, independently: g in {0, 3.27, 6.54, 9.81}, v in {[0,1], [1,0]}; point p = 2 i + j.
  const double g[] = {0.0, 9.81 / 3, 2 * 9.81 / 3, 9.81};
  const nlohmann::json v[] = {{0, 1}, {1, 0}};
  std::map<long long, nlohmann::json> records;
  for (const auto& entry : std::filesystem::directory_iterator(dir + "/parts")) {
    std::ifstream in(entry.path());
    for (std::string line; std::getline(in, line);) {
      nlohmann::json r = nlohmann::json::parse(line);
      EXPECT_TRUE(records.emplace(r["index"].get<long long>(), r).second) << line;
    }
  }
  ASSERT_EQ(records.size(), 8u);
  for (const auto& [p, r] : records) {
    SCOPED_TRACE(p);
    EXPECT_NEAR(r["inputs"]["/parameters/g"].get<double>(), g[p / 2], 1e-12);
    EXPECT_EQ(r["inputs"]["/initial/v"], v[p % 2]);
    EXPECT_EQ(r["status"], "completed");
  }
  // Point 5 (g = 6.54, v = [1, 0]) run alone with the same overrides ends in the same state.
  const Result alone =
      Moreau("run " + kScene + " --set integrator.t_end=2 --set parameters.g=" + records[5]["inputs"]["/parameters/g"].dump() +
             " --set 'initial.v=[1,0]' --json");
  ASSERT_EQ(alone.status, 0) << alone.out;
  const nlohmann::json report = nlohmann::json::parse(alone.out.substr(alone.out.find('{')));
  EXPECT_EQ(report["final"]["q"], records[5]["final_q"]);
  EXPECT_EQ(report["final"]["v"], records[5]["final_v"]);
  // The same sweep again is the same campaign (nothing to run); another one is refused.
  EXPECT_EQ(Moreau(sweep + " --quiet").status, 0);
  const Result other = Moreau("campaign --scene " + kScene + " --vary parameters.g=0:1:2 --out " + dir);
  EXPECT_EQ(other.status, 2);
  EXPECT_NE(other.out.find("holds a different campaign"), std::string::npos) << other.out;
  std::filesystem::remove(dir + "/parts/" + std::filesystem::directory_iterator(dir + "/parts")->path().filename().string());
  const Result missing = Moreau("campaign --collect " + dir);
  EXPECT_EQ(missing.status, 2);
  EXPECT_NE(missing.out.find("samples are missing"), std::string::npos) << missing.out;
}

// 'text' for sh: how this test passes paths on its own command lines.
std::string ShQuote(const std::string& text) {
  std::string q = "'";
  for (char c : text) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// The words sbatch reads from an #SBATCH line (after the magic word), by the rules of Slurm's
// _get_argument (src/sbatch/opt.c): whitespace separates words outside '...' and "...", a backslash takes
// the next character as it is, an unquoted '#' ends the line, an unmatched quote is fatal.
std::vector<std::string> SbatchWords(const std::string& line) {
  std::vector<std::string> words;
  std::size_t p = 0;
  while (true) {
    while (p < line.size() && std::isspace(static_cast<unsigned char>(line[p]))) ++p;
    if (p >= line.size()) break;
    std::string word;
    bool quoted = false, escaped = false, comment = false;
    char quote = 0;
    while (p < line.size() && (quoted || !std::isspace(static_cast<unsigned char>(line[p])))) {
      const char c = line[p];
      if (escaped) {
        escaped = false;
      } else if (c == '\\') {
        escaped = true;
        ++p;
        continue;
      } else if (quoted) {
        if (c == quote) {
          quoted = false;
          ++p;
          continue;
        }
      } else if (c == '"' || c == '\'') {
        quoted = true;
        quote = c;
        ++p;
        continue;
      } else if (c == '#') {
        comment = true;
        break;
      }
      word += c;
      ++p;
    }
    EXPECT_FALSE(quoted) << "sbatch: unmatched quote in " << line;
    if (!word.empty()) words.push_back(word);
    if (comment) break;
  }
  return words;
}

// moreau campaign --slurm against a fake sbatch that records its arguments. A hostile name (a newline
// and a command, spaces and options, $(...)) is refused at /name with exit 2 before anything is written
// or submitted. A directory whose path holds spaces, both quotes, $(...), backquotes, ';', '#' and '%'
// reaches the batch script, its #SBATCH lines and sbatch's arguments as data: the script passes bash -n,
// sbatch's reading of its #SBATCH lines gives exactly the array's options, every option is on sbatch's
// command line with '%' doubled in the log paths (Slurm's pattern for '%'), and running the script as the
// array's tasks and the collect job's --wrap command with sh (as Slurm would) completes the campaign in
// that directory, while none of the commands written into the path runs.
TEST(Cli, SlurmScriptsCarryHostileNamesAndPathsAsData) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(moreau::test_support::scratch_dir()) / "slurm-hostile";
  fs::remove_all(root);
  for (const char* d : {"bin", "calls", "work"}) fs::create_directories(root / d);
  {
    std::ofstream fake(root / "bin" / "sbatch");
    fake << "#!/bin/bash\n"
         << "calls=" << ShQuote((root / "calls").string()) << "\n"
         << "n=$(ls \"$calls\" | wc -l)\n"
         << "printf '%s\\0' \"$@\" > \"$calls/$n\"\n"
         << "echo $((4242 + n))\n";
  }
  fs::permissions(root / "bin" / "sbatch", fs::perms::owner_all);
  // Every call's arguments, in order.
  auto calls = [&] {
    std::vector<std::vector<std::string>> all;
    for (int n = 0; fs::exists(root / "calls" / std::to_string(n)); ++n) {
      std::ifstream in(root / "calls" / std::to_string(n), std::ios::binary);
      std::vector<std::string> args;
      for (std::string a; std::getline(in, a, '\0');) args.push_back(a);
      all.push_back(args);
    }
    return all;
  };
  const std::string prefix = "cd " + ShQuote((root / "work").string()) + " && PATH=" + ShQuote((root / "bin").string()) + ":\"$PATH\" ";
  nlohmann::json scene = nlohmann::json::parse(std::ifstream(std::string(MOREAU_SOURCE_DIR) + "/scenes/forced-relay.json"));
  scene.erase("exact");
  scene["integrator"]["t_end"] = 0.5;
  auto spec_named = [&](const std::string& name) {
    const fs::path file = root / "spec.json";
    nlohmann::json spec = {{"name", name},
                           {"scene", scene},
                           {"inputs", {{{"path", "/parameters/f"}, {"distribution", {{"type", "uniform"}, {"low", 0.0}, {"high", 1.0}}}}}},
                           {"samples", 6},
                           {"seed", 3}};
    std::ofstream(file) << spec.dump();
    return file.string();
  };

  for (const std::string& name : {std::string("x\ntouch injected\n#"), std::string("a --output=/tmp/x --wrap=touch injected"),
                                  std::string("$(touch injected)"), std::string(""), std::string(65, 'a')}) {
    SCOPED_TRACE(name);
    const Result r = Shell(prefix + MOREAU_BINARY + " campaign " + ShQuote(spec_named(name)) + " --out " +
                           ShQuote((root / "named").string()) + " --slurm --tasks 2 2>&1");
    EXPECT_EQ(r.status, 2) << r.out;
    EXPECT_NE(r.out.find("/name: "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("is not a campaign name"), std::string::npos) << r.out;
    EXPECT_TRUE(calls().empty()) << "sbatch was called";
    EXPECT_FALSE(fs::exists(root / "named")) << "something was written";
  }

  const std::string hostile = "out 'q' \"dq\" $(touch cs) `touch bq` ; touch semi #h %j 100%";
  const fs::path dir = root / hostile;
  const Result r = Shell(prefix + MOREAU_BINARY + " campaign " + ShQuote(spec_named("relay-hostile")) + " --out " + ShQuote(dir.string()) +
                         " --slurm --tasks 2 2>&1");
  ASSERT_EQ(r.status, 0) << r.out;
  EXPECT_NE(r.out.find("submitted job array 4242: 2 of 2 tasks (6 samples missing of 6), and collect job 4243 after it"), std::string::npos)
      << r.out;
  // Slurm's file name patterns take '%%' for a '%'.
  std::string logs;
  for (char c : (dir / "slurm").string()) logs += c == '%' ? std::string("%%") : std::string(1, c);
  const std::vector<std::string> array_options = {"--job-name=moreau-relay-hostile", "--output=" + logs + "/task-%A_%a.out",
                                                  "--cpus-per-task=1", "--requeue"};
  const auto all = calls();
  ASSERT_EQ(all.size(), 2u);
  const std::vector<std::string>& array = all[0];
  const std::vector<std::string>& collect = all[1];
  const fs::path script = dir / "slurm" / "campaign.sbatch";
  ASSERT_FALSE(array.empty());
  EXPECT_EQ(array.back(), script.string());
  for (const std::string& o : array_options) EXPECT_EQ(std::count(array.begin(), array.end(), o), 1) << o;
  EXPECT_EQ(std::count(array.begin(), array.end(), "--array=0,1"), 1);
  for (const std::string& o : {std::string("--job-name=moreau-relay-hostile-collect"), "--output=" + logs + "/collect-%j.out",
                               std::string("--dependency=afterok:4242")})
    EXPECT_EQ(std::count(collect.begin(), collect.end(), o), 1) << o;
  const auto wrap = std::find_if(collect.begin(), collect.end(), [](const std::string& a) { return a.rfind("--wrap=", 0) == 0; });
  ASSERT_NE(wrap, collect.end());

  // The script: valid bash; its #SBATCH lines, as sbatch reads them (up to its first command), are the
  // array's options and nothing else.
  EXPECT_EQ(Shell("bash -n " + ShQuote(script.string()) + " 2>&1").status, 0);
  std::vector<std::string> words;
  {
    std::ifstream in(script);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("#SBATCH", 0) == 0) {
        for (std::string& w : SbatchWords(line.substr(7))) words.push_back(std::move(w));
        continue;
      }
      const auto first = line.find_first_not_of(" \t");
      if (first != std::string::npos && line[first] != '#') break;  // sbatch stops at the first command
    }
  }
  std::vector<std::string> want = array_options;
  std::sort(words.begin(), words.end());
  std::sort(want.begin(), want.end());
  EXPECT_EQ(words, want);

  // The array's two tasks, then the collect job, run as Slurm would run them.
  for (int k = 0; k < 2; ++k) {
    const Result task = Shell(prefix + "SLURM_ARRAY_TASK_ID=" + std::to_string(k) + " bash " + ShQuote(script.string()) + " 2>&1");
    EXPECT_EQ(task.status, 0) << task.out;
  }
  const Result collected = Shell(prefix + "sh -c " + ShQuote(wrap->substr(7)) + " 2>&1");
  EXPECT_EQ(collected.status, 0) << collected.out;
  EXPECT_NE(collected.out.find("relay-hostile: "), std::string::npos) << collected.out;
  EXPECT_NE(collected.out.find("of 6 samples succeeded"), std::string::npos) << collected.out;
  EXPECT_TRUE(fs::exists(dir / "summary.json"));
  // Nothing written into the path ran: no file beside the test's own.
  EXPECT_TRUE(fs::is_empty(root / "work"));
  std::set<std::string> entries;
  for (const auto& e : fs::directory_iterator(root)) entries.insert(e.path().filename().string());
  EXPECT_EQ(entries, (std::set<std::string>{"bin", "calls", "work", "spec.json", hostile})) << "a command hidden in the path ran";
}

// An edited or foreign record stops resume and --collect with exit 2, naming the file and the line, and
// leaves the summary as it was; put back, the genuine record is taken again.
TEST(Cli, EditedOrForeignCampaignRecordsAreRefusedWithExit2) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(moreau::test_support::scratch_dir()) / "campaign-edited";
  fs::remove_all(root);
  fs::create_directories(root);
  nlohmann::json scene = nlohmann::json::parse(std::ifstream(std::string(MOREAU_SOURCE_DIR) + "/scenes/forced-relay.json"));
  scene.erase("exact");
  scene["integrator"]["t_end"] = 0.5;
  nlohmann::json spec = {{"name", "relay-records"},
                         {"scene", scene},
                         {"inputs", {{{"path", "/parameters/f"}, {"distribution", {{"type", "uniform"}, {"low", 0.0}, {"high", 1.0}}}}}},
                         {"samples", 6},
                         {"seed", 3}};
  std::ofstream(root / "spec.json") << spec.dump();
  spec["seed"] = 4;  // another campaign: other draws, another spec
  std::ofstream(root / "other.json") << spec.dump();
  const std::string dir = (root / "dir").string(), other = (root / "other").string();
  ASSERT_EQ(Moreau("campaign " + (root / "spec.json").string() + " --out " + dir + " -j 1 --quiet").status, 0);
  ASSERT_EQ(Moreau("campaign " + (root / "other.json").string() + " --out " + other + " -j 1 --quiet").status, 0);
  auto lines_of = [](const std::string& file) {
    std::vector<std::string> lines;
    std::ifstream in(file);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    return lines;
  };
  const std::vector<std::string> genuine = lines_of(dir + "/samples.jsonl"), theirs = lines_of(other + "/samples.jsonl");
  ASSERT_EQ(genuine.size(), 6u);
  ASSERT_EQ(theirs.size(), 6u);
  std::ifstream summary_in(dir + "/summary.json");
  const std::string summary((std::istreambuf_iterator<char>(summary_in)), std::istreambuf_iterator<char>());
  auto write = [&](const std::vector<std::string>& lines) {
    std::ofstream out(dir + "/samples.jsonl", std::ios::trunc);
    for (const std::string& l : lines) out << l << "\n";
  };
  nlohmann::json edited = nlohmann::json::parse(genuine[2]);
  edited["inputs"]["/parameters/f"] = 0.5;
  nlohmann::json flipped = nlohmann::json::parse(genuine[3]);
  flipped["success"] = !flipped["success"].get<bool>();
  const std::vector<std::tuple<std::size_t, std::string, std::string>> cases = {
      {3, edited.dump(), "input /parameters/f"}, {4, flipped.dump(), "its success is"}, {5, theirs[4], "spec_hash"}};
  for (const auto& [line, text, phrase] : cases) {
    SCOPED_TRACE(phrase);
    std::vector<std::string> lines = genuine;
    lines[line - 1] = text;
    write(lines);
    const std::string where = "samples.jsonl' line " + std::to_string(line) + " is not a record of this campaign";
    for (const std::string& command :
         {"campaign --collect " + dir, "campaign " + (root / "spec.json").string() + " --out " + dir + " --quiet"}) {
      const Result r = Moreau(command);
      EXPECT_EQ(r.status, 2) << command << "\n" << r.out;
      EXPECT_NE(r.out.find(where), std::string::npos) << command << "\n" << r.out;
      EXPECT_NE(r.out.find(phrase), std::string::npos) << command << "\n" << r.out;
    }
    std::ifstream now_in(dir + "/summary.json");
    EXPECT_EQ(std::string((std::istreambuf_iterator<char>(now_in)), std::istreambuf_iterator<char>()), summary);
  }
  write(genuine);
  const Result again = Moreau("campaign --collect " + dir);
  EXPECT_EQ(again.status, 0) << again.out;
}
}  // namespace

namespace {
// Runs `moreau` on bad input with a time limit (a hang fails the test instead of blocking it: timeout's
// status 124) and, unless sanitizers are on (their shadow memory needs terabytes of address space), a
// 4 GB address-space limit, so that input read without bound fails fast instead of exhausting the
// machine. `before` runs first in the same shell.
Result MoreauBounded(const std::string& args, const std::string& before = "") {
#if MOREAU_UNDER_ASAN
  const std::string limits = "timeout 60 ";
#else
  const std::string limits = "ulimit -v 4000000; timeout 60 ";
#endif
  return Shell(before + limits + std::string(MOREAU_BINARY) + " " + args + " 2>&1");
}

// The files the bad-input table refers to as {tmp}/...
std::string BadInputDir() {
  static const std::string dir = [] {
    const std::string d = moreau::test_support::scratch_dir() + "/cli-bad-input";
    std::filesystem::remove_all(d);
    std::filesystem::create_directories(d + "/records");
    std::ofstream(d + "/overflow.json") << "{\"name\": \"x\", \"integrator\": {\"t_end\": 1, \"h\": 1e999}}\n";
    std::ofstream(d + "/records/campaign.json") << R"({"scene": ")" << MOREAU_SOURCE_DIR << R"(/scenes/damped-relay.json", "samples": 2,
              "inputs": [{"path": "/parameters/m", "distribution": {"type": "uniform", "low": 1, "high": 3}}]})";
    // Line 1 overflows: a record is checked against the spec once it is read (a line 1 that is not this
    // campaign's record would be refused first, as the row ForeignCampaignRecord shows).
    std::ofstream(d + "/records/samples.jsonl") << R"({"index": 1, "steps": 1e999})"
                                                << "\n"
                                                << R"({"index": 0, "success": true})"
                                                << "\n";
    std::filesystem::create_directories(d + "/foreign");
    std::filesystem::copy_file(d + "/records/campaign.json", d + "/foreign/campaign.json");
    std::ofstream(d + "/foreign/samples.jsonl")
        << R"({"index": 0, "spec_hash": "0123456789abcdef", "inputs": {"/parameters/m": 2.0}, "status": "completed", "success": true})"
        << "\n";
    // A name that would end the #SBATCH line and run a command in every array task.
    nlohmann::json hostile = nlohmann::json::parse(std::ifstream(d + "/records/campaign.json"));
    hostile["name"] = "x\ntouch " + d + "/injected\n#";
    std::ofstream(d + "/hostile-name.json") << hostile.dump();
    return d;
  }();
  return dir;
}

struct BadInput {
  std::string name;
  std::string args;     // {tmp}: BadInputDir(), {scenes}: the shipped scenes
  std::string pointer;  // the field, as the message names it: a JSON pointer or the option
  std::string phrase;   // and a phrase of what is wrong with it
};

class BadCommandLine : public ::testing::TestWithParam<BadInput> {};

std::string Expand(std::string s) {
  for (const auto& [key, value] :
       {std::pair<std::string, std::string>{"{tmp}", BadInputDir()}, {"{scenes}", std::string(MOREAU_SOURCE_DIR) + "/scenes"}}) {
    for (std::size_t at; (at = s.find(key)) != std::string::npos;) s.replace(at, key.size(), value);
  }
  return s;
}

// Bad input on the command line: exit status 2 and one short message naming the field, never a crash
// (status -1: a signal), a hang (124: timeout), unbounded memory (an abort under the address-space
// limit) or a report or table (with NaN in it) instead of the error.
TEST_P(BadCommandLine, ExitsWith2AndNamesTheField) {
  const Result r = MoreauBounded(Expand(GetParam().args));
  EXPECT_EQ(r.status, 2) << r.out.substr(0, 2000);
  EXPECT_NE(r.out.find(GetParam().pointer), std::string::npos) << r.out.substr(0, 2000);
  EXPECT_NE(r.out.find(GetParam().phrase), std::string::npos) << r.out.substr(0, 2000);
  EXPECT_LT(r.out.size(), 1000u) << r.out.substr(0, 2000);
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out.substr(0, 2000);
}

INSTANTIATE_TEST_SUITE_P(
    Cli, BadCommandLine,
    ::testing::Values(
        // Parsing: a number that overflows a double, wherever the JSON comes from.
        BadInput{"NumberOutOfRangeInASceneFile", "run {tmp}/overflow.json", "/integrator/h: ", "number out of range at byte 46"},
        BadInput{"NumberOutOfRangeInAnOverride", "run {scenes}/manipulator.json --set 'initial.v=[0,1e999]'",
                 "/initial/v/1: ", "number out of range"},
        BadInput{"NumberOutOfRangeInAStudysScene", "study {tmp}/overflow.json", "/integrator/h: ", "number out of range"},
        BadInput{"NumberOutOfRangeInACampaignRecord", "campaign --collect {tmp}/records", "samples.jsonl' line 1", "number overflow"},
        // Records: each must be one of this campaign's (its spec's hash, the inputs drawn for its index).
        BadInput{"ForeignCampaignRecord", "campaign --collect {tmp}/foreign", "samples.jsonl' line 1 is not a record of this campaign",
                 "its spec_hash \"0123456789abcdef\" is not this spec's"},
        // Names and paths that reach a Slurm batch script: refused before anything is written or submitted.
        BadInput{"CampaignNameWithANewline", "campaign {tmp}/hostile-name.json --out {tmp}/hostile-name --slurm",
                 "/name: ", "is not a campaign name"},
        BadInput{"SlurmDirectoryWithANewline", "campaign {tmp}/records/campaign.json --out \"$(printf '{tmp}/slurm\\nout')\" --slurm",
                 "--out: ", "control character"},
        // Size: endless or huge input is refused at the limit, not read to the end.
        BadInput{"SceneFromDevZero", "run /dev/zero", "/: ", "larger than 64 MiB"},
        BadInput{"StudySceneFromDevZero", "study /dev/zero", "/: ", "larger than 64 MiB"},
        BadInput{"TrajectoryFromDevZero", "plot /dev/zero -o {tmp}/plot.png", "'/dev/zero' line 1", "longer than 1 MiB"},
        // Step counts: at least one step, and no count that overflows.
        BadInput{"StepSoLongTheRunTakesNoStep", "run {scenes}/manipulator.json --set integrator.h=1e12",
                 "/integrator/h: ", "longer than the interval"},
        BadInput{"StepLongerThanTheInterval", "run {scenes}/manipulator.json --set integrator.h=1e9",
                 "/integrator/h: ", "longer than the interval"},
        BadInput{"AdaptiveRuleStepCountOverflows",
                 "run {scenes}/manipulator.json --set integrator.step_rule=theorem-4.1 --set integrator.t_end=1e300",
                 "/integrator/h: ", "needs at least"},
        BadInput{"FixedRuleStepCountOverflows", "run {scenes}/manipulator.json --set integrator.h=1e-300",
                 "/integrator/h: ", "steps, more than the limit"},
        BadInput{"LureStepLongerThanTheInterval", "run {scenes}/lure-relay.json --set integrator.h=10",
                 "/integrator/h: ", "longer than the interval"},
        // Lur'e graphs whose slopes overflow.
        BadInput{"LureGraphSlopeOverflows",
                 "run {scenes}/lure-graph.json --set 'system.feedback.0.vertices=[[-1e308,-1e308],[1e308,1e308]]'",
                 "/system/feedback/0/vertices/1: ", "overflows"},
        // Studies: every h finite, positive and within the scene's interval and step limit.
        BadInput{"StudyNaNStep", "study {scenes}/damped-relay.json --h nan", "--h: ", "is not a positive finite step size"},
        BadInput{"StudyZeroInAStepList", "study {scenes}/damped-relay.json --h 1e-2,0", "--h: ", "is not a positive finite step size"},
        BadInput{"StudyZeroReferenceStep", "study {scenes}/damped-relay.json --h 1e-2 --reference-h 0",
                 "--reference-h: ", "not a positive finite step size"},
        BadInput{"StudyNegativeReferenceStep", "study {scenes}/damped-relay.json --h 1e-2 --reference-h=-1",
                 "--reference-h: ", "not a positive finite step size"},
        BadInput{"StudyStepLongerThanTheInterval", "study {scenes}/damped-relay.json --h 1e-2,100", "--h: ", "longer than the interval"},
        BadInput{"StudyStepCountOverflows", "study {scenes}/damped-relay.json --h 1e-300", "--h: ", "steps, more than the limit"},
        BadInput{"StudyExactSolutionNotFinite", "study {scenes}/damped-relay.json --h 1e-2 --set 'exact.q.0=sqrt(3 - t)'",
                 "/exact/q/0: ", "not finite"},
        BadInput{"StudyTooManyEvalPoints", "study {scenes}/damped-relay.json --h 1e-2 --eval-points 1000000000",
                 "--eval-points: ", "100000"},
        // Sweeps (grid campaigns): values that are numbers, paths the scene has, and a grid that fits.
        BadInput{"SweepValueNotANumber", "campaign --scene {scenes}/manipulator.json --vary integrator.h=abc:1:3 --out {tmp}/sweep",
                 "--vary integrator.h", "'abc' is not a number"},
        BadInput{"SweepValueOutOfRange", "campaign --scene {scenes}/manipulator.json --vary integrator.h=1e999:1:3 --out {tmp}/sweep",
                 "--vary integrator.h", "not a finite number"},
        BadInput{"SweepListValueOutOfRange", "campaign --scene {scenes}/manipulator.json --vary integrator.h=1e-3,1e999 --out {tmp}/sweep",
                 "--vary integrator.h", "not a finite number"},
        BadInput{"SweepUnknownPath", "campaign --scene {scenes}/manipulator.json --vary parameters.m9=1,2 --out {tmp}/sweep",
                 "--vary parameters.m9=1,2", "the scene has nothing at '/parameters/m9'"},
        BadInput{"SweepTooManyPoints",
                 "campaign --scene {scenes}/manipulator.json --vary parameters.g=0:1:100000 --vary parameters.m1=1:2:100000 --vary "
                 "parameters.m2=1:2:100000 --vary parameters.b=1:2:100000 --out {tmp}/sweep",
                 "--vary", "more than 10000000 points"}),
    [](const auto& info) { return info.param.name; });

// A FIFO has no size to trust and this one never ends: the scene is read up to the limit and refused
// (the writer then dies of SIGPIPE).
TEST(Cli, SceneFromAnEndlessFifoIsRefusedAtTheSizeLimit) {
  const std::string fifo = moreau::test_support::scratch_dir() + "/endless.fifo";
  std::filesystem::remove(fifo);
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  // The writer's shell gets /dev/null for output before it forks the writer: a writer blocked opening the
  // FIFO (when moreau died before reading it) would otherwise hold the pipe this test reads to its end,
  // and the test would wait for ever.
  const Result r = MoreauBounded("run " + fifo, "(yes '[1, 2, 3]' > " + fifo + " &) >/dev/null 2>&1; ");
  // Unblock the writer if the reader never opened the FIFO, so that it cannot outlive the test.
  if (const int fd = open(fifo.c_str(), O_RDONLY | O_NONBLOCK); fd >= 0) close(fd);
  std::filesystem::remove(fifo);
  EXPECT_EQ(r.status, 2) << r.out.substr(0, 2000);
  EXPECT_NE(r.out.find("larger than 64 MiB"), std::string::npos) << r.out.substr(0, 2000);
}
}  // namespace
