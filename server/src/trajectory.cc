#include "trajectory.h"

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>

#include <nlohmann/json.hpp>

namespace moreau::server {
namespace {

// Whether the cell is a JSON number as std::to_chars writes finite doubles.
bool json_number(std::string_view s) {
  if (s.empty()) return false;
  std::size_t i = s[0] == '-' ? 1 : 0;
  return i < s.size() && s[i] >= '0' && s[i] <= '9';
}

// The double a CSV cell reads as: the shortest round-trip text, "nan", "inf" or "-inf" (from_chars reads
// all of them, locale-free); NaN for an empty or unreadable cell.
double cell_value(const char* first, const char* last) {
  double v = std::numeric_limits<double>::quiet_NaN();
  const auto [end, ec] = std::from_chars(first, last, v);
  if (ec == std::errc::result_out_of_range) return std::strtod(std::string(first, last).c_str(), nullptr);
  if (ec != std::errc() || end != last) return std::numeric_limits<double>::quiet_NaN();
  return v;
}

// The values as little-endian IEEE 754 doubles, 8 bytes each, whatever this machine's byte order.
void append_le(std::string& out, const std::vector<double>& values) {
  const std::size_t at = out.size();
  out.resize(at + 8 * values.size());
  char* dst = out.data() + at;
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(dst, values.data(), 8 * values.size());
  } else {
    for (const double v : values) {
      const auto bits = std::bit_cast<std::uint64_t>(v);
      for (int i = 0; i < 8; ++i) *dst++ = static_cast<char>((bits >> (8 * i)) & 0xff);
    }
  }
}

}  // namespace

bool TrajectoryReader::open(const std::string& path, RowWindow window, Format format, std::string* error) {
  in_.open(path, std::ios::binary);
  if (!in_ || !std::getline(in_, header_) || header_.empty()) {
    if (error) *error = "the stored trajectory cannot be read";
    return false;
  }
  names_.clear();
  for (std::size_t start = 0;;) {
    const std::size_t comma = header_.find(',', start);
    names_.emplace_back(header_.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  data_start_ = in_.tellg();
  buffer_.resize(1 << 20);
  begin_ = end_ = 0;
  eof_ = false;
  window_ = window;
  window_.every = std::max<std::int64_t>(1, window_.every);
  whole_span_ = window_.from == -HUGE_VAL && window_.to == HUGE_VAL;
  format_ = format;
  return true;
}

void TrajectoryReader::rewind() {
  in_.clear();
  in_.seekg(data_start_);
  begin_ = end_ = 0;
  eof_ = false;
  seen_in_window_ = 0;
}

bool TrajectoryReader::next_line(std::string_view& line) {
  for (;;) {
    const char* first = buffer_.data() + begin_;
    const char* nl = static_cast<const char*>(std::memchr(first, '\n', end_ - begin_));
    if (nl) {
      line = std::string_view(first, static_cast<std::size_t>(nl - first));
      begin_ += line.size() + 1;
      if (line.empty()) continue;
      return true;
    }
    if (eof_) {  // a last line without its '\n'
      if (begin_ == end_) return false;
      line = std::string_view(first, end_ - begin_);
      begin_ = end_;
      return true;
    }
    // Keep the partial line, at the front, and read more after it (a line longer than the buffer grows it).
    std::memmove(buffer_.data(), first, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
    if (end_ == buffer_.size()) buffer_.resize(buffer_.size() * 2);
    in_.read(buffer_.data() + end_, static_cast<std::streamsize>(buffer_.size() - end_));
    const auto got = static_cast<std::size_t>(in_.gcount());
    end_ += got;
    if (got == 0 || !in_) eof_ = true;
  }
}

bool TrajectoryReader::next_row(std::string_view& row) {
  while (next_line(row)) {
    if (!whole_span_) {
      // t, the first cell, read as strtod reads it (0 if it is not a number).
      double t = 0;
      const char* end = row.data() + row.size();
      const auto parsed = std::from_chars(row.data(), std::find(row.data(), end, ','), t);
      if (parsed.ec != std::errc()) t = std::strtod(std::string(row.substr(0, row.find(','))).c_str(), nullptr);
      if (t < window_.from) continue;
      if (t > window_.to) return false;  // rows are in time order
    }
    if (seen_in_window_++ % window_.every != 0) continue;
    return true;
  }
  return false;
}

bool TrajectoryReader::next(std::string& out, std::size_t budget) {
  if (finished_) return false;
  const std::size_t limit = out.size() + budget;
  if (format_ == Format::kNpy) return next_npy(out, limit);
  if (format_ == Format::kCsv) {
    if (!started_) {
      started_ = true;
      for (std::size_t c = 0; c < names_.size(); ++c) out += (c ? "," : "") + names_[c];
      out += '\n';
    }
    while (out.size() < limit) {
      if (!next_row(row_)) {
        finished_ = true;
        return false;
      }
      out += row_;
      out += '\n';
    }
    return true;
  }
  if (!started_) {
    started_ = true;
    out += "{\"columns\":";
    out += nlohmann::json(names_).dump();
    out += ",\"data\":{";
  }
  while (out.size() < limit) {
    if (column_ == names_.size()) {
      out += "},\"rows\":" + std::to_string(rows_) + "}\n";
      finished_ = true;
      return false;
    }
    if (!column_open_) {
      column_open_ = true;
      first_in_column_ = true;
      rewind();
      if (column_) out += ',';
      out += nlohmann::json(names_[column_]).dump();
      out += ":[";
    }
    if (!next_row(row_)) {
      out += ']';
      column_open_ = false;
      ++column_;
      continue;
    }
    if (column_ == 0) ++rows_;
    // The column_-th cell of the row.
    std::size_t start = 0;
    for (std::size_t c = 0; c < column_ && start != std::string_view::npos; ++c) {
      start = row_.find(',', start);
      if (start != std::string_view::npos) ++start;
    }
    std::string_view cell;
    if (start != std::string_view::npos) {
      const std::size_t comma = row_.find(',', start);
      cell = row_.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start);
    }
    if (!first_in_column_) out += ',';
    first_in_column_ = false;
    if (json_number(cell))
      out += cell;
    else
      out += "null";
  }
  return true;
}

TrajectoryPrefetcher::TrajectoryPrefetcher(std::shared_ptr<TrajectoryReader> reader, std::size_t depth)
    : reader_(std::move(reader)), depth_(std::max<std::size_t>(1, depth)), thread_([this] { run(); }) {}

TrajectoryPrefetcher::~TrajectoryPrefetcher() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void TrajectoryPrefetcher::run() {
  for (;;) {
    std::string part;
    const bool more = reader_->next(part);
    std::unique_lock lock(mu_);
    cv_.wait(lock, [&] { return stop_ || parts_.size() < depth_; });
    if (stop_) return;
    parts_.push_back(std::move(part));
    done_ = !more;
    lock.unlock();
    cv_.notify_all();
    if (!more) return;
  }
}

bool TrajectoryPrefetcher::next(std::string& out) {
  std::unique_lock lock(mu_);
  cv_.wait(lock, [&] { return !parts_.empty() || done_; });
  if (!parts_.empty()) {
    out += parts_.front();
    parts_.pop_front();
  }
  const bool more = !(done_ && parts_.empty());
  lock.unlock();
  cv_.notify_all();
  return more;
}

std::string columns_header_value(const std::vector<std::string>& names) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (std::size_t c = 0; c < names.size(); ++c) {
    if (c) out += ',';
    for (const char ch : names[c]) {
      const auto u = static_cast<unsigned char>(ch);
      if ((u >= 'A' && u <= 'Z') || (u >= 'a' && u <= 'z') || (u >= '0' && u <= '9') || u == '_' || u == '.' || u == '-') {
        out += ch;
      } else {
        out += '%';
        out += kHex[u >> 4];
        out += kHex[u & 15];
      }
    }
  }
  return out;
}

bool TrajectoryReader::next_npy(std::string& out, std::size_t limit) {
  const std::size_t columns = names_.size();
  if (!started_) {
    started_ = true;
    // The header holds the shape: count the rows in the window first, then start again.
    rows_ = 0;
    while (next_row(row_)) ++rows_;
    rewind();
    // Format 1.0: magic, version, the header's length (2 bytes, little-endian), then a Python dict
    // literal padded with spaces and ended by '\n' so that the data starts at a multiple of 64 bytes.
    std::string dict =
        "{'descr': '<f8', 'fortran_order': False, 'shape': (" + std::to_string(rows_) + ", " + std::to_string(columns) + "), }";
    constexpr std::size_t kPrefix = 10;  // magic (6), version (2), header length (2)
    dict.append((64 - (kPrefix + dict.size() + 1) % 64) % 64, ' ');
    dict += '\n';
    out.append("\x93NUMPY\x01\x00", 8);
    out += static_cast<char>(dict.size() & 0xff);
    out += static_cast<char>(dict.size() >> 8);
    out += dict;
  }
  std::vector<double> values(columns);
  while (out.size() < limit) {
    // Exactly the rows the header announces: were the file to change between the passes, missing rows
    // would be NaN and extra ones left out, and the body would still be the array its header describes.
    if (emitted_ == rows_) {
      finished_ = true;
      return false;
    }
    std::fill(values.begin(), values.end(), std::numeric_limits<double>::quiet_NaN());
    if (next_row(row_)) {
      const char* p = row_.data();
      const char* const end = p + row_.size();
      for (std::size_t c = 0; c < columns; ++c) {
        // from_chars finds the cell's end itself; a cell it does not read whole is looked at apart.
        const auto [stop, ec] = std::from_chars(p, end, values[c]);
        const char* comma = stop;
        if (ec != std::errc() || (stop != end && *stop != ',')) {
          comma = static_cast<const char*>(std::memchr(p, ',', static_cast<std::size_t>(end - p)));
          if (!comma) comma = end;
          values[c] = cell_value(p, comma);
        }
        if (comma == end) break;
        p = comma + 1;
      }
    }
    append_le(out, values);
    ++emitted_;
  }
  return true;
}

}  // namespace moreau::server
