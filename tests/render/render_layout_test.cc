// render/: ticks, limits, mapping, decimation, validation and layout (no OpenGL involved).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "moreau/render/figure.h"
#include "moreau/render/layout.h"

using namespace moreau::render;
using ::testing::HasSubstr;

namespace {

std::vector<double> values(const std::vector<Tick>& ticks, bool major_only = true) {
  std::vector<double> v;
  for (const Tick& t : ticks)
    if (t.major || !major_only) v.push_back(t.value);
  return v;
}

std::vector<std::string> labels(const std::vector<Tick>& ticks) {
  std::vector<std::string> v;
  for (const Tick& t : ticks)
    if (t.major) v.push_back(t.label);
  return v;
}

Figure one_series_figure(std::vector<double> x, std::vector<double> y) {
  Figure f;
  f.width_px = 400;
  f.height_px = 300;
  Panel p;
  p.title = "main";
  Series s;
  s.label = "s0";
  s.x = std::move(x);
  s.y = std::move(y);
  p.series.push_back(std::move(s));
  f.panels.push_back(std::move(p));
  return f;
}

// Runs validate() and returns the FigureError message ("" if it did not throw).
std::string validation_error(const Figure& f) {
  try {
    validate(f);
  } catch (const FigureError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(RenderTicks, LinearUnitIntervalUsesOneTwoFiveSteps) {
  const auto ticks = linear_ticks(0, 1, 6);
  EXPECT_THAT(values(ticks), ::testing::Pointwise(::testing::DoubleNear(1e-12), {0.0, 0.2, 0.4, 0.6, 0.8, 1.0}));
  EXPECT_THAT(labels(ticks), ::testing::ElementsAre("0.0", "0.2", "0.4", "0.6", "0.8", "1.0"));
  EXPECT_DOUBLE_EQ(nice_step(0, 1, 11), 0.1);
  EXPECT_DOUBLE_EQ(nice_step(0, 1, 3), 0.5);
  EXPECT_DOUBLE_EQ(nice_step(0, 100, 6), 20);
  EXPECT_DOUBLE_EQ(nice_step(-3, 7, 4), 5);
}

TEST(RenderTicks, LinearStepsAreOneTwoFiveTimesAPowerOfTen) {
  const double ranges[][2] = {{0, 1}, {-5.3, 3.9}, {1e-7, 3e-7}, {120, 9870}, {-1e6, 1e6}, {0.999, 1.001}};
  for (const auto& r : ranges) {
    for (int max_ticks = 2; max_ticks <= 10; ++max_ticks) {
      const double step = nice_step(r[0], r[1], max_ticks);
      const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
      EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 || std::abs(mantissa - 5) < 1e-9)
          << "step " << step << " for [" << r[0] << ", " << r[1] << "]";
      const auto ticks = linear_ticks(r[0], r[1], max_ticks);
      EXPECT_LE(static_cast<int>(ticks.size()), max_ticks);
      EXPECT_GE(ticks.size(), 1u);
      for (const Tick& t : ticks) {
        EXPECT_GE(t.value, r[0] - 1e-9 * std::abs(r[1] - r[0]));
        EXPECT_LE(t.value, r[1] + 1e-9 * std::abs(r[1] - r[0]));
        EXPECT_FALSE(t.label.empty());
      }
    }
  }
}

TEST(RenderTicks, LabelFormats) {
  EXPECT_EQ(format_tick(0.5, 0.5), "0.5");
  EXPECT_EQ(format_tick(0, 0.5), "0.0");
  EXPECT_EQ(format_tick(-2, 1), "-2");
  EXPECT_EQ(format_tick(1500, 500), "1500");
  EXPECT_EQ(format_tick(2.5e-5, 5e-6), "2.5e-5");
  EXPECT_EQ(format_tick(2e6, 1e6), "2e6");
  EXPECT_EQ(format_tick(0, 5e-8, 1e-7), "0");
  EXPECT_EQ(format_tick(5e4, 5e4, 2e5), "5e4");  // the axis reaches 2e5: one style for all labels
  EXPECT_EQ(format_tick(1e15 + 2e4, 1e4), "1.00000000002e15");
  EXPECT_EQ(decade_label(-3), "10\u207B\u00B3");
  EXPECT_EQ(decade_label(0), "10\u2070");
  EXPECT_EQ(decade_label(12), "10\u00B9\u00B2");
}

TEST(RenderTicks, LogAxisTicksAtDecades) {
  const auto ticks = log_ticks(1e-6, 1e2, 10);
  std::vector<double> expected;
  for (int k = -6; k <= 2; ++k) expected.push_back(std::pow(10.0, k));
  EXPECT_THAT(values(ticks), ::testing::Pointwise(::testing::DoubleNear(1e-20), expected));
  EXPECT_EQ(labels(ticks).front(), decade_label(-6));
  EXPECT_EQ(labels(ticks).back(), decade_label(2));
  // Minor ticks at 2..9 x 10^k between the decades, unlabelled.
  int minor = 0;
  for (const Tick& t : ticks) {
    if (t.major) continue;
    ++minor;
    EXPECT_TRUE(t.label.empty());
    const double m = t.value / std::pow(10.0, std::floor(std::log10(t.value) + 1e-12));
    EXPECT_NEAR(m, std::round(m), 1e-9);
  }
  EXPECT_EQ(minor, 8 * 8);
}

TEST(RenderTicks, LogAxisWithManyDecadesLabelsEveryNth) {
  const auto ticks = log_ticks(1e-12, 1e3, 6);
  const auto major = values(ticks);
  ASSERT_GE(major.size(), 2u);
  EXPECT_LE(major.size(), 6u);
  for (double v : major) {
    const double k = std::log10(v);
    EXPECT_NEAR(k, std::round(k), 1e-9);
    EXPECT_EQ(static_cast<int>(std::round(k)) % 3, 0);
  }
}

TEST(RenderTicks, LogAxisNarrowRangeFallsBackToOneTwoFive) {
  const auto ticks = log_ticks(2, 60, 8);
  EXPECT_THAT(values(ticks), ::testing::Pointwise(::testing::DoubleNear(1e-12), {2.0, 5.0, 10.0, 20.0, 50.0}));
  EXPECT_THAT(labels(ticks), ::testing::ElementsAre("2", "5", "10", "20", "50"));
}

// A short log axis that reaches below 1e-3: every label a power of ten, none plain beside them.
TEST(RenderTicks, LogAxisLabelsUseOneNotation) {
  const auto ticks = log_ticks(4e-4, 6e-3, 8);
  EXPECT_THAT(values(ticks), ::testing::Pointwise(::testing::DoubleNear(1e-15), {5e-4, 1e-3, 2e-3, 5e-3}));
  EXPECT_THAT(labels(ticks),
              ::testing::ElementsAre("5\u00D710\u207B\u2074", "10\u207B\u00B3", "2\u00D710\u207B\u00B3", "5\u00D710\u207B\u00B3"));
}

TEST(RenderLimits, AutoLimitsPadAndWidenDegenerateRanges) {
  const Limits a = auto_limits(0, 10, Scale::linear, 0.05);
  EXPECT_DOUBLE_EQ(a.lo, -0.5);
  EXPECT_DOUBLE_EQ(a.hi, 10.5);
  const Limits b = auto_limits(3, 3, Scale::linear, 0.05);
  EXPECT_LT(b.lo, 3);
  EXPECT_GT(b.hi, 3);
  const Limits c = auto_limits(0, 0, Scale::linear, 0.05);
  EXPECT_LT(c.lo, 0);
  EXPECT_GT(c.hi, 0);
  const Limits d = auto_limits(1e-4, 1e2, Scale::log, 0.1);  // 6 decades, 0.6 decade each side
  EXPECT_NEAR(std::log10(d.lo), -4.6, 1e-12);
  EXPECT_NEAR(std::log10(d.hi), 2.6, 1e-12);
  const Limits e = auto_limits(5, 5, Scale::log, 0.1);
  EXPECT_LT(e.lo, 5);
  EXPECT_GT(e.hi, 5);
  EXPECT_GT(e.lo, 0);
}

TEST(RenderMapping, LinearAndLogMapsRoundTrip) {
  const AxisMap x{Scale::linear, 0, 1, 100, 500};
  EXPECT_DOUBLE_EQ(x.to_pixel(0), 100);
  EXPECT_DOUBLE_EQ(x.to_pixel(1), 500);
  EXPECT_DOUBLE_EQ(x.to_pixel(0.25), 200);
  EXPECT_DOUBLE_EQ(x.from_pixel(300), 0.5);
  const AxisMap y{Scale::log, 1e-3, 1e1, 400, 0};  // y axis: larger values higher up
  EXPECT_DOUBLE_EQ(y.to_pixel(1e-3), 400);
  EXPECT_DOUBLE_EQ(y.to_pixel(1e1), 0);
  EXPECT_NEAR(y.to_pixel(1e-1), 200, 1e-9);
  EXPECT_NEAR(y.from_pixel(100), 1, 1e-12);
}

TEST(RenderDecimate, DenseSeriesKeepsAtMostFourVerticesPerColumnAndItsExtremes) {
  const std::size_t n = 100000;
  std::vector<double> px(n), py(n);
  for (std::size_t i = 0; i < n; ++i) {
    px[i] = 10 + 1000.0 * static_cast<double>(i) / (n - 1);
    py[i] = 300 + 200 * std::sin(0.001 * static_cast<double>(i)) + 30 * std::sin(0.7 * static_cast<double>(i));
  }
  const auto kept = decimate(px, py);
  EXPECT_LE(kept.size(), 4u * 1001u);
  EXPECT_GE(kept.size(), 2u * 1000u);
  EXPECT_EQ(kept.front(), 0u);
  EXPECT_EQ(kept.back(), n - 1);
  EXPECT_TRUE(std::is_sorted(kept.begin(), kept.end()));
  // Per column, the kept vertices span the same rows as the full series.
  std::vector<double> lo(1100, 1e9), hi(1100, -1e9), klo(1100, 1e9), khi(1100, -1e9);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<std::size_t>(px[i]);
    lo[c] = std::min(lo[c], py[i]);
    hi[c] = std::max(hi[c], py[i]);
  }
  for (std::size_t i : kept) {
    const auto c = static_cast<std::size_t>(px[i]);
    klo[c] = std::min(klo[c], py[i]);
    khi[c] = std::max(khi[c], py[i]);
  }
  EXPECT_EQ(lo, klo);
  EXPECT_EQ(hi, khi);
}

TEST(RenderDecimate, NonMonotonicCurveAlsoReducedAlongRows) {
  const std::size_t n = 50000;
  std::vector<double> px(n), py(n);
  for (std::size_t i = 0; i < n; ++i) {  // a circle drawn 10 times
    const double a = 20 * std::numbers::pi * static_cast<double>(i) / n;
    px[i] = 200 + 100 * std::cos(a);
    py[i] = 200 + 100 * std::sin(a);
  }
  const auto kept = decimate(px, py, true);
  EXPECT_LT(kept.size(), n / 4);
  EXPECT_EQ(kept.front(), 0u);
  EXPECT_EQ(kept.back(), n - 1);
}

TEST(RenderValidation, AcceptsAGoodFigure) { EXPECT_EQ(validation_error(one_series_figure({0, 1, 2}, {1, 2, 3})), ""); }

TEST(RenderValidation, EmptySeries) {
  const std::string msg = validation_error(one_series_figure({}, {}));
  EXPECT_THAT(msg, HasSubstr("panel 0 'main'"));
  EXPECT_THAT(msg, HasSubstr("series 0 's0'"));
  EXPECT_THAT(msg, HasSubstr("empty"));
}

TEST(RenderValidation, SizeMismatch) {
  const std::string msg = validation_error(one_series_figure({0, 1, 2}, {1, 2}));
  EXPECT_THAT(msg, HasSubstr("series 0 's0'"));
  EXPECT_THAT(msg, HasSubstr("x has 3 values but y has 2"));
}

TEST(RenderValidation, NanAndInf) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  std::string msg = validation_error(one_series_figure({0, 1, 2}, {1, nan, 3}));
  EXPECT_THAT(msg, HasSubstr("y[1] is nan"));
  EXPECT_THAT(msg, HasSubstr("'s0'"));
  msg = validation_error(one_series_figure({0, inf, 2}, {1, 2, 3}));
  EXPECT_THAT(msg, HasSubstr("x[1] is inf"));
}

TEST(RenderValidation, BadFigureSize) {
  Figure f = one_series_figure({0, 1}, {0, 1});
  f.width_px = 10;
  EXPECT_THAT(validation_error(f), HasSubstr("figure width 10 px is outside [64, 8192]"));
  f.width_px = 400;
  f.height_px = 9000;
  EXPECT_THAT(validation_error(f), HasSubstr("figure height 9000 px"));
  f.height_px = 300;
  f.panels.clear();
  EXPECT_THAT(validation_error(f), HasSubstr("no panels"));
}

TEST(RenderValidation, NonPositiveOnLogAxis) {
  Figure f = one_series_figure({0, 1, 2}, {1, 0, 3});
  f.panels[0].y_axis.scale = Scale::log;
  const std::string msg = validation_error(f);
  EXPECT_THAT(msg, HasSubstr("y[1] = 0 is not positive"));
  EXPECT_THAT(msg, HasSubstr("logarithmic"));
  EXPECT_THAT(msg, HasSubstr("panel 0 'main', series 0 's0'"));
  f.panels[0].series[0].y = {1, 2, 3};
  f.panels[0].x_axis.scale = Scale::log;
  EXPECT_THAT(validation_error(f), HasSubstr("x[0] = 0 is not positive"));
}

TEST(RenderValidation, BadLimitsAndColour) {
  Figure f = one_series_figure({0, 1}, {0, 1});
  f.panels[0].y_axis.min = 2;
  f.panels[0].y_axis.max = 1;
  EXPECT_THAT(validation_error(f), HasSubstr("y axis: minimum 2 is not below maximum 1"));
  f.panels[0].y_axis = Axis{};
  f.panels[0].x_axis.scale = Scale::log;
  f.panels[0].x_axis.min = -1;
  f.panels[0].series[0].x = {1, 2};
  EXPECT_THAT(validation_error(f), HasSubstr("log scale needs a positive minimum"));
  f.panels[0].x_axis = Axis{};
  f.panels[0].series[0].color = -1;
  EXPECT_THAT(validation_error(f), HasSubstr("colour index -1"));
}

TEST(RenderLayout, PanelsStackAndShareTheirPlotColumns) {
  Figure f = one_series_figure({0, 1, 2}, {1, 2, 3});
  f.width_px = 900;
  f.height_px = 700;
  f.title = "Two panels";
  Panel second = f.panels[0];
  second.title = "second";
  second.y_label = "a long label";
  second.series[0].y = {-1234.5, 0, 98765.4};  // wider tick labels
  f.panels.push_back(second);
  const FigureLayout l = compute_layout(f);
  ASSERT_EQ(l.panels.size(), 2u);
  const Rect& a = l.panels[0].plot;
  const Rect& b = l.panels[1].plot;
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.w, b.w);
  EXPECT_GT(a.y, 0);
  EXPECT_LT(a.bottom(), b.y);
  EXPECT_LT(b.bottom(), f.height_px);
  EXPECT_LT(a.right(), f.width_px);
  EXPECT_GT(a.h, 150);
  // The mapping sends the limits to the plot edges.
  EXPECT_DOUBLE_EQ(l.panels[0].x.to_pixel(l.panels[0].x.lo), a.x);
  EXPECT_DOUBLE_EQ(l.panels[0].x.to_pixel(l.panels[0].x.hi), a.right());
  EXPECT_DOUBLE_EQ(l.panels[0].y.to_pixel(l.panels[0].y.lo), a.bottom());
  EXPECT_DOUBLE_EQ(l.panels[0].y.to_pixel(l.panels[0].y.hi), a.y);
}

TEST(RenderLayout, ExplicitLimitsAreKept) {
  Figure f = one_series_figure({0, 1}, {0.5, 0.5});
  f.panels[0].x_axis.min = 0;
  f.panels[0].x_axis.max = 1;
  f.panels[0].y_axis.min = 0;
  f.panels[0].y_axis.max = 1;
  const FigureLayout l = compute_layout(f);
  EXPECT_EQ(l.panels[0].x.lo, 0);
  EXPECT_EQ(l.panels[0].x.hi, 1);
  EXPECT_EQ(l.panels[0].y.lo, 0);
  EXPECT_EQ(l.panels[0].y.hi, 1);
  EXPECT_EQ(labels(l.panels[0].y_ticks).front(), "0.0");
  EXPECT_EQ(labels(l.panels[0].y_ticks).back(), "1.0");
}

TEST(RenderLayout, TooManyPanelsForTheHeightThrows) {
  Figure f = one_series_figure({0, 1}, {0, 1});
  f.height_px = 200;
  f.panels.resize(6, f.panels[0]);
  try {
    compute_layout(f);
    FAIL() << "expected FigureError";
  } catch (const FigureError& e) {
    EXPECT_THAT(e.what(), HasSubstr("too small for 6 panel(s)"));
  }
}

TEST(RenderLayout, RangesBeyondDoublePrecisionAreRejected) {
  Figure f = one_series_figure({0, 1}, {-1e308, 1e308});
  try {
    compute_layout(f);
    FAIL() << "expected FigureError";
  } catch (const FigureError& e) {
    EXPECT_THAT(e.what(), HasSubstr("panel 0 'main', y axis: the range"));
    EXPECT_THAT(e.what(), HasSubstr("too wide"));
  }
  f = one_series_figure({0, 1}, {0, 1});
  f.panels[0].x_axis.min = 1e30;
  f.panels[0].x_axis.max = std::nextafter(1e30, 1e31);
  EXPECT_THROW(compute_layout(f), FigureError);
  // Far from the origin but resolvable: fine, and the ticks stay few.
  f.panels[0].x_axis.min = 1e15;
  f.panels[0].x_axis.max = 1e15 + 1e5;
  const FigureLayout l = compute_layout(f);
  EXPECT_GE(l.panels[0].x_ticks.size(), 1u);
  EXPECT_LE(l.panels[0].x_ticks.size(), 12u);
}

TEST(RenderLayout, XTickLabelsDoNotOverlap) {
  Figure f = one_series_figure({0, 123456.0}, {0, 1});
  f.width_px = 300;
  const FigureLayout l = compute_layout(f);
  const auto& ticks = l.panels[0].x_ticks;
  ASSERT_GE(ticks.size(), 2u);
  // Neighbouring labels are at least ~3 characters apart at this size.
  for (std::size_t i = 1; i < ticks.size(); ++i)
    EXPECT_GT(l.panels[0].x.to_pixel(ticks[i].value) - l.panels[0].x.to_pixel(ticks[i - 1].value), 40);
}

TEST(RenderPalette, DistinctColoursThatWrap) {
  const auto& p = palette();
  ASSERT_GE(p.size(), 6u);
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j) EXPECT_FALSE(p[i] == p[j]);
  EXPECT_EQ(palette_color(static_cast<int>(p.size())), p[0]);
  EXPECT_EQ(palette_color(1), p[1]);
}
