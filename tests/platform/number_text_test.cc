// The one number formatter (platform/include/moreau/platform/number_text.h), against independent
// references: std::strtod reads every shortest text back bit for bit; no text with one digit fewer reads
// back; glibc's printf (%.*g, %.*f, C locale) writes the same digits as significant() and fixed(); and the
// known texts of IEEE-754 binary64's landmarks (the smallest subnormal, DBL_MIN, DBL_MAX).
#include "moreau/platform/number_text.h"

#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

namespace moreau::platform {
namespace {

std::uint64_t bits_of(double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

double from_bits(std::uint64_t b) {
  double v;
  std::memcpy(&v, &b, sizeof v);
  return v;
}

double read_back(const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  EXPECT_EQ(*end, '\0') << "strtod stopped inside '" << text << "'";
  return v;
}

// The significant digits of a finite text as to_chars writes it: digits before any exponent, without
// the sign, the point and leading zeros ("0.000123" has 3, "1.5e+10" has 2, "100" has 3).
int significant_digits(const std::string& text) {
  int n = 0;
  bool leading = true;
  for (char c : text) {
    if (c == 'e') break;
    if (c < '0' || c > '9') continue;
    if (c == '0' && leading) continue;
    leading = false;
    ++n;
  }
  return n;
}

std::string printf_text(const char* format, int precision, double v) {
  char buf[400];
  std::snprintf(buf, sizeof buf, format, precision, v);
  return buf;
}

// Random bit patterns cover every exponent, subnormals included, uniformly (random doubles from a
// distribution would cluster around one scale).
TEST(NumberText, ShortestReadsBackBitForBitForRandomDoubles) {
  std::mt19937_64 rng(20240611);
  int checked = 0;
  for (int i = 0; i < 200000; ++i) {
    const double v = from_bits(rng());
    if (!std::isfinite(v)) continue;
    const std::string text = shortest(v);
    ASSERT_LE(text.size(), kShortestMaxChars) << text;
    ASSERT_EQ(bits_of(read_back(text)), bits_of(v)) << text;
    ++checked;
  }
  EXPECT_GT(checked, 199000);
}

// Shortest: with one significant digit fewer, even correctly rounded (printf's %.*e, the nearest such
// decimal), the text no longer reads back. Powers of two are left out: their lower neighbour is half as
// far as the upper one, so the nearest shorter decimal may fail where a farther one would not. So are
// whole numbers written out in full ("53165205877497296"): fewer characters than their exponent form,
// and every digit of them is written, significant or not.
TEST(NumberText, NoTextWithOneDigitFewerReadsBack) {
  std::mt19937_64 rng(7);
  int checked = 0;
  for (int i = 0; i < 50000; ++i) {
    const double v = from_bits(rng());
    if (!std::isfinite(v) || (bits_of(v) & ((std::uint64_t{1} << 52) - 1)) == 0) continue;
    const std::string text = shortest(v);
    if (text.find_first_of(".e") == std::string::npos) continue;
    ++checked;
    const int digits = significant_digits(text);
    if (digits < 2) continue;
    const std::string shorter = printf_text("%.*e", digits - 2, v);  // digits - 1 significant digits
    EXPECT_NE(bits_of(read_back(shorter)), bits_of(v)) << text << " vs " << shorter;
  }
  EXPECT_GT(checked, 45000);
}

TEST(NumberText, ShortestOfKnownValues) {
  EXPECT_EQ(shortest(0.1), "0.1");  // %.17g: 0.10000000000000001
  EXPECT_EQ(shortest(0.8), "0.8");  // %.17g: 0.80000000000000004
  EXPECT_EQ(shortest(0.1 + 0.2), "0.30000000000000004");
  EXPECT_EQ(shortest(1.0), "1");
  EXPECT_EQ(shortest(100.0), "100");
  EXPECT_EQ(shortest(-2.5), "-2.5");
  EXPECT_EQ(shortest(1e21), "1e+21");
  EXPECT_EQ(shortest(1e-7), "1e-07");
  EXPECT_EQ(shortest(123456.789), "123456.789");
  EXPECT_EQ(shortest(0.0), "0");
}

// IEEE-754 binary64's landmarks, whose shortest decimal forms are fixed by the format itself.
TEST(NumberText, ShortestOfSubnormalsAndTheExtremes) {
  const double min_subnormal = std::numeric_limits<double>::denorm_min();  // 2^-1074
  EXPECT_EQ(shortest(min_subnormal), "5e-324");
  EXPECT_EQ(shortest(-min_subnormal), "-5e-324");
  EXPECT_EQ(shortest(DBL_MIN), "2.2250738585072014e-308");                      // 2^-1022
  EXPECT_EQ(shortest(std::nextafter(DBL_MIN, 0.0)), "2.225073858507201e-308");  // the largest subnormal
  EXPECT_EQ(shortest(DBL_MAX), "1.7976931348623157e+308");
  EXPECT_EQ(shortest(-DBL_MIN).size(), kShortestMaxChars);  // the longest text there is
  for (const double v : {min_subnormal, 3 * min_subnormal, std::nextafter(DBL_MIN, 0.0), 1e-310, -4.9e-320})
    EXPECT_EQ(bits_of(read_back(shortest(v))), bits_of(v)) << shortest(v);
}

TEST(NumberText, NegativeZeroKeepsItsSign) {
  EXPECT_EQ(shortest(-0.0), "-0");
  EXPECT_TRUE(std::signbit(read_back(shortest(-0.0))));
  EXPECT_EQ(significant(-0.0, 6), "-0");
  EXPECT_EQ(fixed(-0.0, 2), "-0.00");
}

// One spelling of the values that are not finite, whatever their sign bit or payload (printf writes
// "-nan" for a NaN with the sign bit set), and strtod reads each back as what it names.
TEST(NumberText, NonFiniteValuesHaveOneSpelling) {
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  const double negative_nan = std::copysign(nan, -1.0), signaling = std::numeric_limits<double>::signaling_NaN();
  const double payload = from_bits(0x7ff0000000000001ull);  // NaN with the smallest payload
  for (const double v : {nan, negative_nan, signaling, payload, -payload}) {
    SCOPED_TRACE(bits_of(v));
    EXPECT_EQ(non_finite_text(v), "nan");
    EXPECT_EQ(shortest(v), "nan");
    EXPECT_EQ(significant(v, 10), "nan");
    EXPECT_EQ(fixed(v, 3), "nan");
  }
  EXPECT_EQ(shortest(inf), "inf");
  EXPECT_EQ(shortest(-inf), "-inf");
  EXPECT_EQ(significant(-inf, 6), "-inf");
  EXPECT_EQ(fixed(inf, 2), "inf");
  EXPECT_TRUE(std::isnan(read_back("nan")));
  EXPECT_EQ(read_back("inf"), inf);
  EXPECT_EQ(read_back("-inf"), -inf);
  EXPECT_EQ(non_finite_text(1.0), "");
  EXPECT_EQ(non_finite_text(DBL_MAX), "");
}

TEST(NumberText, SignificantDigitsOfKnownValues) {
  EXPECT_EQ(significant(1.0 / 3.0, 3), "0.333");
  EXPECT_EQ(significant(2.0 / 3.0, 6), "0.666667");
  EXPECT_EQ(significant(1e-5, 6), "1e-05");
  EXPECT_EQ(significant(0.0001, 6), "0.0001");  // exponent -4: still positional
  EXPECT_EQ(significant(1.5e10, 6), "1.5e+10");
  EXPECT_EQ(significant(123456.0, 3), "1.23e+05");
  EXPECT_EQ(significant(123456.0, 6), "123456");
  EXPECT_EQ(significant(100.0, 10), "100");
  EXPECT_EQ(significant(0.1, 17), "0.10000000000000001");
  EXPECT_EQ(significant(0.1, 10), "0.1");
  EXPECT_EQ(significant(2.5, 1), "2");  // exactly halfway: to even
  EXPECT_EQ(significant(3.5, 1), "4");
  EXPECT_EQ(significant(9.9999, 3), "10");
  EXPECT_EQ(significant(-1234.5678, 10), "-1234.5678");
  EXPECT_EQ(significant(1.0 / 3.0, 0), "0.3");  // as %.0g: one digit
  EXPECT_EQ(significant(0.1, 40), significant(0.1, 17));
}

TEST(NumberText, FixedDecimalsOfKnownValues) {
  EXPECT_EQ(fixed(2.0, 2), "2.00");
  EXPECT_EQ(fixed(-1.005, 2), "-1.00");  // -1.005 is -1.00499999999999989...
  EXPECT_EQ(fixed(0.125, 2), "0.12");    // exactly halfway: to even
  EXPECT_EQ(fixed(1e20, 0), "100000000000000000000");
  EXPECT_EQ(fixed(1.5, 0), "2");
  EXPECT_EQ(fixed(DBL_MAX, 17).size(), 309u + 1 + 17);
}

// glibc's printf is an independent implementation of the same two conversions.
TEST(NumberText, SignificantAndFixedWriteWhatPrintfWrites) {
  std::mt19937_64 rng(3);
  std::uniform_int_distribution<int> digits(1, 17), decimals(0, 17), exponent(-30, 30);
  std::uniform_real_distribution<double> mantissa(-10.0, 10.0);
  for (int i = 0; i < 20000; ++i) {
    const double v = from_bits(rng());
    if (!std::isfinite(v)) continue;
    const int d = digits(rng);
    ASSERT_EQ(significant(v, d), printf_text("%.*g", d, v)) << d;
  }
  for (int i = 0; i < 20000; ++i) {
    const double v = std::ldexp(mantissa(rng), exponent(rng));
    const int d = decimals(rng);
    ASSERT_EQ(fixed(v, d), printf_text("%.*f", d, v)) << d;
  }
}

TEST(NumberText, WriteShortestFillsABufferWithoutAllocating) {
  char buf[kShortestMaxChars];
  const double longest = -DBL_MIN;
  char* end = write_shortest(buf, buf + sizeof buf, longest);
  EXPECT_EQ(std::string(buf, end), "-2.2250738585072014e-308");
  end = write_shortest(buf, buf + sizeof buf, -std::numeric_limits<double>::infinity());
  EXPECT_EQ(std::string(buf, end), "-inf");
  // Too little room is an error, never a cut number.
  EXPECT_THROW(write_shortest(buf, buf + 3, 0.125), std::length_error);
  EXPECT_THROW(write_shortest(buf, buf + 2, std::numeric_limits<double>::quiet_NaN()), std::length_error);
  end = write_shortest(buf, buf + 3, 0.5);
  EXPECT_EQ(std::string(buf, end), "0.5");
}

}  // namespace
}  // namespace moreau::platform
