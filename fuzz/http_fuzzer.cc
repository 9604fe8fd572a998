// Fuzzes moreau-server's request handling end to end: one server runs in-process on 127.0.0.1 (an
// ephemeral port, a temporary data directory, one worker, small limits), and each input goes to it over
// a fresh TCP connection. Whatever the bytes, the server must not crash (ASan, UBSan) and must still
// answer GET /healthz with 200 afterwards; a server that stops answering is reported as a crash.
//
// The first byte picks the mode:
//   even: the rest is sent as raw bytes, a whole HTTP request (request line, headers, body) or not;
//   odd:  the rest is the JSON body of POST /v1/jobs (with a correct Content-Type and Content-Length),
//         which spends the executions on the JSON handlers and the scene validation behind them.
// With MOREAU_HTTP_FUZZ_FAIL_ON_500=1 in the environment, a first answer "500 Internal Server Error"
// (an exception no handler expected) is reported as a crash too.
// After writing, the client waits briefly for the answer, then half-closes the connection (so that a
// request missing part of its body ends) and reads what the server sends until it closes, with a short
// timeout.
//
// The HTTP parser itself (libcpp-httplib.so) is a system library and not instrumented: coverage guides
// the fuzzer through the server's handlers, the scene format and the expression compiler.
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <csignal>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

#include "loopback_socket.h"
#include "moreau/server/server.h"

namespace {

namespace fs = std::filesystem;

constexpr int kReplyTimeoutMs = 2000;                 // an answer that takes longer is abandoned (e.g. ?wait=60)
constexpr int kFirstByteWaitMs = 5;                   // how long to wait for an answer before half-closing
constexpr int kHealthTimeoutMs = 10000;               // /healthz must answer within this, else the server is stuck
constexpr std::uintmax_t kRecycleBytes = 256u << 20;  // results kept before the server is restarted afresh
constexpr int kRecycleEvery = 2000;                   // inputs between checks of the data directory

struct Instance {
  fs::path data;
  std::unique_ptr<moreau::server::Server> server;
  int port = 0;
};

Instance* g_instance = nullptr;
int g_inputs = 0;
bool g_fail_on_500 = false;

fs::path make_data_dir() {
  std::error_code ec;
  const fs::path base = fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : fs::temp_directory_path();
  std::string pattern = (base / "moreau-http-fuzz-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) {
    std::perror("mkdtemp");
    std::abort();
  }
  return pattern;
}

Instance* start_instance() {
  auto* in = new Instance;
  in->data = make_data_dir();
  moreau::server::ServerConfig cfg;
  cfg.host = "127.0.0.1";
  cfg.port = 0;
  cfg.data_dir = in->data.string();
  cfg.workers = 1;
  cfg.io_threads = 1;
  cfg.queue = 16;
  cfg.max_connections = 16;
  cfg.max_body_bytes = 256u << 10;
  cfg.max_steps = 20'000;
  cfg.max_samples = 20'000;
  cfg.keep_alive_seconds = 1;
  cfg.lcm_url = "memq://";  // streamed jobs publish in-process, never on the network
  in->server = std::make_unique<moreau::server::Server>(cfg);
  in->port = in->server->start();
  return in;
}

void stop_instance(Instance* in) {
  if (in == nullptr) return;
  in->server->stop();
  std::error_code ec;
  fs::remove_all(in->data, ec);
  delete in;
}

std::uintmax_t directory_bytes(const fs::path& dir) {
  std::uintmax_t total = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (it->is_regular_file(ec)) total += it->file_size(ec);
  }
  return total;
}

// Reads until the server closes the connection or the receive timeout passes.
std::string read_until_close(int fd) {
  std::string out;
  char buf[16384];
  for (;;) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    if (out.size() < (1u << 20)) out.append(buf, static_cast<std::size_t>(n));
  }
  return out;
}

// One exchange: the bytes out, a short wait for the answer, a half-close, and whatever comes back.
std::string exchange(int port, const std::string& request) {
  const int fd = moreau::server::testing::connect_loopback(port, kReplyTimeoutMs);
  if (fd < 0) return "";
  moreau::server::testing::send_all(fd, request);
  pollfd p{fd, POLLIN, 0};
  ::poll(&p, 1, kFirstByteWaitMs);
  ::shutdown(fd, SHUT_WR);
  std::string reply = read_until_close(fd);
  ::close(fd);
  return reply;
}

bool healthy(int port) {
  const int fd = moreau::server::testing::connect_loopback(port, kHealthTimeoutMs);
  if (fd < 0) return false;
  static const std::string kRequest = "GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  moreau::server::testing::send_all(fd, kRequest);
  const std::string reply = read_until_close(fd);
  ::close(fd);
  return reply.rfind("HTTP/1.1 200 ", 0) == 0 && reply.find("{\"status\":\"ok\"}") != std::string::npos;
}

void at_exit() {
  if (g_instance == nullptr) return;  // stopped by MoreauFuzzerTeardown
  stop_instance(g_instance);
  g_instance = nullptr;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  std::signal(SIGPIPE, SIG_IGN);
  const char* strict = std::getenv("MOREAU_HTTP_FUZZ_FAIL_ON_500");
  g_fail_on_500 = strict != nullptr && std::string(strict) == "1";
  g_instance = start_instance();
  std::atexit(at_exit);
  return 0;
}

// The corpus replay (replay_main.cc) stops the server before main returns; under libFuzzer, which has
// no such hook, the atexit handler does.
extern "C" void MoreauFuzzerTeardown() { at_exit(); }

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  // Finished jobs accumulate (records, trajectories): start afresh now and then.
  if (++g_inputs % kRecycleEvery == 0 && directory_bytes(g_instance->data) > kRecycleBytes) {
    stop_instance(g_instance);
    g_instance = start_instance();
  }
  const int port = g_instance->port;
  const std::string rest(reinterpret_cast<const char*>(data) + 1, size - 1);
  const std::string reply =
      (data[0] & 1) == 0
          ? exchange(port, rest)
          : exchange(port, "POST /v1/jobs HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: " +
                               std::to_string(rest.size()) + "\r\n\r\n" + rest);
  // The first answer's status line only: bodies echo input, which may hold any text.
  if (g_fail_on_500 && reply.rfind("HTTP/1.1 500 ", 0) == 0) {
    std::fprintf(stderr, "http_fuzzer: 500 Internal Server Error:\n%s\n", reply.substr(0, 2000).c_str());
    __builtin_trap();
  }
  // The server must still answer. One retry: an exchange may briefly hold every connection thread.
  if (!healthy(port) && !healthy(port)) {
    std::fprintf(stderr, "http_fuzzer: the server no longer answers GET /healthz\n");
    __builtin_trap();
  }
  return 0;
}
