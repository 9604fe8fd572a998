// Trajectory CSV (t, h, q..., v..., energy, as TrajectoryCsvWriter writes it) in the forms the API serves:
// the CSV itself, JSON by column, and a NumPy .npy file of float64 (for clients that want an array, not
// text to parse).
#pragma once

#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <fstream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
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
  enum class Format { kCsv, kJson, kNpy };
  // Opens the file; false (and *error) if it cannot be opened or has no header.
  bool open(const std::string& path, RowWindow window, Format format, std::string* error);
  // Appends the next part of the response (about `budget` bytes) to `out`; false once the response is
  // complete (out may still have received its last part). CSV: the header line, then the rows in the
  // window as stored. JSON: {"columns": [names], "data": {name: [values...], ...}, "rows": N}, numbers
  // copied as written (shortest round-trip form), non-numbers as null; one pass over the file per column.
  // NPY: a .npy version 1.0 file of one C-order array of little-endian float64 ('<f8'), shape (rows,
  // columns): one pass counting the rows in the window (the header holds the shape), then one converting
  // them; each value the double its cell reads as (nan, inf and -inf included), a missing or unreadable
  // cell NaN (JSON's null).
  bool next(std::string& out, std::size_t budget = 64 << 10);

  // The column names of the stored file's header line.
  const std::vector<std::string>& names() const { return names_; }

 private:
  // The next row in the window (a view into buffer_, valid until the next call), or false at the end.
  bool next_row(std::string_view& row);
  // The next non-empty line of the file, read a block at a time (std::getline costs a call per byte).
  bool next_line(std::string_view& line);
  void rewind();
  bool next_npy(std::string& out, std::size_t limit);

  std::ifstream in_;
  std::streampos data_start_;
  std::vector<char> buffer_;
  std::size_t begin_ = 0, end_ = 0;  // the unread part of buffer_
  bool eof_ = false;
  bool whole_span_ = true;  // from = -inf and to = +inf: no row's t needs reading to know it is in the window
  std::string_view row_;
  std::vector<std::string> names_;
  RowWindow window_;
  Format format_ = Format::kCsv;
  std::int64_t seen_in_window_ = 0, rows_ = 0, emitted_ = 0;
  std::size_t column_ = 0;
  bool started_ = false, column_open_ = false, first_in_column_ = true, finished_ = false;
  std::string header_;
};

// A TrajectoryReader's parts made ahead on a thread of its own, at most `depth` of them waiting: for the
// .npy form, whose parts cost more to make (text to doubles) than to send, making the next part overlaps
// sending the last. Destroying it (the response done, or its connection gone) stops the thread after the
// part it is making and joins it.
class TrajectoryPrefetcher {
 public:
  TrajectoryPrefetcher(std::shared_ptr<TrajectoryReader> reader, std::size_t depth = 4);
  ~TrajectoryPrefetcher();
  TrajectoryPrefetcher(const TrajectoryPrefetcher&) = delete;
  TrajectoryPrefetcher& operator=(const TrajectoryPrefetcher&) = delete;
  // As TrajectoryReader::next: appends the next part to `out`; false once the response is complete.
  bool next(std::string& out);

 private:
  void run();

  std::shared_ptr<TrajectoryReader> reader_;
  std::size_t depth_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::string> parts_;
  bool done_ = false, stop_ = false;
  std::thread thread_;  // last: started once the rest is made
};

// The column names as the Moreau-Columns header of an .npy answer carries them: comma-separated, each
// byte other than A-Z, a-z, 0-9, '_', '.' and '-' percent-encoded (%2C, %0D, ...). Scene names are
// identifiers already; the encoding keeps any name that reached a stored file from splitting the list or
// the header.
std::string columns_header_value(const std::vector<std::string>& names);

}  // namespace moreau::server
