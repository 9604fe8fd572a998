// The `moreau` commands that talk to a server (run through moreau-remote), as a user runs them: the real
// client binary against an in-process moreau-server on 127.0.0.1.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/wait.h>

#include "server_fixture.h"

namespace moreau::server {
namespace {

using testing::TestServer;

struct Outcome {
  int status = -1;
  std::string output;  // stdout and stderr
};

// Runs the client with MOREAU_SERVER and MOREAU_TOKEN cleared, so that only the arguments count.
Outcome run_client(const std::string& args) {
  const std::string cmd = "env -u MOREAU_SERVER -u MOREAU_TOKEN " + std::string(MOREAU_CLIENT_BINARY) + " " + args + " 2>&1";
  Outcome o;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return o;
  std::array<char, 4096> buf{};
  while (const std::size_t n = std::fread(buf.data(), 1, buf.size(), p)) o.output.append(buf.data(), n);
  const int rc = pclose(p);
  o.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  return o;
}

TEST(ClientRemote, A401SaysHowToPassAToken) {
  ServerConfig cfg;
  cfg.token = "correct horse battery staple";
  TestServer ts(cfg);
  const std::string server = "--server http://127.0.0.1:" + std::to_string(ts.port());

  const Outcome none = run_client("jobs " + server);
  EXPECT_EQ(none.status, 1) << none.output;
  EXPECT_THAT(none.output, ::testing::HasSubstr("HTTP 401"));
  EXPECT_THAT(none.output, ::testing::HasSubstr("pass it with --token or the environment variable MOREAU_TOKEN"));

  const Outcome wrong = run_client("jobs " + server + " --token wrong");
  EXPECT_EQ(wrong.status, 1) << wrong.output;
  EXPECT_THAT(wrong.output, ::testing::HasSubstr("the token given by --token or MOREAU_TOKEN was not accepted"));

  const Outcome good = run_client("jobs " + server + " --token 'correct horse battery staple'");
  EXPECT_EQ(good.status, 0) << good.output;
}

// `moreau submit --study`: a study on the server, waited for, its table written; its CSV is the one the
// server serves for that study, and its rows are the requested schemes times step sizes.
TEST(ClientRemote, SubmitStudyRunsAServerSideStudy) {
  TestServer ts;
  auto c = ts.client();
  const testing::TempDir dir("client-study");
  const std::string server = " --server http://127.0.0.1:" + std::to_string(ts.port());
  const std::string csv = (dir / "table.csv").string();
  const Outcome done = run_client("submit manipulator --study --set integrator.t_end=0.5 --h 1e-2,1e-3 --schemes abl,explicit --repeats 1 "
                                  "--wait --csv " + csv + server);
  ASSERT_EQ(done.status, 0) << done.output;
  EXPECT_THAT(done.output, ::testing::HasSubstr("order abl"));
  EXPECT_THAT(done.output, ::testing::HasSubstr("order explicit"));
  const auto studies = nlohmann::json::parse(c->Get("/v1/studies")->body);
  ASSERT_EQ(studies.at("count"), 1);
  const std::string id = studies["studies"][0]["id"];
  EXPECT_THAT(done.output, ::testing::HasSubstr(id));
  std::ifstream f(csv, std::ios::binary);
  const std::string written((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(written, c->Get("/v1/studies/" + id + "/table?format=csv")->body);
  EXPECT_EQ(std::count(written.begin(), written.end(), '\n'), 1 + 2 * 2) << written;
  // Without --wait: the id only. Study options without --study, or streaming with it: refused.
  const Outcome queued = run_client("submit manipulator --study --set integrator.t_end=0.1 --h 1e-2,1e-3 --schemes abl --repeats 1" + server);
  ASSERT_EQ(queued.status, 0) << queued.output;
  EXPECT_THAT(queued.output, ::testing::MatchesRegex("[0-9a-f]{32}\n"));
  const Outcome no_flag = run_client("submit manipulator --h 1e-2,1e-3" + server);
  EXPECT_EQ(no_flag.status, 2);
  EXPECT_THAT(no_flag.output, ::testing::HasSubstr("add --study"));
  const Outcome streamed = run_client("submit manipulator --study --stream" + server);
  EXPECT_EQ(streamed.status, 2);
  const Outcome csv_without_wait = run_client("submit manipulator --study --csv " + csv + server);
  EXPECT_EQ(csv_without_wait.status, 2);
  EXPECT_THAT(csv_without_wait.output, ::testing::HasSubstr("add --wait"));
  // A scene the server refuses to study: its reason, in full.
  const Outcome lure = run_client("submit lure-relay --study" + server);
  EXPECT_EQ(lure.status, 2) << lure.output;  // refused input, as a 400 always is
  EXPECT_THAT(lure.output, ::testing::HasSubstr("a Lur'e system (\"lure\") has one scheme: run it instead"));
}

// `moreau figure ID -o FILE`: SVG for a .svg name (the server draws it without GL), PNG otherwise.
TEST(ClientRemote, FigureIsSvgOrPngByTheFileName) {
  TestServer ts;
  auto c = ts.client();
  auto posted = c->Post("/v1/jobs", R"({"scene": "damped-relay"})", "application/json");
  ASSERT_TRUE(posted);
  ASSERT_EQ(posted->status, 202) << posted->body;
  const std::string id = nlohmann::json::parse(posted->body).at("id");
  const auto waited = nlohmann::json::parse(c->Get("/v1/jobs/" + id + "?wait=30")->body);
  ASSERT_EQ(waited.at("state"), "done") << waited.dump();

  const testing::TempDir dir("client-figure");
  const std::string server = " --server http://127.0.0.1:" + std::to_string(ts.port());
  const Outcome svg = run_client("figure " + id + " -o " + (dir / "state.svg").string() + server);
  ASSERT_EQ(svg.status, 0) << svg.output;
  const Outcome png = run_client("figure " + id + " -o " + (dir / "state.png").string() + server);
  ASSERT_EQ(png.status, 0) << png.output;
  const auto read = [](const std::filesystem::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  };
  EXPECT_THAT(read(dir / "state.svg"), ::testing::HasSubstr("<svg"));
  EXPECT_EQ(read(dir / "state.png").substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
}

}  // namespace
}  // namespace moreau::server
