#include "moreau/scene/trajectory_csv.h"

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <stdexcept>

namespace moreau::scene {
namespace {
constexpr std::size_t kBufferBytes = 1 << 20;
constexpr std::size_t kMaxRowBytes = 64;  // per value, including the separator
}  // namespace

TrajectoryCsvWriter::TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& q_names,
                                         const std::vector<std::string>& v_names)
    : path_(path), buffer_(kBufferBytes) {
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_) throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
  std::string header = "t,h";
  for (const auto& q : q_names) header += "," + q;
  for (const auto& v : v_names) header += "," + v;
  header += ",energy\n";
  if (std::fwrite(header.data(), 1, header.size(), file_) != header.size()) {
    failed_ = true;
    error_ = errno;
  }
}

TrajectoryCsvWriter::~TrajectoryCsvWriter() {
  if (file_) {
    flush_buffer();
    std::fclose(file_);
  }
}

void TrajectoryCsvWriter::put(double value) {
  auto [end, ec] = std::to_chars(buffer_.data() + used_, buffer_.data() + buffer_.size(), value);
  (void)ec;
  used_ = static_cast<std::size_t>(end - buffer_.data());
}

void TrajectoryCsvWriter::on_sample(const Sample& s) {
  const auto start = std::chrono::steady_clock::now();
  if (buffer_.size() - used_ < kMaxRowBytes * static_cast<std::size_t>(2 * s.n + 3)) flush_buffer();
  put(s.t);
  buffer_[used_++] = ',';
  put(s.h);
  for (int i = 0; i < s.n; ++i) {
    buffer_[used_++] = ',';
    put(s.q[i]);
  }
  for (int i = 0; i < s.n; ++i) {
    buffer_[used_++] = ',';
    put(s.v[i]);
  }
  buffer_[used_++] = ',';
  put(s.kinetic_energy);
  buffer_[used_++] = '\n';
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void TrajectoryCsvWriter::flush_buffer() {
  if (used_ && file_ && std::fwrite(buffer_.data(), 1, used_, file_) != used_ && !failed_) {
    failed_ = true;
    error_ = errno;
  }
  used_ = 0;
}

void TrajectoryCsvWriter::close() {
  if (!file_) return;
  flush_buffer();
  const bool flushed = std::fflush(file_) == 0;
  if (!flushed && !failed_) error_ = errno;
  const bool closed = std::fclose(file_) == 0;
  if (!closed && !failed_ && flushed) error_ = errno;
  file_ = nullptr;
  if (failed_ || !flushed || !closed)
    throw std::runtime_error("writing '" + path_ + "' failed: " + (error_ ? std::strerror(error_) : "unknown error"));
}

}  // namespace moreau::scene
