// The way points' natural cubic spline (spline_reference.h) against hand values and closed forms.
#include "moreau/core/spline_reference.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>

namespace moreau {
namespace {

CubicSplineReference spline_of(const std::vector<double>& t, const std::vector<double>& q) {
  Eigen::MatrixXd m(static_cast<Eigen::Index>(q.size()), 1);
  for (std::size_t j = 0; j < q.size(); ++j) m(static_cast<Eigen::Index>(j), 0) = q[j];
  EXPECT_EQ(CubicSplineReference::problem(t, m), "");
  return CubicSplineReference(t, m);
}

// Through (0, 0), (1, 1), (2, 0): 2 (1 + 1) M_1 = 6 ((0 - 1) - (1 - 0)), M_1 = -3, by hand; on [0, 1]
// (a = 1 - t, b = t) q = t + (t^3 - t) (-3) / 6 = 1.5 t - 0.5 t^3, q' = 1.5 - 1.5 t^2, q'' = -3 t.
TEST(CubicSplineReference, ThreePointsByHand) {
  const CubicSplineReference s = spline_of({0.0, 1.0, 2.0}, {0.0, 1.0, 0.0});
  EXPECT_DOUBLE_EQ(s.knot_second_derivatives()(1, 0), -3.0);
  ReferencePoint<1> r;
  r.resize(1);
  std::size_t hint = 0;
  for (double t : {0.0, 0.25, 0.5, 0.9}) {
    ASSERT_TRUE(s.at(t, r, hint));
    EXPECT_NEAR(r.q(0), 1.5 * t - 0.5 * t * t * t, 1e-15) << t;
    EXPECT_NEAR(r.v(0), 1.5 - 1.5 * t * t, 1e-15) << t;
    EXPECT_NEAR(r.a(0), -3.0 * t, 1e-15) << t;
  }
  // Symmetric on [1, 2]; natural at both ends; undefined outside.
  ASSERT_TRUE(s.at(1.75, r, hint));
  EXPECT_NEAR(r.q(0), 1.5 * 0.25 - 0.5 * 0.25 * 0.25 * 0.25, 1e-15);
  ASSERT_TRUE(s.at(2.0, r, hint));
  EXPECT_EQ(r.a(0), 0.0);
  EXPECT_FALSE(s.at(2.0001, r, hint));
  EXPECT_FALSE(s.at(-1e-6, r, hint));
}

// A line is its own natural spline (every M_j = 0), at unequal spacing.
TEST(CubicSplineReference, ALineIsReproduced) {
  const CubicSplineReference s = spline_of({0.0, 0.3, 1.0, 1.1, 2.5}, {1.0, 1.6, 3.0, 3.2, 6.0});
  ReferencePoint<1> r;
  r.resize(1);
  std::size_t hint = 0;
  for (double t = 0.0; t <= 2.5; t += 0.01) {
    ASSERT_TRUE(s.at(t, r, hint));
    EXPECT_NEAR(r.q(0), 1.0 + 2.0 * t, 1e-13) << t;
    EXPECT_NEAR(r.v(0), 2.0, 1e-12) << t;
    EXPECT_NEAR(r.a(0), 0.0, 1e-11) << t;
  }
}

// sin on [0, pi] has q'' = 0 at both ends, as the natural spline: its errors in q, q' and q'' fall as
// h^4, h^3 and h^2 (the classical orders), and q' and q'' are continuous across the knots (C2).
TEST(CubicSplineReference, SineConvergesAtTheClassicalOrdersAndIsC2) {
  auto max_errors = [](int intervals) {
    std::vector<double> t, q;
    for (int j = 0; j <= intervals; ++j) {
      t.push_back(std::numbers::pi * j / intervals);
      q.push_back(std::sin(t.back()));
    }
    const CubicSplineReference s = spline_of(t, q);
    ReferencePoint<1> r;
    r.resize(1);
    std::size_t hint = 0;
    std::array<double, 3> e{0.0, 0.0, 0.0};
    for (int k = 0; k <= 10000; ++k) {
      const double x = std::numbers::pi * k / 10000;
      EXPECT_TRUE(s.at(x, r, hint));
      e[0] = std::max(e[0], std::abs(r.q(0) - std::sin(x)));
      e[1] = std::max(e[1], std::abs(r.v(0) - std::cos(x)));
      e[2] = std::max(e[2], std::abs(r.a(0) + std::sin(x)));
    }
    // Continuity at each interior knot: the two sides' limits of q' and q''.
    for (int j = 1; j < intervals; ++j) {
      ReferencePoint<1> left, right;
      left.resize(1);
      right.resize(1);
      EXPECT_TRUE(s.at(t[j] - 1e-9, left, hint));
      EXPECT_TRUE(s.at(t[j] + 1e-9, right, hint));
      EXPECT_NEAR(left.v(0), right.v(0), 1e-7) << j;
      EXPECT_NEAR(left.a(0), right.a(0), 1e-7) << j;
    }
    return e;
  };
  const auto coarse = max_errors(20), fine = max_errors(40);
  EXPECT_GT(coarse[0] / fine[0], 14.0);  // 2^4 = 16
  EXPECT_GT(coarse[1] / fine[1], 7.0);   // 2^3
  EXPECT_GT(coarse[2] / fine[2], 3.5);   // 2^2
  EXPECT_LT(fine[0], 1e-6);
}

TEST(CubicSplineReference, BadWayPointsAreNamed) {
  Eigen::MatrixXd q(2, 1);
  q << 0.0, 1.0;
  EXPECT_NE(CubicSplineReference::problem({0.0}, q.topRows(1)), "");
  EXPECT_NE(CubicSplineReference::problem({0.0, 0.0}, q), "");
  EXPECT_NE(CubicSplineReference::problem({1.0, 0.5}, q), "");
  EXPECT_NE(CubicSplineReference::problem({0.0, NAN}, q), "");
  q(1, 0) = INFINITY;
  EXPECT_NE(CubicSplineReference::problem({0.0, 1.0}, q), "");
}

}  // namespace
}  // namespace moreau
