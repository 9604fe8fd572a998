// The system of the ABL scheme at scale (large_abl_system.h).
#include "moreau/core/large_abl_system.h"

#include <Eigen/SparseCholesky>

#include "moreau/core/banded_ldlt.h"
#include <algorithm>
#include <cmath>
#include <limits>

namespace moreau {

int LargeAblSystem::bandwidth() const { return moreau::bandwidth(mass); }

void LargeAblSystem::evaluate(const Eigen::VectorXd& q, Eigen::VectorXd& g, std::vector<double>& scratch) const {
  if (!gradient) {
    g = force;
    return;
  }
  g.resize(dof());
  gradient->evaluate(q.data(), g.data(), nullptr, scratch.data());
  g += force;
}

std::string LargeAblSystem::validate() const {
  const int n = dof();
  if (n < 1) return "no coordinates";
  if (n > kMaxLargeAblDof) return "more than " + std::to_string(kMaxLargeAblDof) + " coordinates (got " + std::to_string(n) + ")";
  if (mass.rows() != n || mass.cols() != n) return "M is not n x n";
  if (phi.weights.size() != n || phi.gains.size() != n) return "Phi's weights and gains need one entry per coordinate";
  if (phi.norm_gain != 0.0) return "the norm term of Phi is not separable: this path takes quadratic and abs terms only";
  for (int i = 0; i < n; ++i) {
    if (!(phi.weights(i) >= 0.0) || !std::isfinite(phi.weights(i))) return "weight " + std::to_string(i) + " is not a finite number >= 0";
    if (!(phi.gains(i) >= 0.0) || !std::isfinite(phi.gains(i))) return "gain " + std::to_string(i) + " is not a finite number >= 0";
    if (!std::isfinite(force(i))) return "the force is not finite (component " + std::to_string(i) + ")";
  }
  if (mass.nonZeros() > kMaxMassNonzerosPerCoordinate * n)
    return "M has " + std::to_string(mass.nonZeros()) + " nonzeros, more than " + std::to_string(kMaxMassNonzerosPerCoordinate) +
           " per coordinate: the coupling is too dense for this path (each factorisation would not be linear in n)";
  const Eigen::SparseMatrix<double> Mt = mass.transpose();
  for (int j = 0; j < n; ++j) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(mass, j); it; ++it) {
      if (!std::isfinite(it.value())) return "M(" + std::to_string(it.row()) + ", " + std::to_string(j) + ") is not finite";
      if (Mt.coeff(it.row(), j) != it.value())
        return "M is not symmetric: M(" + std::to_string(it.row()) + ", " + std::to_string(j) + ") != M(" + std::to_string(j) + ", " +
               std::to_string(it.row()) + ")";
    }
  }
  return "";
}

double certified_lambda_min(const Eigen::SparseMatrix<double>& M) {
  const int n = static_cast<int>(M.rows());
  if (n == 0) return 0.0;
  double gershgorin = std::numeric_limits<double>::infinity();
  Eigen::VectorXd diag = Eigen::VectorXd::Zero(n);
  for (int j = 0; j < n; ++j) {
    double off = 0.0;
    for (Eigen::SparseMatrix<double>::InnerIterator it(M, j); it; ++it) {
      if (it.row() == j)
        diag(j) = it.value();
      else
        off += std::abs(it.value());
    }
    gershgorin = std::min(gershgorin, diag(j) - off);  // column j's sum: M is symmetric
  }
  if (gershgorin > 0.0) return gershgorin;
  if (!(diag.minCoeff() > 0.0)) return std::min(diag.minCoeff(), 0.0);  // a diagonal entry <= 0: not positive definite
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(M);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0.0)) return 0.0;
  // Inverse iteration towards lambda_min's eigenvector; its Rayleigh quotient is above lambda_min.
  Eigen::VectorXd x = Eigen::VectorXd::Ones(n) / std::sqrt(static_cast<double>(n));
  for (int i = 0; i < 3 * n && i < 60; ++i) {
    x = ldlt.solve(x);
    x.normalize();
  }
  double s = (1.0 - 1e-3) * x.dot(M * x);
  Eigen::SparseMatrix<double> I(n, n);
  I.setIdentity();
  for (int halvings = 0; halvings < 60 && s > 0.0; ++halvings, s *= 0.5) {
    Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt(M - s * I);
    if (llt.info() == Eigen::Success) return s;
  }
  return 0.0;
}

}  // namespace moreau
