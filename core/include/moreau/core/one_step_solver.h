// The one-step problem of the scheme (0.2): given P (positive definite, not necessarily symmetric) and x,
// find the unique y with
//
//   P y + x  in  -d phi(y),     phi(y) = sum_i a_i |y_i| + a_norm ||y||_2,              (6.5)
//
// the inclusion of section 6 of Adly, Brogliato and Le (2016), generalised to any n and to the norm
// term of Remark 4.2. Existence and uniqueness: Theorem 4.1 (P - k1/(2h) I is monotone).
//
// Method, in order (each exact, each verified before it is accepted):
//  1. closed forms: no nonsmooth term (one linear solve); y = 0 when -x lies in d phi(0) (this is what
//     makes a component at rest exactly 0.0); P diagonal and phi separable (componentwise soft
//     threshold).
//  2. semismooth Newton on the natural map of (6.5), in its primal-dual active-set form (Hintermueller,
//     Ito and Kunisch 2002), the route Remark 6.1 points to: guess the sign pattern s in {-1, 0, +1}^n,
//     solve the linear (or, with a norm term, smooth) equations it implies with y_i = 0.0 exactly where
//     s_i = 0, check the inclusion, update the pattern. Warm-started from the previous step's pattern,
//     it usually needs one solve. Deviation from the paper: Lemma 6.1's projection form (6.8) is not
//     iterated; it characterises the same solution, and the pattern equations are exact.
//  3. if the pattern iteration cycles: for separable phi (no norm term), block principal pivoting with
//     Judice and Pires' safeguard (Murty's least-index rule when the count of broken components stops
//     falling), finite for the P-matrix P (see principal_pivoting); with a norm term, a search over the
//     radius t = ||y|| whose every trial is a separable problem solved by that pivoting (solve_by_radius:
//     polynomial, no enumeration of the 3^n patterns; the enumeration is the tests' reference), and only
//     if that finds no pattern, forward-backward splitting y <- prox(y - gamma (P y + x)),
//     gamma = mu / L^2, globally convergent because y -> P y + x is strongly monotone, whose pattern is
//     then polished exactly.
// A solution is accepted only when dist(-(P y + x), d phi(y)) is within round-off of the problem's scale;
// otherwise solve() returns false and the caller must stop: an unsolved step is never used.
//
// Linear solves: LU with partial pivoting. Dense (Eigen's PartialPivLU, or its 2x2 case inline), or, for
// dynamic sizes when the caller states that P is zero beyond a bandwidth b from its diagonal and b is
// small (6 b <= n), the same elimination confined to the band (LAPACK's dgbtrf scheme: pivots from the b
// rows below, fill-in up to 2 b above the diagonal), O(n b^2) instead of O(n^3). For dense P of dynamic
// size 16 <= n <= 128 and separable phi (robot chains), a step's patterns share one LU (solve_from_base):
// that of its first pattern's free block, which later patterns update by a Schur complement of the few
// components whose state changed, O(f^2) per changed component instead of a new O(f^3) factorisation
// each; a solution those solves leave above the round-off tolerance is solved again directly. The
// acceptance residual is always computed with the whole of P, so a wrong bandwidth cannot pass unseen.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "moreau/core/types.h"

namespace moreau {

struct OneStepStats {
  int iterations = 0;      // linear (or Newton) solves of pattern equations, or fixed-point sweeps
  double residual = 0.0;   // dist(-(P y + x), d phi(y)) of the returned y
  double tolerance = 0.0;  // the round-off bound the residual was accepted against
  bool used_fallback = false;
  // y = 0 came from the closed form of step 1 (-x lies in d phi(0)): every component of y is exactly 0.0.
  // The solver's own statement, for callers that need to know that the solution rests at the origin (a
  // sliding variable on its surface) without comparing floats.
  bool zero_by_closed_form = false;
};

// The safeguard of Judice and Pires (Comput. Oper. Res. 21, 1994) for block principal pivoting: while
// the count of broken components falls below its lowest, every broken component changes state at once (a
// block pivot); after kTries passes without a new lowest count, only the broken one of least index does
// (Murty's rule, finite for P-matrices), until the count falls below its lowest again. Shared by the
// dense solver below and the sparse one (sparse_one_step_solver.h).
struct PivotingSafeguard {
  static constexpr int kTries = 3;
  int lowest = std::numeric_limits<int>::max();
  int tries = 0;
  // Whether the pass that found `count` broken components pivots them all (else the least index only).
  bool block_pivot(int count) {
    const bool block = count < lowest || tries < kTries;
    if (count < lowest) {
      lowest = count;
      tries = 0;
    } else {
      ++tries;
    }
    return block;
  }
};

template <int N>
class OneStepSolver {
 public:
  using Pattern = Eigen::Matrix<std::int8_t, N, 1>;

  OneStepSolver() = default;

  // gains a_i >= 0 and a_norm >= 0 of phi; bandwidth: P(i, j) == 0 whenever |i - j| > bandwidth, for
  // every P this solver will be given (-1: no such promise). Sizes every buffer once: solve() does not
  // allocate.
  void configure(const Vec<N>& gains, double norm_gain, int bandwidth = -1) {
    const int n = static_cast<int>(gains.size());
    a_ = gains;
    an_ = norm_gain;
    bandwidth_ = (N == Eigen::Dynamic && bandwidth >= 0 && 6 * bandwidth <= n) ? bandwidth : -1;
    nonsmooth_ = an_ > 0.0 || (a_.array() > 0.0).any();
    share_factorisation_ = N == Eigen::Dynamic && bandwidth_ < 0 && an_ == 0.0 && n >= kShareMin && n <= kShareMax;
    if (share_factorisation_) {
      base_lu_.setZero(n, n);
      base_cols_.setZero(n, n);
      small_.setZero(n, n);
      col_ready_.setZero(n);
      base_transpositions_.setZero(n);
      small_transpositions_.setZero(n);
      base_index_.setZero(n);
      base_position_.setZero(n);
      index_.setZero(n);
      u_.setZero(n);
      col_.setZero(n);
      small_rhs_.setZero(n);
    }
    pattern_.setZero(n);
    start_.setZero(n);
    newton_patterns_.setZero(n, max_newton_iterations(n) + 1);
    trial_.setZero(n);
    tried_.setZero(n);
    if (an_ > 0.0) shifted_.setZero(n, n);
    pinned_.setZero(n);
    A_.setZero(n, n);
    J_.setZero(n, n);
    b_.setZero(n);
    w_.setZero(n);
    r_.setZero(n);
    dy_.setZero(n);
    best_.setZero(n);
    if constexpr (N == Eigen::Dynamic) lu_ = Eigen::PartialPivLU<Mat<N>>(n);
  }

  int size() const { return static_cast<int>(a_.size()); }

  // The bandwidth the linear solves use, or -1 for dense LU.
  int banded_width() const { return bandwidth_; }
  // Whether the pattern solves of a step share one LU (solve_from_base); use_direct_solves() turns that
  // off (each pattern then factorises its own n x n matrix, as for other sizes).
  bool shares_factorisation() const { return share_factorisation_; }
  void use_direct_solves() { share_factorisation_ = false; }
  // Since configure: patterns whose shared-factorisation solution missed the round-off tolerance and
  // were solved again directly (accept_shared_solution), and steps whose shared-factorisation solves
  // could not finish at all, solved again from the start with direct solves (solve()).
  std::int64_t direct_resolves() const { return direct_resolves_; }
  std::int64_t direct_retries() const { return direct_retries_; }
  // Since configure: patterns solved by a Schur complement update of the step's base LU (solve_from_base).
  std::int64_t schur_updates() const { return schur_updates_; }

  // Solves (6.5). On success returns true with y the solution; on failure returns false (y then holds
  // the best iterate, for diagnostics only).
  bool solve(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, OneStepStats& stats) {
    if constexpr (N != Eigen::Dynamic) return solve_with(P, x, y, stats);  // direct_ is always true
    direct_ = !share_factorisation_;
    if (direct_) return solve_with(P, x, y, stats);
    base_size_ = -1;
    col_ready_.setZero();
    start_ = pattern_;
    if (solve_with(P, x, y, stats)) return true;
    // The shared factorisation's rounding (or a tie it decided the other way) kept the step from an
    // accepted solution: the same step with direct solves, from the same starting pattern.
    ++direct_retries_;
    const int tried = stats.iterations;
    direct_ = true;
    pattern_ = start_;
    const bool ok = solve_with(P, x, y, stats);
    stats.iterations += tried;
    return ok;
  }

  // dist(-(P y + x), d phi(y)): zero exactly at the solution of (6.5).
  double residual(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y) {
    set_w(P, x, y);
    const bool y_zero = y.squaredNorm() == 0.0;  // ||y|| == 0, without its square root
    if (!y_zero && an_ > 0.0) w_ -= (an_ / y.norm()) * y;
    return residual_of_w(y, y_zero);
  }

  const Pattern& pattern() const { return pattern_; }

 private:
  bool solve_with(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, OneStepStats& stats) {
    const int n = size();
    stats = OneStepStats{};
    w_from_pattern_ = false;
    double scale_px;  // ||P||_inf
    if constexpr (N == Eigen::Dynamic) {
      abs_row_sums(P, dy_, bandwidth_);  // dy_ is free until the pattern iteration
      scale_px = dy_.maxCoeff();
    } else {
      scale_px = P.cwiseAbs().rowwise().sum().maxCoeff();
    }
    const double gain_scale = (n > 0 ? a_.maxCoeff() : 0.0) + an_;

    if (!nonsmooth_) {
      if (bandwidth_ >= 0) {
        A_ = P;
        b_ = -x;
        if (!banded_lu_solve(y)) return false;
      } else {
        lu_.compute(P);
        y.noalias() = lu_.solve(-x);
      }
      stats.iterations = 1;
      return accept(P, x, y, scale_px, gain_scale, stats);
    }

    // y = 0 solves (6.5) iff -x lies in d phi(0) = A [-1,1]^n + a_norm B.
    {
      w_ = -x;
      // (Without a norm term only whether the distance is 0 matters: no square root.)
      const double to_box2 = (w_ - w_.cwiseMax(-a_).cwiseMin(a_)).squaredNorm();
      if (an_ == 0.0 ? to_box2 == 0.0 : std::sqrt(to_box2) <= an_) {
        y.setZero(n);
        pattern_.setZero(n);
        stats.iterations = 0;
        stats.zero_by_closed_form = true;
        return accept(P, x, y, scale_px, gain_scale, stats);
      }
    }

    // P diagonal and phi separable: componentwise soft threshold, exact.
    if (an_ == 0.0 || n == 1) {
      if (is_diagonal(P)) {
        const double extra = (n == 1) ? an_ : 0.0;  // in one dimension ||y|| = |y|
        for (int i = 0; i < n; ++i) {
          const double ai = a_(i) + extra;
          const double xi = x(i);
          if (std::abs(xi) <= ai) {
            y(i) = 0.0;
            pattern_(i) = 0;
          } else {
            const double s = xi > 0.0 ? 1.0 : -1.0;  // y has the sign of -x
            y(i) = -(xi - ai * s) / P(i, i);
            pattern_(i) = static_cast<std::int8_t>(-s);
          }
        }
        stats.iterations = 1;
        return accept(P, x, y, scale_px, gain_scale, stats);
      }
    }

    // Semismooth Newton (primal-dual active set) from the previous step's pattern.
    if (all_zero(pattern_)) initial_pattern(x);
    const int max_newton = max_newton_iterations(n);
    for (int it = 0; it < max_newton; ++it) {
      ++stats.iterations;
      if (solve_pattern(P, x, pattern_, y) && consistent(P, x, y, pattern_, scale_px, gain_scale)) {
        if (direct_) return accept(P, x, y, scale_px, gain_scale, stats, /*w_is_current=*/true);
        return accept_shared_solution(P, x, y, scale_px, gain_scale, stats);
      }
      newton_patterns_.col(it) = pattern_;
      if (!update_pattern(P, x, y)) break;  // no change: a fixed point that is not a solution
      // With P and x fixed, each pattern determines the next: a pattern seen before means the iteration
      // cycles through patterns none of which solved. Skip to the pattern the remaining iterations would
      // have ended on (the fallback starts from it, as if they had run), without their solves.
      newton_patterns_.col(it + 1) = pattern_;
      const int seen = earlier_newton_pattern(it + 1);
      if (seen >= 0) {
        const int period = it + 1 - seen;
        pattern_ = newton_patterns_.col(seen + (max_newton - seen) % period);
        break;
      }
    }

    // Fallbacks. Separable phi: safeguarded principal pivoting, finite and exact. With a norm term: the
    // search over the radius, then forward-backward.
    stats.used_fallback = true;
    if (an_ == 0.0) return principal_pivoting(P, x, y, scale_px, gain_scale, stats);
    if (radius_search(P, x, y, scale_px, gain_scale, stats)) return accept(P, x, y, scale_px, gain_scale, stats);
    return forward_backward(P, x, y, scale_px, gain_scale, stats);
  }

 public:
  // The norm term's fallback alone (step 3), for the tests that hold it against the enumeration of every
  // pattern: true with y the solution of (6.5), accepted as solve()'s answers are. Requires a_norm > 0
  // and -x outside d phi(0) (else y = 0, solve()'s closed form).
  bool solve_by_radius(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, OneStepStats& stats) {
    stats = OneStepStats{};
    stats.used_fallback = true;
    direct_ = true;
    const double scale_px = P.cwiseAbs().rowwise().sum().maxCoeff();
    const double gain_scale = (size() > 0 ? a_.maxCoeff() : 0.0) + an_;
    pattern_.setZero(size());
    y.setZero(size());
    return radius_search(P, x, y, scale_px, gain_scale, stats) && accept(P, x, y, scale_px, gain_scale, stats);
  }

 private:
  // With the norm term a_norm ||y|| (Remark 4.2): y != 0 solves (6.5) iff it solves the separable problem
  //
  //   (P + (a_norm / t) I) y + x  in  -d(sum_i a_i |y_i|)(y)                                    (6.5_t)
  //
  // at t = ||y||, since the subdifferential of a_norm ||.|| at y != 0 is a_norm y / ||y||. For t > 0,
  // P + (a_norm / t) I has a symmetric part more positive definite than P's, so (6.5_t) has one solution
  // y(t) (Theorem 4.1's argument), exact by principal_pivoting in finitely many pivots. g(t) = ||y(t)|| - t
  // is continuous; near t = 0, y(t) ~ -(t / a_norm) soft(x) (soft: the componentwise soft threshold by a)
  // and ||soft(x)|| > a_norm exactly when y = 0 does not solve (6.5), so g > 0 there; for large t, y(t)
  // stays bounded and g < 0; every root t* gives a solution y(t*) of (6.5), which is unique, so the root
  // is too. The search brackets it (doubling or halving t), then bisects (geometrically while the bracket
  // spans more than a factor 2). Each trial's pattern (the signs of y(t)) is tried in (6.5)'s own pattern
  // equations (solve_pattern, Newton with the norm term): the first that satisfies (6.5) is the answer.
  // Near t* the pattern of y(t) is that of the solution (or, at a tie, one whose equations the solution
  // also satisfies), so the search ends once the bracket is narrow enough to separate the breakpoints of
  // the pattern; the cap on trials (kMaxRadiusTrials, far beyond double precision's resolution of t) is
  // a safety net. Cost: a few pivoting solves of n x n systems per trial, polynomial in n, where the
  // enumeration this replaces tried up to 3^n patterns (9.7 ms mean per step at n = 10).
  bool radius_search(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, double scale_px, double gain_scale, OneStepStats& stats) {
    const int n = size();
    const double an = an_;
    const auto g_at = [&](double t, bool& solved) {
      // y(t) by principal pivoting on the separable problem, from the pattern of the last trial.
      shifted_ = P;
      shifted_.diagonal().array() += an / t;
      an_ = 0.0;
      OneStepStats inner;
      principal_pivoting(shifted_, x, best_, scale_px + an / t, gain_scale - an, inner);
      an_ = an;
      stats.iterations += inner.iterations;
      const double g = best_.norm() - t;  // (before solve_pattern, whose Newton steps use best_)
      // Its pattern, tried in (6.5)'s equations unless it is the one tried last.
      for (int i = 0; i < n; ++i) trial_(i) = best_(i) > 0.0 ? 1 : (best_(i) < 0.0 ? -1 : 0);
      solved = false;
      if (!tried_any_ || (trial_.array() != tried_.array()).any()) {
        tried_ = trial_;
        tried_any_ = true;
        ++stats.iterations;
        if (solve_pattern(P, x, trial_, y) && consistent(P, x, y, trial_, scale_px, gain_scale)) {
          pattern_ = trial_;
          solved = true;
        }
      }
      return g;
    };
    tried_any_ = false;
    bool solved = false;
    // A first radius: the norm of the iterate the pattern iteration ended on, else ||x|| / ||P||_inf.
    double t = y.allFinite() && y.norm() > 0.0 ? y.norm() : x.norm() / std::max(scale_px, 1e-300);
    if (!(t > 0.0) || !std::isfinite(t)) return false;
    double lo = 0.0, hi = 0.0;
    int trials = 0;
    double g = g_at(t, solved);
    ++trials;
    if (solved) return true;
    if (g > 0.0) {
      lo = t;
      for (hi = 2.0 * t; trials < kMaxRadiusTrials; hi *= 2.0) {
        ++trials;
        if (g_at(hi, solved) <= 0.0 || solved) break;
        lo = hi;
      }
    } else {
      hi = t;
      for (lo = 0.5 * t; trials < kMaxRadiusTrials && lo > 0.0; lo *= 0.5) {
        ++trials;
        if (g_at(lo, solved) > 0.0 || solved) break;
        hi = lo;
      }
    }
    if (solved) return true;
    while (trials < kMaxRadiusTrials && hi - lo > 4.0 * std::numeric_limits<double>::epsilon() * hi && lo > 0.0) {
      const double mid = hi > 2.0 * lo ? std::sqrt(lo * hi) : 0.5 * (lo + hi);
      ++trials;
      g = g_at(mid, solved);
      if (solved) return true;
      (g > 0.0 ? lo : hi) = mid;
    }
    return false;
  }
  static constexpr int kMaxRadiusTrials = 400;

  // The residual from w_ = -(P y + x) - a_norm y / ||y|| (the last term only when y != 0).
  double residual_of_w(const Vec<N>& y, bool y_zero) const {
    if (y_zero) {
      return std::max(0.0, (w_ - w_.cwiseMax(-a_).cwiseMin(a_)).norm() - an_);
    }
    double sum = 0.0;
    for (int i = 0; i < size(); ++i) {
      double d;
      if (y(i) > 0.0)
        d = w_(i) - a_(i);
      else if (y(i) < 0.0)
        d = w_(i) + a_(i);
      else
        d = std::max(0.0, std::abs(w_(i)) - a_(i));
      sum += d * d;
    }
    return std::sqrt(sum);
  }

  static bool all_zero(const Pattern& s) { return (s.array() == 0).all(); }

  static bool is_diagonal(const Mat<N>& P) {
    const int n = static_cast<int>(P.rows());
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i)
        if (i != j && P(i, j) != 0.0) return false;
    return true;
  }

  // The accepted residual: a few ulps of the size of the terms of (6.5). w_is_current: consistent() has
  // just computed w_, y_zero_ and pattern_scale_ for this y, the quantities residual() and the scale need.
  bool accept(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y, double scale_px, double gain_scale, OneStepStats& stats,
              bool w_is_current = false) {
    const double scale =
        w_is_current ? pattern_scale_ : x.cwiseAbs().maxCoeff() + scale_px * (y.size() ? y.cwiseAbs().maxCoeff() : 0.0) + gain_scale;
    stats.tolerance = 256.0 * std::numeric_limits<double>::epsilon() * std::max(scale, 1e-300);
    stats.residual = w_is_current ? residual_of_w(y, y_zero_) : residual(P, x, y);
    return std::isfinite(stats.residual) && stats.residual <= stats.tolerance && y.allFinite();
  }

  // accept() for y from a shared-factorisation solve (solve_from_base) of the current pattern, consistent()
  // having just passed. It can miss the round-off tolerance where the direct solve of the same pattern
  // meets it (its error grows with the conditioning of the base block and of the Schur complement):
  // that pattern is then solved directly, and the rest of the step's solves are direct too.
  bool accept_shared_solution(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, double scale_px, double gain_scale, OneStepStats& stats) {
    if (w_from_pattern_) {  // the residual from the product itself, not from the pattern's quantities
      w_from_pattern_ = false;
      multiplier_estimate(P, x, y);
    }
    if (accept(P, x, y, scale_px, gain_scale, stats, /*w_is_current=*/true)) return true;
    direct_ = true;
    ++direct_resolves_;
    ++stats.iterations;
    return solve_pattern(P, x, pattern_, y) && consistent(P, x, y, pattern_, scale_px, gain_scale) &&
           accept(P, x, y, scale_px, gain_scale, stats, /*w_is_current=*/true);
  }

  static int max_newton_iterations(int n) { return 2 * n + 8; }

  // The first j < m with newton_patterns_.col(j) equal to col(m), or -1.
  int earlier_newton_pattern(int m) const {
    for (int j = 0; j < m; ++j)
      if ((newton_patterns_.col(j).array() == newton_patterns_.col(m).array()).all()) return j;
    return -1;
  }

  // A first pattern from y = 0: a component moves where |x_i| exceeds its gain, against x_i.
  void initial_pattern(const Vec<N>& x) {
    bool any = false;
    for (int i = 0; i < size(); ++i) {
      if (a_(i) > 0.0 && std::abs(x(i)) > a_(i)) {
        pattern_(i) = x(i) > 0.0 ? -1 : 1;
        any = true;
      } else {
        pattern_(i) = 0;
      }
    }
    if (!any) {
      // Only the norm term keeps y = 0 from solving: every component is free to move.
      for (int i = 0; i < size(); ++i) pattern_(i) = x(i) > 0.0 ? -1 : 1;
    }
  }

  // solve_pattern for n = 2 without a norm term, in scalars: the entries solve2 receives are those A_ and
  // b_ would hold (a pinned component's row and column those of the identity, its right-hand side 0), so
  // the same operations on the same values: the same bits, without the copies and loops of the general
  // path (this is the paper's manipulator, whose every step comes here).
  bool solve_pattern2(const Mat<N>& P, const Vec<N>& x, const Pattern& s, Vec<N>& y) {
    w_from_pattern_ = false;
    const bool pin0 = a_(0) > 0.0 && s(0) == 0, pin1 = a_(1) > 0.0 && s(1) == 0;
    pinned_(0) = pin0;
    pinned_(1) = pin1;
    if (pin0 && pin1) {
      y.setZero();
      return true;
    }
    const bool off_diagonal = !(pin0 || pin1);
    solve2(pin0 ? 1.0 : P(0, 0), off_diagonal ? P(0, 1) : 0.0, off_diagonal ? P(1, 0) : 0.0, pin1 ? 1.0 : P(1, 1),
           pin0 ? 0.0 : -(x(0) + a_(0) * s(0)), pin1 ? 0.0 : -(x(1) + a_(1) * s(1)), y);
    if (pin0) y(0) = 0.0;  // exactly zero, not round-off
    if (pin1) y(1) = 0.0;
    return y.allFinite();
  }

  // Solves the equations of pattern s: y_i = 0 where a_i > 0 and s_i = 0; elsewhere
  // (P y)_i + x_i + a_i s_i + a_norm y_i / ||y|| = 0. Returns false if they have no usable solution.
  bool solve_pattern(const Mat<N>& P, const Vec<N>& x, const Pattern& s, Vec<N>& y) {
    if constexpr (N == 2) {
      if (an_ == 0.0) return solve_pattern2(P, x, s, y);
    }
    const int n = size();
    w_from_pattern_ = false;
    for (int i = 0; i < n; ++i) b_(i) = -(x(i) + a_(i) * s(i));
    bool any_free = false;
    for (int i = 0; i < n; ++i) {
      pinned_(i) = (a_(i) > 0.0 && s(i) == 0) ? 1 : 0;
      if (pinned_(i))
        b_(i) = 0.0;
      else
        any_free = true;
    }
    if (!any_free) {
      y.setZero(n);
      return an_ == 0.0;  // with a norm term y = 0 was already ruled out
    }
    if (!direct_) {  // (separable phi: no Newton iteration below)
      if (!solve_from_base(P, x, s, y)) return false;
      pin_zeros(s, y);
      return y.allFinite();
    }
    if (bandwidth_ >= 0 && an_ == 0.0) {  // the band of P itself, pinned: no copy of the whole of P
      if (!banded_lu_solve(y, &P)) return false;
      pin_zeros(s, y);
      return y.allFinite();
    }
    A_ = P;
    for (int i = 0; i < n; ++i) {
      if (!pinned_(i)) continue;
      A_.row(i).setZero();
      A_.col(i).setZero();
      A_(i, i) = 1.0;
    }
    if constexpr (N == 2) {
      solve2(A_(0, 0), A_(0, 1), A_(1, 0), A_(1, 1), b_(0), b_(1), y);
    } else {
      if (bandwidth_ >= 0) {
        if (!banded_lu_solve(y)) return false;
      } else {
        lu_.compute(A_);
        y.noalias() = lu_.solve(b_);
      }
    }
    pin_zeros(s, y);
    if (an_ == 0.0) return y.allFinite();

    // The norm term: y != 0 here, so ||y|| is smooth; Newton on the free components, from the linear
    // solution, with step halving on the residual norm.
    if (y.norm() == 0.0) {
      for (int i = 0; i < n; ++i)
        if (!pinned_(i)) y(i) = b_(i);
      if (y.norm() == 0.0) return false;
    }
    double fnorm = pattern_equation_residual(y);
    for (int it = 0; it < 60; ++it) {
      const double ny = y.norm();
      J_ = A_;
      for (int i = 0; i < n; ++i) {
        if (pinned_(i)) continue;
        for (int j = 0; j < n; ++j) {
          if (pinned_(j)) continue;
          J_(i, j) += an_ * ((i == j ? 1.0 : 0.0) - y(i) * y(j) / (ny * ny)) / ny;
        }
      }
      lu_.compute(J_);
      dy_.noalias() = lu_.solve(r_);
      double step = 1.0;
      for (int ls = 0; ls < 40; ++ls) {
        best_ = y - step * dy_;
        pin_zeros(s, best_);
        if (best_.norm() > 0.0) {
          const double fnew = pattern_equation_residual(best_);
          if (fnew < fnorm || fnew == 0.0) {
            y = best_;
            fnorm = fnew;
            break;
          }
        }
        step *= 0.5;
      }
      pattern_equation_residual(y);  // refresh r_ for the next Jacobian solve
      if (step * dy_.norm() <= 4.0 * std::numeric_limits<double>::epsilon() * y.norm()) break;
    }
    return y.allFinite() && y.norm() > 0.0;
  }

  // The pattern's equations P_FF y_F = b_F, y_R = 0 (F free, R pinned, f = |F|), with one LU for the
  // several patterns of a step wherever the active-set iteration changes few components at a time:
  //  - the step's first pattern is its base: B = P_F0F0 is gathered and factorised (2/3 f0^3);
  //  - a later pattern F differs from F0 by the components A = F \ F0 that started moving and
  //    D = F0 \ F that came to rest. With K = [P_F0A, E_D] and L^T = [P_AF0; E_D^T] (E_D: the columns of
  //    the identity at D's places in F0) its equations are the bordered system
  //        [ B    K ] [ y_F0      ]   [ b_F0   ]
  //        [ L^T  Z ] [ y_A ; mu  ] = [ b_A ; 0 ],     Z = [ P_AA  0 ; 0  0 ],
  //    where mu holds y_D = 0 (it absorbs rows D of b_F0). It is solved through the Schur complement
  //    S = Z - L^T B^{-1} K (m x m, m = |A| + |D|): y_F0 = B^{-1} b_F0 - B^{-1} K (y_A ; mu). S is
  //    invertible exactly when P_FF is (eliminating mu and y_D from the bordered matrix leaves P_FF). The
  //    columns B^{-1} k_j are solved once per step, when first needed: O(f0^2) each, then O(m^2 f0 + m^3)
  //    per pattern instead of a new O(f^3) LU;
  //  - where that would cost more operations than P_FF's own LU (many components changed), P_FF is
  //    factorised and becomes the base.
  // False when a system is singular (P_FF is). Also w_ = -(P y + x) without the whole product with P:
  // w_F = a_F s_F, since (P y)_F = b_F, and w_R = -P_RF y_F - x_R.
  bool solve_from_base(const Mat<N>& P, const Vec<N>& x, const Pattern& s, Vec<N>& y) {
    const int n = size();
    for (int i = 0; i < n; ++i) w_(i) = a_(i) * s(i);  // the free components' (pinned ones below)
    w_from_pattern_ = true;
    int f = 0;
    for (int i = 0; i < n; ++i) f += !pinned_(i);
    // A, then D, in index_; and the columns of B^{-1} K not yet solved this step.
    int m = 0, added = 0, new_columns = 0;
    if (base_size_ >= 0) {
      for (int i = 0; i < n; ++i)
        if (!pinned_(i) && base_position_(i) < 0) index_(m++) = i;
      added = m;
      for (int i = 0; i < n; ++i)
        if (pinned_(i) && base_position_(i) >= 0) index_(m++) = i;
      for (int c = 0; c < m; ++c) new_columns += !col_ready_(index_(c));
    }
    const double f0 = base_size_, mm = m;
    const double schur_cost = (new_columns + 1) * 2.0 * f0 * f0 + 2.0 * added * mm * f0 + 2.0 / 3.0 * mm * mm * mm;
    const double own_cost = 2.0 / 3.0 * f * f * f;
    y.setZero(n);
    if (base_size_ < 0 || own_cost < schur_cost) {
      if (!factor_base(P)) return false;
      for (int k = 0; k < f; ++k) u_(k) = b_(base_index_(k));
      lu_solve(base_lu_, base_transpositions_, f, u_);
      for (int k = 0; k < f; ++k) y(base_index_(k)) = u_(k);
    } else {
      ++schur_updates_;
      const int nb = base_size_;
      for (int c = 0; c < m; ++c) {
        const int j = index_(c);
        if (col_ready_(j)) continue;
        if (c < added) {
          for (int k = 0; k < nb; ++k) col_(k) = P(base_index_(k), j);
        } else {
          col_.head(nb).setZero();
          col_(base_position_(j)) = 1.0;
        }
        lu_solve(base_lu_, base_transpositions_, nb, col_);
        base_cols_.col(j).head(nb) = col_.head(nb);
        col_ready_(j) = 1;
      }
      for (int k = 0; k < nb; ++k) u_(k) = b_(base_index_(k));
      lu_solve(base_lu_, base_transpositions_, nb, u_);
      // S and its right-hand side, row by row: a row of A from P's row (gathered over F0), a row of D
      // from the columns' entries at its place in F0.
      for (int r = 0; r < m; ++r) {
        const int i = index_(r);
        if (r < added) {
          for (int k = 0; k < nb; ++k) col_(k) = P(i, base_index_(k));
          for (int c = 0; c < m; ++c) {
            const int j = index_(c);
            small_(r, c) = (c < added ? P(i, j) : 0.0) - col_.head(nb).dot(base_cols_.col(j).head(nb));
          }
          small_rhs_(r) = b_(i) - col_.head(nb).dot(u_.head(nb));
        } else {
          const int p = base_position_(i);
          for (int c = 0; c < m; ++c) small_(r, c) = -base_cols_(p, index_(c));
          small_rhs_(r) = -u_(p);
        }
      }
      if (m > 0) {
        if (!lu_factor(small_, small_transpositions_, m)) return false;
        lu_solve(small_, small_transpositions_, m, small_rhs_);
      }
      for (int c = 0; c < m; ++c) u_.head(nb) -= small_rhs_(c) * base_cols_.col(index_(c)).head(nb);
      for (int k = 0; k < nb; ++k) {
        const int i = base_index_(k);
        if (!pinned_(i)) y(i) = u_(k);
      }
      for (int c = 0; c < added; ++c) y(index_(c)) = small_rhs_(c);
    }
    for (int i = 0; i < n; ++i)
      if (pinned_(i)) w_(i) = -P.row(i).dot(y) - x(i);
    return y.allFinite();
  }

  // The current pattern's free set becomes the step's base: P_FF gathered into base_lu_ and factorised.
  bool factor_base(const Mat<N>& P) {
    const int n = size();
    int f = 0;
    for (int i = 0; i < n; ++i) {
      base_position_(i) = pinned_(i) ? -1 : f;
      if (!pinned_(i)) base_index_(f++) = i;
    }
    for (int c = 0; c < f; ++c)
      for (int k = 0; k < f; ++k) base_lu_(k, c) = P(base_index_(k), base_index_(c));
    col_ready_.setZero();
    base_size_ = f;
    if (lu_factor(base_lu_, base_transpositions_, f)) return true;
    base_size_ = -1;
    return false;
  }

  // LU with partial pivoting of the leading m x m block of A, in place (unit lower and upper factors),
  // the row interchanges in t: t(k) is the row swapped with row k at step k. No allocation. False on a
  // zero pivot. Above 16 rows Eigen's blocked LU (the one PartialPivLU runs: panels of 8 columns, the
  // trailing block updated by a matrix product); below, the same elimination unblocked, written here:
  // calling blocked_lu for every size (it runs Eigen's unblocked_lu below 16 rows) made the 64-link
  // chain, whose later patterns factorise many Schur complements of a few rows, 4 % slower (80.7-80.9
  // against 76.4-78.0 us per step, alternating builds): per-column calls through Ref and maxCoeff cost
  // more than the elimination on blocks that small.
  static bool lu_factor(Mat<N>& A, Eigen::Matrix<int, N, 1>& t, int m) {
    if (m > 16) {
      int transpositions = 0;
      return Eigen::internal::partial_lu_impl<double, Eigen::ColMajor, int>::blocked_lu(m, m, A.data(), A.outerStride(), t.data(),
                                                                                        transpositions) < 0;
    }
    for (int k = 0; k < m; ++k) {
      int p = k;
      for (int i = k + 1; i < m; ++i)
        if (std::abs(A(i, k)) > std::abs(A(p, k))) p = i;
      t(k) = p;
      if (A(p, k) == 0.0) return false;
      if (p != k) A.row(k).head(m).swap(A.row(p).head(m));
      const int rest = m - k - 1;
      if (rest == 0) break;
      A.col(k).segment(k + 1, rest) /= A(k, k);
      A.block(k + 1, k + 1, rest, rest).noalias() -= A.col(k).segment(k + 1, rest) * A.row(k).segment(k + 1, rest);
    }
    return true;
  }
  // rhs <- S^{-1} rhs for S the leading m x m block whose factors lu_factor left in A.
  static void lu_solve(const Mat<N>& A, const Eigen::Matrix<int, N, 1>& t, int m, Vec<N>& rhs) {
    for (int k = 0; k < m; ++k) std::swap(rhs(k), rhs(t(k)));
    const auto lu = A.topLeftCorner(m, m);
    lu.template triangularView<Eigen::UnitLower>().solveInPlace(rhs.head(m));
    lu.template triangularView<Eigen::Upper>().solveInPlace(rhs.head(m));
  }

  // y = A^{-1} b for n = 2: Eigen's PartialPivLU (partial pivoting, the first row on a tie, l = a10 / a00,
  // u11 = a11 - l a01, then the unit-lower and upper substitutions) operation for operation, so the result
  // is bit-identical, without its loops and calls: the step's hottest path (the paper's manipulator).
  static void solve2(double a00, double a01, double a10, double a11, double b0, double b1, Vec<N>& y) {
    if (std::abs(a10) > std::abs(a00)) {
      std::swap(a00, a10);
      std::swap(a01, a11);
      std::swap(b0, b1);
    }
    const double l = a00 != 0.0 ? a10 / a00 : a10;
    const double u11 = a11 - l * a01;
    const double y1 = (b1 - l * b0) / u11;
    y(1) = y1;
    y(0) = (b0 - a01 * y1) / a00;
  }

  // y = A_^{-1} b_ for A_ zero beyond bandwidth_ from its diagonal: Gaussian elimination with partial
  // pivoting confined to the band, on copies in J_ and r_ (A_ and b_ stay for the norm term's Newton
  // iteration). A row swap brings entries up to 2 bandwidth_ right of the diagonal, so the upper factor
  // is kept that wide. False when a pivot is 0 (A_ singular): the pattern then has no usable solution.
  // With `pinned_source`, the matrix is that P with the pinned components' rows and columns those of the
  // identity (what solve_pattern would have made A_), read from P's band directly.
  bool banded_lu_solve(Vec<N>& y, const Mat<N>* pinned_source = nullptr) {
    const int n = size(), kl = bandwidth_, ku = 2 * bandwidth_;
    for (int j = 0; j < n; ++j) {  // the band and the fill-in rows above it (zeros in A_)
      for (int i = std::max(0, j - ku); i <= std::min(n - 1, j + kl); ++i) {
        if (pinned_source == nullptr)
          J_(i, j) = A_(i, j);
        else if (pinned_(i) || pinned_(j))
          J_(i, j) = i == j ? 1.0 : 0.0;
        else
          J_(i, j) = i - j <= kl && j - i <= kl ? (*pinned_source)(i, j) : 0.0;
      }
    }
    r_ = b_;
    for (int k = 0; k < n; ++k) {
      const int last_row = std::min(n - 1, k + kl), last_col = std::min(n - 1, k + ku);
      int p = k;
      for (int i = k + 1; i <= last_row; ++i)
        if (std::abs(J_(i, k)) > std::abs(J_(p, k))) p = i;
      if (p != k) {
        for (int j = k; j <= last_col; ++j) std::swap(J_(k, j), J_(p, j));
        std::swap(r_(k), r_(p));
      }
      const double pivot = J_(k, k);
      if (pivot == 0.0) return false;
      for (int i = k + 1; i <= last_row; ++i) {
        const double l = J_(i, k) / pivot;
        if (l == 0.0) continue;
        for (int j = k + 1; j <= last_col; ++j) J_(i, j) -= l * J_(k, j);
        r_(i) -= l * r_(k);
      }
    }
    for (int k = n - 1; k >= 0; --k) {
      double sum = r_(k);
      const int last_col = std::min(n - 1, k + ku);
      for (int j = k + 1; j <= last_col; ++j) sum -= J_(k, j) * y(j);
      y(k) = sum / J_(k, k);
    }
    return true;
  }

  // r_ = A y - b + a_norm y / ||y|| on the free components (0 on the pinned ones); returns ||r_||.
  double pattern_equation_residual(const Vec<N>& y) {
    r_.noalias() = A_ * y;
    r_ -= b_;
    const double ny = y.norm();
    for (int i = 0; i < size(); ++i) {
      if (pinned_(i)) {
        r_(i) = 0.0;
      } else if (ny > 0.0) {
        r_(i) += an_ * y(i) / ny;
      }
    }
    return r_.norm();
  }

  void pin_zeros(const Pattern& s, Vec<N>& y) const {
    for (int i = 0; i < size(); ++i)
      if (a_(i) > 0.0 && s(i) == 0) y(i) = 0.0;  // exactly zero, not round-off
  }

  // w_ = -(P y + x) for the y of the last pattern solve, unless solve_from_base gave it already.
  void multiplier_estimate(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y) {
    if (w_from_pattern_) return;
    set_w(P, x, y);
  }
  // w_ = -(P y) - x. The product goes into w_ itself: nested in an expression, Eigen would evaluate it
  // into a temporary, on the heap at dynamic sizes (an allocation per step). The same values.
  void set_w(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y) {
    w_.noalias() = P * y;
    w_ = -w_ - x;
  }

  // Whether y (from pattern s) satisfies (6.5): free components keep their sign, pinned ones have a
  // multiplier within their gain.
  bool consistent(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y, const Pattern& s, double scale_px, double gain_scale) {
    multiplier_estimate(P, x, y);
    y_zero_ = y.squaredNorm() == 0.0;  // ||y|| == 0, without its square root
    if (an_ > 0.0) {
      if (y_zero_) return false;
      w_ -= (an_ / y.norm()) * y;
    }
    const double tol = pattern_tolerance(x, y, scale_px, gain_scale);
    for (int i = 0; i < size(); ++i)
      if (breaks_pattern(i, y, s, tol)) return false;
    return true;
  }

  // The slack of the multiplier test below: a few ulps of the size of the terms of (6.5).
  // Keeps the scale for accept(), which follows on the same y.
  double pattern_tolerance(const Vec<N>& x, const Vec<N>& y, double scale_px, double gain_scale) {
    pattern_scale_ = x.cwiseAbs().maxCoeff() + scale_px * y.cwiseAbs().maxCoeff() + gain_scale;
    return 64.0 * std::numeric_limits<double>::epsilon() * pattern_scale_;
  }

  // Whether component i breaks pattern s at y, with w_ = -(P y + x) (- a_norm y / ||y||) current: a
  // moving component with the wrong sign, or a resting one whose multiplier leaves [-a_i, a_i].
  bool breaks_pattern(int i, const Vec<N>& y, const Pattern& s, double tol) const {
    if (!(a_(i) > 0.0)) return false;
    return s(i) != 0 ? y(i) * s(i) < 0.0 : std::abs(w_(i)) > a_(i) + tol;
  }

  // The active-set update of the semismooth Newton method: s_i = sign(c_i y_i + w_i) where that exceeds
  // a_i, else 0, with w the multiplier estimate and c_i = P_ii. Returns whether the pattern changed.
  bool update_pattern(const Mat<N>& P, const Vec<N>& x, const Vec<N>& y) {
    multiplier_estimate(P, x, y);
    const double ny = y.norm();
    if (an_ > 0.0 && ny > 0.0) w_ -= (an_ / ny) * y;
    bool changed = false;
    for (int i = 0; i < size(); ++i) {
      if (!(a_(i) > 0.0)) continue;
      const double u = P(i, i) * y(i) + w_(i);
      const std::int8_t si = std::abs(u) > a_(i) ? (u > 0.0 ? 1 : -1) : 0;
      if (si != pattern_(i)) {
        pattern_(i) = si;
        changed = true;
      }
    }
    return changed;
  }

  // Separable phi (a_norm = 0): (6.5) is the box-constrained LCP "P y + x + s = 0, s_i in a_i Sgn(y_i)",
  // and P is a P-matrix (its symmetric part is positive definite under Theorem 4.1's condition), so it has
  // one solution. Block principal pivoting with the safeguard of Judice and Pires (Comput. Oper. Res. 21,
  // 1994): each sweep solves the pattern's equations and counts the components that break it (a moving
  // one with the wrong sign, a resting one whose multiplier leaves [-a_i, a_i]); while the count falls,
  // every such component changes state at once (as the active-set update); after kTries sweeps without a
  // new lowest count, only the one of least index changes (Murty's rule, finite for P-matrices), until
  // the count falls below its lowest again. Exact like every other path: the result is the pattern's own
  // solution, with 0.0 where a component rests. The sweep cap is a safety net, never a tolerance.
  bool principal_pivoting(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, double scale_px, double gain_scale, OneStepStats& stats) {
    const int n = size();
    const long max_sweeps = 100L * n + 1000;
    PivotingSafeguard safeguard;
    for (long sweep = 0; sweep < max_sweeps; ++sweep) {
      ++stats.iterations;
      if (!solve_pattern(P, x, pattern_, y)) return false;  // singular: P is not a P-matrix
      multiplier_estimate(P, x, y);
      const double tol = pattern_tolerance(x, y, scale_px, gain_scale);
      int count = 0, first = -1;
      for (int i = 0; i < n; ++i) {
        if (!breaks_pattern(i, y, pattern_, tol)) continue;
        ++count;
        if (first < 0) first = i;
      }
      if (count == 0) {
        y_zero_ = y.squaredNorm() == 0.0;
        if (direct_) return accept(P, x, y, scale_px, gain_scale, stats, /*w_is_current=*/true);
        return accept_shared_solution(P, x, y, scale_px, gain_scale, stats);
      }
      const bool block = safeguard.block_pivot(count);
      // A broken moving component comes to rest; a broken resting one moves the way its multiplier left
      // [-a_i, a_i].
      for (int i = block ? 0 : first; i < (block ? n : first + 1); ++i)
        if (breaks_pattern(i, y, pattern_, tol)) pattern_(i) = pattern_(i) != 0 ? 0 : (w_(i) > 0.0 ? 1 : -1);
    }
    accept(P, x, y, scale_px, gain_scale, stats);
    return false;
  }

  // prox of gamma*phi: soft threshold by gamma*a, then shrink the norm by gamma*a_norm (the prox of an
  // l1 plus l2 penalty is the composition of the two).
  void prox(Vec<N>& z, double gamma) const {
    for (int i = 0; i < size(); ++i) {
      const double t = gamma * a_(i);
      z(i) = z(i) > t ? z(i) - t : (z(i) < -t ? z(i) + t : 0.0);
    }
    if (an_ > 0.0) {
      const double nz = z.norm();
      const double t = gamma * an_;
      if (nz <= t)
        z.setZero();
      else
        z *= (1.0 - t / nz);
    }
  }

  bool forward_backward(const Mat<N>& P, const Vec<N>& x, Vec<N>& y, double scale_px, double gain_scale, OneStepStats& stats) {
    const int n = size();
    const Mat<N> Ps = 0.5 * (P + P.transpose());
    Eigen::SelfAdjointEigenSolver<Mat<N>> eig(Ps, Eigen::EigenvaluesOnly);
    const double mu = eig.eigenvalues()(0);
    Eigen::JacobiSVD<Mat<N>> svd(P);
    const double L = svd.singularValues()(0);
    if (!(mu > 0.0) || !(L > 0.0)) return false;
    const double gamma = mu / (L * L);
    y.setZero(n);
    for (int it = 1; it <= 200000; ++it) {
      w_.noalias() = P * y;
      w_ += x;
      best_ = y - gamma * w_;
      prox(best_, gamma);
      y = best_;
      ++stats.iterations;
      if (it % 64 == 0) {
        for (int i = 0; i < n; ++i) trial_(i) = y(i) > 0.0 ? 1 : (y(i) < 0.0 ? -1 : 0);
        if (solve_pattern(P, x, trial_, dy_) && consistent(P, x, dy_, trial_, scale_px, gain_scale)) {
          y = dy_;
          pattern_ = trial_;
          return accept(P, x, y, scale_px, gain_scale, stats);
        }
      }
    }
    accept(P, x, y, scale_px, gain_scale, stats);
    return false;
  }

  Vec<N> a_;
  double an_ = 0.0;
  int bandwidth_ = -1;  // the band of the linear solves, -1 dense
  bool nonsmooth_ = false;
  Pattern pattern_, trial_, pinned_, tried_;
  bool tried_any_ = false;                                         // radius_search: whether tried_ holds a pattern tried this search
  Eigen::Matrix<std::int8_t, N, Eigen::Dynamic> newton_patterns_;  // the semismooth Newton's patterns, in order
  Mat<N> A_, J_, shifted_;                                         // shifted_: P + (a_norm / t) I of radius_search
  Vec<N> b_, w_, r_, dy_, best_;
  bool y_zero_ = false;          // whether the y consistent() checked last is 0
  double pattern_scale_ = 0.0;   // the scale of the terms of (6.5) at that y (pattern_tolerance)
  bool w_from_pattern_ = false;  // w_ is -(P y + x) for the last pattern solve, from solve_from_base
  Eigen::PartialPivLU<Mat<N>> lu_;

  // The shared factorisation (solve_from_base): sizes where it applies, and its buffers.
  static constexpr int kShareMin = 16;   // below, a pattern's own LU costs little
  static constexpr int kShareMax = 128;  // the sizes it is tested and measured on (its buffers are n x n)
  bool share_factorisation_ = false;
  bool direct_ = true;  // this attempt's pattern solves are direct
  std::int64_t direct_resolves_ = 0, direct_retries_ = 0, schur_updates_ = 0;
  Pattern start_, col_ready_;
  // The step's base pattern: its free set F0 (base_index_, base_size_ = |F0|, -1 before the step's first
  // pattern; base_position_(i) = position of i in F0 or -1), the LU factors of P_F0F0 in the leading
  // block of base_lu_ with their row interchanges, and the columns B^{-1} k_j that col_ready_ marks.
  int base_size_ = -1;
  Mat<N> base_lu_, base_cols_, small_;  // small_: the Schur complement S of a later pattern
  Eigen::Matrix<int, N, 1> base_transpositions_, small_transpositions_, base_index_, base_position_, index_;
  Vec<N> u_, col_, small_rhs_;
};

}  // namespace moreau
