// Writes the trajectory as CSV while the run goes: t, h, q_1..q_n, v_1..v_n, energy, then the run's
// signals if it has any (a tracking run's q_d, e, sigma and u: Simulation::signal_names). Rows are
// formatted in shortest round-trip form (platform::write_shortest, std::to_chars; a value that is not
// finite as nan, inf or -inf) into a large buffer, so output costs little and memory does not grow with
// the number of steps.
#pragma once

#include <chrono>
#include <cstdio>
#include <istream>
#include <string>
#include <vector>

#include "moreau/core/observer.h"

namespace moreau::scene {

class TrajectoryCsvWriter : public RunObserver {
 public:
  // Opens `path` and writes the header. Throws std::runtime_error if the file cannot be written.
  TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& q_names, const std::vector<std::string>& v_names,
                      const std::vector<std::string>& signal_names = {});
  ~TrajectoryCsvWriter() override;
  void on_sample(const Sample& s) override;
  // Flushes and closes; throws if anything failed to be written (a full disk, say).
  void close();
  double seconds() const { return seconds_; }  // time spent formatting and writing

 private:
  void put(double value);
  void flush_buffer();
  std::FILE* file_ = nullptr;
  std::string path_;
  std::vector<char> buffer_;
  std::size_t used_ = 0;
  bool failed_ = false;
  int error_ = 0;  // errno of the first failed write
  double seconds_ = 0.0;
  std::chrono::steady_clock::time_point flushed_;  // when the rows last reached the file
};

// A trajectory as TrajectoryCsvWriter writes it, read back: q[i] and v[i] hold coordinate i over time.
struct TrajectoryColumns {
  std::vector<std::string> q_names, v_names;
  std::vector<double> t, h, energy;
  std::vector<std::vector<double>> q, v;
  std::vector<std::string> signal_names;     // the columns after energy
  std::vector<std::vector<double>> signals;  // likewise, one vector per column
};

// Reads a trajectory CSV: the header t,h,q_1..q_n,v_1..v_n,energy (columns after energy are the signals),
// then rows of as many finite numbers. Lines are read with a bound (1 MiB; a row takes about 25 bytes
// per value), so input without line ends (/dev/zero, a binary file) is refused, not read whole. Throws
// std::runtime_error naming `source` and the line ("'traj.csv' line 3: 'x' is not a finite number").
TrajectoryColumns read_trajectory_csv(std::istream& in, const std::string& source);

}  // namespace moreau::scene
