#include "http_transport.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <thread>

namespace moreau::server {
namespace {

using Clock = std::chrono::steady_clock;

thread_local ConnectionContext* t_connection = nullptr;
// Set while the accept thread runs a connection's task itself: the task may only refuse it.
thread_local bool t_refuse_only = false;

std::string address_of(const sockaddr_storage& a, int* port) {
  char buf[INET6_ADDRSTRLEN] = {0};
  if (a.ss_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(&a);
    ::inet_ntop(AF_INET, &in->sin_addr, buf, sizeof buf);
    if (port) *port = ntohs(in->sin_port);
  } else if (a.ss_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(&a);
    ::inet_ntop(AF_INET6, &in6->sin6_addr, buf, sizeof buf);
    if (port) *port = ntohs(in6->sin6_port);
  }
  return buf;
}

std::string peer_address(int fd, int* port) {
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) return {};
  return address_of(a, port);
}

std::string local_address(int fd, int* port) {
  sockaddr_storage a{};
  socklen_t len = sizeof a;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) return {};
  return address_of(a, port);
}

// Waits until `fd` is ready for `events` or `deadline` passes; true if ready.
bool wait_for(int fd, short events, Clock::time_point deadline) {
  while (true) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000)));
    if (r > 0) return true;
    if (r < 0 && errno != EINTR) return false;
  }
}

// A connection as httplib's parser reads and writes it: buffered reads that stop at the phase's deadline
// and byte budget, writes that give up after the write timeout.
class GuardedStream final : public httplib::Stream {
 public:
  GuardedStream(int fd, const TransportLimits& limits, ConnectionContext& ctx) : fd_(fd), limits_(limits), ctx_(ctx) {}

  // A new request: its headers must come within the header timeout of its first byte (already waited
  // for by the caller) and within the header byte limit.
  void begin_request() {
    deadline_ = Clock::now() + limits_.header_timeout;
    budget_ = limits_.max_header_bytes;
    in_headers_ = true;
    line_complete_ = false;
    written_ = 0;
  }
  // The headers are parsed: the body (if any) has the body timeout and the raw body limit.
  void begin_body() {
    deadline_ = Clock::now() + limits_.body_timeout;
    in_headers_ = false;
    // Bytes already buffered past the headers belong to the body.
    budget_ = limits_.max_raw_body_bytes;
    budget_ = buffered() > budget_ ? 0 : budget_ - buffered();
  }
  std::size_t buffered() const { return end_ - begin_; }
  // Whether the request line has been read to its end (a newline went to the parser), and how many bytes
  // were written since the request began (0: nothing was answered).
  bool request_line_complete() const { return line_complete_; }
  std::size_t written() const { return written_; }

  bool is_readable() const override { return buffered() > 0 || wait_for(fd_, POLLIN, deadline_); }
  bool is_writable() const override { return wait_for(fd_, POLLOUT, Clock::now() + limits_.write_timeout); }

  ssize_t read(char* ptr, size_t size) override {
    if (buffered() == 0 && !fill()) return -1;
    const std::size_t n = std::min(size, buffered());
    std::memcpy(ptr, buf_ + begin_, n);
    begin_ += n;
    if (in_headers_ && !line_complete_ && std::memchr(ptr, '\n', n)) line_complete_ = true;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    std::size_t done = 0;
    while (done < size) {
      const ssize_t w = ::send(fd_, ptr + done, size - done, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (w > 0) {
        done += static_cast<std::size_t>(w);
        continue;
      }
      if (w < 0 && errno == EINTR) continue;
      if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        if (!wait_for(fd_, POLLOUT, Clock::now() + limits_.write_timeout)) return -1;
        continue;
      }
      return -1;
    }
    written_ += size;
    return static_cast<ssize_t>(size);
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { ip = peer_address(fd_, &port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { ip = local_address(fd_, &port); }
  socket_t socket() const override { return fd_; }

 private:
  bool fill() {
    begin_ = end_ = 0;
    if (budget_ == 0) {
      (in_headers_ ? ctx_.headers_too_large : ctx_.too_large) = true;
      ctx_.close_after = true;
      return false;
    }
    while (true) {
      if (!wait_for(fd_, POLLIN, deadline_)) {
        ctx_.timed_out = true;
        ctx_.close_after = true;
        return false;
      }
      const std::size_t want = std::min(sizeof buf_, budget_);
      const ssize_t r = ::recv(fd_, buf_, want, MSG_DONTWAIT);
      if (r > 0) {
        end_ = static_cast<std::size_t>(r);
        budget_ -= end_;
        return true;
      }
      if (r < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK)) continue;
      ctx_.close_after = true;
      return false;  // closed by the client, or an error
    }
  }

  int fd_;
  const TransportLimits& limits_;
  ConnectionContext& ctx_;
  Clock::time_point deadline_ = Clock::now();
  bool in_headers_ = true;
  bool line_complete_ = false;
  std::size_t written_ = 0;
  std::size_t budget_ = 0;  // bytes this phase of the request (headers, or body) may still read
  char buf_[16 << 10];
  std::size_t begin_ = 0, end_ = 0;
};

// Answers a request the transport ends itself (a connection over a limit, a request line or headers over
// their byte limit), without waiting on the client: a write that does not fit the socket buffer is dropped,
// and the connection is closed. `error` and `detail` are the transport's own text (no quote or backslash
// to escape). The headers every answer of the server carries (server.cc, set_post_routing_handler) are
// written here too: httplib's handlers never see these answers.
void answer_and_close(int fd, int status, const char* error, const std::string& detail) {
  const std::string body = std::string("{\"error\":\"") + error + "\",\"reason\":\"" + detail + "\"}\n";
  const char* phrase = status == 503   ? "Service Unavailable"
                       : status == 414 ? "URI Too Long"
                       : status == 431 ? "Request Header Fields Too Large"
                                       : "Error";
  const std::string head = "HTTP/1.1 " + std::to_string(status) + " " + phrase + "\r\nContent-Type: application/json\r\n" +
                           (status == 503 ? "Retry-After: 1\r\n" : "") + "Connection: close\r\n" +
                           "X-Content-Type-Options: nosniff\r\nContent-Security-Policy: " + kApiContentSecurityPolicy + "\r\n" +
                           "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n";
  const std::string all = head + body;
  [[maybe_unused]] const ssize_t ignored = ::send(fd, all.data(), all.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

// httplib's task queue, one thread per connection (see the header). While the connections are all
// taken, the accept thread runs a new connection's task itself, which only refuses it: refused
// connections never start threads.
class ThreadPerConnection final : public httplib::TaskQueue {
 public:
  explicit ThreadPerConnection(int max_threads) : max_threads_(max_threads) {}
  void enqueue(std::function<void()> fn) override {
    {
      std::unique_lock lock(mu_);
      if (running_ >= max_threads_) {
        lock.unlock();
        t_refuse_only = true;
        fn();
        t_refuse_only = false;
        return;
      }
      ++running_;
    }
    std::thread([this, fn = std::move(fn)] {
      fn();
      std::lock_guard lock(mu_);
      if (--running_ == 0) idle_.notify_all();
    }).detach();
  }
  void shutdown() override {
    std::unique_lock lock(mu_);
    idle_.wait(lock, [&] { return running_ == 0; });
  }

 private:
  const int max_threads_;
  std::mutex mu_;
  std::condition_variable idle_;
  int running_ = 0;
};

}  // namespace

ConnectionContext* current_connection() { return t_connection; }

GuardedHttpServer::GuardedHttpServer(TransportLimits limits) : limits_(limits) {
  const int max = std::max(1, limits_.max_connections);
  new_task_queue = [max] { return new ThreadPerConnection(max); };
}

GuardedHttpServer::~GuardedHttpServer() = default;

TransportStats GuardedHttpServer::stats() const {
  std::lock_guard lock(mu_);
  return {open_, refused_, timed_out_};
}

std::string GuardedHttpServer::admit(const std::string& client, socket_t sock) {
  std::lock_guard lock(mu_);
  std::string refused;
  if (t_refuse_only || open_ >= limits_.max_connections) {
    refused = "this server holds at most " + std::to_string(limits_.max_connections) + " connections at once";
  } else if (per_client_[client] >= limits_.max_connections_per_client) {
    refused =
        "this server holds at most " + std::to_string(limits_.max_connections_per_client) + " connections from one client address at once";
  }
  if (!refused.empty()) {
    if (per_client_[client] == 0) per_client_.erase(client);
    ++refused_;
    return refused;
  }
  ++per_client_[client];
  ++open_;
  sockets_.insert(sock);
  return {};
}

void GuardedHttpServer::release(const std::string& client, socket_t sock) {
  std::lock_guard lock(mu_);
  auto it = per_client_.find(client);
  if (it != per_client_.end() && --it->second <= 0) per_client_.erase(it);
  --open_;
  sockets_.erase(sock);
}

void GuardedHttpServer::shut_down_connections() {
  std::lock_guard lock(mu_);
  for (socket_t s : sockets_) ::shutdown(s, SHUT_RD);
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  const std::string client = peer_address(sock, nullptr);
  if (const std::string why = admit(client, sock); !why.empty()) {
    answer_and_close(sock, 503, "too many connections", why);
    if (on_refused) on_refused(503);
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
    return false;
  }

  ConnectionContext ctx;
  ctx.client = client;
  GuardedStream stream(sock, limits_, ctx);
  bool ok = true;
  for (int served = 0; served < std::max(1, limits_.keep_alive_requests); ++served) {
    // Idle between requests: the next one must begin within the keep-alive timeout.
    if (stream.buffered() == 0 && !wait_for(sock, POLLIN, Clock::now() + limits_.keep_alive_timeout)) break;
    ctx.close_after = ctx.timed_out = ctx.too_large = ctx.headers_too_large = false;
    stream.begin_request();
    const bool last = served + 1 >= limits_.keep_alive_requests;
    bool connection_closed = false;
    t_connection = &ctx;
    ok = process_request(stream, last, connection_closed, [&](httplib::Request&) { stream.begin_body(); });
    t_connection = nullptr;
    // A request line or headers that ran past max_header_bytes before their end: httplib's line reader
    // fails, and process_request returns without a word (a 100,000-character path was answered by a
    // closed connection). httplib itself answers 414 to a complete request line longer than
    // CPPHTTPLIB_REQUEST_URI_MAX_LENGTH (8192, fixed when the library was built); one too long to reach
    // its end within the header limit is answered 414 here, as are headers cut there 431.
    if (!ok && ctx.headers_too_large && stream.written() == 0) {
      const int status = stream.request_line_complete() ? 431 : 414;
      answer_and_close(sock, status, status == 414 ? "URI too long" : "request headers too large",
                       status == 414
                           ? "the request line may take at most " + std::to_string(kMaxRequestLineBytes) + " bytes"
                           : "the request line and headers may take at most " + std::to_string(limits_.max_header_bytes) + " bytes");
      if (on_refused) on_refused(status);
    }
    if (ctx.timed_out) {
      std::lock_guard lock(mu_);
      ++timed_out_;
    }
    if (!ok || connection_closed || ctx.close_after) break;
  }
  release(client, sock);
  ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
  return ok;
}

}  // namespace moreau::server
