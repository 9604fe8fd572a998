#include "trajectory.h"

#include <charconv>
#include <cmath>

#include <nlohmann/json.hpp>

namespace moreau::server {
namespace {

// Splits the CSV into its header names and, per column, the cells as views into `csv`.
bool split(std::string_view csv, std::vector<std::string>& names, std::vector<std::vector<std::string_view>>& cells,
           std::string* error) {
  auto next_line = [&](std::string_view& line) {
    if (csv.empty()) return false;
    const std::size_t nl = csv.find('\n');
    line = csv.substr(0, nl);
    csv = nl == std::string_view::npos ? std::string_view{} : csv.substr(nl + 1);
    return true;
  };
  std::string_view line;
  if (!next_line(line) || line.empty()) {
    if (error) *error = "the trajectory is empty";
    return false;
  }
  for (std::size_t start = 0;;) {
    const std::size_t comma = line.find(',', start);
    names.emplace_back(line.substr(start, comma - start));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  cells.assign(names.size(), {});
  std::size_t row = 1;
  while (next_line(line)) {
    ++row;
    if (line.empty()) continue;
    std::size_t col = 0;
    for (std::size_t start = 0;; ++col) {
      const std::size_t comma = line.find(',', start);
      if (col < cells.size()) cells[col].push_back(line.substr(start, comma - start));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    if (col + 1 != names.size()) {
      if (error) *error = "trajectory line " + std::to_string(row) + " has " + std::to_string(col + 1) + " values, expected " +
                          std::to_string(names.size());
      return false;
    }
  }
  return true;
}

// Whether the cell is a JSON number as std::to_chars writes finite doubles.
bool json_number(std::string_view s) {
  if (s.empty()) return false;
  std::size_t i = s[0] == '-' ? 1 : 0;
  return i < s.size() && s[i] >= '0' && s[i] <= '9';
}

}  // namespace

std::optional<std::string> trajectory_json(std::string_view csv, std::string* error) {
  std::vector<std::string> names;
  std::vector<std::vector<std::string_view>> cells;
  if (!split(csv, names, cells, error)) return std::nullopt;
  std::string out;
  out.reserve(csv.size() + 64 * names.size());
  out += "{\"columns\":";
  out += nlohmann::json(names).dump();
  out += ",\"rows\":";
  out += std::to_string(cells.empty() ? 0 : cells[0].size());
  out += ",\"data\":{";
  for (std::size_t c = 0; c < names.size(); ++c) {
    if (c) out += ',';
    out += nlohmann::json(names[c]).dump();
    out += ":[";
    for (std::size_t r = 0; r < cells[c].size(); ++r) {
      if (r) out += ',';
      if (json_number(cells[c][r])) out += cells[c][r];
      else out += "null";
    }
    out += ']';
  }
  out += "}}\n";
  return out;
}

std::optional<Columns> trajectory_columns(std::string_view csv, std::string* error) {
  Columns cols;
  std::vector<std::vector<std::string_view>> cells;
  if (!split(csv, cols.names, cells, error)) return std::nullopt;
  cols.values.resize(cells.size());
  for (std::size_t c = 0; c < cells.size(); ++c) {
    cols.values[c].reserve(cells[c].size());
    for (std::string_view cell : cells[c]) {
      double v = NAN;
      const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), v);
      if (ec != std::errc() || end != cell.data() + cell.size()) v = NAN;
      cols.values[c].push_back(v);
    }
  }
  return cols;
}

}  // namespace moreau::server
