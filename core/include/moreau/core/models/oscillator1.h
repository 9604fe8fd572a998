// A one-degree-of-freedom textbook model with known closed forms, as a compiled C++ model:
//
//   m x'' + k x + f0  in  -(c x' + a Sign(x'))
//
// constant mass m, a spring k, a constant force f0 (F = f0 in (0.1)), a viscous damper c and a relay
// (Coulomb friction) a, the last two as the controller Phi(v) = c v^2 / 2 + a |v|. With k = f0 = 0 it is
// the damped relay, which stops at t* = (m/c) ln(1 + c v0 / a); with c = k = 0 the forced relay; with
// c = f0 = 0 the Coulomb oscillator.
#pragma once

#include "moreau/core/controller.h"
#include "moreau/core/types.h"

namespace moreau::models {

struct Oscillator1 {
  static constexpr int kDof = 1;
  double mass_kg = 1.0, stiffness_n_per_m = 0.0, force_n = 0.0;
  Controller<1> phi;

  Oscillator1(double m, double k, double f0, double c, double a) : mass_kg(m), stiffness_n_per_m(k), force_n(f0) {
    phi.weights = Vec<1>(c);
    phi.gains = Vec<1>(a);
  }
  int dof() const { return 1; }
  const Controller<1>& controller() const { return phi; }
  bool constant_mass() const { return true; }
  bool constant_terms() const { return stiffness_n_per_m == 0.0; }  // g = k x + f0
  void mass(const Vec<1>&, Mat<1>& M) const { M(0, 0) = mass_kg; }
  void evaluate(double, const Vec<1>& q, const Vec<1>&, LagrangianTerms<1>& out) const {
    out.M(0, 0) = mass_kg;
    out.C(0, 0) = 0.0;
    out.g(0) = stiffness_n_per_m * q(0) + force_n;
  }
};

}  // namespace moreau::models
