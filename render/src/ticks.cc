// Ticks, limits, mapping and decimation (layout.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "moreau/platform/number_text.h"
#include "moreau/render/layout.h"

namespace moreau::render {
namespace {

int count_multiples(double lo, double hi, double step) {
  const double eps = 1e-9;
  const double first = std::ceil(lo / step - eps);
  const double last = std::floor(hi / step + eps);
  return static_cast<int>(std::max(0.0, last - first + 1));
}

// Mantissa with trailing zeros removed: 2.50 -> "2.5", 3.00 -> "3".
std::string trim_zeros(std::string s) {
  if (s.find('.') == std::string::npos) return s;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s;
}

// Labels of 1-2-5 ticks on a short log axis: plain ("0.002"), or as powers of ten ("5×10⁻⁵"), one
// notation for every tick of an axis (log_ticks chooses).
std::string log_label(double m, int k, bool plain) {
  if (plain) return platform::significant(m * std::pow(10.0, k), 6);
  if (m == 1) return decade_label(k);
  return std::to_string(static_cast<int>(m)) + "\u00D7" + decade_label(k);
}

}  // namespace

double nice_step(double lo, double hi, int max_ticks) {
  max_ticks = std::max(max_ticks, 2);
  const double range = hi - lo;
  if (!(range > 0) || !std::isfinite(range)) return 1.0;
  const double raw = range / (max_ticks - 1);
  double base = std::pow(10.0, std::floor(std::log10(raw)));
  for (int guard = 0; guard < 8; ++guard, base *= 10) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double step = m * base;
      if (count_multiples(lo, hi, step) <= max_ticks) return step;
    }
  }
  return range;
}

std::string format_tick(double v, double step, double magnitude) {
  const int step_exp = static_cast<int>(std::floor(std::log10(step) + 1e-9));
  if (std::abs(v) < step * 1e-9) v = 0;
  const double mag = std::abs(v);
  if (magnitude <= 0) magnitude = mag;
  if (magnitude >= 1e5 || step < 1e-4) {
    if (mag == 0) return "0";
    const int e = static_cast<int>(std::floor(std::log10(mag) + 1e-12));
    const int decimals = std::clamp(e - step_exp, 0, 15);
    std::string mant = trim_zeros(platform::fixed(v / std::pow(10.0, e), decimals));
    if (mant == "10" || mant == "-10") {  // rounding carried into the next decade
      mant = mant[0] == '-' ? "-1" : "1";
      return mant + "e" + std::to_string(e + 1);
    }
    return mant + "e" + std::to_string(e);
  }
  const int decimals = std::clamp(-step_exp, 0, 10);
  return platform::fixed(v, decimals);
}

std::vector<Tick> linear_ticks(double lo, double hi, int max_ticks) {
  std::vector<Tick> ticks;
  if (!(hi > lo)) return ticks;
  const double step = nice_step(lo, hi, max_ticks);
  const double eps = 1e-9;
  const double first = std::ceil(lo / step - eps);
  const double last = std::floor(hi / step + eps);
  const auto count = static_cast<long>(std::min(last - first + 1, 1000.0));
  const double magnitude = std::max(std::abs(first * step), std::abs(last * step));
  for (long j = 0; j < count; ++j) {
    double v = (first + static_cast<double>(j)) * step;
    if (std::abs(v) < step * 1e-9) v = 0;
    ticks.push_back({v, format_tick(v, step, magnitude), true});
  }
  return ticks;
}

std::string decade_label(int exponent) {
  static const char* const sup[] = {"\u2070", "\u00B9", "\u00B2", "\u00B3", "\u2074", "\u2075", "\u2076", "\u2077", "\u2078", "\u2079"};
  std::string s = "10";
  if (exponent < 0) s += "\u207B";
  const std::string digits = std::to_string(std::abs(exponent));
  for (char c : digits) s += sup[c - '0'];
  return s;
}

std::vector<Tick> log_ticks(double lo, double hi, int max_major) {
  std::vector<Tick> ticks;
  if (!(lo > 0) || !(hi > lo)) return ticks;
  max_major = std::max(max_major, 2);
  const double a = std::log10(lo), b = std::log10(hi);
  const int kmin = static_cast<int>(std::ceil(a - 1e-9));
  const int kmax = static_cast<int>(std::floor(b + 1e-9));
  const int decades = kmax - kmin + 1;
  if (decades >= 2) {
    const int step = (decades + max_major - 1) / max_major;
    for (int k = static_cast<int>(std::floor(a)); k <= kmax; ++k) {
      const double p = std::pow(10.0, k);
      if (k >= kmin) {
        const bool major = ((k % step) + step) % step == 0;
        ticks.push_back({p, major ? decade_label(k) : std::string(), major});
      }
      if (step == 1) {
        for (int m = 2; m <= 9; ++m) {
          const double v = m * p;
          if (v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12)) ticks.push_back({v, std::string(), false});
        }
      }
    }
    std::sort(ticks.begin(), ticks.end(), [](const Tick& x, const Tick& y) { return x.value < y.value; });
    return ticks;
  }
  // Less than two decades: 1-2-5 values, labelled plainly when every one of them reads well so (in
  // [1e-3, 1e4)), else every one as a power of ten: never "0.001" beside "5×10⁻⁴" on one axis. Else
  // linear ticks.
  std::vector<std::pair<double, int>> marks;  // (m, k) of m 10^k
  for (int k = static_cast<int>(std::floor(a)); k <= static_cast<int>(std::ceil(b)); ++k) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double v = m * std::pow(10.0, k);
      if (v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12)) marks.emplace_back(m, k);
    }
  }
  const bool plain = std::all_of(marks.begin(), marks.end(), [](const auto& mk) {
    const double v = mk.first * std::pow(10.0, mk.second);
    return v >= 1e-3 && v < 1e4;
  });
  for (const auto& [m, k] : marks) ticks.push_back({m * std::pow(10.0, k), log_label(m, k, plain), true});
  if (ticks.size() >= 2 && static_cast<int>(ticks.size()) <= max_major + 1) return ticks;
  return linear_ticks(lo, hi, max_major);
}

Limits auto_limits(double data_min, double data_max, Scale scale, double padding) {
  if (scale == Scale::log) {
    double a = std::log10(data_min), b = std::log10(data_max);
    if (!(b - a > 1e-12)) {
      a -= 0.5;
      b += 0.5;
    } else {
      const double pad = padding * (b - a);
      a -= pad;
      b += pad;
    }
    return {std::pow(10.0, a), std::pow(10.0, b)};
  }
  double lo = data_min, hi = data_max;
  const double scale_ref = std::max(std::abs(lo), std::abs(hi));
  if (!(hi - lo > 1e-12 * scale_ref) || hi - lo == 0) {
    const double w = scale_ref > 0 ? 0.1 * scale_ref : 1.0;
    return {lo - w, hi + w};
  }
  const double pad = padding * (hi - lo);
  return {lo - pad, hi + pad};
}

double AxisMap::to_pixel(double v) const {
  double a = lo, b = hi, x = v;
  if (scale == Scale::log) {
    constexpr double tiny = std::numeric_limits<double>::min();
    a = std::log10(lo);
    b = std::log10(hi);
    x = std::log10(std::max(v, tiny));
  }
  return pixel_lo + (x - a) / (b - a) * (pixel_hi - pixel_lo);
}

double AxisMap::from_pixel(double p) const {
  const double t = (p - pixel_lo) / (pixel_hi - pixel_lo);
  if (scale == Scale::log) {
    const double a = std::log10(lo), b = std::log10(hi);
    return std::pow(10.0, a + t * (b - a));
  }
  return lo + t * (hi - lo);
}

namespace {

// One pass of run decimation: runs of consecutive points whose `key` coordinate falls in the same
// pixel keep their first, extreme `other` values, and last point.
std::vector<std::size_t> decimate_pass(std::span<const double> key, std::span<const double> other, const std::vector<std::size_t>& idx) {
  std::vector<std::size_t> out;
  out.reserve(std::min<std::size_t>(idx.size(), 4096));
  const std::size_t n = idx.size();
  std::size_t i = 0;
  while (i < n) {
    const double cell = std::floor(key[idx[i]]);
    std::size_t j = i, jmin = i, jmax = i;
    while (j + 1 < n && std::floor(key[idx[j + 1]]) == cell) {
      ++j;
      if (other[idx[j]] < other[idx[jmin]]) jmin = j;
      if (other[idx[j]] > other[idx[jmax]]) jmax = j;
    }
    std::size_t keep[4] = {i, jmin, jmax, j};
    std::sort(keep, keep + 4);
    for (int k = 0; k < 4; ++k)
      if (k == 0 || keep[k] != keep[k - 1]) out.push_back(idx[keep[k]]);
    i = j + 1;
  }
  return out;
}

}  // namespace

std::vector<std::size_t> decimate(std::span<const double> px, std::span<const double> py, bool by_rows) {
  const std::size_t n = std::min(px.size(), py.size());
  std::vector<std::size_t> idx(n);
  for (std::size_t i = 0; i < n; ++i) idx[i] = i;
  idx = decimate_pass(px, py, idx);
  if (by_rows) idx = decimate_pass(py, px, idx);
  return idx;
}

}  // namespace moreau::render
