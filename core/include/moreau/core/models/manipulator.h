// The two-degree-of-freedom manipulator of section 6 of Adly, Brogliato and Le (2016), written as a
// compiled C++ model (the same system as scenes/manipulator.json):
//
//   M(q) = [[m1 + m2, m2 b cos th2], [m2 b cos th2, I + m2 b^2]],   q = (x1, th2)
//   C(q, v) = [[0, -m2 b th2' sin th2], [0, 0]]                      (the Christoffel C of (1.4)-(1.5))
//   grad V(q) = (0, b m2 g sin th2)
//   F(t, q, v) = (sin t, sin x1) when perturbed (Figures 6.4, 6.5), else 0
//   Phi(v) = 1/2 ||v||^2 + |v1| + |v2|
//
// The paper gives no values for m1, m2, b, I, g; the defaults are the ones scenes/manipulator.json uses.
#pragma once

#include <cmath>

#include "moreau/core/controller.h"
#include "moreau/core/types.h"

namespace moreau::models {

struct ManipulatorParameters {
  double m1_kg = 1.0;          // cart mass
  double m2_kg = 1.0;          // link mass
  double b_m = 0.5;            // distance from the joint to the link's centre of mass
  double inertia_kg_m2 = 0.1;  // link inertia about its centre of mass
  double gravity_m_s2 = 9.81;
  bool perturbed = false;  // F = (sin t, sin x1)
};

class Manipulator {
 public:
  static constexpr int kDof = 2;

  explicit Manipulator(const ManipulatorParameters& p = {}) : p_(p) {
    phi_.weights = Vec<2>(1.0, 1.0);
    phi_.gains = Vec<2>(1.0, 1.0);
    phi_.norm_gain = 0.0;
  }
  Manipulator(const ManipulatorParameters& p, const Controller<2>& phi) : p_(p), phi_(phi) {}

  int dof() const { return 2; }
  const Controller<2>& controller() const { return phi_; }
  bool constant_mass() const { return false; }
  bool constant_terms() const { return false; }

  void mass(const Vec<2>& q, Mat<2>& M) const {
    const double off = p_.m2_kg * p_.b_m * std::cos(q(1));
    M << p_.m1_kg + p_.m2_kg, off, off, p_.inertia_kg_m2 + p_.m2_kg * p_.b_m * p_.b_m;
  }

  void evaluate(double t, const Vec<2>& q, const Vec<2>& v, LagrangianTerms<2>& out) const {
    const double c = std::cos(q(1)), s = std::sin(q(1));
    const double m2b = p_.m2_kg * p_.b_m;
    out.M << p_.m1_kg + p_.m2_kg, m2b * c, m2b * c, p_.inertia_kg_m2 + m2b * p_.b_m;
    out.C << 0.0, -m2b * v(1) * s, 0.0, 0.0;
    out.g << 0.0, m2b * p_.gravity_m_s2 * s;
    if (p_.perturbed) {
      out.g(0) += std::sin(t);
      out.g(1) += std::sin(q(0));
    }
  }

 private:
  ManipulatorParameters p_;
  Controller<2> phi_;
};

}  // namespace moreau::models
