// Trajectory CSV (t, h, q..., v..., energy, as TrajectoryCsvWriter writes it) in the forms the API serves.
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace moreau::server {

// Which rows of a stored trajectory a response carries: those with from <= t <= to, and of them every
// `every`-th (the first, the every+1-th, ...).
struct RowWindow {
  double from = -HUGE_VAL, to = HUGE_VAL;
  std::int64_t every = 1;
};

// A stored trajectory read piece by piece, so that a response of any length takes bounded memory. The
// file is opened once (it stays readable if the job is deleted meanwhile).
class TrajectoryReader {
 public:
  enum class Format { kCsv, kJson };
  // Opens the file; false (and *error) if it cannot be opened or has no header.
  bool open(const std::string& path, RowWindow window, Format format, std::string* error);
  // Appends the next part of the response (about `budget` bytes) to `out`; false once the response is
  // complete (out may still have received its last part). CSV: the header line, then the rows in the
  // window as stored. JSON: {"columns": [names], "data": {name: [values...], ...}, "rows": N}, numbers
  // copied as written (shortest round-trip form), non-numbers as null; one pass over the file per column.
  bool next(std::string& out, std::size_t budget = 64 << 10);

 private:
  bool next_row(std::string& line);  // the next row in the window, or false at the end
  void rewind();

  std::ifstream in_;
  std::streampos data_start_;
  std::vector<std::string> names_;
  RowWindow window_;
  Format format_ = Format::kCsv;
  std::int64_t seen_in_window_ = 0, rows_ = 0;
  std::size_t column_ = 0;
  bool started_ = false, column_open_ = false, first_in_column_ = true, finished_ = false;
  std::string line_;
};

}  // namespace moreau::server
