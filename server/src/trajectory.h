// Trajectory CSV (t, h, q..., v..., energy, as TrajectoryCsvWriter writes it) in the forms the API serves.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::server {

struct Columns {
  std::vector<std::string> names;
  std::vector<std::vector<double>> values;  // one vector per column
};

// {"columns": [names...], "rows": N, "data": {name: [values...], ...}}, numbers copied as written
// (shortest round-trip form), non-finite values as null. nullopt and *error if the CSV is malformed.
std::optional<std::string> trajectory_json(std::string_view csv, std::string* error);

// The columns as numbers. nullopt and *error if the CSV is malformed.
std::optional<Columns> trajectory_columns(std::string_view csv, std::string* error);

}  // namespace moreau::server
