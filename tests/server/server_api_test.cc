// moreau-server over HTTP, in-process on an ephemeral port: the life of a job, bad requests, limits,
// cancellation, a full queue and authentication.
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "moreau/scene/simulation.h"
#include "conditional.h"
#include "job.h"
#include "moreau/scene/trajectory_csv.h"
#include "server_fixture.h"
#include "trajectory.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::strong_etag;
using moreau::server::testing::manipulator;
using moreau::server::testing::read_json_file;
using moreau::server::testing::submit;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_running;
using moreau::server::testing::wait_step;
using moreau::test_support::TempDir;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

std::size_t count_lines(const std::string& s) { return static_cast<std::size_t>(std::count(s.begin(), s.end(), '\n')); }

json error_of(const httplib::Result& r) { return json::parse(r->body); }

// A .npy body read by the format's description (numpy/lib/format.py), not by the server's writer: the
// magic, version 1.0, the header's length, the header dict, then rows * columns little-endian doubles.
struct NpyArray {
  std::string header;
  std::int64_t rows = -1, columns = -1;
  std::vector<std::uint64_t> bits;  // the values' bit patterns, row after row
};
NpyArray parse_npy(const std::string& body) {
  NpyArray a;
  if (body.size() < 10 || body.compare(0, 8, std::string("\x93NUMPY\x01\x00", 8)) != 0) {
    ADD_FAILURE() << "not an .npy 1.0 file";
    return a;
  }
  const std::size_t header_len = static_cast<unsigned char>(body[8]) | (static_cast<std::size_t>(static_cast<unsigned char>(body[9])) << 8);
  if (10 + header_len > body.size()) {
    ADD_FAILURE() << "header longer than the body";
    return a;
  }
  a.header = body.substr(10, header_len);
  EXPECT_EQ((10 + header_len) % 64, 0u) << "the data is aligned";
  EXPECT_EQ(a.header.back(), '\n');
  EXPECT_THAT(a.header, ::testing::HasSubstr("'descr': '<f8'"));
  EXPECT_THAT(a.header, ::testing::HasSubstr("'fortran_order': False"));
  const std::size_t shape = a.header.find("'shape': (");
  if (shape == std::string::npos) {
    ADD_FAILURE() << a.header;
    return a;
  }
  char* end = nullptr;
  a.rows = std::strtoll(a.header.c_str() + shape + 10, &end, 10);
  EXPECT_EQ(std::string(end, 2), ", ");
  a.columns = std::strtoll(end + 2, &end, 10);
  EXPECT_EQ(*end, ')');
  const std::size_t data = 10 + header_len;
  EXPECT_EQ(body.size() - data, static_cast<std::size_t>(a.rows * a.columns * 8)) << "the body is the array its header describes";
  for (std::size_t at = data; at + 8 <= body.size(); at += 8) {
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(static_cast<unsigned char>(body[at + i])) << (8 * i);
    a.bits.push_back(v);
  }
  return a;
}

// A CSV body's header names and its cells read by strtod, as bit patterns (the CSV's shortest round-trip
// text reads back as the very double written).
struct CsvTable {
  std::vector<std::string> names;
  std::vector<std::uint64_t> bits;
  std::size_t rows = 0;
};
CsvTable parse_csv(const std::string& body) {
  CsvTable t;
  std::istringstream in(body);
  std::string line;
  std::getline(in, line);
  std::istringstream header(line);
  for (std::string name; std::getline(header, name, ',');) t.names.push_back(name);
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    ++t.rows;
    std::istringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');)
      t.bits.push_back(std::bit_cast<std::uint64_t>(std::strtod(cell.c_str(), nullptr)));
  }
  return t;
}

// What `moreau run scenes/manipulator.json --out FILE` gives: the report and the trajectory CSV.
struct LocalRun {
  json report;
  std::string csv;
};
LocalRun run_locally(const json& doc) {
  auto sim = moreau::scene::Simulation::from_json(doc);
  const TempDir dir("local");
  const fs::path csv_path = dir / "traj.csv";
  moreau::scene::TrajectoryCsvWriter csv(csv_path.string(), sim.position_names(), sim.velocity_names());
  const auto summary = sim.run(&csv);
  csv.close();
  return LocalRun{sim.report_json(summary), slurp(csv_path)};
}

// `strict` as `moreau run --strict`: the manipulator at h = 1 with a large initial velocity breaks (4.2)
// of Theorem 4.1 from its first step (tests/scene/guarantees_test.cc computes r_0 from the paper's closed
// forms). Without strict the job is done and its report's guarantees say so; with strict it is failed,
// and the report says why. A strict that is not a boolean is refused with its pointer.
TEST(ServerApi, StrictJobFailsWhenARelieduponHypothesisFails) {
  TestServer ts;
  auto c = ts.client();
  const json overrides = {"integrator.h=1", "initial.v=[10,10]", "integrator.t_end=20"};
  auto lax = submit(*c, {{"scene", "manipulator"}, {"overrides", overrides}});
  ASSERT_EQ(lax->status, 202) << lax->body;
  const json done = wait_final(*c, json::parse(lax->body)["id"]);
  ASSERT_EQ(done["state"], "done") << done.dump(2);
  EXPECT_EQ(done["report"]["guarantees"][0]["result"], "Theorem 4.1");
  EXPECT_EQ(done["report"]["guarantees"][0]["verdict"], "fails");

  auto strict = submit(*c, {{"scene", "manipulator"}, {"overrides", overrides}, {"strict", true}});
  ASSERT_EQ(strict->status, 202) << strict->body;
  const json failed = wait_final(*c, json::parse(strict->body)["id"]);
  ASSERT_EQ(failed["state"], "failed") << failed.dump(2);
  EXPECT_THAT(failed["reason"].get<std::string>(), ::testing::HasSubstr("strict: Theorem 4.1: (4.2)"));
  EXPECT_EQ(failed["report"]["status"], "failed");

  auto ok = submit(*c, {{"scene", "manipulator"}, {"strict", true}});
  ASSERT_EQ(ok->status, 202) << ok->body;
  EXPECT_EQ(wait_final(*c, json::parse(ok->body)["id"])["state"], "done");

  auto bad = submit(*c, {{"scene", "manipulator"}, {"strict", "yes"}});
  ASSERT_EQ(bad->status, 400);
  EXPECT_EQ(error_of(bad)["pointer"], "/strict");
}

TEST(ServerApi, JobLifeFromSubmissionToResults) {
  TestServer ts;
  auto c = ts.client();
  const json scene = manipulator();

  auto r = submit(*c, {{"scene", scene}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const json accepted = json::parse(r->body);
  const std::string id = accepted["id"];
  EXPECT_THAT(id, ::testing::MatchesRegex("[0-9a-f]{32}"));
  EXPECT_EQ(accepted["url"], "/v1/jobs/" + id);
  EXPECT_EQ(r->get_header_value("Location"), "/v1/jobs/" + id);
  EXPECT_THAT(accepted["state"].get<std::string>(), ::testing::AnyOf("queued", "running", "done"));

  const json job = wait_final(*c, id);
  ASSERT_EQ(job["state"], "done") << job.dump(2);
  EXPECT_EQ(job["scene"], "manipulator");
  EXPECT_DOUBLE_EQ(job["progress"]["t"].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(job["progress"]["fraction"].get<double>(), 1.0);
  EXPECT_EQ(job["progress"]["step"], 10000);

  // The same numbers as a local run (what `moreau run` prints), and the same trajectory bytes.
  const LocalRun local = run_locally(scene);
  const json& report = job["report"];
  ASSERT_TRUE(local.report["converged_step"].is_number());
  EXPECT_EQ(report["converged_step"], local.report["converged_step"]);
  EXPECT_EQ(report["converged_time"], local.report["converged_time"]);
  EXPECT_EQ(report["final"], local.report["final"]);
  EXPECT_EQ(report["steps"], 10000);
  EXPECT_EQ(report["status"], "completed");

  // The raw report is the file on disk, and the job's JSON embeds the same document.
  auto raw = c->Get("/v1/jobs/" + id + "/report");
  ASSERT_EQ(raw->status, 200);
  EXPECT_EQ(json::parse(raw->body), report);
  EXPECT_EQ(raw->body, slurp(ts.data() / "jobs" / id / "report.json"));

  auto csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv");
  ASSERT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Content-Type"), "text/csv");
  EXPECT_EQ(csv->body, local.csv);
  EXPECT_EQ(count_lines(csv->body), 10002u);  // header + 10001 states
  EXPECT_EQ(csv->body.substr(0, csv->body.find('\n')), "t,h,x1,th2,x1_dot,th2_dot,energy");

  auto tj = c->Get("/v1/jobs/" + id + "/trajectory");
  ASSERT_EQ(tj->status, 200);
  const json traj = json::parse(tj->body);
  EXPECT_EQ(traj["columns"], json({"t", "h", "x1", "th2", "x1_dot", "th2_dot", "energy"}));
  EXPECT_EQ(traj["rows"], 10001);
  ASSERT_EQ(traj["data"]["t"].size(), 10001u);
  EXPECT_DOUBLE_EQ(traj["data"]["t"][10000].get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(traj["data"]["x1"][0].get<double>(), 3.0);
  EXPECT_EQ(traj["data"]["x1"][10000], report["final"]["q"][0]);

  // Server-sent events: the state changes in order, and the stream ends with the final state.
  auto ev = c->Get("/v1/jobs/" + id + "/events");
  ASSERT_EQ(ev->status, 200);
  EXPECT_THAT(ev->get_header_value("Content-Type"), ::testing::StartsWith("text/event-stream"));
  const std::string& events = ev->body;
  const auto queued = events.find("\"state\":\"queued\"");
  const auto running = events.find("\"state\":\"running\"");
  const auto done = events.find("\"state\":\"done\"");
  ASSERT_NE(queued, std::string::npos) << events;
  ASSERT_NE(running, std::string::npos) << events;
  ASSERT_NE(done, std::string::npos) << events;
  EXPECT_LT(queued, running);
  EXPECT_LT(running, done);
  EXPECT_THAT(events, ::testing::HasSubstr("event: state\n"));

  // Listed, and counted by /metrics.
  auto list = json::parse(c->Get("/v1/jobs")->body);
  ASSERT_EQ(list["count"], 1);
  EXPECT_EQ(list["jobs"][0]["id"], id);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs?state=done")->body)["count"], 1);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs?state=running")->body)["count"], 0);
  auto metrics = c->Get("/metrics");
  ASSERT_EQ(metrics->status, 200);
  EXPECT_THAT(metrics->body, ::testing::HasSubstr("moreau_jobs{state=\"done\"} 1\n"));
  EXPECT_THAT(metrics->body, ::testing::HasSubstr("moreau_steps_total 10000\n"));
  EXPECT_THAT(metrics->body, ::testing::HasSubstr("moreau_queue_length 0\n"));

  // A figure: PNG from render/, or 501 when the build has no render/.
  auto fig = c->Get("/v1/jobs/" + id + "/figure?kind=energy");
  ASSERT_TRUE(fig);
  if (fig->status == 200) {
    EXPECT_EQ(fig->get_header_value("Content-Type"), "image/png");
    EXPECT_EQ(fig->body.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
    EXPECT_TRUE(fs::exists(ts.data() / "jobs" / id / "figure-energy.png"));
    // The same figure as SVG (no GL): text, served and cached apart from the PNG.
    auto svg = c->Get("/v1/jobs/" + id + "/figure?kind=energy&format=svg");
    ASSERT_TRUE(svg);
    EXPECT_EQ(svg->status, 200) << svg->body;
    EXPECT_EQ(svg->get_header_value("Content-Type"), "image/svg+xml");
    EXPECT_THAT(svg->body, ::testing::HasSubstr("<svg"));
    EXPECT_THAT(svg->body, ::testing::HasSubstr("</svg>"));
    EXPECT_TRUE(fs::exists(ts.data() / "jobs" / id / "figure-energy.svg"));
    EXPECT_EQ(c->Get("/v1/jobs/" + id + "/figure?kind=energy&format=svg")->body, svg->body) << "served again from the cache";
  } else {
    EXPECT_EQ(fig->status, 501) << fig->body;
  }
  EXPECT_EQ(c->Get("/v1/jobs/" + id + "/figure?kind=nope")->status, 400);
  // A query parameter the endpoint does not read is a 400 that names it, never silently ignored.
  auto gif = c->Get("/v1/jobs/" + id + "/figure?format=gif");
  EXPECT_EQ(gif->status, 400);
  EXPECT_THAT(gif->body, ::testing::HasSubstr("'format' must be png or svg"));
  auto typo = c->Get("/v1/jobs/" + id + "/figure?knd=energy");
  EXPECT_EQ(typo->status, 400);
  EXPECT_THAT(typo->body, ::testing::HasSubstr("unknown query parameter 'knd'"));
  EXPECT_THAT(typo->body, ::testing::HasSubstr("(it takes kind, width, height, format, robust_y)"));
  auto report_param = c->Get("/v1/jobs/" + id + "/report?format=csv");
  EXPECT_EQ(report_param->status, 400);
  EXPECT_THAT(report_param->body, ::testing::HasSubstr("unknown query parameter 'format'"));
  EXPECT_THAT(report_param->body, ::testing::HasSubstr("(it takes none)"));
}

// format=npy: the rows of format=csv, window and all, as one float64 array whose every value is the
// double its CSV cell reads as, bit for bit; the column names in the Moreau-Columns header.
TEST(ServerApi, TrajectoryAsNpyIsTheCsvsDoublesBitForBit) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "manipulator-tracking"}, {"overrides", {"integrator.t_end=0.5", "output.every=1"}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  for (const std::string window : {"", "&from=0.1&to=0.3", "&every=7", "&from=0.05&every=3", "&from=0.4&to=0.1", "&from=100"}) {
    SCOPED_TRACE(window);
    auto csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv" + window);
    auto npy = c->Get("/v1/jobs/" + id + "/trajectory?format=npy" + window);
    ASSERT_TRUE(csv && npy);
    if (window == "&from=0.4&to=0.1") {  // the window's bounds are checked as for csv
      EXPECT_EQ(npy->status, 400);
      EXPECT_EQ(npy->body, csv->body);
      continue;
    }
    ASSERT_EQ(csv->status, 200);
    ASSERT_EQ(npy->status, 200) << npy->body;
    EXPECT_EQ(npy->get_header_value("Content-Type"), "application/octet-stream");
    EXPECT_EQ(npy->get_header_value("Content-Disposition"), "attachment; filename=\"" + id + ".npy\"");
    const CsvTable table = parse_csv(csv->body);
    ASSERT_GE(table.names.size(), 7u);
    std::string joined;
    for (const auto& name : table.names) joined += (joined.empty() ? "" : ",") + name;
    EXPECT_EQ(npy->get_header_value("Moreau-Columns"), joined);
    const NpyArray array = parse_npy(npy->body);
    EXPECT_EQ(array.rows, static_cast<std::int64_t>(table.rows));
    EXPECT_EQ(array.columns, static_cast<std::int64_t>(table.names.size()));
    EXPECT_EQ(array.bits, table.bits);
    if (window == "&from=100") {
      EXPECT_EQ(array.rows, 0);
    }
    if (window.empty()) {
      EXPECT_EQ(array.rows, 501);
    }
  }
  EXPECT_NE(c->Get("/v1/jobs/" + id + "/trajectory?format=npy")->get_header_value("ETag"),
            c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->get_header_value("ETag"));
}

// The .npy writer on a stored file with what a run rarely writes: non-finite values, -0, a subnormal, the
// largest double, a short row and an unreadable cell (NaN, as JSON's null); the same bytes made ahead on
// a thread; and names that need encoding in the header.
TEST(ServerApi, TrajectoryNpyReadsEveryCellAsItsDoubleAndEncodesNames) {
  const TempDir dir("npy");
  const fs::path path = dir / "trajectory.csv";
  {
    std::ofstream out(path, std::ios::binary);
    out << "t,h,x\n"
        << "0,0.001,nan\n"
        << "0.001,0.001,-inf\n"
        << "0.002,0.001,inf\n"
        << "0.003,0.001,-0\n"
        << "0.004,0.001,5e-324\n"
        << "0.005,0.001,1.7976931348623157e+308\n"
        << "0.006,0.001\n"
        << "0.007,0.001,x\n";
  }
  moreau::server::TrajectoryReader reader;
  std::string error;
  ASSERT_TRUE(reader.open(path.string(), {}, moreau::server::TrajectoryReader::Format::kNpy, &error)) << error;
  std::string body;
  while (reader.next(body, 16)) {
  }
  const NpyArray array = parse_npy(body);
  ASSERT_EQ(array.rows, 8);
  ASSERT_EQ(array.columns, 3);
  auto x = [&](int row) { return std::bit_cast<double>(array.bits[static_cast<std::size_t>(3 * row + 2)]); };
  EXPECT_TRUE(std::isnan(x(0)));
  EXPECT_EQ(x(1), -HUGE_VAL);
  EXPECT_EQ(x(2), HUGE_VAL);
  EXPECT_EQ(array.bits[3 * 3 + 2], std::bit_cast<std::uint64_t>(-0.0));
  EXPECT_EQ(x(4), std::numeric_limits<double>::denorm_min());
  EXPECT_EQ(x(5), std::numeric_limits<double>::max());
  EXPECT_TRUE(std::isnan(x(6)));
  EXPECT_TRUE(std::isnan(x(7)));
  EXPECT_EQ(std::bit_cast<double>(array.bits[3 * 7]), 0.007);

  // Made ahead on a thread: the same bytes; and a response given up half way stops its thread (the
  // destructor returns while the thread waits for room to put its next part).
  auto npy_reader = [](const fs::path& p) {
    auto r = std::make_shared<moreau::server::TrajectoryReader>();
    EXPECT_TRUE(r->open(p.string(), {}, moreau::server::TrajectoryReader::Format::kNpy, nullptr));
    return r;
  };
  {
    moreau::server::TrajectoryPrefetcher ahead(npy_reader(path), 1);
    std::string prefetched;
    while (ahead.next(prefetched)) {
    }
    EXPECT_EQ(prefetched, body);
  }
  const fs::path long_path = dir / "long.csv";
  {
    std::ofstream out(long_path, std::ios::binary);
    out << "t,h,x\n";
    for (int i = 0; i < 50000; ++i) out << i * 0.001 << ",0.001," << i << "\n";
  }
  std::string whole;
  for (auto r = npy_reader(long_path); r->next(whole);) {
  }
  {
    moreau::server::TrajectoryPrefetcher ahead(npy_reader(long_path), 2);
    std::string some;
    ASSERT_TRUE(ahead.next(some));
    EXPECT_EQ(some, whole.substr(0, some.size()));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the thread fills its two places and waits
  }
  {
    moreau::server::TrajectoryPrefetcher ahead(npy_reader(long_path));
    std::string all;
    while (ahead.next(all)) {
    }
    EXPECT_EQ(all, whole);
    EXPECT_EQ(parse_npy(all).rows, 50000);
  }

  EXPECT_EQ(moreau::server::columns_header_value({"t", "h", "x1_dot", "a.b-c"}), "t,h,x1_dot,a.b-c");
  EXPECT_EQ(moreau::server::columns_header_value({"a,b", "c\r\nSet-Cookie: x", "%", "\xc3\xa9"}),
            "a%2Cb,c%0D%0ASet-Cookie%3A%20x,%25,%C3%A9");
}

TEST(ServerApi, ShippedScenesByNameWithOverrides) {
  TestServer ts;
  auto c = ts.client();
  auto list = c->Get("/v1/scenes");
  ASSERT_EQ(list->status, 200);
  const json scenes = json::parse(list->body);
  bool found = false;
  for (const auto& s : scenes["scenes"]) found = found || s["name"] == "manipulator";
  EXPECT_TRUE(found) << scenes.dump(2);
  auto one = c->Get("/v1/scenes/manipulator");
  ASSERT_EQ(one->status, 200);
  EXPECT_EQ(one->body, slurp("scenes/manipulator.json"));
  EXPECT_EQ(c->Get("/v1/scenes/nope")->status, 404);
  EXPECT_EQ(c->Get("/v1/scenes/..%2F..%2Fetc%2Fpasswd")->status, 404);

  // By name, with overrides in both forms.
  auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1"}}});
  ASSERT_EQ(r->status, 202) << r->body;
  json job = wait_final(*c, json::parse(r->body)["id"]);
  EXPECT_EQ(job["report"]["steps"], 1000);
  r = submit(*c, {{"scene", "manipulator"}, {"overrides", {{"integrator.t_end", 0.5}, {"/integrator/h", 0.01}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  job = wait_final(*c, json::parse(r->body)["id"]);
  EXPECT_EQ(job["report"]["steps"], 50);
}

// Robots from URDF through the server: a shipped URDF scene by name (its URDF file is read next to it,
// in the server's own scene directory), coordinates named after the joints; a scene sent with a URDF
// *path* is refused, since the server opens no path a client names.
TEST(ServerApi, UrdfScenesRunByNameAndPathsFromClientsAreRefused) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "iiwa14-controller"}, {"overrides", {"integrator.t_end=0.05"}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const json job = wait_final(*c, json::parse(r->body)["id"]);
  EXPECT_EQ(job["state"], "done") << job.dump(2);
  EXPECT_EQ(job["report"]["coordinates"][0], "iiwa_joint_1");
  EXPECT_EQ(job["report"]["coordinates"].size(), 7u);
  auto traj = c->Get("/v1/jobs/" + job["id"].get<std::string>() + "/trajectory");
  ASSERT_EQ(traj->status, 200);
  const json columns = json::parse(traj->body)["columns"];
  EXPECT_EQ(columns[2], "iiwa_joint_1") << columns.dump();
  EXPECT_EQ(columns[9], "iiwa_joint_1_dot") << columns.dump();

  json scene = json::parse(slurp("scenes/iiwa14-controller.json"));
  r = submit(*c, {{"scene", scene}});
  EXPECT_EQ(r->status, 400) << r->body;
  EXPECT_EQ(error_of(r)["pointer"], "/system/urdf/file") << r->body;
}

TEST(ServerApi, BadRequestsGetClearErrors) {
  ServerConfig cfg;
  cfg.max_body_bytes = 64 * 1024;
  cfg.max_steps = 1'000'000;
  cfg.max_samples = 100'000;
  TestServer ts(cfg);
  auto c = ts.client();

  // A scene error names the field.
  json scene = manipulator();
  scene["integrator"]["h"] = 0;
  auto r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/integrator/h");
  EXPECT_EQ(error_of(r)["where"], "scene");
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("> 0"));
  EXPECT_EQ(error_of(r)["error"], "invalid scene");

  r = c->Post("/v1/jobs", "{\"scene\": {", "application/json");
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["error"], "malformed JSON");

  // Invalid UTF-8 is a JSON syntax error; quoting it back in the reason must not turn it into a 500.
  r = c->Post("/v1/jobs", "{\"scene\": \"\xff\xfe\"}", "application/json");
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["error"], "malformed JSON");
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("ill-formed UTF-8"));

  // Nesting is bounded before parsing: the JSON library copies documents recursively, and 20000 levels
  // (40 KB, under the body limit) used to overflow a connection thread's stack.
  const std::string deep = "{\"scene\": {\"name\": " + std::string(20000, '[') + std::string(20000, ']') + "}}";
  r = c->Post("/v1/jobs", deep, "application/json");
  ASSERT_TRUE(r) << "the server died";
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["error"], "malformed JSON");
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("nested deeper than 64 levels at byte 81"));
  r = submit(*c, {{"scene", manipulator()}, {"overrides", {"a" + std::string(100, '.') + "=1"}}});
  ASSERT_EQ(r->status, 400);
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("deeper than 64"));

  r = c->Post("/v1/jobs", manipulator().dump(), "text/plain");
  ASSERT_EQ(r->status, 415);
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("application/json"));
  EXPECT_EQ(c->Post("/v1/jobs", json({{"scene", manipulator()}}).dump(), "application/json; charset=utf-8")->status, 202);

  r = c->Post("/v1/jobs", std::string(100 * 1024, ' '), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 413);

  r = submit(*c, {{"scene", manipulator()}, {"colour", "blue"}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/colour");
  EXPECT_EQ(error_of(r)["where"], "request");
  r = submit(*c, {{"overrides", json::array()}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/scene");
  r = submit(*c, {{"scene", "no-such-scene"}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/scene");
  r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.nope=1"}}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/integrator/nope");
  r = submit(*c, {{"scene", manipulator()}, {"stream", {{"period", -1}}}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/stream/period");
  r = submit(*c, {{"scene", manipulator()}, {"stream", {{"channel", "lower-case"}}}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/stream/channel");

  // Limits: steps per job and trajectory rows, each naming the field to change.
  scene = manipulator();
  scene["integrator"]["t_end"] = 10000;  // 1e7 steps
  r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/integrator/h");
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("at most 1000000 steps"));
  scene = manipulator();
  scene["integrator"]["t_end"] = 500;  // 5e5 steps, every one recorded: more than 1e5 rows
  r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 400);
  EXPECT_EQ(error_of(r)["pointer"], "/output/every");
  EXPECT_THAT(error_of(r)["reason"].get<std::string>(), ::testing::HasSubstr("at least 6"));
  scene["output"]["every"] = 6;
  EXPECT_EQ(submit(*c, {{"scene", scene}})->status, 202);

  // Unknown ids: 404, whether well formed or not, and nothing is created on disk for them.
  const auto before = std::distance(fs::directory_iterator(ts.data() / "jobs"), fs::directory_iterator());
  for (const std::string id : {"0123456789abcdef0123456789abcdef", "0123456789ABCDEF0123456789ABCDEF", "..", "x",
                               "0123456789abcdef0123456789abcdef0", "%2e%2e%2f%2e%2e"}) {
    for (const std::string suffix : {"", "/report", "/trajectory", "/events", "/figure"}) {
      auto g = c->Get("/v1/jobs/" + id + suffix);
      ASSERT_TRUE(g);
      EXPECT_EQ(g->status, 404) << id << suffix;
      EXPECT_THAT(error_of(g)["error"].get<std::string>(), ::testing::AnyOf("no such job", "not found"));
    }
    EXPECT_EQ(c->Delete("/v1/jobs/" + id)->status, 404);
  }
  EXPECT_EQ(std::distance(fs::directory_iterator(ts.data() / "jobs"), fs::directory_iterator()), before);
  EXPECT_EQ(c->Get("/v1/nothing")->status, 404);
  EXPECT_EQ(c->Get("/v1/jobs?state=bogus")->status, 400);
}

// Promptness is stated in steps, not milliseconds (no timed assertion): the flag is set before DELETE
// answers, and the run checks it every RunObserver::kControlInterval = 256 steps, where it also publishes
// its step; so the run ends at most 256 steps after the step a GET shows once DELETE has answered.
TEST(ServerApi, CancellingARunningJobStopsAtItsNextCheck) {
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  cfg.max_samples = 1'000'000;
  TestServer ts(cfg);
  auto c = ts.client();
  json scene = manipulator();
  scene["integrator"]["t_end"] = 1e6;  // 1e9 steps: minutes of work
  scene["output"]["every"] = 10000;
  auto r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, id), "running");
  // Into its run (past its first check), so that what follows is the cancellation of a stepping run.
  ASSERT_GE(wait_step(*c, id, moreau::RunObserver::kControlInterval), moreau::RunObserver::kControlInterval);

  // DELETE answers at once: 202, cancelling; the run stops at its next check (every 256 steps) and
  // the job is then cancelled, with what it computed stored.
  auto d = c->Delete("/v1/jobs/" + id);
  ASSERT_EQ(d->status, 202) << d->body;
  EXPECT_EQ(json::parse(d->body)["state"], "cancelling");
  const std::int64_t seen = json::parse(c->Get("/v1/jobs/" + id)->body)["progress"]["step"].get<std::int64_t>();
  const json job = wait_final(*c, id);
  EXPECT_EQ(job["state"], "cancelled");
  EXPECT_LE(job["report"]["steps"].get<std::int64_t>(), seen + moreau::RunObserver::kControlInterval)
      << "the run went on past its next cancellation check";
  EXPECT_THAT(job["reason"].get<std::string>(), ::testing::HasSubstr("cancelled"));
  // Said once: "cancelled by request at step N", not "cancelled by request (cancelled at step N)".
  EXPECT_THAT(job["reason"].get<std::string>(), ::testing::MatchesRegex("cancelled by request at step [0-9]+"));
  EXPECT_EQ(job["report"]["status"], "cancelled");
  EXPECT_LT(job["report"]["t_final"].get<double>(), 1e6);
  // A cancelled job keeps the trajectory it had; cancelling again is harmless.
  EXPECT_EQ(c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->status, 200);
  EXPECT_EQ(c->Delete("/v1/jobs/" + id)->status, 200);
}

// A running job's stream carries its state for a live plot (`sample`: t, step, n, q, v, energy), at most
// ten a second; once the job is final its stream replays no samples (its figures show the run).
TEST(ServerApi, RunningJobSendsSamplesOfItsStateAndAFinalOneKeepsNone) {
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  cfg.max_samples = 1'000'000;
  TestServer ts(cfg);
  auto c = ts.client();
  json scene = manipulator();
  scene["integrator"]["t_end"] = 1e6;  // minutes of work
  scene["output"]["every"] = 10000;
  auto r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, id), "running");
  std::vector<json> samples;
  std::string buffer;
  const auto start = Clock::now();
  c->Get("/v1/jobs/" + id + "/events", [&](const char* data, std::size_t size) {
    buffer.append(data, size);
    for (std::size_t end; (end = buffer.find("\n\n")) != std::string::npos; buffer.erase(0, end + 2)) {
      const std::string block = buffer.substr(0, end);
      const auto data_at = block.find("\ndata: ");
      if (block.find("event: sample\n") != std::string::npos && data_at != std::string::npos)
        samples.push_back(json::parse(block.substr(data_at + 7)));
    }
    return samples.size() < 4;
  });
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  ASSERT_EQ(samples.size(), 4u);
  // The first at the start (step 0), the next ones at least 100 ms of wall time apart.
  EXPECT_EQ(samples[0]["step"], 0);
  EXPECT_GE(seconds, 0.25);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const json& s = samples[i];
    EXPECT_EQ(s["n"], 2) << s;
    ASSERT_EQ(s["q"].size(), 2u) << s;
    ASSERT_EQ(s["v"].size(), 2u) << s;
    EXPECT_TRUE(s["t"].is_number() && s["energy"].is_number()) << s;
    EXPECT_FALSE(s.contains("indices")) << s;
    EXPECT_EQ(s["names"], json({"x1", "th2"})) << s;  // the scene's coordinates, for the plot's legend
    if (i > 0) {
      EXPECT_GT(s["step"].get<std::int64_t>(), samples[i - 1]["step"].get<std::int64_t>());
    }
  }
  EXPECT_DOUBLE_EQ(samples[0]["q"][0].get<double>(), scene["initial"]["q"][0].get<double>());
  ASSERT_EQ(c->Delete("/v1/jobs/" + id)->status, 202);
  EXPECT_EQ(wait_final(*c, id)["state"], "cancelled");
  const std::string replay = c->Get("/v1/jobs/" + id + "/events")->body;
  EXPECT_THAT(replay, ::testing::HasSubstr("\"state\":\"cancelled\""));
  EXPECT_EQ(replay.find("event: sample"), std::string::npos) << replay;
}

// A sample of many coordinates carries 16 of each of q and v, evenly spread from the first to the last
// and named by their indices; a value that is not finite is null.
TEST(ServerApi, SampleEventsOfManyCoordinatesAreBounded) {
  std::vector<double> q(40), v(40);
  for (int i = 0; i < 40; ++i) {
    q[i] = i;
    v[i] = -i;
  }
  q[39] = std::numeric_limits<double>::quiet_NaN();
  moreau::Sample s{7, 0.5, 1e-3, 40, q.data(), v.data(), 1.25};
  const json j = moreau::server::sample_event(s);
  EXPECT_EQ(j["n"], 40);
  EXPECT_EQ(j["step"], 7);
  ASSERT_EQ(j["q"].size(), 16u);
  ASSERT_EQ(j["v"].size(), 16u);
  ASSERT_EQ(j["indices"].size(), 16u);
  EXPECT_EQ(j["indices"].front(), 0);
  EXPECT_EQ(j["indices"].back(), 39);
  for (std::size_t k = 0; k + 1 < 16; ++k) {
    EXPECT_LT(j["indices"][k].get<int>(), j["indices"][k + 1].get<int>());
    EXPECT_EQ(j["q"][k].get<double>(), j["indices"][k].get<double>());
    EXPECT_EQ(j["v"][k].get<double>(), -j["indices"][k].get<double>());
  }
  EXPECT_TRUE(j["q"][15].is_null());
  EXPECT_FALSE(j.contains("names"));  // none given
  // Named: the names of the coordinates shown, in the same order.
  std::vector<std::string> names;
  for (int i = 0; i < 40; ++i) names.push_back("joint_" + std::to_string(i));
  const json named = moreau::server::sample_event(s, names);
  ASSERT_EQ(named["names"].size(), 16u);
  for (std::size_t k = 0; k < 16; ++k) EXPECT_EQ(named["names"][k], "joint_" + std::to_string(named["indices"][k].get<int>()));
  // Few coordinates: all of them, no indices.
  moreau::Sample few{0, 0.0, 1e-3, 3, q.data(), v.data(), 0.0};
  const json k = moreau::server::sample_event(few);
  EXPECT_EQ(k["q"], json({0.0, 1.0, 2.0}));
  EXPECT_FALSE(k.contains("indices"));
}

// --max-job-seconds bounds the work one job can take, whatever its step count: a run of 1e9 manipulator
// steps (minutes of work, within --max-steps) is stopped at its deadline, ends failed with the reason, and
// keeps the trajectory it wrote. Without the limit the same job is still running when the test stops it
// (CancellingARunningJobStopsAtItsNextCheck shows it runs past this test's deadline).
TEST(ServerApi, AJobPastMaxJobSecondsEndsFailedAndKeepsWhatItWrote) {
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  cfg.max_samples = 1'000'000;
  cfg.max_job_seconds = 0.5;
  TestServer ts(cfg);
  auto c = ts.client();
  json scene = manipulator();
  scene["integrator"]["t_end"] = 1e6;  // 1e9 steps
  scene["output"]["every"] = 10000;
  auto r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  const json job = wait_final(*c, id, 60);
  EXPECT_EQ(job["state"], "failed");
  EXPECT_THAT(job["reason"].get<std::string>(),
              ::testing::HasSubstr("ran longer than this server's limit of 0.5 s of wall-clock time (--max-job-seconds)"));
  EXPECT_EQ(job["report"]["status"], "failed");
  EXPECT_GT(job["report"]["steps"].get<std::int64_t>(), 0);
  EXPECT_LT(job["report"]["t_final"].get<double>(), 1e6);
  auto csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv");
  ASSERT_EQ(csv->status, 200);
  EXPECT_GT(std::count(csv->body.begin(), csv->body.end(), '\n'), 1);  // the header and at least one row
  // The next job gets its own deadline: a short one completes.
  json small = manipulator();
  auto r2 = submit(*c, {{"scene", small}});
  ASSERT_EQ(r2->status, 202) << r2->body;
  EXPECT_EQ(wait_final(*c, json::parse(r2->body)["id"])["state"], "done");
}

TEST(ServerApi, FullQueueAnswers429WithRetryAfter) {
  ServerConfig cfg;
  cfg.workers = 1;
  cfg.queue = 2;
  cfg.max_steps = 2'000'000'000;
  TestServer ts(cfg);
  auto c = ts.client();
  json long_scene = manipulator();
  long_scene["integrator"]["t_end"] = 1e6;
  long_scene["output"]["every"] = 100000;
  auto r = submit(*c, {{"scene", long_scene}});
  ASSERT_EQ(r->status, 202);
  const std::string running = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, running), "running");

  std::vector<std::string> queued;
  for (int i = 0; i < 2; ++i) {
    r = submit(*c, {{"scene", long_scene}});
    ASSERT_EQ(r->status, 202) << r->body;
    queued.push_back(json::parse(r->body)["id"]);
  }
  r = submit(*c, {{"scene", manipulator()}});
  ASSERT_EQ(r->status, 429) << r->body;
  ASSERT_TRUE(r->has_header("Retry-After"));
  EXPECT_GE(std::stoi(r->get_header_value("Retry-After")), 1);
  EXPECT_EQ(error_of(r)["error"], "queue full");
  EXPECT_THAT(c->Get("/metrics")->body, ::testing::HasSubstr("moreau_jobs_rejected_total{reason=\"queue_full\"} 1\n"));

  // A queued job is cancelled at once, which frees a place.
  auto d = c->Delete("/v1/jobs/" + queued[0]);
  ASSERT_EQ(d->status, 200);
  EXPECT_EQ(json::parse(d->body)["state"], "cancelled");
  EXPECT_EQ(submit(*c, {{"scene", manipulator()}})->status, 202);
  EXPECT_EQ(c->Delete("/v1/jobs/" + running)->status, 202);  // running: cancelling
  // The worker freed by the cancellation may already have taken queued[1]: cancelled at once (200) if it
  // had not, cancelling (202) if it had.
  const int last = c->Delete("/v1/jobs/" + queued[1])->status;
  EXPECT_TRUE(last == 200 || last == 202) << last;
}

// A known path with a method it does not take: 405 with the methods it does take in Allow; OPTIONS says
// the same with 204. The server's table of methods is checked against its routes both ways, path by
// path: every method Allow lists reaches a handler (whatever it then answers, it is not "not found" or
// 405), and every other method gets 405 with that same Allow.
TEST(ServerApi, WrongMethodIs405WithAllowAndOptionsAnswers) {
  TestServer ts;
  auto c = ts.client();
  const std::string id = "/0123456789abcdef0123456789abcdef";
  const std::vector<std::pair<std::string, std::string>> paths = {
      {"/", "GET, HEAD, OPTIONS"},
      {"/ui/app.js", "GET, HEAD, OPTIONS"},
      {"/ui/style.css", "GET, HEAD, OPTIONS"},
      {"/healthz", "GET, HEAD, OPTIONS"},
      {"/metrics", "GET, HEAD, OPTIONS"},
      {"/v1/openapi.json", "GET, HEAD, OPTIONS"},
      {"/v1/scenes", "GET, HEAD, OPTIONS"},
      {"/v1/scenes/manipulator", "GET, HEAD, OPTIONS"},
      {"/v1/jobs", "GET, HEAD, POST, OPTIONS"},
      {"/v1/jobs" + id, "GET, HEAD, DELETE, OPTIONS"},
      {"/v1/jobs" + id + "/events", "GET, HEAD, OPTIONS"},
      {"/v1/jobs" + id + "/report", "GET, HEAD, OPTIONS"},
      {"/v1/jobs" + id + "/trajectory", "GET, HEAD, OPTIONS"},
      {"/v1/jobs" + id + "/figure", "GET, HEAD, OPTIONS"},
      {"/v1/studies", "GET, HEAD, POST, OPTIONS"},
      {"/v1/studies" + id, "GET, HEAD, DELETE, OPTIONS"},
      {"/v1/studies" + id + "/events", "GET, HEAD, OPTIONS"},
      {"/v1/studies" + id + "/table", "GET, HEAD, OPTIONS"},
      {"/v1/studies" + id + "/figure", "GET, HEAD, OPTIONS"},
  };
  for (const auto& [path, allow] : paths) {
    SCOPED_TRACE(path);
    auto o = c->Options(path);
    ASSERT_TRUE(o);
    EXPECT_EQ(o->status, 204);
    EXPECT_EQ(o->get_header_value("Allow"), allow);
    for (const std::string method : {"GET", "POST", "DELETE", "PUT", "PATCH"}) {
      SCOPED_TRACE(method);
      httplib::Result r = method == "GET"      ? c->Get(path)
                          : method == "POST"   ? c->Post(path, "{}", "application/json")
                          : method == "DELETE" ? c->Delete(path)
                          : method == "PUT"    ? c->Put(path, "{}", "application/json")
                                               : c->Patch(path, "{}", "application/json");
      ASSERT_TRUE(r);
      const json body = json::parse(r->body, nullptr, false);
      const std::string error = body.is_object() ? body.value("error", "") : "";
      if (allow.find(method) != std::string::npos) {
        EXPECT_NE(r->status, 405) << r->body;
        EXPECT_NE(error, "not found") << r->body;
      } else {
        EXPECT_EQ(r->status, 405) << r->body;
        EXPECT_EQ(r->get_header_value("Allow"), allow);
        EXPECT_THAT(body.value("reason", ""), ::testing::HasSubstr(method + " is not allowed on " + path));
      }
    }
  }
  auto unknown = c->Options("/v1/nothing");
  ASSERT_TRUE(unknown);
  EXPECT_EQ(unknown->status, 404);
}

TEST(ServerApi, FinishedResultsFiguresAndStaticFilesAnswerIfNoneMatchWith304) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.3"}}});
  ASSERT_EQ(r->status, 202);
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const std::string job = "/v1/jobs/" + id;
  std::map<std::string, std::string> tags;
  for (const std::string& path :
       {job + "/report", job + "/trajectory", job + "/trajectory?format=csv", job + "/trajectory?from=0.1&every=2",
        job + "/trajectory?format=npy", job + "/trajectory?format=npy&from=0.1&every=2", job + "/figure?kind=phase",
        job + "/figure?kind=phase&format=svg", job + "/figure?kind=energy&width=300&height=260", std::string("/v1/openapi.json"),
        std::string("/"), std::string("/ui/app.js")}) {
    SCOPED_TRACE(path);
    auto first = c->Get(path);
    ASSERT_TRUE(first);
    ASSERT_EQ(first->status, 200);
    const std::string etag = first->get_header_value("ETag");
    ASSERT_FALSE(etag.empty());
    EXPECT_EQ(tags.count(etag), 0u) << "a different representation has a different tag: " << tags[etag];
    tags[etag] = path;
    // The same request again: the same tag and bytes. With the tag: 304 and no body, alone, in a list,
    // weak or not, or "*". With another tag: the whole answer.
    auto again = c->Get(path);
    EXPECT_EQ(again->get_header_value("ETag"), etag);
    EXPECT_EQ(again->body, first->body);
    const std::string opaque = etag.rfind("W/", 0) == 0 ? etag.substr(2) : etag;
    for (const std::string& held : {etag, "\"x\", " + etag, "W/" + opaque, opaque + " ,\"y\"", std::string("*")}) {
      auto cached = c->Get(path, {{"If-None-Match", held}});
      ASSERT_TRUE(cached);
      EXPECT_EQ(cached->status, 304) << held;
      EXPECT_EQ(cached->body, "");
      EXPECT_EQ(cached->get_header_value("ETag"), etag);
    }
    auto stale = c->Get(path, {{"If-None-Match", "\"0000000000000000\", W/\"x\""}});
    EXPECT_EQ(stale->status, 200);
    EXPECT_EQ(stale->body, first->body);
  }
  // A strong tag is the bytes' hash: the report's tag is that of the bytes served.
  auto report = c->Get(job + "/report");
  EXPECT_EQ(report->get_header_value("ETag"), strong_etag(report->body));
  // Unfinished and failing answers carry no tag.
  auto running = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1e4", "output.every=1000"}}});
  const std::string busy = json::parse(running->body)["id"];
  auto early = c->Get("/v1/jobs/" + busy + "/report");
  EXPECT_EQ(early->status, 409);
  EXPECT_FALSE(early->has_header("ETag"));
  c->Delete("/v1/jobs/" + busy);
}

TEST(ServerApi, JobListFiltersPagesWithACursorAndShowsQueuePositions) {
  ServerConfig cfg;
  cfg.workers = 1;  // one job runs, the others wait: their places in the queue are known
  TestServer ts(cfg);
  auto c = ts.client();
  auto named = [](const std::string& name, double t_end) {
    json doc = manipulator();
    doc["name"] = name;
    doc["integrator"]["t_end"] = t_end;
    doc["output"]["every"] = 1000;
    return json{{"scene", doc}};
  };
  auto id_of = [](const httplib::Result& r) { return json::parse(r->body)["id"].get<std::string>(); };
  const std::string blocker = id_of(submit(*c, named("blocker", 5e4)));
  ASSERT_EQ(wait_running(*c, blocker), "running");
  const std::string q1 = id_of(submit(*c, named("alpha", 0.1))), q2 = id_of(submit(*c, named("beta", 0.1)));
  EXPECT_EQ(json::parse(c->Get("/v1/jobs/" + q1)->body)["queue_position"], 1);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs/" + q2)->body)["queue_position"], 2);
  EXPECT_FALSE(json::parse(c->Get("/v1/jobs/" + blocker)->body).contains("queue_position"));
  const json queued = json::parse(c->Get("/v1/jobs?state=queued")->body);
  ASSERT_EQ(queued["count"], 2);
  EXPECT_EQ(queued["jobs"][0]["queue_position"], 1);
  EXPECT_EQ(queued["jobs"][1]["queue_position"], 2);
  // Cancelling the first queued one moves the other up.
  c->Delete("/v1/jobs/" + q1);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs/" + q2)->body)["queue_position"], 1);
  c->Delete("/v1/jobs/" + blocker);
  wait_final(*c, q2);

  // More jobs, then the list filtered by scene and state, and paged back from the newest.
  std::vector<std::string> ids = {blocker, q1, q2};
  for (int i = 0; i < 5; ++i) ids.push_back(id_of(submit(*c, named(i % 2 ? "alpha" : "beta", 0.05))));
  for (const auto& id : ids) wait_final(*c, id);
  const json alphas = json::parse(c->Get("/v1/jobs?scene=alpha")->body);
  EXPECT_EQ(alphas["count"], 3);  // q1 and two of the five
  for (const auto& j : alphas["jobs"]) EXPECT_EQ(j["scene"], "alpha");
  const json done_alphas = json::parse(c->Get("/v1/jobs?scene=alpha&state=done")->body);
  EXPECT_EQ(done_alphas["count"], 2);  // q1 was cancelled
  std::vector<std::string> paged;
  std::string url = "/v1/jobs?limit=3";
  for (int page = 0; page < 10 && !url.empty(); ++page) {
    const json p = json::parse(c->Get(url)->body);
    std::vector<std::string> these;
    for (const auto& j : p["jobs"]) these.push_back(j["id"]);
    EXPECT_LE(these.size(), 3u);
    paged.insert(paged.begin(), these.begin(), these.end());  // each page is older than the last
    url = p.value("next", "");
  }
  EXPECT_EQ(paged, ids) << "the pages, newest first, cover every job once, oldest first within a page";
  const json filtered_page = json::parse(c->Get("/v1/jobs?limit=1&scene=alpha")->body);
  EXPECT_THAT(filtered_page.value("next", ""), ::testing::HasSubstr("scene=alpha"));
  auto bad_cursor = c->Get("/v1/jobs?before=0123456789abcdef0123456789abcdef");
  EXPECT_EQ(bad_cursor->status, 400);
  EXPECT_THAT(bad_cursor->body, ::testing::HasSubstr("'before'"));
}

TEST(ServerApi, PurgeDeletesAFinishedJobWithItsFilesAndNeverARunningOne) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.2"}}});
  const std::string done = json::parse(r->body)["id"];
  wait_final(*c, done);
  ASSERT_TRUE(std::filesystem::exists(ts.data() / "jobs" / done / "report.json"));
  EXPECT_EQ(c->Delete("/v1/jobs/" + done + "?purge=maybe")->status, 400);
  EXPECT_EQ(c->Delete("/v1/jobs/" + done + "?wait=1")->status, 400) << "DELETE reads no wait";
  auto purged = c->Delete("/v1/jobs/" + done + "?purge=true");
  ASSERT_EQ(purged->status, 200) << purged->body;
  EXPECT_EQ(json::parse(purged->body), json({{"id", done}, {"deleted", true}}));
  EXPECT_FALSE(std::filesystem::exists(ts.data() / "jobs" / done));
  EXPECT_EQ(c->Get("/v1/jobs/" + done)->status, 404);
  EXPECT_EQ(c->Get("/v1/jobs/" + done + "/report")->status, 404);
  EXPECT_EQ(c->Delete("/v1/jobs/" + done + "?purge=1")->status, 404);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["total"], 0);

  // A running job is not purged: cancel it first; its partial results then go with it.
  auto long_run = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=5e4", "output.every=1000"}}});
  const std::string running = json::parse(long_run->body)["id"];
  auto refused = c->Delete("/v1/jobs/" + running + "?purge=true");
  EXPECT_EQ(refused->status, 409);
  EXPECT_THAT(refused->body, ::testing::HasSubstr("cancel it"));
  EXPECT_TRUE(std::filesystem::exists(ts.data() / "jobs" / running));
  c->Delete("/v1/jobs/" + running);
  EXPECT_EQ(wait_final(*c, running)["state"], "cancelled");
  EXPECT_EQ(c->Delete("/v1/jobs/" + running + "?purge=true")->status, 200);
  EXPECT_FALSE(std::filesystem::exists(ts.data() / "jobs" / running));

  // A purged job stays gone after a restart.
  const auto data = ts.release_data();
  ts.stop();
  TestServer again(ServerConfig{}, data.path());
  auto c2 = again.client();
  EXPECT_EQ(c2->Get("/v1/jobs/" + done)->status, 404);
  EXPECT_EQ(json::parse(c2->Get("/v1/jobs")->body)["total"], 0);
}

TEST(ServerApi, LureFiguresShowStateOutputAndStorageNotMechanicalLabels) {
  TestServer ts;
  auto c = ts.client();
  auto lure = submit(*c, {{"scene", read_json_file("scenes/lure-relay-2state.json")}});
  auto mech = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.2"}}});
  const std::string lure_id = json::parse(lure->body)["id"], mech_id = json::parse(mech->body)["id"];
  ASSERT_EQ(wait_final(*c, lure_id)["state"], "done");
  ASSERT_EQ(wait_final(*c, mech_id)["state"], "done");
  auto svg = [&](const std::string& id, const std::string& kind) {
    auto r = c->Get("/v1/jobs/" + id + "/figure?format=svg&kind=" + kind);
    EXPECT_EQ(r->status, 200) << r->body;
    return r->body;
  };
  const std::string state = svg(lure_id, "state"), phase = svg(lure_id, "phase"), energy = svg(lure_id, "energy");
  EXPECT_THAT(state, ::testing::HasSubstr("State x"));
  EXPECT_THAT(state, ::testing::HasSubstr("Output y = C x"));
  EXPECT_THAT(state, ::testing::Not(::testing::HasSubstr("Positions")));
  EXPECT_THAT(state, ::testing::Not(::testing::HasSubstr("Velocities")));
  EXPECT_THAT(phase, ::testing::HasSubstr("(x1, x2)"));
  EXPECT_THAT(phase, ::testing::Not(::testing::HasSubstr("x1_dot")));
  // No P in the scene: the storage is the positive realness test's certificate.
  EXPECT_THAT(energy, ::testing::HasSubstr("W = 1/2 x^T P x (storage, P from the positive realness test)"));
  EXPECT_THAT(energy, ::testing::Not(::testing::HasSubstr("&lt;M v, v&gt;")));
  EXPECT_THAT(energy, ::testing::Not(::testing::HasSubstr("<M v, v>")));
  // A mechanical job keeps its labels.
  const std::string mstate = svg(mech_id, "state"), menergy = svg(mech_id, "energy");
  EXPECT_THAT(mstate, ::testing::HasSubstr("Positions"));
  EXPECT_THAT(mstate, ::testing::Not(::testing::HasSubstr("Output y")));
  EXPECT_THAT(menergy, ::testing::HasSubstr("M v, v"));
}

// A job's figures are `moreau run --figure`'s, byte for byte at the same size and title: units, the
// mechanical energy, impacts marked from the report, and ?robust_y=true as --robust-y.
TEST(ServerApi, JobFiguresAreTheCommandLinesFigures) {
#ifndef MOREAU_CLIENT_BINARY
  GTEST_SKIP() << "the moreau client is not part of this build";
#else
  TestServer ts;
  auto c = ts.client();
  const TempDir dir("cli-figures");
  struct Case {
    std::string scene, kind;
    bool robust;
  };
  const Case cases[] = {{"bouncing-ball-e0.5", "state", false},
                        {"bouncing-ball-e0.5", "energy", false},
                        {"manipulator-fig6.4", "state", false},
                        {"iiwa14-joint-limit", "state", true}};
  std::map<std::string, std::string> ids;
  for (const Case& k : cases) {
    if (ids.count(k.scene)) continue;
    auto r = submit(*c, {{"scene", k.scene}});
    ASSERT_EQ(r->status, 202) << r->body;
    ids[k.scene] = json::parse(r->body)["id"];
    ASSERT_EQ(wait_final(*c, ids[k.scene])["state"], "done");
  }
  for (const Case& k : cases) {
    const std::string& id = ids[k.scene];
    auto served = c->Get("/v1/jobs/" + id + "/figure?format=svg&width=640&height=480&kind=" + k.kind + (k.robust ? "&robust_y=true" : ""));
    ASSERT_EQ(served->status, 200) << served->body;
    const fs::path drawn = dir / (k.scene + "-" + k.kind + ".svg");
    const std::string cmd = std::string(MOREAU_CLIENT_BINARY) + " run " + MOREAU_SOURCE_DIR + "/scenes/" + k.scene +
                            ".json --progress never --size 640x480 --title '" + k.scene + " (" + id.substr(0, 8) + ")' --figure " + k.kind +
                            "=" + drawn.string() + (k.robust ? " --robust-y" : "") + " > /dev/null 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    std::ifstream in(drawn, std::ios::binary);
    EXPECT_EQ(served->body, std::string(std::istreambuf_iterator<char>(in), {})) << k.scene << " " << k.kind;
  }
  // robust_y draws another figure than the full range (the iiwa's 48 rad/s spike is clipped), and is
  // either true or false.
  const std::string iiwa = ids["iiwa14-joint-limit"];
  EXPECT_NE(c->Get("/v1/jobs/" + iiwa + "/figure?format=svg&kind=state&robust_y=false")->body,
            c->Get("/v1/jobs/" + iiwa + "/figure?format=svg&kind=state&robust_y=true")->body);
  auto bad = c->Get("/v1/jobs/" + iiwa + "/figure?robust_y=yes");
  EXPECT_EQ(bad->status, 400);
  EXPECT_THAT(bad->body, ::testing::HasSubstr("'robust_y' must be true or false"));
#endif
}

TEST(ServerApi, CorsIsOffByDefaultAndAnswersOnlyTheConfiguredOrigin) {
  const httplib::Headers from_page = {{"Origin", "http://page.test:9000"}};
  const httplib::Headers preflight = {{"Origin", "http://page.test:9000"},
                                      {"Access-Control-Request-Method", "POST"},
                                      {"Access-Control-Request-Headers", "authorization, content-type"}};
  {
    TestServer ts;  // default: no CORS header on anything
    auto c = ts.client();
    auto r = c->Get("/v1/jobs", from_page);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_FALSE(r->has_header("Access-Control-Allow-Origin"));
    auto p = c->Options("/v1/jobs", preflight);
    ASSERT_TRUE(p);
    EXPECT_FALSE(p->has_header("Access-Control-Allow-Origin"));
    EXPECT_FALSE(p->has_header("Access-Control-Allow-Methods"));
  }
  ServerConfig cfg;
  cfg.token = "cors token";
  cfg.cors_origin = "http://page.test:9000";
  TestServer ts(cfg);
  auto anonymous = ts.client();
  auto good = ts.client(cfg.token);
  // The preflight carries no token and is answered: the methods of the path and the headers a page sends.
  auto p = anonymous->Options("/v1/jobs", preflight);
  ASSERT_TRUE(p);
  EXPECT_EQ(p->status, 204);
  EXPECT_EQ(p->get_header_value("Access-Control-Allow-Origin"), "http://page.test:9000");
  EXPECT_EQ(p->get_header_value("Access-Control-Allow-Methods"), "GET, HEAD, POST, OPTIONS");
  EXPECT_THAT(p->get_header_value("Access-Control-Allow-Headers"), ::testing::HasSubstr("Authorization"));
  EXPECT_THAT(p->get_header_value("Access-Control-Allow-Headers"), ::testing::HasSubstr("Content-Type"));
  // Answers to the origin, errors included, are marked readable by it; the token is still needed.
  auto ok = good->Get("/v1/jobs", from_page);
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  EXPECT_EQ(ok->get_header_value("Access-Control-Allow-Origin"), "http://page.test:9000");
  EXPECT_EQ(ok->get_header_value("Vary"), "Origin");
  auto denied = anonymous->Get("/v1/jobs", from_page);
  ASSERT_TRUE(denied);
  EXPECT_EQ(denied->status, 401);
  EXPECT_EQ(denied->get_header_value("Access-Control-Allow-Origin"), "http://page.test:9000");
  auto missing = good->Get("/v1/jobs/0123456789abcdef0123456789abcdef", from_page);
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
  EXPECT_EQ(missing->get_header_value("Access-Control-Allow-Origin"), "http://page.test:9000");
  auto posted = good->Post("/v1/jobs", from_page, json({{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.1"}}}).dump(),
                           "application/json");
  ASSERT_TRUE(posted);
  EXPECT_EQ(posted->status, 202);
  EXPECT_EQ(posted->get_header_value("Access-Control-Allow-Origin"), "http://page.test:9000");
  EXPECT_THAT(posted->get_header_value("Access-Control-Expose-Headers"), ::testing::HasSubstr("Location"));
  // Another origin gets nothing, and its "preflight" is an ordinary OPTIONS, which needs the token.
  const httplib::Headers other = {{"Origin", "http://evil.test"}, {"Access-Control-Request-Method", "POST"}};
  auto o = anonymous->Options("/v1/jobs", other);
  ASSERT_TRUE(o);
  EXPECT_EQ(o->status, 401);
  EXPECT_FALSE(o->has_header("Access-Control-Allow-Origin"));
  auto og = good->Get("/v1/jobs", other);
  ASSERT_TRUE(og);
  EXPECT_FALSE(og->has_header("Access-Control-Allow-Origin"));
  // The answer depends on the Origin, so every answer says so (a cache must not reuse one across origins),
  // and origins compare without case.
  auto plain = good->Get("/v1/jobs");
  EXPECT_EQ(plain->get_header_value("Vary"), "Origin");
  EXPECT_FALSE(plain->has_header("Access-Control-Allow-Origin"));
  auto shouted = good->Get("/v1/jobs", {{"Origin", "HTTP://PAGE.TEST:9000"}});
  EXPECT_EQ(shouted->get_header_value("Access-Control-Allow-Origin"), "HTTP://PAGE.TEST:9000");
  // Any origin, without a token, would let every web page use the server: refused at start.
  ServerConfig open_to_all;
  open_to_all.cors_origin = "*";
  EXPECT_THROW(TestServer{open_to_all}, std::runtime_error);
  open_to_all.token = "t";
  EXPECT_NO_THROW(TestServer{open_to_all});
}

TEST(ServerApi, TokenGuardsEveryEndpointButHealthzAndThePage) {
  ServerConfig cfg;
  cfg.token = "correct horse battery staple";
  TestServer ts(cfg);
  auto anonymous = ts.client();
  auto wrong = ts.client("correct horse battery stapler");
  auto good = ts.client(cfg.token);

  EXPECT_EQ(anonymous->Get("/healthz")->status, 200);
  // The web page's static files hold no data: the page asks for the token.
  for (const std::string path : {"/", "/ui/app.js", "/ui/style.css"}) EXPECT_EQ(anonymous->Get(path)->status, 200) << path;
  // Every route (and paths that match none: the check runs before routing), with no token, a wrong one,
  // one with a prefix of the token, the token with a suffix, and the token without the Bearer scheme.
  const std::string id = "/0123456789abcdef0123456789abcdef";
  const std::string gets[] = {"/v1/jobs",
                              "/v1/scenes",
                              "/v1/scenes/manipulator",
                              "/metrics",
                              "/v1/jobs" + id,
                              "/v1/jobs" + id + "/events",
                              "/v1/jobs" + id + "/report",
                              "/v1/jobs" + id + "/trajectory",
                              "/v1/jobs" + id + "/figure",
                              "/v1/studies",
                              "/v1/studies" + id,
                              "/v1/studies" + id + "/events",
                              "/v1/studies" + id + "/table",
                              "/v1/studies" + id + "/figure",
                              "/no/such/route",
                              "/healthz/x",
                              "/ui/other.js",
                              "/ui/app.js/x",
                              "/index.html"};
  httplib::Headers no_scheme = {{"Authorization", cfg.token}};
  httplib::Headers prefix = {{"Authorization", "Bearer correct horse"}};
  for (const auto& path : gets) {
    auto r = anonymous->Get(path);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401) << path;
    EXPECT_EQ(r->get_header_value("WWW-Authenticate"), "Bearer realm=\"moreau\"");
    EXPECT_EQ(wrong->Get(path)->status, 401) << path;
    EXPECT_EQ(anonymous->Get(path, no_scheme)->status, 401) << path;
    EXPECT_EQ(anonymous->Get(path, prefix)->status, 401) << path;
  }
  for (const std::string path : {"/v1/jobs", "/v1/studies"}) {
    EXPECT_EQ(anonymous->Post(path, json({{"scene", manipulator()}}).dump(), "application/json")->status, 401) << path;
    EXPECT_EQ(wrong->Post(path, json({{"scene", manipulator()}}).dump(), "application/json")->status, 401) << path;
  }
  for (const std::string& path : {"/v1/jobs" + id, "/v1/studies" + id}) {
    EXPECT_EQ(anonymous->Delete(path)->status, 401) << path;
    EXPECT_EQ(wrong->Delete(path)->status, 401) << path;
  }
  EXPECT_EQ(good->Get("/v1/jobs" + id)->status, 404) << "a good token gets through to the route";
  EXPECT_EQ(good->Get("/v1/jobs")->status, 200);
  EXPECT_EQ(good->Get("/metrics")->status, 200);
  auto r = submit(*good, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=1"}}});
  ASSERT_EQ(r->status, 202);
  EXPECT_EQ(wait_final(*good, json::parse(r->body)["id"])["state"], "done");
}

TEST(ServerApi, KeepJobsDeletesTheOldestFinished) {
  ServerConfig cfg;
  cfg.keep_jobs = 3;
  TestServer ts(cfg);
  auto c = ts.client();
  std::vector<std::string> ids;
  for (int i = 0; i < 5; ++i) {
    auto r = submit(*c, {{"scene", manipulator()}, {"overrides", {"integrator.t_end=0.1"}}});
    ASSERT_EQ(r->status, 202);
    ids.push_back(json::parse(r->body)["id"]);
    ASSERT_EQ(wait_final(*c, ids.back())["state"], "done");
  }
  EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["total"], 3);
  for (int i = 0; i < 5; ++i) {
    const bool kept = i >= 2;
    EXPECT_EQ(c->Get("/v1/jobs/" + ids[i])->status, kept ? 200 : 404) << i;
    EXPECT_EQ(fs::exists(ts.data() / "jobs" / ids[i]), kept) << i;
    if (kept) {
      EXPECT_EQ(c->Get("/v1/jobs/" + ids[i] + "/report")->status, 200) << i;
    }
  }
  // A restart with a smaller limit prunes what it recovers.
  c.reset();
  ts.stop();
  ServerConfig smaller;
  smaller.keep_jobs = 2;
  const TempDir data = ts.release_data();
  {
    TestServer again(smaller, data.path());
    auto c2 = again.client();
    EXPECT_EQ(json::parse(c2->Get("/v1/jobs")->body)["total"], 2);
    EXPECT_EQ(c2->Get("/v1/jobs/" + ids[2])->status, 404);
    EXPECT_EQ(c2->Get("/v1/jobs/" + ids[4])->status, 200);
  }
}

TEST(ServerApi, RemoteAddressNeedsATokenOrAnExplicitFlag) {
  const TempDir data("remote");
  ServerConfig cfg;
  cfg.data_dir = data.path().string();
  cfg.host = "0.0.0.0";
  cfg.port = 0;
  moreau::server::Server s(cfg);
  try {
    s.start();
    FAIL() << "started on 0.0.0.0 without a token";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("--allow-unauthenticated-remote"));
  }
  s.stop();
}

}  // namespace
