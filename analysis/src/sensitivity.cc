#include "moreau/analysis/sensitivity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <boost/math/distributions/normal.hpp>
#include <boost/random/sobol.hpp>

#include "moreau/platform/number_text.h"

namespace moreau::scene {

// ---- the design ----

std::int64_t saltelli_points(std::int64_t base_rows, int inputs) { return base_rows * (static_cast<std::int64_t>(inputs) + 2); }

SaltelliPlace saltelli_place(std::int64_t i, int inputs) {
  const std::int64_t per_row = static_cast<std::int64_t>(inputs) + 2;
  return {i / per_row, static_cast<int>(i % per_row)};
}

std::vector<double> saltelli_point(const std::vector<double>& base, int block) {
  const std::size_t k = base.size() / 2;
  const auto b = static_cast<std::size_t>(block);
  if (b == k + 1) return {base.begin() + static_cast<std::ptrdiff_t>(k), base.end()};
  std::vector<double> u(base.begin(), base.begin() + static_cast<std::ptrdiff_t>(k));
  if (b >= 1 && b <= k) u[b - 1] = base[k + b - 1];
  return u;
}

std::vector<std::vector<double>> saltelli_design(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b) {
  if (a.size() != b.size()) throw std::invalid_argument("saltelli_design: A and B have different numbers of rows");
  std::vector<std::vector<double>> points;
  if (a.empty()) return points;
  const int k = static_cast<int>(a[0].size());
  points.reserve(static_cast<std::size_t>(saltelli_points(static_cast<std::int64_t>(a.size()), k)));
  for (std::size_t j = 0; j < a.size(); ++j) {
    if (a[j].size() != a[0].size() || b[j].size() != a[0].size())
      throw std::invalid_argument("saltelli_design: rows of A and B differ in dimension");
    std::vector<double> base = a[j];
    base.insert(base.end(), b[j].begin(), b[j].end());
    for (int block = 0; block < k + 2; ++block) points.push_back(saltelli_point(base, block));
  }
  return points;
}

std::vector<double> sobol_sequence_point(std::uint64_t index, int dimension) {
  std::vector<double> u(static_cast<std::size_t>(dimension), 0.0);
  if (index == 0) return u;  // Boost's engine starts after the origin
  boost::random::sobol engine(static_cast<std::size_t>(dimension));
  engine.seed(index - 1);
  for (double& x : u) x = static_cast<double>(engine()) * 0x1.0p-64;
  return u;
}

std::vector<std::vector<double>> saltelli_design_sobol(std::int64_t base_rows, int inputs, std::uint64_t skip) {
  const auto k = static_cast<std::size_t>(inputs);
  std::vector<std::vector<double>> a, b;
  a.reserve(static_cast<std::size_t>(base_rows));
  b.reserve(static_cast<std::size_t>(base_rows));
  boost::random::sobol engine(2 * k);
  std::uint64_t next = skip;  // the Sobol index of the engine's next point (the origin aside)
  if (skip > 0) engine.seed(skip - 1);
  for (std::int64_t j = 0; j < base_rows; ++j, ++next) {
    std::vector<double> p(2 * k, 0.0);
    if (next > 0)
      for (double& x : p) x = static_cast<double>(engine()) * 0x1.0p-64;
    a.emplace_back(p.begin(), p.begin() + static_cast<std::ptrdiff_t>(k));
    b.emplace_back(p.begin() + static_cast<std::ptrdiff_t>(k), p.end());
  }
  return saltelli_design(a, b);
}

// ---- the estimators ----

namespace {

// SplitMix64 (Steele, Lea and Flood 2014): the resamples' stream, the same on every platform.
std::uint64_t splitmix64_next(std::uint64_t& state) {
  std::uint64_t x = (state += 0x9E3779B97F4A7C15ull);
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
// A row in [0, n): x mod n (its bias, below n / 2^64, is nothing here).
std::int64_t row_below(std::uint64_t x, std::int64_t n) { return static_cast<std::int64_t>(x % static_cast<std::uint64_t>(n)); }

// The estimates from the rows listed in `rows` (each row of y, centred): S_i, ST_i and ST_i - S_i per
// input, and Var(Y). Returns false when Var(Y) is 0 over those rows.
struct Estimates {
  std::vector<double> first, total;
  double mean = 0, variance = 0;
};
bool estimate(const std::vector<double>& y, int k, const std::vector<std::int64_t>& rows, Estimates& e) {
  const std::size_t per_row = static_cast<std::size_t>(k) + 2;
  const auto n = static_cast<double>(rows.size());
  // Var(Y) over the A and B values, in two passes (the mean, then the squares about it).
  double sum = 0;
  for (std::int64_t j : rows) {
    const double* r = &y[static_cast<std::size_t>(j) * per_row];
    sum += r[0] + r[k + 1];
  }
  e.mean = sum / (2 * n);
  double squares = 0;
  for (std::int64_t j : rows) {
    const double* r = &y[static_cast<std::size_t>(j) * per_row];
    squares += (r[0] - e.mean) * (r[0] - e.mean) + (r[k + 1] - e.mean) * (r[k + 1] - e.mean);
  }
  e.variance = squares / (2 * n);
  e.first.assign(static_cast<std::size_t>(k), 0.0);
  e.total.assign(static_cast<std::size_t>(k), 0.0);
  if (!(e.variance > 0.0)) return false;
  for (int i = 0; i < k; ++i) {
    double v = 0, vt = 0;
    for (std::int64_t j : rows) {
      const double* r = &y[static_cast<std::size_t>(j) * per_row];
      const double fa = r[0], fab = r[1 + i], fb = r[k + 1];
      v += fb * (fab - fa);           // Saltelli et al. (2010), Table 2 (b)
      vt += (fa - fab) * (fa - fab);  // Jansen (1999), Table 2 (f)
    }
    e.first[static_cast<std::size_t>(i)] = v / n / e.variance;
    e.total[static_cast<std::size_t>(i)] = vt / (2 * n) / e.variance;
  }
  return true;
}

}  // namespace

SobolIndices sobol_indices(const std::vector<double>& y, int inputs, const SobolOptions& options) {
  if (inputs < 1) throw std::invalid_argument("sobol_indices: at least one input");
  const std::size_t per_row = static_cast<std::size_t>(inputs) + 2;
  if (y.size() % per_row != 0) throw std::invalid_argument("sobol_indices: the values are not N (k + 2) (Saltelli's design)");
  const auto n = static_cast<std::int64_t>(y.size() / per_row);
  if (n < 2) throw std::invalid_argument("sobol_indices: fewer than 2 rows");
  if (!(options.confidence > 0.0 && options.confidence < 1.0)) throw std::invalid_argument("sobol_indices: confidence outside (0, 1)");
  if (options.resamples < 2) throw std::invalid_argument("sobol_indices: fewer than 2 bootstrap resamples");
  for (double v : y)
    if (!std::isfinite(v)) throw std::invalid_argument("sobol_indices: a value that is not a finite number");

  // Centred by the mean of every value, as SALib does (its first-order estimator is not shift-invariant).
  double total = 0;
  for (double v : y) total += v;
  const double centre = total / static_cast<double>(y.size());
  std::vector<double> yc(y.size());
  for (std::size_t i = 0; i < y.size(); ++i) yc[i] = y[i] - centre;

  SobolIndices r;
  r.inputs = inputs;
  r.rows = n;
  r.confidence = options.confidence;
  r.resamples = options.resamples;
  const auto k = static_cast<std::size_t>(inputs);
  r.first.resize(k);
  r.total.resize(k);
  r.interaction.resize(k);

  std::vector<std::int64_t> rows(static_cast<std::size_t>(n));
  for (std::int64_t j = 0; j < n; ++j) rows[static_cast<std::size_t>(j)] = j;
  Estimates e;
  r.defined = estimate(yc, inputs, rows, e);
  r.mean = e.mean + centre;
  r.variance = e.variance;
  if (!r.defined) return r;
  for (std::size_t i = 0; i < k; ++i) {
    r.first[i].estimate = e.first[i];
    r.total[i].estimate = e.total[i];
    r.interaction[i].estimate = e.total[i] - e.first[i];
  }

  // The bootstrap: sums and sums of squares of each estimate over the resamples. A resample whose A and
  // B values are all equal (possible only for tiny N) has no variance to share: it is skipped.
  std::vector<double> s1(3 * k, 0.0), s2(3 * k, 0.0);
  int used = 0;
  std::uint64_t state = options.seed;
  Estimates b;
  for (int m = 0; m < options.resamples; ++m) {
    for (std::int64_t& j : rows) j = row_below(splitmix64_next(state), n);
    if (!estimate(yc, inputs, rows, b)) continue;
    ++used;
    for (std::size_t i = 0; i < k; ++i) {
      const double values[3] = {b.first[i], b.total[i], b.total[i] - b.first[i]};
      for (std::size_t c = 0; c < 3; ++c) {
        s1[c * k + i] += values[c];
        s2[c * k + i] += values[c] * values[c];
      }
    }
  }
  if (used < 2) return r;  // no spread to measure: the intervals stay points
  const double z = boost::math::quantile(boost::math::normal(), 0.5 + options.confidence / 2.0);
  const double u = used;
  for (std::size_t c = 0; c < 3; ++c) {
    std::vector<SobolInterval>& out = c == 0 ? r.first : c == 1 ? r.total : r.interaction;
    for (std::size_t i = 0; i < k; ++i) {
      const double mean = s1[c * k + i] / u;
      const double var = std::max(0.0, (s2[c * k + i] - u * mean * mean) / (u - 1.0));
      out[i].half_width = z * std::sqrt(var);
    }
  }
  return r;
}

// ---- which inputs matter ----

std::vector<InputImportance> input_importance(const SobolIndices& indices, const std::vector<std::optional<double>>& rank_correlations,
                                              double threshold) {
  std::vector<InputImportance> out(static_cast<std::size_t>(indices.inputs));
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (indices.defined) {
      out[i].first_order = indices.first[i].low() > threshold;
      out[i].total = indices.total[i].low() > threshold;
      out[i].interactions = indices.interaction[i].low() > threshold;
    }
    if (i < rank_correlations.size() && rank_correlations[i]) out[i].rank = *rank_correlations[i] * *rank_correlations[i] >= threshold;
  }
  return out;
}

namespace {
std::string join(const std::vector<std::string>& items) {
  if (items.empty()) return "none";
  std::string s;
  for (std::size_t i = 0; i < items.size(); ++i) s += (i == 0 ? "" : i + 1 == items.size() ? " and " : ", ") + items[i];
  return s;
}
std::string format_threshold(double t) { return platform::significant(t, 6); }
}  // namespace

std::string describe_importance(const std::vector<std::string>& names, const std::vector<InputImportance>& importance, double threshold) {
  std::vector<std::string> by_sobol, by_rank, only_sobol, only_rank;
  bool any_rank = false;
  for (std::size_t i = 0; i < importance.size() && i < names.size(); ++i) {
    const InputImportance& m = importance[i];
    const bool sobol = m.first_order || m.total || m.interactions;
    if (sobol) {
      const char* how = m.first_order && m.interactions ? "alone and through interactions"
                        : m.first_order                 ? "alone"
                        : m.interactions                ? "through interactions only"
                                                        : "in total";
      by_sobol.push_back(names[i] + " (" + how + ")");
    }
    if (m.rank) {
      any_rank = true;
      if (*m.rank) by_rank.push_back(names[i]);
      if (sobol && !*m.rank) only_sobol.push_back(names[i]);
      if (!sobol && *m.rank) only_rank.push_back(names[i]);
    }
  }
  const std::string t = format_threshold(threshold);
  std::string s = "by Sobol indices (interval above " + t + "): " + join(by_sobol);
  if (any_rank) {
    s += "; by Spearman's rank correlation (rho^2 >= " + t + "): " + join(by_rank);
    if (!only_sobol.empty())
      s += "; the rank correlation misses " + join(only_sobol) + " (an effect that is not monotone, or an interaction)";
    if (!only_rank.empty()) s += "; only the rank correlation finds " + join(only_rank) + " (its Sobol interval reaches below " + t + ")";
  }
  return s;
}

}  // namespace moreau::scene
