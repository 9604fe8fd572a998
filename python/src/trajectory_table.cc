#include "trajectory_table.h"

#include <algorithm>
#include <limits>
#include <utility>

namespace moreau::python {

namespace {
// 2^24 values (128 MiB) reserved at most; a longer run grows its table as a vector does.
constexpr std::int64_t kMaxReservedValues = std::int64_t{1} << 24;
}  // namespace

TrajectoryTable::TrajectoryTable(int n, int m, std::int64_t expected_rows) : n_(n), m_(m) {
  values_.reserve(static_cast<std::size_t>(std::clamp<std::int64_t>(expected_rows * columns(), 0, kMaxReservedValues)));
}

void TrajectoryTable::on_sample(const Sample& s) {
  values_.push_back(s.t);
  values_.push_back(s.h);
  values_.insert(values_.end(), s.q, s.q + n_);
  values_.insert(values_.end(), s.v, s.v + n_);
  values_.push_back(s.kinetic_energy);
  // A run whose samples carry fewer signals than it names (none before its first control) fills with NaN.
  for (int i = 0; i < m_; ++i) values_.push_back(i < s.m ? s.signals[i] : std::numeric_limits<double>::quiet_NaN());
}

render::TimeSeriesData TrajectoryTable::time_series(std::vector<std::string> q_names, std::vector<std::string> v_names,
                                                    std::vector<std::string> signal_names) const {
  render::TimeSeriesData data;
  const std::int64_t r = rows(), c = columns();
  data.q_names = std::move(q_names);
  data.v_names = std::move(v_names);
  data.signal_names = std::move(signal_names);
  data.t.resize(r);
  data.h.resize(r);
  data.energy.resize(r);
  data.q.assign(n_, std::vector<double>(r));
  data.v.assign(n_, std::vector<double>(r));
  data.signals.assign(m_, std::vector<double>(r));
  for (std::int64_t k = 0; k < r; ++k) {
    const double* row = values_.data() + k * c;
    data.t[k] = row[0];
    data.h[k] = row[1];
    for (int i = 0; i < n_; ++i) {
      data.q[i][k] = row[2 + i];
      data.v[i][k] = row[2 + n_ + i];
    }
    data.energy[k] = row[2 + 2 * n_];
    for (int j = 0; j < m_; ++j) data.signals[j][k] = row[3 + 2 * n_ + j];
  }
  return data;
}

}  // namespace moreau::python
