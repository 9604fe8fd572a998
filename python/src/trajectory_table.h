// A run's recorded states as one table of doubles, row after row, with the columns of a trajectory CSV
// (trajectory_csv.h): t, h, the n positions, the n velocities, the energy, then the m signals. The
// Python module hands this table to numpy through the buffer protocol, so the arrays a Result gives are
// views of the run's own memory, not copies.
#pragma once

#include <cstdint>
#include <vector>

#include "moreau/core/observer.h"
#include "moreau/render/figures.h"

namespace moreau::python {

class TrajectoryTable : public RunObserver {
 public:
  // `expected_rows`: the rows the run will record, reserved at once (the planned steps over output_every,
  // plus the first and last), so that a long run does not move its table while it grows; capped so that a
  // scene with a huge max_steps does not reserve memory it never fills.
  TrajectoryTable(int n, int m, std::int64_t expected_rows);

  void on_sample(const Sample& s) override;

  int n() const { return n_; }
  int m() const { return m_; }
  std::int64_t columns() const { return 3 + 2 * static_cast<std::int64_t>(n_) + m_; }
  std::int64_t rows() const { return static_cast<std::int64_t>(values_.size()) / columns(); }
  double* data() { return values_.data(); }
  const double* data() const { return values_.data(); }

  // The columns as render/'s time series (copied: figures are drawn from their own vectors).
  render::TimeSeriesData time_series(std::vector<std::string> q_names, std::vector<std::string> v_names,
                                     std::vector<std::string> signal_names) const;

 private:
  int n_, m_;
  std::vector<double> values_;
};

}  // namespace moreau::python
