#include "moreau/scene/trajectory_csv.h"

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string_view>

#include "moreau/platform/number_text.h"
#include "moreau/scene/line_reader.h"

namespace moreau::scene {
namespace {
constexpr std::size_t kBufferBytes = 1 << 20;
// The rows written so far reach the file at least this often, not only once a buffer is full: readers
// of a running job's file (the server's GET /v1/jobs/{id}/kinematics, which the page's 3D view follows;
// `tail -f`) then see it advance while it runs, however slowly its rows come. One write a period.
constexpr std::chrono::milliseconds kFlushPeriod{500};
constexpr std::size_t kMaxRowBytes = 64;  // per value, including the separator
static_assert(kMaxRowBytes > platform::kShortestMaxChars);
}  // namespace

TrajectoryCsvWriter::TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& q_names,
                                         const std::vector<std::string>& v_names, const std::vector<std::string>& signal_names)
    : path_(path), buffer_(kBufferBytes), flushed_(std::chrono::steady_clock::now()) {
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_) throw std::runtime_error("cannot write '" + path + "': " + std::strerror(errno));
  std::string header = "t,h";
  for (const auto& q : q_names) header += "," + q;
  for (const auto& v : v_names) header += "," + v;
  header += ",energy";
  for (const auto& name : signal_names) header += "," + name;
  header += "\n";
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
  char* end = platform::write_shortest(buffer_.data() + used_, buffer_.data() + buffer_.size(), value);
  used_ = static_cast<std::size_t>(end - buffer_.data());
}

void TrajectoryCsvWriter::on_sample(const Sample& s) {
  const auto start = std::chrono::steady_clock::now();
  if (buffer_.size() - used_ < kMaxRowBytes * static_cast<std::size_t>(2 * s.n + s.m + 3)) flush_buffer();
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
  for (int i = 0; i < s.m; ++i) {
    buffer_[used_++] = ',';
    put(s.signals[i]);
  }
  buffer_[used_++] = '\n';
  auto now = std::chrono::steady_clock::now();
  if (now - flushed_ >= kFlushPeriod) {
    flush_buffer();
    if (file_ && std::fflush(file_) != 0 && !failed_) {
      failed_ = true;
      error_ = errno;
    }
    flushed_ = now = std::chrono::steady_clock::now();
  }
  seconds_ += std::chrono::duration<double>(now - start).count();
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

namespace {
// The comma-separated cells of a line, as views into it.
std::vector<std::string_view> cells_of(std::string_view line) {
  std::vector<std::string_view> cells;
  for (std::size_t start = 0;;) {
    const std::size_t comma = line.find(',', start);
    cells.push_back(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (comma == std::string_view::npos) return cells;
    start = comma + 1;
  }
}
}  // namespace

TrajectoryColumns read_trajectory_csv(std::istream& in, const std::string& source) {
  constexpr std::size_t kMaxLine = std::size_t{1} << 20;
  auto next_line = [&](std::string& line, std::size_t row) {
    return read_line(in, line, kMaxLine, source + " line " + std::to_string(row), "1 MiB");
  };
  std::string line;
  if (!next_line(line, 1)) throw std::runtime_error(source + " is empty");
  std::vector<std::string> cols;
  for (std::string_view c : cells_of(line)) cols.emplace_back(c);
  // t, h, q_1..q_n, v_1..v_n, energy (and possibly more columns after energy).
  std::size_t energy_col = 0;
  for (std::size_t i = 0; i < cols.size(); ++i)
    if (cols[i] == "energy") energy_col = i;
  if (cols.size() < 5 || cols[0] != "t" || cols[1] != "h" || energy_col < 4 || (energy_col - 2) % 2 != 0)
    throw std::runtime_error(source + " is not a Moreau trajectory (header must be t,h,q...,v...,energy)");
  const std::size_t n = (energy_col - 2) / 2;
  TrajectoryColumns data;
  for (std::size_t i = 0; i < n; ++i) {
    data.q_names.push_back(cols[2 + i]);
    data.v_names.push_back(cols[2 + n + i]);
  }
  data.q.resize(n);
  data.v.resize(n);
  for (std::size_t i = energy_col + 1; i < cols.size(); ++i) data.signal_names.push_back(cols[i]);
  data.signals.resize(data.signal_names.size());
  std::vector<double> values;
  std::size_t row = 1;
  while (next_line(line, row + 1)) {
    ++row;
    if (line.empty()) continue;
    values.clear();
    for (std::string_view cell : cells_of(line)) {
      double v = 0.0;
      const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), v);
      if (ec != std::errc() || end != cell.data() + cell.size() || !std::isfinite(v))
        throw std::runtime_error(source + " line " + std::to_string(row) + ": '" + std::string(cell.substr(0, 40)) +
                                 "' is not a finite number");
      values.push_back(v);
    }
    if (values.size() != cols.size())
      throw std::runtime_error(source + " line " + std::to_string(row) + ": expected " + std::to_string(cols.size()) + " values, got " +
                               std::to_string(values.size()));
    data.t.push_back(values[0]);
    data.h.push_back(values[1]);
    for (std::size_t i = 0; i < n; ++i) {
      data.q[i].push_back(values[2 + i]);
      data.v[i].push_back(values[2 + n + i]);
    }
    data.energy.push_back(values[energy_col]);
    for (std::size_t i = 0; i < data.signals.size(); ++i) data.signals[i].push_back(values[energy_col + 1 + i]);
  }
  if (data.t.empty()) throw std::runtime_error(source + " has no rows");
  return data;
}

}  // namespace moreau::scene
