#include "trajectory.h"

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <cmath>

#include <nlohmann/json.hpp>

namespace moreau::server {
namespace {

// Whether the cell is a JSON number as std::to_chars writes finite doubles.
bool json_number(std::string_view s) {
  if (s.empty()) return false;
  std::size_t i = s[0] == '-' ? 1 : 0;
  return i < s.size() && s[i] >= '0' && s[i] <= '9';
}

}  // namespace

bool TrajectoryReader::open(const std::string& path, RowWindow window, Format format, std::string* error) {
  in_.open(path, std::ios::binary);
  if (!in_ || !std::getline(in_, line_) || line_.empty()) {
    if (error) *error = "the stored trajectory cannot be read";
    return false;
  }
  names_.clear();
  for (std::size_t start = 0;;) {
    const std::size_t comma = line_.find(',', start);
    names_.emplace_back(line_.substr(start, comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  data_start_ = in_.tellg();
  window_ = window;
  window_.every = std::max<std::int64_t>(1, window_.every);
  format_ = format;
  return true;
}

void TrajectoryReader::rewind() {
  in_.clear();
  in_.seekg(data_start_);
  seen_in_window_ = 0;
}

bool TrajectoryReader::next_row(std::string& line) {
  while (std::getline(in_, line)) {
    if (line.empty()) continue;
    const double t = std::strtod(line.c_str(), nullptr);
    if (t < window_.from) continue;
    if (t > window_.to) return false;  // rows are in time order
    if (seen_in_window_++ % window_.every != 0) continue;
    return true;
  }
  return false;
}

bool TrajectoryReader::next(std::string& out, std::size_t budget) {
  if (finished_) return false;
  const std::size_t limit = out.size() + budget;
  if (format_ == Format::kCsv) {
    if (!started_) {
      started_ = true;
      for (std::size_t c = 0; c < names_.size(); ++c) out += (c ? "," : "") + names_[c];
      out += '\n';
    }
    while (out.size() < limit) {
      if (!next_row(line_)) {
        finished_ = true;
        return false;
      }
      out += line_;
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
    if (!next_row(line_)) {
      out += ']';
      column_open_ = false;
      ++column_;
      continue;
    }
    if (column_ == 0) ++rows_;
    // The column_-th cell of the row.
    std::size_t start = 0;
    for (std::size_t c = 0; c < column_ && start != std::string::npos; ++c) {
      start = line_.find(',', start);
      if (start != std::string::npos) ++start;
    }
    std::string_view cell;
    if (start != std::string::npos) {
      const std::size_t comma = line_.find(',', start);
      cell = std::string_view(line_).substr(start, comma == std::string::npos ? std::string::npos : comma - start);
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

}  // namespace moreau::server
