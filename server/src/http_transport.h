// The HTTP transport: connections, their limits and their deadlines, under cpp-httplib's request parsing
// and routing.
//
// cpp-httplib serves each connection on a thread of a fixed pool and reads it with a per-read timeout.
// That lets a few dozen slow clients (headers or a body sent a byte at a time, or long polls) hold every
// thread, and lets a header line grow without bound. GuardedHttpServer keeps httplib's parser and
// router and replaces what surrounds them:
//   - one thread per connection, at most `max_connections` in all and `max_connections_per_client` per
//     client address; a connection over either limit is answered 503 at once and closed, so a held
//     connection never keeps an ordinary request waiting for a thread;
//   - a request's headers must arrive within `header_timeout` and at most `max_header_bytes`; its body
//     within `body_timeout` and at most `max_raw_body_bytes` as sent (the decoded size is bounded by the
//     handler that reads it, read_body in request_screening.h);
//   - an idle keep-alive connection is closed after `keep_alive_timeout`, and after `keep_alive_requests`
//     requests.
// Handlers learn about their connection through current_connection() (same thread).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>

// After Eigen: httplib.h pulls in <resolv.h>, whose `_res` macro breaks Eigen's product kernels if it
// comes first (the server's files include the scene and job headers before this one).
#include <httplib.h>

namespace moreau::server {

// The Content-Security-Policy of every answer but the web page's own files (which carry theirs): nothing
// the server sends (a figure, a CSV, a report, an error that quotes a client's text) loads or runs
// anything, or is framed, if a browser opens it. Sent with "X-Content-Type-Options: nosniff".
inline constexpr char kApiContentSecurityPolicy[] = "default-src 'none'; frame-ancestors 'none'; sandbox";

// The longest request line httplib parses (CPPHTTPLIB_REQUEST_URI_MAX_LENGTH, fixed when the library was
// built: 8192 in Debian's libcpp-httplib 0.11.4); a longer one is answered 414 URI Too Long.
inline constexpr std::size_t kMaxRequestLineBytes = CPPHTTPLIB_REQUEST_URI_MAX_LENGTH;

struct TransportLimits {
  int max_connections = 512;                         // open connections in all (each holds one thread)
  int max_connections_per_client = 64;               // open connections from one client address
  std::chrono::milliseconds header_timeout{10'000};  // request line and headers, from their first byte
  std::chrono::milliseconds body_timeout{60'000};    // the whole body, from the end of the headers
  std::chrono::milliseconds write_timeout{10'000};   // one write to a client that does not read
  std::chrono::seconds keep_alive_timeout{5};        // idle time between requests
  int keep_alive_requests = 100;                     // requests on one connection, then it is closed
  std::size_t max_header_bytes = 64 << 10;           // request line and headers
  std::size_t max_raw_body_bytes = 8u << 20;         // a body as sent (chunked framing, compressed)
};

// What a request's handler may learn about, and ask of, its connection.
struct ConnectionContext {
  std::string client;              // the client's address
  bool close_after = false;        // close the connection after this response (its body was not all read)
  bool timed_out = false;          // a read of this request passed its deadline
  bool too_large = false;          // the request's raw body passed its byte limit
  bool headers_too_large = false;  // its request line and headers passed max_header_bytes
};

// The connection the calling thread serves, or nullptr outside a request.
ConnectionContext* current_connection();

struct TransportStats {
  std::int64_t open = 0;             // connections open now
  std::int64_t refused_total = 0;    // connections refused (over a connection limit)
  std::int64_t timed_out_total = 0;  // requests whose headers or body missed their deadline
};

class GuardedHttpServer : public httplib::Server {
 public:
  explicit GuardedHttpServer(TransportLimits limits);
  ~GuardedHttpServer() override;

  const TransportLimits& limits() const { return limits_; }
  TransportStats stats() const;
  // Called with the status of each answer the transport writes itself, outside httplib (a connection
  // refused over a limit: 503; a request line or headers past max_header_bytes: 414, 431), for the
  // response metrics.
  std::function<void(int status)> on_refused;

  // Wakes every connection blocked in a read (used when stopping: idle keep-alive connections and slow
  // clients then end at once instead of at their deadlines).
  void shut_down_connections();

 private:
  bool process_and_close_socket(socket_t sock) override;
  // Reserves a connection slot for `client`; empty, or why it is refused (a limit is reached).
  std::string admit(const std::string& client, socket_t sock);
  void release(const std::string& client, socket_t sock);

  TransportLimits limits_;
  mutable std::mutex mu_;
  std::map<std::string, int> per_client_;
  std::set<socket_t> sockets_;
  std::int64_t open_ = 0, refused_ = 0, timed_out_ = 0;
};

}  // namespace moreau::server
