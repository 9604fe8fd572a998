// Hostile clients against a real in-process server on 127.0.0.x: every way a body can arrive (length,
// chunked, compressed, announced with Expect), strict framing, slow and waiting clients, connection
// limits, the SSE resume id, result and figure bounds, the request log, and pruning while reading.
// Each test states the limit it holds the server to; the raw requests are written byte for byte.
#include <poll.h>
#include <zlib.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "loopback_socket.h"
#include "server_fixture.h"
#include "storage.h"
#include "support/xml_chars.h"

namespace {

using moreau::server::ServerConfig;
using moreau::server::testing::manipulator;
using moreau::server::testing::submit;
using moreau::server::testing::TestServer;
using moreau::server::testing::wait_final;
using moreau::server::testing::wait_running;
using moreau::test_support::TempDir;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// A connection to 127.0.0.1:port from 127.0.0.`host`: a test acts as several clients.
int connect_from(int host, int port, int timeout_ms = 10'000) { return moreau::server::testing::connect_loopback(port, timeout_ms, host); }

struct RawResponse {
  int status = 0;
  std::string head, body;
  bool closed = false;  // the server closed the connection after it
};

// Reads one response (headers, then Content-Length bytes or up to the close); status 0 if none came
// within the socket's receive timeout.
RawResponse read_response(int fd) {
  RawResponse r;
  std::string buf;
  char chunk[16384];
  std::size_t header_end = std::string::npos;
  std::size_t need = std::string::npos;
  while (true) {
    if (header_end == std::string::npos) {
      header_end = buf.find("\r\n\r\n");
      if (header_end != std::string::npos) {
        r.head = buf.substr(0, header_end);
        std::sscanf(r.head.c_str(), "HTTP/1.1 %d", &r.status);
        const auto cl = r.head.find("Content-Length: ");
        if (cl != std::string::npos) need = header_end + 4 + std::stoul(r.head.substr(cl + 16));
      }
    }
    if (need != std::string::npos && buf.size() >= need) break;
    const ssize_t n = ::recv(fd, chunk, sizeof chunk, 0);
    if (n == 0) {
      r.closed = true;
      break;
    }
    if (n < 0) break;
    buf.append(chunk, static_cast<std::size_t>(n));
  }
  if (header_end != std::string::npos)
    r.body = buf.substr(header_end + 4, need == std::string::npos ? std::string::npos : need - header_end - 4);
  if (!r.closed) {
    // Whether the server closes right after: a read that returns 0 soon.
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 200) > 0) r.closed = ::recv(fd, chunk, sizeof chunk, MSG_PEEK) == 0;
  }
  return r;
}

RawResponse round_trip(int port, const std::string& request, int host = 1) {
  const int fd = connect_from(host, port);
  if (fd < 0) return {};
  moreau::server::testing::send_all(fd, request);
  RawResponse r = read_response(fd);
  ::close(fd);
  return r;
}

std::string post_head(const std::string& path, const std::string& framing, const std::string& extra = "") {
  return "POST " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n" + framing + extra + "\r\n";
}

std::string chunked(const std::string& body, std::size_t piece = 4096) {
  std::string out;
  char size[32];
  for (std::size_t at = 0; at < body.size(); at += piece) {
    const std::size_t n = std::min(piece, body.size() - at);
    std::snprintf(size, sizeof size, "%zx\r\n", n);
    out += size;
    out.append(body, at, n);
    out += "\r\n";
  }
  return out + "0\r\n\r\n";
}

// gzip of `zeros` zero bytes followed by `text` (a decompression bomb when zeros is large).
std::string gzip(std::size_t zeros, const std::string& text = "") {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 9, Z_DEFLATED, 15 + 16, 9, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out;
  std::vector<unsigned char> in(1 << 20, 0), buf(1 << 16);
  auto pump = [&](const unsigned char* data, std::size_t n, int flush) {
    z.next_in = const_cast<unsigned char*>(data);
    z.avail_in = static_cast<uInt>(n);
    do {
      z.next_out = buf.data();
      z.avail_out = static_cast<uInt>(buf.size());
      deflate(&z, flush);
      out.append(reinterpret_cast<char*>(buf.data()), buf.size() - z.avail_out);
    } while (z.avail_out == 0);
  };
  for (std::size_t left = zeros; left > 0;) {
    const std::size_t n = std::min(left, in.size());
    pump(in.data(), n, Z_NO_FLUSH);
    left -= n;
  }
  pump(reinterpret_cast<const unsigned char*>(text.data()), text.size(), Z_FINISH);
  deflateEnd(&z);
  return out;
}

std::int64_t peak_rss_kib() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stoll(line.substr(6));
  return -1;
}

json small_job() { return {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.01"}}}; }

// --max-body holds for the bytes after decoding, whatever the framing, and memory stays bounded.
TEST(Hostile, BodyLimitHoldsForEveryFraming) {
  ServerConfig cfg;
  cfg.max_body_bytes = 64 << 10;
  TestServer ts(cfg);
  const int port = ts.port();
  const std::string big(100 << 10, ' ');

  // Announced over the limit: refused before any of it is read, and the connection closed.
  RawResponse r = round_trip(port, post_head("/v1/jobs", "Content-Length: " + std::to_string(big.size()) + "\r\n") + big);
  EXPECT_EQ(r.status, 413) << r.head;
  EXPECT_TRUE(r.closed);
  // Chunked, no length announced: counted while read.
  r = round_trip(port, post_head("/v1/jobs", "Transfer-Encoding: chunked\r\n") + chunked(big));
  EXPECT_EQ(r.status, 413) << r.head << r.body;
  EXPECT_THAT(r.body, ::testing::HasSubstr("after Content-Encoding is decoded"));
  // No framing at all: a POST must say how long its body is.
  r = round_trip(port, post_head("/v1/jobs", "") + big);
  EXPECT_EQ(r.status, 411) << r.head;

  // A gzip bomb: 256 MiB of zeros in about 256 KiB, under the limit as sent, far over it decoded.
  const std::int64_t before = peak_rss_kib();
  const std::string bomb = gzip(256u << 20);
  ASSERT_LT(bomb.size(), cfg.max_body_bytes * 8);
  r = round_trip(port,
                 post_head("/v1/jobs", "Content-Length: " + std::to_string(bomb.size()) + "\r\n", "Content-Encoding: gzip\r\n") + bomb);
  EXPECT_EQ(r.status, 413) << r.head << r.body;
  // ... and chunked.
  r = round_trip(port, post_head("/v1/jobs", "Transfer-Encoding: chunked\r\n", "Content-Encoding: gzip\r\n") + chunked(bomb, 60000));
  EXPECT_EQ(r.status, 413) << r.head << r.body;
  const std::int64_t growth_kib = peak_rss_kib() - before;
  // The bound: the body limit and one decoding buffer per request, far from the 256 MiB decoded.
  EXPECT_LT(growth_kib, 32 << 10) << "peak RSS grew by " << growth_kib << " KiB";
  std::printf("[ measure  ] peak RSS growth over two gzip bombs of 256 MiB: %lld KiB\n", static_cast<long long>(growth_kib));

  // Expect: 100-continue with a length over the limit: 413 instead of 100, and the body never sent.
  {
    const int fd = connect_from(1, port);
    moreau::server::testing::send_all(
        fd, post_head("/v1/jobs", "Content-Length: " + std::to_string(big.size()) + "\r\n", "Expect: 100-continue\r\n"));
    r = read_response(fd);
    ::close(fd);
    EXPECT_EQ(r.status, 413) << r.head;
    EXPECT_TRUE(r.closed);
  }
  // An honest compressed job under the limit is accepted.
  const std::string job = gzip(0, small_job().dump());
  r = round_trip(port, post_head("/v1/jobs", "Content-Length: " + std::to_string(job.size()) + "\r\n", "Content-Encoding: gzip\r\n") + job);
  EXPECT_EQ(r.status, 202) << r.head << r.body;
  // The server still answers.
  EXPECT_EQ(ts.client()->Get("/healthz")->status, 200);
}

// Framing that two servers could read two ways is refused, not interpreted.
TEST(Hostile, FramingIsStrict) {
  TestServer ts;
  const int port = ts.port();
  const std::string body = small_job().dump();
  const std::string len = "Content-Length: " + std::to_string(body.size()) + "\r\n";
  struct Case {
    const char* name;
    std::string request;
    int status;
    const char* phrase;
  };
  const std::vector<Case> cases = {
      {"both lengths", post_head("/v1/jobs", len + "Transfer-Encoding: chunked\r\n") + chunked(body), 400, "both Transfer-Encoding"},
      {"two lengths", post_head("/v1/jobs", len + len) + body, 400, "more than once"},
      {"other coding", post_head("/v1/jobs", "Transfer-Encoding: gzip, chunked\r\n") + chunked(body), 400, "only Transfer-Encoding"},
      {"length not a number", post_head("/v1/jobs", "Content-Length: 12abc\r\n") + body, 400, "not a decimal"},
      {"NUL in JSON", post_head("/v1/jobs", "Content-Length: " + std::to_string(body.size() + 1) + "\r\n") + body + std::string(1, '\0'),
       400, "NUL byte at offset"},
      {"GET with a body", "GET /healthz HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello", 400, "take no body"},
      {"unknown encoding", post_head("/v1/jobs", len, "Content-Encoding: zstd\r\n") + body, 415, "Content-Encoding"},
      {"wrong type", "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: text/plain\r\n" + len + "\r\n" + body, 415, "application/json"},
      {"unknown POST path", post_head("/v1/nothing", len) + body, 404, "not found"},
      {"headers without end", "GET /healthz HTTP/1.1\r\nX-Endless: " + std::string(100 << 10, 'a'), 431, "at most 65536 bytes"},
  };
  for (const auto& c : cases) {
    const RawResponse r = round_trip(port, c.request);
    EXPECT_EQ(r.status, c.status) << c.name << "\n" << r.head << "\n" << r.body;
    EXPECT_THAT(r.body, ::testing::HasSubstr(c.phrase)) << c.name;
  }
  EXPECT_EQ(ts.client()->Get("/healthz")->status, 200);
}

// 64 slow or waiting connections from other addresses do not keep /healthz or a submission waiting.
TEST(Hostile, SlowClientsAndLongPollsDoNotLockOthersOut) {
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  // The data directory on tmpfs where there is one: the bound below is on waiting behind other clients,
  // and a submission's own fsyncs, on a disk the rest of a parallel test run is also writing, took 2.8
  // and 5.4 s by themselves in one CI run (with /healthz answered in 5 ms).
  std::error_code ec;
  const TempDir data("hostile-slow", std::filesystem::is_directory("/dev/shm", ec) ? std::filesystem::path("/dev/shm")
                                                                                   : std::filesystem::temp_directory_path());
  TestServer ts(cfg, data.path());
  const int port = ts.port();
  auto c = ts.client();
  // A job that runs for minutes, for the long polls to wait on.
  json scene = manipulator();
  scene["integrator"]["t_end"] = 1e6;
  scene["output"]["every"] = 100000;
  auto r = submit(*c, {{"scene", scene}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string long_id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, long_id), "running");

  // From 127.0.0.2 to .5, 16 connections each: 16 send headers a byte at a time, 16 send a body a byte
  // at a time, 32 long-poll the running job (?wait=30).
  std::vector<int> held;
  for (int i = 0; i < 64; ++i) {
    const int fd = connect_from(2 + i % 4, port);
    ASSERT_GE(fd, 0);
    if (i < 16) {
      moreau::server::testing::send_all(fd, "GET /heal");
    } else if (i < 32) {
      moreau::server::testing::send_all(fd, post_head("/v1/jobs", "Content-Length: 1000\r\n") + "{");
    } else {
      moreau::server::testing::send_all(fd, "GET /v1/jobs/" + long_id + "?wait=30 HTTP/1.1\r\nHost: x\r\n\r\n");
    }
    held.push_back(fd);
  }
  std::atomic<bool> trickling{true};
  std::thread trickle([&] {
    while (trickling) {
      for (int i = 0; i < 32; ++i) ::send(held[i], i < 16 ? "t" : " ", 1, MSG_NOSIGNAL);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });

  // While they are held: /healthz and a submission from 127.0.0.1, each answered within 1 s.
  for (int round = 0; round < 3; ++round) {
    auto fresh = ts.client();
    auto t0 = Clock::now();
    auto h = fresh->Get("/healthz");
    const double healthz_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ASSERT_TRUE(h) << "no answer to /healthz";
    EXPECT_EQ(h->status, 200);
    EXPECT_LT(healthz_ms, 1000.0);
    t0 = Clock::now();
    auto s = submit(*fresh, small_job());
    const double submit_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    ASSERT_TRUE(s) << "no answer to the submission";
    EXPECT_EQ(s->status, 202) << s->body;
    EXPECT_LT(submit_ms, 1000.0);
    std::printf("[ measure  ] with 64 connections held: /healthz %.2f ms, submission %.2f ms\n", healthz_ms, submit_ms);
  }
  trickling = false;
  trickle.join();
  for (int fd : held) ::close(fd);
  c->Delete("/v1/jobs/" + long_id);
  wait_final(*c, long_id);
}

// One address holds at most --max-connections-per-client; the next is answered 503 at once, and other
// addresses are served.
TEST(Hostile, ConnectionsPerClientAreCapped) {
  ServerConfig cfg;
  cfg.max_connections_per_client = 4;
  TestServer ts(cfg);
  std::vector<int> held;
  for (int i = 0; i < 4; ++i) {
    held.push_back(connect_from(7, ts.port()));
    moreau::server::testing::send_all(held.back(), "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n");
    EXPECT_EQ(read_response(held.back()).status, 200);  // each is open and served (keep-alive)
  }
  const RawResponse over = round_trip(ts.port(), "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n", 7);
  EXPECT_EQ(over.status, 503) << over.head;
  EXPECT_THAT(over.body, ::testing::HasSubstr("from one client address"));
  EXPECT_EQ(round_trip(ts.port(), "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n", 8).status, 200);
  EXPECT_THAT(ts.client()->Get("/metrics")->body, ::testing::HasSubstr("moreau_http_connections_refused_total 1\n"));
  ::close(held[0]);
  held.erase(held.begin());
  // The slot is given back when the connection ends (the server notices the close on its next read).
  const auto deadline = Clock::now() + std::chrono::seconds(10);
  int status = 0;
  while (Clock::now() < deadline && (status = round_trip(ts.port(), "GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n", 7).status) != 200) {
  }
  EXPECT_EQ(status, 200);
  for (int fd : held) ::close(fd);
}

// Headers and bodies that do not arrive in time: the connection is cut at the deadline, not held.
TEST(Hostile, SlowHeadersAndBodiesAreCutAtTheirDeadlines) {
  ServerConfig cfg;
  cfg.header_timeout_ms = 300;
  cfg.body_timeout_ms = 300;
  TestServer ts(cfg);
  for (const std::string& start : {std::string("GET /heal"), post_head("/v1/jobs", "Content-Length: 100\r\n") + "{"}) {
    const int fd = connect_from(1, ts.port());
    const auto t0 = Clock::now();
    moreau::server::testing::send_all(fd, start);
    // A byte every 50 ms: each read is quick, the whole is not.
    bool cut = false;
    while (!cut && Clock::now() - t0 < std::chrono::seconds(10)) {
      if (::send(fd, "x", 1, MSG_NOSIGNAL) < 0) cut = true;
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 50) > 0) {
        char b[4096];
        const ssize_t n = ::recv(fd, b, sizeof b, 0);
        if (n <= 0 || std::string(b, static_cast<std::size_t>(n)).find("408") != std::string::npos) cut = true;
      }
    }
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    EXPECT_TRUE(cut) << start;
    EXPECT_LT(ms, 5000.0) << start;
    ::close(fd);
  }
  EXPECT_EQ(ts.client()->Get("/healthz")->status, 200);
}

// Last-Event-ID is an id the job has sent, or a 400: never wrapped around to some other position.
TEST(Hostile, LastEventIdMustBeOneTheJobSent) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, small_job());
  const std::string id = json::parse(r->body)["id"];
  wait_final(*c, id);
  for (const char* bad : {"-1", "18446744073709551615", "99999", "1e3", "abc", "3x"}) {
    auto e = c->Get("/v1/jobs/" + id + "/events", {{"Last-Event-ID", bad}});
    ASSERT_TRUE(e);
    EXPECT_EQ(e->status, 400) << bad;
    EXPECT_THAT(e->body, ::testing::HasSubstr("Last-Event-ID")) << bad;
  }
  auto all = c->Get("/v1/jobs/" + id + "/events");
  ASSERT_EQ(all->status, 200);
  auto after1 = c->Get("/v1/jobs/" + id + "/events", {{"Last-Event-ID", "1"}});
  ASSERT_EQ(after1->status, 200);
  EXPECT_EQ(after1->body.find("id: 1\n"), std::string::npos);
  EXPECT_NE(after1->body.find("id: 2\n"), std::string::npos);
}

// The trajectory is served piece by piece, and a window (from, to, every) gives exactly the stored
// rows it names: the reference is the whole CSV filtered here.
TEST(Hostile, TrajectoryWindowsServeTheStoredRows) {
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=1", "output.every=10"}}});
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const std::string full = c->Get("/v1/jobs/" + id + "/trajectory?format=csv")->body;
  std::istringstream in(full);
  std::string header, line;
  std::getline(in, header);
  std::vector<std::string> rows;
  while (std::getline(in, line))
    if (!line.empty()) rows.push_back(line);
  ASSERT_GT(rows.size(), 50u);
  std::string expected = header + "\n";
  std::vector<std::string> kept;
  std::int64_t seen = 0;
  for (const auto& row : rows) {
    const double t = std::stod(row.substr(0, row.find(',')));
    if (t < 0.25 || t > 0.75) continue;
    if (seen++ % 3 == 0) {
      expected += row + "\n";
      kept.push_back(row);
    }
  }
  auto w = c->Get("/v1/jobs/" + id + "/trajectory?format=csv&from=0.25&to=0.75&every=3");
  ASSERT_EQ(w->status, 200) << w->body;
  EXPECT_EQ(w->body, expected);
  // JSON of the same window: the same numbers, column by column.
  auto j = c->Get("/v1/jobs/" + id + "/trajectory?from=0.25&to=0.75&every=3");
  ASSERT_EQ(j->status, 200) << j->body;
  const json doc = json::parse(j->body);
  ASSERT_EQ(doc["rows"], kept.size());
  const auto names = doc["columns"].get<std::vector<std::string>>();
  for (std::size_t k = 0; k < kept.size(); ++k) {
    std::istringstream cells(kept[k]);
    std::string cell;
    for (std::size_t col = 0; std::getline(cells, cell, ','); ++col)
      EXPECT_EQ(doc["data"][names[col]][k].get<double>(), std::stod(cell)) << names[col] << " row " << k;
  }
  // The whole JSON has every row.
  EXPECT_EQ(json::parse(c->Get("/v1/jobs/" + id + "/trajectory")->body)["rows"], rows.size());
  for (const char* bad : {"from=x", "every=0", "every=1.5", "from=2&to=1"})
    EXPECT_EQ(c->Get("/v1/jobs/" + id + "/trajectory?" + std::string(bad))->status, 400) << bad;
}

// A result that could exceed --max-result-bytes is refused at submission (422), with the decimation
// that would fit; figures are bounded in pixels.
TEST(Hostile, ResultsAndFiguresAreBounded) {
  ServerConfig cfg;
  cfg.max_result_bytes = 1 << 20;
  TestServer ts(cfg);
  auto c = ts.client();
  // 10001 rows of 7 columns at most 25 bytes: 1.75 MB > 1 MiB.
  auto r = submit(*c, {{"scene", "manipulator"}});
  ASSERT_EQ(r->status, 422) << r->body;
  const json e = json::parse(r->body);
  EXPECT_EQ(e["pointer"], "/output/every");
  EXPECT_THAT(e["reason"].get<std::string>(), ::testing::HasSubstr("1048576 bytes"));
  r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"output.every=4"}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  auto f = c->Get("/v1/jobs/" + id + "/figure?width=4096&height=4096");
  EXPECT_EQ(f->status, 400);
  EXPECT_THAT(f->body, ::testing::HasSubstr("pixels"));
}

// A figure is drawn from a stored trajectory of at most --max-figure-source-bytes (it is read whole).
TEST(Hostile, FiguresOfHugeTrajectoriesAreRefused) {
  ServerConfig cfg;
  cfg.max_figure_source_bytes = 64 << 10;
  TestServer ts(cfg);
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=2"}}});  // 2001 rows, about 200 KB
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  auto f = c->Get("/v1/jobs/" + id + "/figure?kind=state");
  EXPECT_EQ(f->status, 422) << f->body;
  EXPECT_THAT(f->body, ::testing::HasSubstr("draws figures from at most 65536"));
  r = submit(*c, {{"scene", "manipulator"}, {"overrides", {"integrator.t_end=0.1"}}});
  const std::string small = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, small)["state"], "done");
  EXPECT_EQ(c->Get("/v1/jobs/" + small + "/figure?kind=state")->status, 200);
}

// The request log writes control bytes escaped: a request cannot add lines of its own.
TEST(Hostile, RequestLogEscapesControlBytes) {
  ServerConfig cfg;
  cfg.log_requests = true;
  TestServer ts(cfg);
  ::testing::internal::CaptureStderr();
  round_trip(ts.port(), "GET /a%0d%0amoreau-server:%20FORGED%1b[31m HTTP/1.1\r\nHost: x\r\n\r\n");
  ts.client()->Get("/healthz");
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_THAT(log, ::testing::HasSubstr("\\x0d\\x0amoreau-server: FORGED\\x1b[31m"));
  EXPECT_EQ(log.find("\nmoreau-server: FORGED"), std::string::npos) << log;
  EXPECT_EQ(log.find('\x1b'), std::string::npos);
}

// Every answer carries "X-Content-Type-Options: nosniff", and every answer but the web page's files a
// Content-Security-Policy under which nothing it holds runs, loads or is framed if a browser opens it
// (a figure, a CSV, a report, an error quoting a client's text): results, errors, conditional answers
// and streams alike. The page keeps its own policy, on its 304 too.
TEST(Hostile, EveryAnswerSaysNosniffAndCarriesARestrictivePolicy) {
  const std::string api_policy = "default-src 'none'; frame-ancestors 'none'; sandbox";
  TestServer ts;
  auto c = ts.client();
  auto r = submit(*c, {{"scene", "damped-relay"}});
  ASSERT_EQ(r->status, 202) << r->body;
  EXPECT_EQ(r->get_header_value("X-Content-Type-Options"), "nosniff");
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const std::string job = "/v1/jobs/" + id;
  const auto report = c->Get(job + "/report");
  ASSERT_EQ(report->status, 200);
  struct Case {
    std::string path;
    int status;
    httplib::Headers headers;
  };
  const std::vector<Case> cases = {
      {job + "/figure?kind=state", 200, {}},             // PNG
      {job + "/figure?kind=phase&format=svg", 200, {}},  // SVG
      {job + "/trajectory?format=csv", 200, {}},         // CSV, streamed
      {job + "/trajectory", 200, {}},                    // JSON, streamed
      {job + "/report", 200, {}},                        // the report
      {job + "/report", 304, {{"If-None-Match", report->get_header_value("ETag")}}},
      {job, 200, {}},
      {job + "/events", 200, {}},  // server-sent events (a final job: replayed, then the end)
      {"/v1/jobs", 200, {}},
      {"/metrics", 200, {}},
      {"/healthz", 200, {}},
      {"/v1/openapi.json", 200, {}},
      {"/v1/nothing", 404, {}},  // an error
      {job + "/figure?kind=<svg>", 400, {}},
  };
  for (const Case& k : cases) {
    const auto a = c->Get(k.path, k.headers);
    ASSERT_TRUE(a) << k.path;
    EXPECT_EQ(a->status, k.status) << k.path << "\n" << a->body.substr(0, 300);
    EXPECT_EQ(a->get_header_value_count("X-Content-Type-Options"), 1u) << k.path;
    EXPECT_EQ(a->get_header_value("X-Content-Type-Options"), "nosniff") << k.path;
    EXPECT_EQ(a->get_header_value_count("Content-Security-Policy"), 1u) << k.path;
    EXPECT_EQ(a->get_header_value("Content-Security-Policy"), api_policy) << k.path;
  }
  // Refused while screening (a body on a GET), and answered by the transport itself (a request line
  // too long to read): the same headers.
  for (const std::string& raw : {std::string("GET /healthz HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello"),
                                 "GET /" + std::string(100000, 'a') + " HTTP/1.1\r\nHost: x\r\n\r\n"}) {
    const RawResponse a = round_trip(ts.port(), raw);
    EXPECT_NE(a.status, 0) << raw.substr(0, 40);
    EXPECT_THAT(a.head, ::testing::HasSubstr("\r\nX-Content-Type-Options: nosniff")) << a.head;
    EXPECT_THAT(a.head, ::testing::HasSubstr("\r\nContent-Security-Policy: " + api_policy)) << a.head;
  }
  // The page: its own policy (its script and style), once, on 200 and 304.
  const auto page = c->Get("/");
  ASSERT_EQ(page->status, 200);
  const auto page_304 = c->Get("/", {{"If-None-Match", page->get_header_value("ETag")}});
  ASSERT_EQ(page_304->status, 304);
  for (const auto* a : {&page, &page_304}) {
    EXPECT_EQ((*a)->get_header_value_count("Content-Security-Policy"), 1u);
    EXPECT_THAT((*a)->get_header_value("Content-Security-Policy"), ::testing::HasSubstr("script-src 'self'"));
    EXPECT_EQ((*a)->get_header_value("X-Content-Type-Options"), "nosniff");
  }
}

// A request line longer than httplib reads (8192 bytes, fixed when the library was built) is answered
// 414 with the error as JSON and the connection closed, also when it is too long to reach its end within
// the 64 KiB the request line and headers may take (a 100,000-character path was answered by a closed
// connection, nothing said). Shorter ones are routed as usual; the server stays healthy.
TEST(Hostile, LongRequestLinesAreAnswered414) {
  TestServer ts;
  const int port = ts.port();
  for (const std::size_t n : {std::size_t{9000}, std::size_t{60000}, std::size_t{100000}}) {
    const RawResponse r = round_trip(port, "GET /v1/jobs/" + std::string(n, 'a') + " HTTP/1.1\r\nHost: x\r\n\r\n");
    EXPECT_EQ(r.status, 414) << n << "\n" << r.head;
    EXPECT_TRUE(r.closed) << n;
    const json body = json::parse(r.body, nullptr, false);
    ASSERT_TRUE(body.is_object()) << n << ": " << r.body;
    EXPECT_EQ(body.value("error", ""), "URI too long") << n;
    EXPECT_EQ(body.value("reason", ""), "the request line may take at most 8192 bytes") << n;
  }
  // A long query is the same request line.
  EXPECT_EQ(round_trip(port, "GET /v1/jobs?state=" + std::string(100000, 'x') + " HTTP/1.1\r\nHost: x\r\n\r\n").status, 414);
  // Under the limit: routed (no such job; the id is not one).
  EXPECT_EQ(round_trip(port, "GET /v1/jobs/" + std::string(8000, 'a') + " HTTP/1.1\r\nHost: x\r\n\r\n").status, 404);
  EXPECT_EQ(ts.client()->Get("/healthz")->status, 200);
  const std::string metrics = ts.client()->Get("/metrics")->body;
  EXPECT_THAT(metrics, ::testing::HasSubstr("moreau_http_responses_total{code=\"414\"} 4")) << metrics;
}

// A control byte in a scene name (the figure's title) made the job's SVG figures invalid XML. Each
// character XML 1.0 forbids or discourages is drawn as U+FFFD, and the figure is XML 1.0 text.
TEST(Hostile, FiguresOfScenesNamedWithControlBytesAreXml) {
  TestServer ts;
  auto c = ts.client();
  const std::string name = "ctl\x01\x1b[2J\x7f\xc2\x9b evil\xef\xbf\xbe";
  auto r = submit(*c, {{"scene", "damped-relay"}, {"overrides", {{"name", name}}}});
  ASSERT_EQ(r->status, 202) << r->body;
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_final(*c, id)["state"], "done");
  const std::string fffd = "\xef\xbf\xbd";
  for (const char* kind : {"state", "energy", "step", "phase"}) {
    const auto f = c->Get("/v1/jobs/" + id + "/figure?kind=" + kind + "&format=svg");
    ASSERT_EQ(f->status, 200) << kind << ": " << f->body;
    EXPECT_EQ(f->get_header_value("Content-Type"), "image/svg+xml");
    EXPECT_EQ(moreau::test_support::xml_1_0_problem(f->body), "") << kind;
    EXPECT_THAT(f->body, ::testing::HasSubstr("ctl" + fffd + fffd + "[2J" + fffd + fffd + " evil" + fffd)) << kind;
  }
}

// Pruning (--keep-jobs) while clients read and delete: every answer is the job's (200) or its absence
// (404), never a 409 or 500 from a job seen half deleted.
TEST(Hostile, PruningNeverRacesReaders) {
  ServerConfig cfg;
  cfg.keep_jobs = 2;
  TestServer ts(cfg);
  auto c = ts.client();
  std::mutex mu;
  std::vector<std::string> ids;
  std::atomic<bool> running{true};
  std::atomic<int> bad{0}, reads{0};
  std::string first_bad;
  std::vector<std::thread> readers;
  for (int t = 0; t < 2; ++t) {
    readers.emplace_back([&] {
      auto rc = ts.client();
      while (running) {
        std::vector<std::string> snapshot;
        {
          std::lock_guard l(mu);
          snapshot = ids;
        }
        for (const auto& id : snapshot) {
          for (const std::string path : {"/report", "/trajectory?format=csv", ""}) {
            auto r = rc->Get("/v1/jobs/" + id + path);
            ++reads;
            if (!r || (r->status != 200 && r->status != 404)) {
              std::lock_guard l(mu);
              if (bad++ == 0) first_bad = path + ": " + (r ? std::to_string(r->status) + " " + r->body : "no answer");
            }
          }
        }
      }
    });
  }
  // Readers take only jobs seen done: for them, 409 ("no report yet") would be a job seen half deleted.
  for (int i = 0; i < 20; ++i) {
    auto r = submit(*c, small_job());
    ASSERT_EQ(r->status, 202);
    const std::string id = json::parse(r->body)["id"];
    ASSERT_EQ(wait_final(*c, id)["state"], "done");
    std::lock_guard l(mu);
    ids.push_back(id);
  }
  running = false;
  for (auto& t : readers) t.join();
  EXPECT_EQ(bad.load(), 0) << first_bad;
  EXPECT_GT(reads.load(), 20);
  EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["total"], 2);
}

}  // namespace

namespace {

// Accepted means stored: a submission whose record cannot be written (the disk full just then) is
// answered 507 and leaves nothing; a run whose results cannot be written ends failed, saying why,
// never done with a missing file. The disk is made full by the storage layer's test seam.
TEST(Hostile, NothingAcceptedIsLostWhenTheDiskFills) {
  auto& fault = moreau::server::write_fault_for_testing();
  std::atomic<bool> records_fail{false}, results_fail{false};
  fault = [&](const std::filesystem::path& p) {
    const std::string name = p.filename().string();
    if (records_fail && (name == "job.json.tmp" || name == "scene.json.tmp")) return ENOSPC;
    if (results_fail && (name == "trajectory.csv.tmp" || name == "report.json.tmp")) return ENOSPC;
    return 0;
  };
  {
    TestServer ts;
    auto c = ts.client();
    records_fail = true;
    auto r = submit(*c, small_job());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 507) << r->body;
    EXPECT_THAT(r->body, ::testing::HasSubstr("No space left on device"));
    EXPECT_EQ(json::parse(c->Get("/v1/jobs")->body)["total"], 0);
    std::size_t dirs = 0;
    for (const auto& e : std::filesystem::directory_iterator(ts.data() / "jobs")) dirs += e.is_directory() ? 1 : 0;
    EXPECT_EQ(dirs, 0u);
    records_fail = false;

    results_fail = true;
    r = submit(*c, small_job());
    ASSERT_EQ(r->status, 202) << r->body;
    const std::string id = json::parse(r->body)["id"];
    const json j = wait_final(*c, id);
    EXPECT_EQ(j["state"], "failed");
    EXPECT_THAT(j.value("reason", ""), ::testing::HasSubstr("cannot store the results"));
    EXPECT_EQ(c->Get("/v1/jobs/" + id + "/report")->status, 409);
    results_fail = false;

    // Every 202 survives a restart.
    r = submit(*c, small_job());
    ASSERT_EQ(r->status, 202);
    const std::string kept = json::parse(r->body)["id"];
    EXPECT_EQ(wait_final(*c, kept)["state"], "done");
    c.reset();
    ts.stop();
    const TempDir data = ts.release_data();
    TestServer again({}, data.path());
    auto c2 = again.client();
    EXPECT_EQ(json::parse(c2->Get("/v1/jobs/" + kept)->body)["state"], "done");
    EXPECT_EQ(json::parse(c2->Get("/v1/jobs/" + id)->body)["state"], "failed");
  }
  fault = nullptr;
}

// DELETE of a running job: 202 cancelling, then cancelled; after a restart the list and the report
// both say cancelled, and the progress is where the run stopped.
TEST(Hostile, CancelledStaysCancelledAcrossARestart) {
  ServerConfig cfg;
  cfg.max_steps = 2'000'000'000;
  TestServer ts(cfg);
  auto c = ts.client();
  json scene = manipulator();
  scene["integrator"]["t_end"] = 1e6;
  scene["output"]["every"] = 100000;
  auto r = submit(*c, {{"scene", scene}});
  const std::string id = json::parse(r->body)["id"];
  ASSERT_EQ(wait_running(*c, id), "running");
  // Wait until it has made progress.
  for (auto deadline = Clock::now() + std::chrono::seconds(10);
       json::parse(c->Get("/v1/jobs/" + id)->body)["progress"]["step"].get<std::int64_t>() == 0 && Clock::now() < deadline;) {
  }
  auto d = c->Delete("/v1/jobs/" + id);
  ASSERT_EQ(d->status, 202) << d->body;
  EXPECT_EQ(json::parse(d->body)["state"], "cancelling");
  const json final = wait_final(*c, id);
  ASSERT_EQ(final["state"], "cancelled");
  const double t_stop = final["report"]["t_final"];
  EXPECT_GT(t_stop, 0.0);
  EXPECT_EQ(c->Delete("/v1/jobs/" + id)->status, 200);  // already cancelled: harmless
  c.reset();
  ts.stop();
  const TempDir data = ts.release_data();
  TestServer again({}, data.path());
  auto c2 = again.client();
  const json listed = json::parse(c2->Get("/v1/jobs")->body)["jobs"][0];
  EXPECT_EQ(listed["state"], "cancelled");
  EXPECT_EQ(listed["progress"]["t"].get<double>(), t_stop);
  EXPECT_EQ(json::parse(c2->Get("/v1/jobs/" + id + "/report")->body)["status"], "cancelled");
}

}  // namespace
