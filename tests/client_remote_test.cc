// The `moreau` commands that talk to a server (run through moreau-remote), as a user runs them: the real
// client binary against an in-process moreau-server on 127.0.0.1.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
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

}  // namespace
}  // namespace moreau::server
