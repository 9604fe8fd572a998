// The contact system of the large-contact path (large_contact_system.h).
#include "moreau/core/large_contact_system.h"

#include <cmath>

namespace moreau {

void LargeContactSystem::evaluate(const Eigen::VectorXd& q, Eigen::VectorXd& gap, Eigen::SparseMatrix<double, Eigen::RowMajor>& H,
                                  std::vector<double>& scratch) const {
  if (linear()) {
    gap.noalias() = gradients * q;
    gap += offsets;
    return;
  }
  gap.resize(num_constraints());
  nonlinear_gaps->evaluate(q.data(), gap.data(), H.valuePtr(), scratch.data());
}

std::string LargeContactSystem::validate() const {
  const int n = dof(), nc = num_constraints();
  if (n < 1) return "no coordinates";
  if (n > kMaxLargeContactDof)
    return "more than " + std::to_string(kMaxLargeContactDof) + " coordinates (" + std::to_string(n) +
           "): the bound on one run's memory and step time";
  if (nc > kMaxLargeContacts)
    return "more than " + std::to_string(kMaxLargeContacts) + " contacts (" + std::to_string(nc) +
           "): the bound on one run's memory and step time";
  if (force.size() != n) return "force has " + std::to_string(force.size()) + " entries, expected " + std::to_string(n);
  if (gradients.cols() != n)
    return "the gradient matrix has " + std::to_string(gradients.cols()) + " columns, expected " + std::to_string(n);
  if (linear() && offsets.size() != nc) return "offsets has " + std::to_string(offsets.size()) + " entries, expected " + std::to_string(nc);
  if (static_cast<int>(restitution.size()) != nc)
    return "restitution has " + std::to_string(restitution.size()) + " entries, expected " + std::to_string(nc);
  for (int j = 0; j < n; ++j)
    if (!(mass(j) > 0.0) || !std::isfinite(mass(j))) return "mass " + std::to_string(j) + " is not a finite positive number";
  if (!force.allFinite()) return "force is not finite";
  if (linear() && !offsets.allFinite()) return "an offset is not finite";
  // How densely the contacts couple: D = H M^-1 H^T has at most sum_j c_j^2 nonzeros, c_j the contacts
  // on coordinate j. The path is for contacts that each touch a few others (a ball has a handful of
  // neighbours); a dense coupling would make each pass's factorisation cubic, one request's step time
  // unbounded in practice.
  std::vector<long long> per_coordinate(static_cast<std::size_t>(n), 0);
  for (int i = 0; i < nc; ++i)
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(gradients, i); it; ++it)
      ++per_coordinate[static_cast<std::size_t>(it.col())];
  long long coupling = 0;
  for (long long c : per_coordinate) coupling += c * c;
  const long long allowed = kMaxDelassusNonzerosPerContact * static_cast<long long>(nc) + 4096;
  if (coupling > allowed)
    return "the contacts couple too densely for this path: H M^-1 H^T may have " + std::to_string(coupling) + " nonzeros, more than " +
           std::to_string(kMaxDelassusNonzerosPerContact) + " per contact (" + std::to_string(allowed) +
           "); it is for contacts that each touch a few others";
  for (int i = 0; i < nc; ++i) {
    bool nonzero = false;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(gradients, i); it; ++it) {
      if (!std::isfinite(it.value())) return "the gradient of contact " + std::to_string(i) + " is not finite";
      nonzero = nonzero || it.value() != 0.0 || !linear();  // nonlinear: an entry of the pattern
    }
    if (!nonzero) return "the gradient of contact " + std::to_string(i) + (linear() ? " is zero" : " reads no coordinate");
    const double e = restitution[static_cast<std::size_t>(i)];
    if (!(e >= 0.0 && e <= 1.0)) return "the restitution of contact " + std::to_string(i) + " is outside [0, 1]";
  }
  return {};
}

}  // namespace moreau
