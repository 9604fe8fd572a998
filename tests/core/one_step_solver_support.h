// Shared by the two halves of the one-step solver's tests (one_step_solver_test.cc and
// one_step_solver_pivoting_test.cc): the independent brute-force reference of (6.5) without the norm
// term, random problems checked against it at any size, and the inclusion's residual computed from its
// definition.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "moreau/core/one_step_solver.h"

namespace moreau {
namespace {

// Independent reference for phi = sum a_i |y_i| (no norm term): try every sign pattern, solve its
// linear system with a different factorisation (full-pivot LU on the reduced system), keep the one
// satisfying the inclusion. Unique by Theorem 4.1, so the first hit is the answer.
// Every sign pattern s in {-1, 0, 1}^n, in order (3^n of them): the references' enumeration.
inline std::vector<std::vector<int>> SignPatterns(int n) {
  std::vector<std::vector<int>> out(1, std::vector<int>());
  for (int i = 0; i < n; ++i) {
    std::vector<std::vector<int>> longer;
    for (const std::vector<int>& head : out)
      for (int si : {-1, 0, 1}) {
        longer.push_back(head);
        longer.back().push_back(si);
      }
    out = std::move(longer);
  }
  return out;
}

inline Eigen::VectorXd BruteForce(const Eigen::MatrixXd& P, const Eigen::VectorXd& x, const Eigen::VectorXd& a) {
  const int n = static_cast<int>(x.size());
  for (const std::vector<int>& s : SignPatterns(n)) {
    std::vector<int> free;
    for (int i = 0; i < n; ++i)
      if (s[i] != 0) free.push_back(i);
    Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
    if (!free.empty()) {
      const int m = static_cast<int>(free.size());
      Eigen::MatrixXd A(m, m);
      Eigen::VectorXd b(m);
      for (int r = 0; r < m; ++r) {
        b(r) = -(x(free[r]) + a(free[r]) * s[free[r]]);
        for (int cc = 0; cc < m; ++cc) A(r, cc) = P(free[r], free[cc]);
      }
      Eigen::VectorXd yf = A.fullPivLu().solve(b);
      for (int r = 0; r < m; ++r) y(free[r]) = yf(r);
    }
    bool ok = true;
    const Eigen::VectorXd w = -(P * y + x);
    for (int i = 0; i < n && ok; ++i) {
      if (s[i] != 0)
        ok = y(i) * s[i] >= 0.0;
      else
        ok = std::abs(w(i)) <= a(i) * (1 + 1e-12);
    }
    if (ok) return y;
  }
  ADD_FAILURE() << "brute force found no pattern";
  return Eigen::VectorXd::Zero(n);
}

template <int N>
void RandomProblems(int n, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unif(0.0, 2.0);
  OneStepSolver<N> solver;
  Vec<N> a(n);
  for (int i = 0; i < n; ++i) a(i) = unif(rng);
  solver.configure(a, 0.0);
  int zeros = 0;
  for (int trial = 0; trial < count; ++trial) {
    // P = S + K with S symmetric positive definite and K skew: the structure of M/h + C + W.
    Eigen::MatrixXd G(n, n), K(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        G(i, j) = gauss(rng);
        K(i, j) = gauss(rng);
      }
    Mat<N> P = G * G.transpose() + 0.5 * Eigen::MatrixXd::Identity(n, n) + 0.8 * (K - K.transpose());
    Vec<N> x(n);
    for (int i = 0; i < n; ++i) x(i) = 2.0 * gauss(rng);
    Vec<N> y(n);
    OneStepStats st;
    ASSERT_TRUE(solver.solve(P, x, y, st)) << "trial " << trial << " residual " << st.residual;
    const Eigen::VectorXd ref = BruteForce(P, x, a);
    for (int i = 0; i < n; ++i) {
      if (ref(i) == 0.0) {
        EXPECT_EQ(y(i), 0.0) << "component " << i << " of trial " << trial << " must be exactly zero";
        ++zeros;
      } else {
        EXPECT_NEAR(y(i), ref(i), 1e-12 * (1.0 + std::abs(ref(i))));
      }
    }
    EXPECT_LE(st.residual, st.tolerance);
  }
  EXPECT_GT(zeros, 0) << "the random problems should exercise sticking components";
}

// dist(-(P y + x), d phi(y)) for phi = sum a_i |y_i| + a_norm ||y||, computed here from its definition.
// Independent reference for phi = sum a_i |y_i| + a_norm ||y|| (Remark 4.2), a_norm > 0, when y = 0 is
// not the answer: every sign pattern s (components with a_i = 0 always free), and for each the radius
// t = ||y|| of its equations y_F = -(P_FF + (a_norm / t) I)^{-1} (x_F + a_F s_F), y_R = 0, found by a scan
// of t over 16 decades and bisection of each sign change; the first y that keeps its pattern's signs and
// multipliers is the answer (unique by Theorem 4.1). Another route than the solver's (no pivoting, no
// Newton), and exponential: the small-n oracle only.
inline Eigen::VectorXd BruteForceWithNorm(const Eigen::MatrixXd& P, const Eigen::VectorXd& x, const Eigen::VectorXd& a, double a_norm) {
  const int n = static_cast<int>(x.size());
  for (const std::vector<int>& s : SignPatterns(n)) {
    std::vector<int> free;
    bool skip = false;
    for (int i = 0; i < n; ++i) {
      if (a(i) == 0.0 && s[i] != 0) skip = true;  // a component without a gain has no sign pattern
      if (s[i] != 0 || a(i) == 0.0) free.push_back(i);
    }
    if (skip || free.empty()) continue;
    const int m = static_cast<int>(free.size());
    const auto y_at = [&](double t) {
      Eigen::MatrixXd A(m, m);
      Eigen::VectorXd b(m);
      for (int r = 0; r < m; ++r) {
        b(r) = -(x(free[r]) + a(free[r]) * s[free[r]]);
        for (int cc = 0; cc < m; ++cc) A(r, cc) = P(free[r], free[cc]) + (r == cc ? a_norm / t : 0.0);
      }
      const Eigen::VectorXd yf = A.fullPivLu().solve(b);
      Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
      for (int r = 0; r < m; ++r) y(free[r]) = yf(r);
      return y;
    };
    const auto h = [&](double t) { return y_at(t).norm() - t; };
    double t_prev = 1e-8, h_prev = h(t_prev);
    for (int k = 1; k <= 400; ++k) {
      const double t = 1e-8 * std::pow(10.0, 16.0 * k / 400.0);
      const double h_t = h(t);
      if ((h_prev > 0.0) != (h_t > 0.0)) {
        double lo = t_prev, hi = t;
        const bool lo_positive = h_prev > 0.0;
        for (int it = 0; it < 200; ++it) {
          const double mid = 0.5 * (lo + hi);
          ((h(mid) > 0.0) == lo_positive ? lo : hi) = mid;
        }
        const Eigen::VectorXd y = y_at(0.5 * (lo + hi));
        Eigen::VectorXd w = -(P * y + x) - (a_norm / y.norm()) * y;
        bool ok = true;
        for (int i = 0; i < n && ok; ++i) {
          if (s[i] != 0)
            ok = y(i) * s[i] >= 0.0;
          else if (a(i) > 0.0)
            ok = std::abs(w(i)) <= a(i) * (1 + 1e-9) + 1e-12;
        }
        if (ok) return y;
      }
      t_prev = t;
      h_prev = h_t;
    }
  }
  ADD_FAILURE() << "brute force with the norm term found no pattern";
  return Eigen::VectorXd::Zero(n);
}

inline double InclusionResidual(const Eigen::MatrixXd& P, const Eigen::VectorXd& x, const Eigen::VectorXd& a, double a_norm,
                                const Eigen::VectorXd& y) {
  Eigen::VectorXd w = -(P * y + x);
  const double ny = y.norm();
  if (ny == 0.0) {
    const Eigen::VectorXd clipped = w.cwiseMax(-a).cwiseMin(a);
    return std::max(0.0, (w - clipped).norm() - a_norm);
  }
  if (a_norm > 0.0) w -= (a_norm / ny) * y;
  double sum = 0.0;
  for (int i = 0; i < y.size(); ++i) {
    const double d = y(i) > 0.0 ? w(i) - a(i) : (y(i) < 0.0 ? w(i) + a(i) : std::max(0.0, std::abs(w(i)) - a(i)));
    sum += d * d;
  }
  return std::sqrt(sum);
}

}  // namespace
}  // namespace moreau
