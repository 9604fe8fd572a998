// The system of the ABL scheme at scale (large_abl_integrator.h): thousands of coordinates, stored in
// memory linear in their number.
//
//   M q'' + grad V(q) + F  in  -dPhi(q'),   Phi(v) = sum_i w_i v_i^2 / 2 + a_i |v_i|,
//
// the system (0.1) of Adly, Brogliato and Le (2016) with M constant, symmetric positive definite and
// sparse (a chain's or a finite-element bar's banded M), so that C = 0 (a constant M has no Christoffel
// symbols), F constant, and a separable Phi (viscous and Coulomb friction at every coordinate, the
// controller's quadratic and abs terms of controller.h; the norm term is not separable and is not taken).
// grad V is either constant (folded into `force`) or given by a SparseVectorFunction, each of whose
// components reads a few coordinates (the springs, pendulums and contacts-free couplings of a chain).
// No I/O here: the scene compiles its expressions into that function (scene/input/sparse_vector_tapes.h).
#pragma once

#include <Eigen/SparseCore>
#include <memory>
#include <string>
#include <vector>

#include "moreau/core/controller.h"
#include "moreau/core/sparse_vector_function.h"

namespace moreau {

// The largest system this path takes, as the large-contact path's (large_contact_system.h): memory and a
// step's time are linear in n, and the bound keeps one request's both bounded.
inline constexpr int kMaxLargeAblDof = 10000;
// The coupling this path takes: M's nonzeros at most this many per coordinate. A banded M of bandwidth b
// has 2 b + 1 per row; a dense coupling would make each factorisation of the step cubic.
inline constexpr long long kMaxMassNonzerosPerCoordinate = 32;

struct LargeAblSystem {
  Eigen::SparseMatrix<double> mass;  // M: n x n, constant, symmetric positive definite, both triangles stored
  Controller<Eigen::Dynamic> phi;    // w_i >= 0, a_i >= 0, no norm term
  Eigen::VectorXd force;             // the constant part of g = grad V + F (n entries)
  // The rest of g: grad V(q) of a nonlinear potential, value[i] = dV/dq_i (an empty Jacobian pattern: the
  // scheme (0.2) is explicit in position and never differentiates g). Null: g is constant.
  std::shared_ptr<const SparseVectorFunction> gradient;

  int dof() const { return static_cast<int>(force.size()); }
  // max |i - j| over M's stored entries: the band of every factorisation (natural order when narrow).
  int bandwidth() const;
  // g(q) = force + grad V(q). `scratch`: gradient->make_scratch(), or empty when g is constant.
  void evaluate(const Eigen::VectorXd& q, Eigen::VectorXd& g, std::vector<double>& scratch) const;
  // "" when the system is valid for the integrator, else what is wrong: sizes, a value that is not finite,
  // M not symmetric or too densely coupled, a weight or gain < 0, a norm term, a size above the limit.
  // Positive definiteness is certified_lambda_min's.
  std::string validate() const;
};

// A certified positive lower bound of lambda_min(M) for a symmetric sparse M (both triangles stored), or
// a value <= 0 when M is not shown positive definite: Gershgorin's bound when it is positive, else
// s = (1 - 1e-3) times the Rayleigh quotient of an inverse-iteration vector, certified by a Cholesky
// factor of M - s I (halving s until one exists; a symmetric matrix is positive definite iff it has one),
// the certificate step_conditions.h uses for dense M. `exact` is set false: the value is a bound.
double certified_lambda_min(const Eigen::SparseMatrix<double>& M);

}  // namespace moreau
