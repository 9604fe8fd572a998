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
#include "../../client/terminal_text.h"  // client/: the escaping the remote commands print through

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
  const Outcome done = run_client(
      "submit manipulator --study --set integrator.t_end=0.5 --h 1e-2,1e-3 --schemes abl,explicit --repeats 1 "
      "--wait --csv " +
      csv + server);
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
  const Outcome queued =
      run_client("submit manipulator --study --set integrator.t_end=0.1 --h 1e-2,1e-3 --schemes abl --repeats 1" + server);
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

// ---- Server text on the reader's terminal -----------------------------------------------------------

// The escaping itself, against expectations written out by hand.
TEST(TerminalSafe, ControlBidiBackslashAndInvalidUtf8BecomeVisibleText) {
  using moreau::cli::terminal_safe;
  using moreau::cli::terminal_safe_json;
  EXPECT_EQ(terminal_safe("manipulator"), "manipulator");
  EXPECT_EQ(terminal_safe("caf\xc3\xa9 \xe2\x88\x9a"), "caf\xc3\xa9 \xe2\x88\x9a");  // other UTF-8 kept as it is
  EXPECT_EQ(terminal_safe(std::string("a\0b", 3)), R"(a\x00b)");
  EXPECT_EQ(terminal_safe("\x1b]0;t\x07\x1b[2J\t\n\r\x7f"), R"(\x1b]0;t\x07\x1b[2J\x09\x0a\x0d\x7f)");
  EXPECT_EQ(terminal_safe("\xc2\x9b"
                          "31m \xc2\x80 \xc2\x9f \xc2\xa0"),
            "\\u{9b}31m \\u{80} \\u{9f} \xc2\xa0");  // C1; U+00A0 is not one
  EXPECT_EQ(terminal_safe("\xe2\x80\xaa\xe2\x80\xae\xe2\x81\xa6\xe2\x81\xa9\xe2\x80\xa9"),
            "\\u{202a}\\u{202e}\\u{2066}\\u{2069}\xe2\x80\xa9");  // U+2029 is not a bidirectional control
  EXPECT_EQ(terminal_safe("back\\slash"), R"(back\\slash)");
  // Not UTF-8: a lone continuation byte, a truncated sequence, an overlong ESC, a UTF-8 surrogate.
  EXPECT_EQ(terminal_safe("\x80|\xe2\x80|\xc0\x9b|\xed\xa0\x80"), R"(\x80|\xe2\x80|\xc0\x9b|\xed\xa0\x80)");
  // JSON text stays the same JSON: unsafe characters as \uNNNN, its own white space kept.
  const std::string json_text = "{\"a\": \"x\xe2\x80\xaey\xc2\x9bz\x7f\"}\n";
  EXPECT_EQ(terminal_safe_json(json_text), "{\"a\": \"x\\u202ey\\u009bz\\u007f\"}\n");
  EXPECT_EQ(nlohmann::json::parse(terminal_safe_json(json_text)), nlohmann::json::parse(json_text));
  EXPECT_EQ(terminal_safe_json("\"\xff\""), "\"\\ufffd\"");
}

// Bytes a terminal acts on, or that reorder what it shows, in text the client printed: ESC, BEL, DEL,
// other C0 controls (newline and tab aside), C1 controls (U+0080-U+009F in UTF-8) and the bidirectional
// controls U+202A-U+202E, U+2066-U+2069. The offset of the first, or npos.
std::size_t first_unsafe_byte(const std::string& s) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && c != '\n' && c != '\t') || c == 0x7f) return i;
    if (c == 0xc2 && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) >= 0x80 && static_cast<unsigned char>(s[i + 1]) <= 0x9f)
      return i;
    if (c == 0xe2 && i + 2 < s.size()) {
      const unsigned char b = static_cast<unsigned char>(s[i + 1]), d = static_cast<unsigned char>(s[i + 2]);
      if ((b == 0x80 && d >= 0xaa && d <= 0xae) || (b == 0x81 && d >= 0xa6 && d <= 0xa9)) return i;
    }
  }
  return std::string::npos;
}

// A scene named to retitle (OSC 0 ... BEL) and clear (CSI 2 J) another user's terminal, to show "evil" as
// "live" (U+202E), with a C1 CSI (U+009B) and DEL: `moreau jobs` and `moreau status` show each of those
// characters as an escape, never the character; --json and `moreau result` print JSON that means the
// same name, with the characters as \uNNNN.
TEST(ClientRemote, HostileSceneNamesArePrintedAsVisibleEscapes) {
  TestServer ts;
  auto c = ts.client();
  const std::string hostile =
      "\x1b]0;pwned\x07\x1b[2Jctl\xe2\x80\xae"
      "evil\xc2\x9b"
      "31m\x7f back\\slash";
  const std::string shown = R"(\x1b]0;pwned\x07\x1b[2Jctl\u{202e}evil\u{9b}31m\x7f back\\slash)";
  auto posted =
      c->Post("/v1/jobs", nlohmann::json({{"scene", "damped-relay"}, {"overrides", {{"name", hostile}}}}).dump(), "application/json");
  ASSERT_TRUE(posted);
  ASSERT_EQ(posted->status, 202) << posted->body;
  const std::string id = nlohmann::json::parse(posted->body).at("id");
  const auto waited = nlohmann::json::parse(c->Get("/v1/jobs/" + id + "?wait=30")->body);
  ASSERT_EQ(waited.at("state"), "done") << waited.dump();
  ASSERT_EQ(waited.at("scene"), hostile);  // the server keeps the name as sent: the client must escape it

  const std::string server = " --server http://127.0.0.1:" + std::to_string(ts.port());
  const Outcome jobs = run_client("jobs" + server);
  ASSERT_EQ(jobs.status, 0) << jobs.output;
  EXPECT_EQ(first_unsafe_byte(jobs.output), std::string::npos) << jobs.output;
  EXPECT_THAT(jobs.output, ::testing::HasSubstr(id + "  done      100.0%  " + shown + "\n"));

  const Outcome status = run_client("status " + id + server);
  ASSERT_EQ(status.status, 0) << status.output;
  EXPECT_EQ(first_unsafe_byte(status.output), std::string::npos) << status.output;
  EXPECT_THAT(status.output, ::testing::HasSubstr("job " + id + "  " + shown + "  done\n"));

  for (const std::string& args : {"status " + id + " --json", std::string("jobs --json")}) {
    const Outcome json_out = run_client(args + server);
    ASSERT_EQ(json_out.status, 0) << json_out.output;
    EXPECT_EQ(first_unsafe_byte(json_out.output), std::string::npos) << args << "\n" << json_out.output;
    const auto parsed = nlohmann::json::parse(json_out.output, nullptr, false);
    ASSERT_FALSE(parsed.is_discarded()) << args << "\n" << json_out.output;
    EXPECT_EQ(parsed.contains("jobs") ? parsed["jobs"].at(0).at("scene") : parsed.at("scene"), hostile) << args;
  }
  const Outcome report = run_client("result " + id + server);
  ASSERT_EQ(report.status, 0) << report.output;
  EXPECT_EQ(first_unsafe_byte(report.output), std::string::npos) << report.output;
  const auto parsed = nlohmann::json::parse(report.output, nullptr, false);
  ASSERT_FALSE(parsed.is_discarded()) << report.output;
  EXPECT_EQ(parsed.at("scene"), hostile);
}

}  // namespace
}  // namespace moreau::server
