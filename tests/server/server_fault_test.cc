// moreau-server under faults, as a separate process (the real binary, MOREAU_SERVER_BINARY):
//
//   KillNine          SIGKILL while jobs run, at several moments (commits in progress among them),
//                     then a restart on the same data directory: every finished result is served
//                     byte-identically, every interrupted job is failed with the reason, no temporary
//                     file is left.
//   UnwritableData    --data under a regular file, and on a read-only bind mount (a private mount
//                     namespace): the server exits with a message naming the directory, never a signal.
//   DiskFull          the data directory on a 256 KiB tmpfs (private mount namespace; without mount
//                     permission, RLIMIT_FSIZE instead): a job whose trajectory does not fit fails with
//                     a reason saying its results could not be stored, the server stays up, earlier
//                     results stay intact, and once space is freed new jobs succeed.
//   PortInUse         a second server on a port in use must exit with "cannot bind", and a killed
//                     server's port must be reusable at once.
//   CancellationStorm ~200 jobs submitted from several threads while others DELETE them at random
//                     moments (queued, running, finished; several times each): every job ends final,
//                     no worker stays busy, and a fresh job still runs.
//
// Every child process is killed and reaped by an RAII guard (and gets SIGKILL if this process dies).
// MOREAU_SERVER_BINARY in the environment runs the tests against another server build.
// Figures measured with this test are in docs/reliability.md ("Faults").
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <linux/magic.h>
#include <sys/stat.h>
#include <sys/statfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "support/temp_dir.h"

namespace {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;
using moreau::test_support::TempDir;
using ::testing::AnyOf;
using ::testing::HasSubstr;

constexpr const char* kReasonCrashed = "the server died while the job was running: it runs again from the start";

// ---- small utilities ----

std::optional<std::string> slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream os;
  os << in.rdbuf();
  return os.str();
}

// FNV-1a, 64 bits: enough to tell a changed file from the same one.
std::uint64_t fnv1a(std::string_view s) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : s) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

struct Digest {
  std::uint64_t hash = 0;
  std::size_t size = 0;
  bool operator==(const Digest&) const = default;
};
Digest digest(std::string_view s) { return {fnv1a(s), s.size()}; }

int shell(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::vector<fs::path> temp_files_under(const fs::path& root) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->path().extension() == ".tmp") out.push_back(it->path());
  }
  return out;
}

std::int64_t count_lines(const std::string& s) { return std::count(s.begin(), s.end(), '\n'); }

// ---- a moreau-server child process ----

struct SpawnOptions {
  std::optional<rlim_t> fsize_limit;  // RLIMIT_FSIZE for the child (SIGXFSZ ignored)
};

// A child process (moreau-server, possibly behind `unshare ... exec`), its stdout and stderr in files.
// The destructor kills (SIGKILL) and reaps it if it is still there; PR_SET_PDEATHSIG kills it if the
// test process dies first.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const fs::path& log_dir, const SpawnOptions& opt = {}) {
    static std::atomic<int> serial{0};
    const std::string tag = std::to_string(serial++);
    out_ = log_dir / ("server-" + tag + ".out");
    err_ = log_dir / ("server-" + tag + ".err");
    // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const std::string out = out_.string(), err = err_.string();
    const pid_t parent = getpid();
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (getppid() != parent) _exit(127);
      const int o = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int e = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (o < 0 || e < 0) _exit(127);
      dup2(o, 1);
      dup2(e, 2);
      const int null = ::open("/dev/null", O_RDONLY);
      if (null >= 0) dup2(null, 0);
      if (opt.fsize_limit) {
        struct rlimit rl = {*opt.fsize_limit, *opt.fsize_limit};
        setrlimit(RLIMIT_FSIZE, &rl);
        ::signal(SIGXFSZ, SIG_IGN);
      }
      execvp(args[0], args.data());
      _exit(127);
    }
  }
  ~Child() { kill_and_reap(); }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  bool running() {
    poll();
    return !status_;
  }
  // The wait status once the child has exited (reaped), else nullopt.
  std::optional<int> poll() {
    if (!status_ && pid_ > 0) {
      int st = 0;
      if (waitpid(pid_, &st, WNOHANG) == pid_) status_ = st;
    }
    return status_;
  }
  std::optional<int> wait_exit(double seconds) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
    while (!poll() && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return status_;
  }
  void signal(int sig) {
    if (!poll()) ::kill(pid_, sig);
  }
  int kill_and_reap() {
    if (pid_ > 0 && !poll()) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      while (waitpid(pid_, &st, 0) < 0 && errno == EINTR) {
      }
      status_ = st;
    }
    return status_.value_or(0);
  }
  std::string out() const { return slurp(out_).value_or(""); }
  std::string err() const { return slurp(err_).value_or(""); }

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
  fs::path out_, err_;
};

// Waits for "listening on http://HOST:PORT" on the child's stdout; 0 if it exited or never said so.
int wait_listening(Child& c, double seconds = 10) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  const std::string key = "listening on http://127.0.0.1:";
  while (Clock::now() < deadline) {
    const std::string out = c.out();
    const auto at = out.find(key);
    if (at != std::string::npos && out.find('\n', at) != std::string::npos) return std::atoi(out.c_str() + at + key.size());
    if (!c.running()) return 0;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return 0;
}

// The server under test: MOREAU_SERVER_BINARY from the build, or the environment variable of that name
// (to run these tests against another build or an installed server).
std::string server_binary() {
  const char* env = std::getenv("MOREAU_SERVER_BINARY");
  return env && *env ? env : MOREAU_SERVER_BINARY;
}

std::vector<std::string> server_args(const fs::path& data, std::vector<std::string> extra = {}, int port = 0) {
  std::vector<std::string> a = {server_binary(), "--host",      "127.0.0.1",    "--port", std::to_string(port),
                                "--data",        data.string(), "--keep-alive", "2"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

// A running server: the child, its port, and a keep-alive client.
struct Running {
  std::unique_ptr<Child> child;
  int port = 0;
  std::unique_ptr<httplib::Client> client() const {
    auto c = std::make_unique<httplib::Client>("127.0.0.1", port);
    c->set_keep_alive(true);
    c->set_tcp_nodelay(true);
    c->set_connection_timeout(5, 0);
    c->set_read_timeout(20, 0);
    return c;
  }
};

Running start_server(std::vector<std::string> argv, const fs::path& log_dir, const SpawnOptions& opt = {}) {
  Running r;
  r.child = std::make_unique<Child>(argv, log_dir, opt);
  r.port = wait_listening(*r.child);
  if (r.port == 0) {
    throw std::runtime_error("moreau-server did not start: " + r.child->out() + r.child->err());
  }
  return r;
}

httplib::Result post_job(httplib::Client& c, const json& body) { return c.Post("/v1/jobs", body.dump(), "application/json"); }

json get_json(httplib::Client& c, const std::string& path) {
  auto r = c.Get(path);
  if (!r) throw std::runtime_error("GET " + path + ": " + httplib::to_string(r.error()));
  return json::parse(r->body);
}

bool is_final_state(const std::string& s) { return s == "done" || s == "failed" || s == "cancelled"; }

json wait_final(httplib::Client& c, const std::string& id, double seconds = 20) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  while (true) {
    const json j = get_json(c, "/v1/jobs/" + id + "?wait=2");
    if (is_final_state(j.value("state", ""))) return j;
    if (Clock::now() > deadline) throw std::runtime_error("job " + id + " not final in time: " + j.dump());
  }
}

std::string wait_state_not(httplib::Client& c, const std::string& id, const std::string& state, double seconds = 10) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(seconds);
  std::string s = state;
  while (Clock::now() < deadline) {
    s = get_json(c, "/v1/jobs/" + id).value("state", "");
    if (s != state) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return s;
}

// One value of the Prometheus text, or -1.
double metric(const std::string& text, const std::string& name) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(name + " ", 0) == 0) return std::stod(line.substr(name.size() + 1));
  }
  return -1;
}

std::string describe_exit(int status) {
  if (WIFEXITED(status)) return "exit " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return std::string("signal ") + strsignal(WTERMSIG(status));
  return "status " + std::to_string(status);
}

json damped_relay() { return json::parse(slurp("scenes/damped-relay.json").value()); }
json manipulator() { return json::parse(slurp("scenes/manipulator.json").value()); }

// A job that runs until it is stopped: the manipulator over a very long horizon, few rows.
json long_job() { return {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1e6", "output.every=100000"}}}; }

// ---- a. SIGKILL while jobs run ----

struct Finished {
  Digest report, csv;
  std::string state;
};

TEST(ServerFault, KillNineWhileJobsRunThenRestart) {
  TempDir tmp("fault-kill");
  const fs::path data = tmp.path() / "data";
  const auto args = server_args(data, {"--workers", "2", "--max-steps", "2000000000", "--queue", "256"});

  std::map<std::string, Finished> finished;  // every job seen final so far, with its results' digests
  // The trajectory each request body gave, the first time one of its jobs was seen done: every other job
  // of the same body, run before a kill or again after one, must give the same bytes.
  std::map<std::string, Digest> trajectory_of_body;
  std::map<std::string, std::string> body_of;  // job id -> its request body
  // Kill moments: when this many of the round's short jobs are done (0: as soon as all are submitted).
  const std::vector<int> kill_after = {0, 2, 10, 24};
  int total_jobs = 0, seen_done_total = 0, done_unseen_total = 0, rerun_running_total = 0, rerun_queued_total = 0, tmp_left_total = 0;
  std::mt19937 rng(12345);

  for (std::size_t round = 0; round < kill_after.size(); ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    Running srv = start_server(args, tmp.path());
    auto c = srv.client();

    // L1 occupies one worker for good; the short jobs run one after another on the other; L2 then
    // takes that worker too, so that the jobs submitted after it (Q) cannot start before the kill.
    std::vector<std::string> shorts, queued_behind, longs;
    auto submit = [&](const json& body) {
      auto r = post_job(*c, body);
      if (!r || r->status != 202) throw std::runtime_error("submit failed: " + (r ? r->body : httplib::to_string(r.error())));
      ++total_jobs;
      const std::string id = json::parse(r->body)["id"].get<std::string>();
      body_of[id] = body.dump();
      return id;
    };
    longs.push_back(submit(long_job()));
    ASSERT_EQ(wait_state_not(*c, longs[0], "queued"), "running");
    // The short jobs take 1e5 to 3e5 steps (a few milliseconds each, one row per 100 steps), so that the
    // kill finds one running more often than not.
    for (int i = 0; i < 30; ++i) {
      json body;
      if (i % 3 == 2) {
        body = {{"scene", manipulator()}, {"overrides", {"integrator.t_end=" + std::to_string(100 * (1 + i % 2)), "output.every=100"}}};
      } else {
        body = {{"scene", damped_relay()},
                {"overrides", {"integrator.t_end=" + std::to_string(100 * (1 + rng() % 3)), "output.every=100"}}};
      }
      shorts.push_back(submit(body));
    }
    longs.push_back(submit(long_job()));
    for (int i = 0; i < 3; ++i) queued_behind.push_back(submit({{"scene", "damped-relay"}}));

    // Wait until enough short jobs are done, then kill at once.
    const std::set<std::string> this_round(shorts.begin(), shorts.end());
    std::set<std::string> seen_done;
    const auto deadline = Clock::now() + std::chrono::seconds(20);
    while (static_cast<int>(seen_done.size()) < kill_after[round] && Clock::now() < deadline) {
      const json list = get_json(*c, "/v1/jobs?state=done&limit=64");
      for (const auto& j : list["jobs"]) {
        const std::string id = j["id"];
        if (this_round.count(id)) seen_done.insert(id);
      }
    }
    // Digests of what was seen done (they must not change, whatever happens next).
    for (const auto& id : seen_done) {
      auto rep = c->Get("/v1/jobs/" + id + "/report");
      auto csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv");
      ASSERT_TRUE(rep && csv);
      ASSERT_EQ(rep->status, 200);
      ASSERT_EQ(csv->status, 200);
      finished[id] = {digest(rep->body), digest(csv->body), "done"};
    }
    // More jobs may be finishing right now: the kill lands in the middle of the queue's flow.
    if (kill_after[round] > 0) {
      // keep the flow going a random fraction of a job's time so the kill hits different phases
      std::this_thread::sleep_for(std::chrono::microseconds(rng() % 3000));
    }
    c.reset();
    srv.child->kill_and_reap();
    const int status = *srv.child->poll();
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << describe_exit(status);
    const int tmp_left = static_cast<int>(temp_files_under(data).size());
    tmp_left_total += tmp_left;
    // What the records say at the kill: the jobs that were running and those that had not started.
    std::vector<std::string> all = longs;
    all.insert(all.end(), shorts.begin(), shorts.end());
    all.insert(all.end(), queued_behind.begin(), queued_behind.end());
    // (A report on disk commits a run, whatever its record says: such a run is done, not run again.)
    std::set<std::string> running_at_kill, queued_at_kill, committed_at_kill;
    for (const auto& id : all) {
      const std::string state = json::parse(slurp(data / "jobs" / id / "job.json").value_or("{}")).value("state", "");
      if (fs::exists(data / "jobs" / id / "report.json"))
        committed_at_kill.insert(id);
      else if (state == "running")
        running_at_kill.insert(id);
      else if (state == "queued")
        queued_at_kill.insert(id);
      else
        ADD_FAILURE() << "job " << id << ": state " << state << " and no report at the kill";
    }
    EXPECT_TRUE(running_at_kill.count(longs[0]));
    for (const auto& id : queued_behind) EXPECT_TRUE(queued_at_kill.count(id)) << id;

    // Restart on the same data directory. The endless jobs are run again too: cancel them, so that the
    // others can run.
    Running again = start_server(args, tmp.path());
    auto c2 = again.client();
    for (const auto& id : longs) {
      const json job = get_json(*c2, "/v1/jobs/" + id);
      EXPECT_THAT(job.value("state", ""), AnyOf("queued", "running")) << job.dump();
      if (running_at_kill.count(id)) {
        EXPECT_EQ(job.value("reason", ""), job.value("state", "") == "queued" ? kReasonCrashed : "");
      }
      auto d = c2->Delete("/v1/jobs/" + id);
      ASSERT_TRUE(d);
      EXPECT_TRUE(d->status == 200 || d->status == 202) << d->body;
      EXPECT_EQ(wait_final(*c2, id)["state"], "cancelled");
    }
    // Every other job of the round ends done: the ones seen done as they were, the others committed at
    // the kill or run again after it, each with the trajectory its body gives.
    int done_unseen = 0, rerun_running = 0, rerun_queued = 0;
    for (const auto& id : all) {
      if (std::find(longs.begin(), longs.end(), id) != longs.end()) continue;
      SCOPED_TRACE("job " + id);
      const json job = wait_final(*c2, id, 60);
      ASSERT_EQ(job.value("state", ""), "done") << job.dump();
      if (seen_done.count(id)) continue;
      auto rep = c2->Get("/v1/jobs/" + id + "/report");
      auto csv = c2->Get("/v1/jobs/" + id + "/trajectory?format=csv");
      ASSERT_TRUE(rep && csv);
      ASSERT_EQ(rep->status, 200);
      ASSERT_EQ(csv->status, 200);
      const json report = json::parse(rep->body);
      EXPECT_EQ(report.value("status", ""), "completed");
      // The header, and a row every 100 steps (the short jobs) or every step (those behind L2) from step 0
      // to the last.
      const std::int64_t every = this_round.count(id) ? 100 : 1;
      EXPECT_EQ(count_lines(csv->body), report["steps"].get<std::int64_t>() / every + 2) << "a truncated trajectory";
      finished[id] = {digest(rep->body), digest(csv->body), "done"};
      const json record = json::parse(slurp(data / "jobs" / id / "job.json").value_or("{}"));
      if (running_at_kill.count(id)) {
        ++rerun_running;
        EXPECT_EQ(record.value("crashes", 0), 1) << "a job the server died under counts it";
      } else {
        ++(queued_at_kill.count(id) ? rerun_queued : done_unseen);  // done_unseen: committed between the last look and the kill
        EXPECT_FALSE(record.contains("crashes"));
      }
    }

    // Nothing runs now: a temporary file would be one the kill left and the restart did not remove.
    EXPECT_TRUE(temp_files_under(data).empty()) << "temporary files survived the restart";

    // Every result finished in this round or an earlier one: the same bytes over HTTP and on disk, and
    // the same trajectory as every other job of its body.
    int verified = 0;
    for (const auto& [id, f] : finished) {
      if (f.state != "done") continue;
      SCOPED_TRACE("finished job " + id);
      auto rep = c2->Get("/v1/jobs/" + id + "/report");
      auto csv = c2->Get("/v1/jobs/" + id + "/trajectory?format=csv");
      ASSERT_TRUE(rep && csv);
      EXPECT_EQ(digest(rep->body), f.report);
      EXPECT_EQ(digest(csv->body), f.csv);
      EXPECT_EQ(digest(slurp(data / "jobs" / id / "report.json").value_or("")), f.report);
      EXPECT_EQ(digest(slurp(data / "jobs" / id / "trajectory.csv").value_or("")), f.csv);
      EXPECT_EQ(get_json(*c2, "/v1/jobs/" + id)["state"], "done");
      const auto [it, first] = trajectory_of_body.emplace(body_of.at(id), f.csv);
      if (!first) {
        EXPECT_EQ(it->second, f.csv) << "a job of the same body gave another trajectory";
      }
      ++verified;
    }
    seen_done_total += static_cast<int>(seen_done.size());
    done_unseen_total += done_unseen;
    rerun_running_total += rerun_running;
    rerun_queued_total += rerun_queued;
    std::cout << "[kill -9] round " << round << ": killed after " << seen_done.size() << " jobs seen done; " << done_unseen
              << " more done at the kill, " << rerun_running << " run again (were running), " << rerun_queued
              << " run again (had not started), " << tmp_left << " temporary files left by the kill; " << verified
              << " finished results verified byte for byte\n";

    // The restarted server takes new jobs; a clean stop exits 0.
    auto r = post_job(*c2, {{"scene", "damped-relay"}});
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202);
    EXPECT_EQ(wait_final(*c2, json::parse(r->body)["id"])["state"], "done");
    c2.reset();
    again.child->signal(SIGTERM);
    const auto st = again.child->wait_exit(10);
    ASSERT_TRUE(st.has_value()) << "no exit within 10 s of SIGTERM";
    EXPECT_TRUE(WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << describe_exit(*st);
  }
  std::cout << "[kill -9] " << kill_after.size() << " rounds, " << total_jobs << " jobs: " << seen_done_total
            << " seen done before the kill, " << done_unseen_total << " committed at the kill, " << rerun_running_total
            << " run again after dying under them, " << rerun_queued_total << " run after the restart that had not started, "
            << tmp_left_total << " temporary files cleaned up; every job but the cancelled endless ones done\n";
}

// ---- a2. server-sent event ids across a SIGKILL and restarts ----

struct Sse {
  std::uint64_t id;
  std::string name, data;
};

// The events of a stream, read until it ends or `stop_after` events with an id are in (then the client
// hangs up), from `last_event_id` if given.
std::vector<Sse> read_events(httplib::Client& c, const std::string& path, std::optional<std::uint64_t> last_event_id = {},
                             std::size_t stop_after = SIZE_MAX) {
  std::vector<Sse> out;
  std::string buf;
  httplib::Headers h;
  if (last_event_id) h.emplace("Last-Event-ID", std::to_string(*last_event_id));
  c.Get(path, h, [&](const char* data, std::size_t len) {
    buf.append(data, len);
    for (auto end = buf.find("\n\n"); end != std::string::npos; end = buf.find("\n\n")) {
      const std::string block = buf.substr(0, end);
      buf.erase(0, end + 2);
      Sse e{0, "", ""};
      bool has_id = false;
      std::istringstream lines(block);
      for (std::string line; std::getline(lines, line);) {
        if (line.rfind("id: ", 0) == 0) e.id = std::stoull(line.substr(4)), has_id = true;
        if (line.rfind("event: ", 0) == 0) e.name = line.substr(7);
        if (line.rfind("data: ", 0) == 0) e.data = line.substr(6);
      }
      if (has_id) out.push_back(e);
      if (out.size() >= stop_after) return false;
    }
    return true;
  });
  return out;
}

TEST(ServerFault, EventIdsGoOnAcrossAKillAndRestarts) {
  TempDir tmp("fault-sse-ids");
  const fs::path data = tmp.path() / "data";
  const auto args = server_args(data, {"--workers", "2", "--max-steps", "2000000000"});
  std::string done_id, running_id;
  std::vector<Sse> done_events;
  std::uint64_t running_last = 0, failed_id = 0;
  {
    Running srv = start_server(args, tmp.path());
    auto c = srv.client();
    auto d = post_job(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.5"}}});
    ASSERT_EQ(d->status, 202);
    done_id = json::parse(d->body)["id"];
    ASSERT_EQ(wait_final(*c, done_id)["state"], "done");
    done_events = read_events(*c, "/v1/jobs/" + done_id + "/events");
    ASSERT_FALSE(done_events.empty());
    auto r = post_job(*c, long_job());
    ASSERT_EQ(r->status, 202);
    running_id = json::parse(r->body)["id"];
    // Its state events and some progress and sample events (about ten a second of each), then hang up and
    // kill the server.
    const auto seen = read_events(*c, "/v1/jobs/" + running_id + "/events", std::nullopt, 5);
    ASSERT_EQ(seen.size(), 5u);
    EXPECT_THAT(seen.back().name, ::testing::AnyOf("progress", "sample"));
    for (std::size_t i = 1; i < seen.size(); ++i) EXPECT_GT(seen[i].id, seen[i - 1].id);
    running_last = seen.back().id;
    srv.child->kill_and_reap();
  }
  // Restart 1 runs the killed job again; it is killed again under it; restart 2 fails it (a job the
  // server died under twice); restart 3, after another kill, shows the same failure with the same id.
  for (int restart = 1; restart <= 3; ++restart) {
    SCOPED_TRACE("restart " + std::to_string(restart));
    Running srv = start_server(args, tmp.path());
    auto c = srv.client();
    // The finished job: its final state event again, with the id it had; resuming from the event before
    // it gives exactly it, from it nothing.
    const auto replay = read_events(*c, "/v1/jobs/" + done_id + "/events");
    ASSERT_EQ(replay.size(), 1u);
    EXPECT_EQ(replay[0].id, done_events.back().id);
    EXPECT_EQ(replay[0].data, done_events.back().data);
    const auto resumed = read_events(*c, "/v1/jobs/" + done_id + "/events", done_events.back().id - 1);
    ASSERT_EQ(resumed.size(), 1u);
    EXPECT_EQ(resumed[0].id, done_events.back().id);
    EXPECT_TRUE(read_events(*c, "/v1/jobs/" + done_id + "/events", done_events.back().id).empty());
    if (restart == 1) {
      // Queued again (saying why), then running, then progress: ids after every event it sent before the
      // kill, so a client that resumes from the last one it saw misses nothing and gets nothing twice.
      const auto after = read_events(*c, "/v1/jobs/" + running_id + "/events", running_last, 4);
      ASSERT_EQ(after.size(), 4u);
      EXPECT_EQ(after[0].name, "state");
      EXPECT_THAT(after[0].data, HasSubstr("\"queued\""));
      EXPECT_THAT(after[0].data, HasSubstr(kReasonCrashed));
      EXPECT_GT(after[0].id, running_last);
      EXPECT_EQ(after[1].name, "state");
      EXPECT_THAT(after[1].data, HasSubstr("\"running\""));
      for (std::size_t i = 1; i < after.size(); ++i) EXPECT_GT(after[i].id, after[i - 1].id);
      running_last = after.back().id;
    } else {
      // Failed, with an id after every event it sent, and the same after a further restart.
      const auto after = read_events(*c, "/v1/jobs/" + running_id + "/events", running_last);
      ASSERT_EQ(after.size(), 1u);
      EXPECT_EQ(after[0].name, "state");
      EXPECT_THAT(after[0].data, HasSubstr("\"failed\""));
      EXPECT_THAT(after[0].data, HasSubstr("the server died twice while the job was running"));
      EXPECT_GT(after[0].id, running_last);
      EXPECT_EQ(read_events(*c, "/v1/jobs/" + running_id + "/events").at(0).id, after[0].id);
      if (restart == 2) failed_id = after[0].id;
      EXPECT_EQ(after[0].id, failed_id) << "the same id after the third restart as after the second";
    }
    srv.child->kill_and_reap();
  }
}

// ---- b. unwritable data directory ----

void expect_clean_refusal(Child& child, const std::string& dir_named) {
  ASSERT_EQ(wait_listening(child, 10), 0) << "the server started: " << child.out();
  const auto st = child.wait_exit(10);
  ASSERT_TRUE(st.has_value()) << "the server did not exit; stdout: " << child.out();
  EXPECT_TRUE(WIFEXITED(*st)) << describe_exit(*st) << "\n" << child.err();
  if (WIFEXITED(*st)) {
    EXPECT_NE(WEXITSTATUS(*st), 0);
  }
  const std::string err = child.err();
  EXPECT_THAT(err, HasSubstr("moreau-server: "));
  EXPECT_THAT(err, HasSubstr(dir_named)) << "the message should name the directory";
  EXPECT_THAT(child.out(), ::testing::Not(HasSubstr("listening on"))) << child.err();
  std::cout << "[unwritable] " << describe_exit(*st) << ": " << err;
}

TEST(ServerFault, DataDirectoryUnderARegularFile) {
  TempDir tmp("fault-notdir");
  const fs::path file = tmp.path() / "file";
  std::ofstream(file) << "not a directory\n";
  Child child(server_args(file / "data"), tmp.path());
  expect_clean_refusal(child, (file / "data").string());
}

bool can_bind_mount_read_only(const fs::path& dir) {
  const std::string d = dir.string();
  return shell("unshare -m sh -c 'mount --bind \"" + d + "\" \"" + d + "\" && mount -o remount,ro,bind \"" + d + "\"' >/dev/null 2>&1") ==
         0;
}

// `unshare -m sh -c 'mount --bind DIR DIR && mount -o remount,ro,bind DIR && exec moreau-server ...'`
std::vector<std::string> read_only_server_args(const fs::path& ro_dir, const fs::path& data) {
  std::vector<std::string> a = {
      "unshare", "-m",           "sh", "-c", "mount --bind \"$1\" \"$1\" && mount -o remount,ro,bind \"$1\" && shift && exec \"$@\"",
      "sh",      ro_dir.string()};
  const auto s = server_args(data);
  a.insert(a.end(), s.begin(), s.end());
  return a;
}

TEST(ServerFault, ReadOnlyDataDirectory) {
  TempDir tmp("fault-ro");
  const fs::path ro = tmp.path() / "ro";
  fs::create_directories(ro);
  // Tests run as root, for whom a mode of 0555 does not stop writes: a read-only bind mount does.
  if (!can_bind_mount_read_only(ro)) {
    GTEST_SKIP() << "cannot make a read-only bind mount here (unshare -m and mount --bind need CAP_SYS_ADMIN); "
                    "chmod alone does not stop root from writing";
  }
  {
    SCOPED_TRACE("an empty read-only directory");
    Child child(read_only_server_args(ro, ro), tmp.path());
    expect_clean_refusal(child, ro.string());
  }
  {
    SCOPED_TRACE("a data directory below a read-only one");
    Child child(read_only_server_args(ro, ro / "data"), tmp.path());
    expect_clean_refusal(child, (ro / "data").string());
  }
  {
    // A data directory that was used before (DATA/jobs exists, with a finished job), now read-only:
    // nothing can be stored in it, so the server must say so rather than start and fail every job.
    SCOPED_TRACE("a used data directory, now read-only");
    {
      Running srv = start_server(server_args(ro, {"--workers", "1"}), tmp.path());
      auto c = srv.client();
      auto r = post_job(*c, {{"scene", "damped-relay"}, {"overrides", {"integrator.t_end=1"}}});
      ASSERT_TRUE(r);
      ASSERT_EQ(r->status, 202);
      ASSERT_EQ(wait_final(*c, json::parse(r->body)["id"])["state"], "done");
      c.reset();
      srv.child->signal(SIGTERM);
      ASSERT_TRUE(srv.child->wait_exit(10));
    }
    ASSERT_TRUE(fs::is_directory(ro / "jobs"));
    Child child(read_only_server_args(ro, ro), tmp.path());
    expect_clean_refusal(child, ro.string());
  }
}

// A port another server listens on: the second server must not start (with SO_REUSEPORT it would
// share the port and take part of the connections, with its own data directory); and a server killed
// with SIGKILL can be replaced on its port at once (its connections in TIME_WAIT do not stop the bind).
TEST(ServerFault, PortInUse) {
  TempDir tmp("fault-port");
  Running first = start_server(server_args(tmp.path() / "a"), tmp.path());
  {
    auto c = first.client();
    for (int i = 0; i < 5; ++i) ASSERT_EQ(c->Get("/healthz")->status, 200);
  }
  Child second(server_args(tmp.path() / "b", {}, first.port), tmp.path());
  ASSERT_EQ(wait_listening(second, 5), 0) << "a second server started on port " << first.port
                                          << " while the first listens: " << second.out();
  const auto st = second.wait_exit(5);
  ASSERT_TRUE(st.has_value());
  EXPECT_TRUE(WIFEXITED(*st) && WEXITSTATUS(*st) != 0) << describe_exit(*st);
  EXPECT_THAT(second.err(), HasSubstr("cannot bind 127.0.0.1:" + std::to_string(first.port)));
  std::cout << "[port in use] " << describe_exit(*st) << ": " << second.err();

  // Connections, then SIGKILL, then a new server on the same port right away.
  {
    auto c = first.client();
    auto r = post_job(*c, {{"scene", "damped-relay"}});
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202);
  }
  first.child->kill_and_reap();
  Child again(server_args(tmp.path() / "a", {}, first.port), tmp.path());
  EXPECT_EQ(wait_listening(again), first.port) << again.err();
}

// ---- c. full disk ----

TEST(ServerFault, DiskFullFailsTheJobAndTheServerRecovers) {
  TempDir tmp("fault-full");
  const fs::path mnt = tmp.path() / "mnt";
  fs::create_directories(mnt);
  const std::string m = mnt.string();
  // MOREAU_FAULT_NO_MOUNT=1 takes the RLIMIT_FSIZE path even where mounting is permitted.
  const char* no_mount = std::getenv("MOREAU_FAULT_NO_MOUNT");
  const bool can_mount =
      !(no_mount && *no_mount == '1') && shell("unshare -m sh -c 'mount -t tmpfs -o size=16k tmpfs \"" + m + "\"' >/dev/null 2>&1") == 0;

  // With a tmpfs: files are reached through /proc/PID/root (the server's own mount namespace).
  std::unique_ptr<Running> srv;
  fs::path data, root;
  if (can_mount) {
    data = mnt / "data";
    std::vector<std::string> a = {"unshare", "-m", "sh", "-c", "mount -t tmpfs -o size=256k,mode=0755 tmpfs \"$1\" && shift && exec \"$@\"",
                                  "sh",      m};
    const auto s = server_args(data, {"--workers", "1"});
    a.insert(a.end(), s.begin(), s.end());
    srv = std::make_unique<Running>(start_server(a, tmp.path()));
    root = fs::path("/proc/" + std::to_string(srv->child->pid()) + "/root");
  } else {
    // Fallback: every file the server writes is limited to 256 KiB (EFBIG instead of ENOSPC).
    data = tmp.path() / "data";
    SpawnOptions opt;
    opt.fsize_limit = 256 * 1024;
    srv = std::make_unique<Running>(start_server(server_args(data, {"--workers", "1"}), tmp.path(), opt));
    root = "/";
  }
  std::cout << "[disk full] " << (can_mount ? "256 KiB tmpfs in a private mount namespace" : "RLIMIT_FSIZE 256 KiB") << "\n";
  auto on_disk = [&](const fs::path& p) { return root / p.relative_path(); };
  auto c = srv->client();
  auto healthy = [&] {
    auto h = c->Get("/healthz");
    return h && h->status == 200;
  };

  // Two small results first.
  std::map<std::string, std::pair<Digest, Digest>> before;
  for (int i = 0; i < 2; ++i) {
    auto r = post_job(*c, {{"scene", "damped-relay"}, {"overrides", {"integrator.t_end=1", "output.every=50"}}});
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202) << r->body;
    const std::string id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_final(*c, id)["state"], "done");
    before[id] = {digest(c->Get("/v1/jobs/" + id + "/report")->body), digest(c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->body)};
  }

  // A job whose trajectory (about 1 MB) cannot fit.
  auto r = post_job(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=10"}}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string big = json::parse(r->body)["id"];
  const json failed = wait_final(*c, big);
  EXPECT_EQ(failed["state"], "failed");
  const std::string reason = failed.value("reason", "");
  std::cout << "[disk full] the job that does not fit: " << failed["state"] << ", reason: " << reason << "\n";
  EXPECT_THAT(reason, AnyOf(HasSubstr("No space left on device"), HasSubstr("File too large")));
  EXPECT_THAT(reason, HasSubstr("cannot store the results")) << "the reason should say the results could not be stored";
  EXPECT_TRUE(healthy());
  EXPECT_TRUE(srv->child->running());
  // Its partial files do not stay behind, taking the space.
  const auto leftovers = temp_files_under(on_disk(data / "jobs" / big));
  EXPECT_TRUE(leftovers.empty()) << leftovers.size() << " temporary file(s) of the failed job left, e.g. " << leftovers.front();

  if (can_mount) {
    // Fill what is left, then try a small job: refused or failed, with a clear reason, never a crash.
    // Written through /proc/PID/root into the server's tmpfs: checked to be that tmpfs, and bounded,
    // so that nothing can ever fill a real disk.
    const fs::path filler = on_disk(mnt / "filler");
    struct statfs sf {};
    ASSERT_EQ(statfs(on_disk(mnt).c_str(), &sf), 0);
    ASSERT_EQ(sf.f_type, TMPFS_MAGIC) << "not the server's tmpfs: " << on_disk(mnt);
    {
      std::ofstream f(filler, std::ios::binary);
      const std::string block(4096, 'x');
      for (int i = 0; i < 64 && f.write(block.data(), block.size()); ++i) {
      }
    }
    std::error_code ec;
    std::cout << "[disk full] filler of " << fs::file_size(filler, ec) << " bytes\n";
    r = post_job(*c, {{"scene", "damped-relay"}, {"overrides", {"integrator.t_end=1", "output.every=50"}}});
    ASSERT_TRUE(r);
    std::string outcome = std::to_string(r->status);
    if (r->status == 202) {
      const json j = wait_final(*c, json::parse(r->body)["id"]);
      EXPECT_EQ(j["state"], "failed");
      EXPECT_THAT(j.value("reason", ""), HasSubstr("cannot store the results"));
      outcome += " then " + j.value("state", "") + ": " + j.value("reason", "");
    } else {
      EXPECT_EQ(r->status, 507) << r->body;
      EXPECT_THAT(r->body, HasSubstr("No space left on device"));
      outcome += " " + r->body;
    }
    std::cout << "[disk full] a small job on the full disk: " << outcome;
    EXPECT_TRUE(healthy());
    // A refused submission leaves nothing behind: every job directory is a job the server knows.
    std::error_code ec2;
    std::size_t dirs = 0;
    for (const auto& e : fs::directory_iterator(on_disk(data / "jobs"), ec2)) dirs += e.is_directory() ? 1 : 0;
    EXPECT_EQ(dirs, get_json(*c, "/v1/jobs")["total"].get<std::size_t>()) << "job directories left by refused submissions";
    fs::remove(filler);
  }

  // Earlier results are intact, over HTTP and on disk.
  for (const auto& [id, d] : before) {
    EXPECT_EQ(get_json(*c, "/v1/jobs/" + id)["state"], "done");
    EXPECT_EQ(digest(c->Get("/v1/jobs/" + id + "/report")->body), d.first);
    EXPECT_EQ(digest(c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->body), d.second);
    EXPECT_EQ(digest(slurp(on_disk(data / "jobs" / id / "report.json")).value_or("")), d.first);
    EXPECT_EQ(digest(slurp(on_disk(data / "jobs" / id / "trajectory.csv")).value_or("")), d.second);
  }
  // With space again, new jobs succeed.
  for (int i = 0; i < 3; ++i) {
    r = post_job(*c, {{"scene", "damped-relay"}, {"overrides", {"integrator.t_end=2", "output.every=20"}}});
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 202) << r->body;
    const json j = wait_final(*c, json::parse(r->body)["id"]);
    EXPECT_EQ(j["state"], "done") << j.dump();
  }
  EXPECT_TRUE(healthy());
  c.reset();
  srv->child->signal(SIGTERM);
  const auto st = srv->child->wait_exit(10);
  ASSERT_TRUE(st.has_value());
  EXPECT_TRUE(WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << describe_exit(*st) << "\n" << srv->child->err();
}

// ---- d. cancellation storm ----

TEST(ServerFault, CancellationStorm) {
  TempDir tmp("fault-storm");
  Running srv =
      start_server(server_args(tmp.path() / "data", {"--workers", "2", "--queue", "1000", "--max-connections", "128"}), tmp.path());
  constexpr int kSubmitters = 4, kCancellers = 4, kJobsPerSubmitter = 50;
  // About 10 ms of integration each (100k steps), 101 rows: long enough to be cancelled while running.
  const json body = {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=100", "output.every=1000"}}};

  std::mutex mu;
  std::vector<std::string> ids;
  std::atomic<int> submitters_left{kSubmitters};
  std::atomic<int> delete_200{0}, delete_409{0}, delete_other{0}, submit_errors{0};
  std::atomic<std::int64_t> delete_max_us{0};
  std::vector<std::string> problems;
  auto problem = [&](const std::string& p) {
    std::lock_guard l(mu);
    if (problems.size() < 20) problems.push_back(p);
  };
  auto cancel = [&](httplib::Client& c, const std::string& id) {
    const auto t0 = Clock::now();
    auto r = c.Delete("/v1/jobs/" + id);
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - t0).count();
    std::int64_t prev = delete_max_us.load();
    while (us > prev && !delete_max_us.compare_exchange_weak(prev, us)) {
    }
    if (!r) {
      ++delete_other;
      problem("DELETE " + id + ": " + httplib::to_string(r.error()));
      return;
    }
    const json j = json::parse(r->body, nullptr, false);
    if ((r->status == 200 && j.value("state", "") == "cancelled") || (r->status == 202 && j.value("state", "") == "cancelling")) {
      ++delete_200;
    } else if (r->status == 409) {
      ++delete_409;
    } else {
      ++delete_other;
      problem("DELETE " + id + ": " + std::to_string(r->status) + " " + r->body);
    }
  };

  const auto t_start = Clock::now();
  std::vector<std::thread> threads;
  for (int s = 0; s < kSubmitters; ++s) {
    threads.emplace_back([&, s] {
      auto c = srv.client();
      std::mt19937 rng(100 + s);
      for (int i = 0; i < kJobsPerSubmitter; ++i) {
        auto r = post_job(*c, body);
        if (!r || r->status != 202) {
          ++submit_errors;
          problem("POST: " + (r ? std::to_string(r->status) + " " + r->body : httplib::to_string(r.error())));
          continue;
        }
        const std::string id = json::parse(r->body)["id"];
        {
          std::lock_guard l(mu);
          ids.push_back(id);
        }
        if (rng() % 4 == 0) cancel(*c, id);  // before it runs, most likely
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 2000));
      }
      --submitters_left;
    });
  }
  for (int k = 0; k < kCancellers; ++k) {
    threads.emplace_back([&, k] {
      auto c = srv.client();
      std::mt19937 rng(200 + k);
      int after = 0;  // rounds after the last submission: cancels of finished jobs too
      while (after < 150) {
        if (submitters_left.load() == 0) ++after;
        std::vector<std::string> picked;
        if (k % 2 == 1) {
          // Hunts running jobs: the ones the list shows running now.
          auto r = c->Get("/v1/jobs?state=running");
          const json list = r ? json::parse(r->body, nullptr, false) : json();
          if (list.is_object() && list.contains("jobs"))
            for (const auto& j : list["jobs"]) picked.push_back(j.value("id", ""));
        } else {
          std::lock_guard l(mu);
          if (!ids.empty()) {
            // Mostly recent jobs (queued or running), sometimes any (often finished).
            const std::size_t n = ids.size();
            picked.push_back(rng() % 3 == 0 ? ids[rng() % n] : ids[n - 1 - rng() % std::min<std::size_t>(n, 8)]);
          }
        }
        for (const auto& id : picked) cancel(*c, id);
        std::this_thread::sleep_for(std::chrono::microseconds(rng() % 3000));
      }
    });
  }
  for (auto& t : threads) t.join();
  const double storm_seconds = std::chrono::duration<double>(Clock::now() - t_start).count();

  auto c = srv.client();
  // Every job final; then cancel each once more (a finished job: 409, a cancelled one: 200 again).
  std::map<std::string, int> by_state;
  int cancelled_before_run = 0, cancelled_running = 0, with_report = 0;
  for (const auto& id : ids) {
    const json j = wait_final(*c, id, 20);
    const std::string state = j["state"];
    ++by_state[state];
    const std::string reason = j.value("reason", "");
    if (state == "cancelled") {
      if (reason == "cancelled before it ran")
        ++cancelled_before_run;
      else if (reason.rfind("cancelled by request", 0) == 0)
        ++cancelled_running;
      else
        problem("cancelled with reason '" + reason + "'");
    }
    auto rep = c->Get("/v1/jobs/" + id + "/report");
    if (rep && rep->status == 200) ++with_report;
    if (state == "done" && (!rep || rep->status != 200)) problem("done without a report: " + id);
    cancel(*c, id);
  }
  EXPECT_EQ(static_cast<int>(ids.size()), kSubmitters * kJobsPerSubmitter);
  EXPECT_EQ(submit_errors.load(), 0);
  EXPECT_EQ(delete_other.load(), 0);
  EXPECT_EQ(by_state["failed"], 0);
  EXPECT_EQ(by_state["done"] + by_state["cancelled"], static_cast<int>(ids.size()));
  EXPECT_LT(delete_max_us.load(), 2'000'000) << "a DELETE took " << delete_max_us.load() / 1000 << " ms";
  EXPECT_TRUE(problems.empty()) << ::testing::PrintToString(problems);

  // No worker stays busy and the queue is empty.
  double busy = -1, queue = -1;
  const auto deadline = Clock::now() + std::chrono::seconds(5);
  std::string metrics;
  do {
    metrics = c->Get("/metrics")->body;
    busy = metric(metrics, "moreau_workers_busy");
    queue = metric(metrics, "moreau_queue_length");
  } while ((busy != 0 || queue != 0) && Clock::now() < deadline && (std::this_thread::sleep_for(std::chrono::milliseconds(5)), true));
  EXPECT_EQ(busy, 0) << metrics;
  EXPECT_EQ(queue, 0) << metrics;
  EXPECT_EQ(metric(metrics, "moreau_jobs{state=\"queued\"}"), 0);
  EXPECT_EQ(metric(metrics, "moreau_jobs{state=\"running\"}"), 0);

  // A fresh job still runs, promptly.
  const auto t0 = Clock::now();
  auto r = post_job(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=2"}}});
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 202);
  EXPECT_EQ(wait_final(*c, json::parse(r->body)["id"], 5)["state"], "done");
  const double fresh_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  EXPECT_LT(fresh_ms, 2000);

  std::cout << "[storm] " << ids.size() << " jobs in " << storm_seconds << " s; DELETEs: " << delete_200 << " x 200, " << delete_409
            << " x 409, " << delete_other << " other; slowest DELETE " << delete_max_us.load() / 1000.0
            << " ms; final: " << by_state["done"] << " done, " << by_state["cancelled"] << " cancelled (" << cancelled_before_run
            << " before running, " << cancelled_running << " while running), " << by_state["failed"] << " failed; " << with_report
            << " with a report; workers busy " << busy << ", queue " << queue << "; a fresh job done in " << fresh_ms << " ms\n";
  c.reset();
  srv.child->signal(SIGTERM);
  const auto st = srv.child->wait_exit(10);
  ASSERT_TRUE(st.has_value());
  EXPECT_TRUE(WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << describe_exit(*st);
}

}  // namespace
