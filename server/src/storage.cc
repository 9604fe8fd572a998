#include "storage.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <mutex>
#include <random>
#include <stdexcept>

namespace moreau::server {
namespace {

[[noreturn]] void fail(const std::string& what, const std::filesystem::path& path) {
  throw std::runtime_error(what + " '" + path.string() + "': " + std::strerror(errno));
}

}  // namespace

namespace {

// A write that failed (a full disk, say) removes its file: a part of it is of no use, and it would go on
// holding the space.
[[noreturn]] void fail_and_remove(const std::string& what, const std::filesystem::path& path, int fd) {
  const int e = errno;
  if (fd >= 0) ::close(fd);
  ::unlink(path.c_str());
  errno = e;
  fail(what, path);
}

void write_fd(const std::filesystem::path& tmp, std::string_view bytes, Durability durability) {
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create", tmp);
  if (const auto& fault = write_fault_for_testing(); fault) {
    if (const int e = fault(tmp); e != 0) {
      errno = e;
      fail_and_remove("cannot write", tmp, fd);
    }
  }
  const char* p = bytes.data();
  std::size_t left = bytes.size();
  while (left > 0) {
    const ssize_t w = ::write(fd, p, left);
    if (w < 0) {
      if (errno == EINTR) continue;
      fail_and_remove("cannot write", tmp, fd);
    }
    p += w;
    left -= static_cast<std::size_t>(w);
  }
  if (durability == Durability::kFsync && ::fsync(fd) != 0) fail_and_remove("cannot fsync", tmp, fd);
  if (::close(fd) != 0) fail_and_remove("cannot close", tmp, -1);
}

}  // namespace

std::function<int(const std::filesystem::path&)>& write_fault_for_testing() {
  static std::function<int(const std::filesystem::path&)> fault;
  return fault;
}

void write_file(const std::filesystem::path& path, std::string_view bytes) { write_fd(path, bytes, Durability::kRename); }

void write_file_atomic(const std::filesystem::path& path, std::string_view bytes, Durability durability) {
  std::filesystem::path tmp = path;
  tmp += ".tmp";
  write_fd(tmp, bytes, durability);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    errno = e;
    fail("cannot rename into", path);
  }
}

void check_writable_directory(const std::filesystem::path& dir) {
  // A file name no job uses (ids are 32 hex digits) and no other server process on the same
  // directory picks at the same time.
  const std::filesystem::path probe = dir / (".write-check-" + std::to_string(::getpid()));
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) fail("cannot create files in", dir);
  ::close(fd);
  if (::unlink(probe.c_str()) != 0) fail("cannot remove files in", dir);
}

void fsync_path(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail("cannot open", path);
  if (::fsync(fd) != 0) {
    const int e = errno;
    ::close(fd);
    errno = e;
    fail("cannot fsync", path);
  }
  ::close(fd);
}

std::optional<std::string> read_file(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return std::nullopt;
  std::string out;
  char buf[65536];
  while (true) {
    const ssize_t r = ::read(fd, buf, sizeof buf);
    if (r < 0) {
      if (errno == EINTR) continue;
      ::close(fd);
      return std::nullopt;
    }
    if (r == 0) break;
    out.append(buf, static_cast<std::size_t>(r));
  }
  ::close(fd);
  return out;
}

bool is_job_id(std::string_view s) {
  if (s.size() != 32) return false;
  for (char c : s)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

std::string new_job_id() {
  static std::mutex mu;
  static std::random_device device;
  std::uint32_t words[4];
  {
    std::lock_guard lock(mu);
    for (auto& w : words) w = device();
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string id;
  id.reserve(32);
  for (std::uint32_t w : words)
    for (int shift = 28; shift >= 0; shift -= 4) id.push_back(kHex[(w >> shift) & 0xF]);
  return id;
}

}  // namespace moreau::server
