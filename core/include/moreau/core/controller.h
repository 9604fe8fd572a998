// The set-valued controller of (0.1): a convex potential Phi of the velocity,
//
//   Phi(v) = 1/2 sum_i w_i v_i^2  +  sum_i a_i |v_i|  +  a_norm ||v||_2
//            (quadratic)             (abs)               (norm, Remark 4.2)
//
// so that dPhi(v) = W v + A Sign(v) + a_norm d||v||, with W = diag(w), A = diag(a) and Sign the
// set-valued sign of (6.2). The section 6 controller of Adly, Brogliato and Le (2016),
// Phi(y) = 1/2 ||y||^2 + |y_1| + |y_2|, is w = (1, 1), a = (1, 1), a_norm = 0.
#pragma once

#include <algorithm>
#include <cmath>

#include "moreau/core/types.h"

namespace moreau {

// <xi, v> for every xi in dPhi(v), Phi = 1/2 <W v, v> + sum_i a_i |v_i| + a_norm ||v|| (Controller below):
// <W v, v> + sum_i a_i |v_i| + a_norm ||v||. The same for every element of the subdifferential, because
// the nonsmooth parts are positively homogeneous of degree 1 (Euler's identity <z, v> = phi(v) for z in
// dphi(v)). The power the controller (and friction) takes out of the system at velocity v, >= 0.
template <int N>
double dissipation_rate(const Vec<N>& w, const Vec<N>& a, double a_norm, const Vec<N>& v) {
  const auto abs_v = v.cwiseAbs().array();  // w_i v_i^2 + a_i |v_i| = |v_i| (w_i |v_i| + a_i)
  const double separable = (abs_v * (w.array() * abs_v + a.array())).sum();
  return a_norm != 0.0 ? separable + a_norm * v.norm() : separable;
}

template <int N>
struct Controller {
  Vec<N> weights;          // w_i >= 0: the quadratic part, which enters the one-step matrix P
  Vec<N> gains;            // a_i >= 0: the separable nonsmooth part
  double norm_gain = 0.0;  // a_norm >= 0: the isotropic nonsmooth part

  static Controller zero(int n) {
    Controller c;
    c.weights.setZero(n);
    c.gains.setZero(n);
    return c;
  }

  int size() const { return static_cast<int>(weights.size()); }
  bool has_quadratic() const { return (weights.array() != 0.0).any(); }
  bool has_nonsmooth() const { return norm_gain > 0.0 || (gains.array() != 0.0).any(); }

  // eta of Assumption 4.1: Phi(v) >= eta ||v||^2 + alpha ||v|| + Phi(0) holds with eta = min_i w_i / 2.
  double eta() const { return size() == 0 ? 0.0 : 0.5 * weights.minCoeff(); }
  // alpha of Assumption 4.1: sum a_i |v_i| >= min_i a_i ||v||_1 >= min_i a_i ||v||_2.
  double alpha() const { return (size() == 0 ? 0.0 : gains.minCoeff()) + norm_gain; }

  double value(const Vec<N>& v) const { return 0.5 * v.dot(weights.cwiseProduct(v)) + gains.dot(v.cwiseAbs()) + norm_gain * v.norm(); }

  // Distance from z to dPhi(0) = A [-1, 1]^n + a_norm B (a box plus a ball): the equilibrium residual of
  // Theorem 4.3 with z = -F(Q, 0) - grad V(Q). Zero when z lies in dPhi(0).
  double distance_to_subdifferential_at_zero(const Vec<N>& z) const {
    const double to_box = (z - z.cwiseMax(-gains).cwiseMin(gains)).norm();
    return std::max(0.0, to_box - norm_gain);
  }

  // Whether z lies in the interior of dPhi(0), the condition of Theorem 4.3 for finite-step convergence.
  // The box-plus-ball has an interior point z iff its distance to the box is < a_norm, or, with no norm
  // term, |z_i| < a_i for every i.
  bool in_interior_of_subdifferential_at_zero(const Vec<N>& z) const {
    if (norm_gain > 0.0) {
      // Interior of box + ball = {z : dist(z, box) < a_norm}, the box possibly degenerate.
      return (z - z.cwiseMax(-gains).cwiseMin(gains)).norm() < norm_gain;
    }
    return (z.array().abs() < gains.array()).all();
  }
};

}  // namespace moreau
