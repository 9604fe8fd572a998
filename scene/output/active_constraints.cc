#include "active_constraints.h"

#include <algorithm>
#include <cmath>

#include <Eigen/SparseQR>

#include "moreau/scene/scene_model.h"

namespace moreau::scene::detail {

namespace {

// A scene compiled for the large-contact path alone: the gaps and gradients from its system (H sparse,
// constant or evaluated at the end), the rank of the active rows by sparse QR; `gradients` stays empty.
ActiveConstraints large_contact_path_at_end(const LagrangianScene& scene, const RunSummary& s) {
  ActiveConstraints out;
  const CompiledLagrangian& c = *scene.compiled;
  if (!c.large_contacts) return out;
  const LargeContactSystem& sys = *c.large_contacts;
  const int n = scene.n;
  const Eigen::Map<const Eigen::VectorXd> q(s.q_final.data(), n);
  std::vector<double> v(static_cast<std::size_t>(n), 0.0), split(static_cast<std::size_t>(2 * n));
  ForceTerms(c).split(s.t_final, s.q_final.data(), v.data(), split.data(), split.data() + n);
  out.grad_u = Eigen::Map<const Eigen::VectorXd>(split.data(), n);
  const double h = scene.settings.h;
  out.gap_tolerance = 10.0 * h * h * out.grad_u.norm() / std::max(s.mass.lambda_min, 1e-300) + 1e-12;
  // The gaps and gradients at the end: constant H with linear gaps, evaluated at q_final otherwise.
  Eigen::VectorXd gaps;
  Eigen::SparseMatrix<double, Eigen::RowMajor> H = sys.gradients;
  std::vector<double> scratch = sys.linear() ? std::vector<double>{} : sys.nonlinear_gaps->make_scratch();
  sys.evaluate(q, gaps, H, scratch);
  for (int i = 0; i < sys.num_constraints(); ++i)
    if (std::isfinite(gaps(i)) && gaps(i) <= out.gap_tolerance) out.active.push_back(i);
  out.evaluated = true;
  out.sparse_rank = 0;
  if (out.active.empty()) return out;
  std::vector<Eigen::Triplet<double>> t;
  for (std::size_t a = 0; a < out.active.size(); ++a)
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(H, out.active[a]); it; ++it)
      t.emplace_back(static_cast<int>(a), static_cast<int>(it.col()), it.value());
  // The rank of the active rows H_A (a x n) is that of its transpose; SparseQR factorises the one with at
  // least as many rows as columns, with column pivoting by the same 1e-10 threshold as the report's dense QR.
  const Eigen::Index a = static_cast<Eigen::Index>(out.active.size());
  const bool transpose = a < n;
  Eigen::SparseMatrix<double> A(transpose ? n : a, transpose ? a : n);
  if (transpose)
    for (auto& e : t) e = Eigen::Triplet<double>(e.col(), e.row(), e.value());
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  Eigen::SparseQR<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> qr;
  qr.setPivotThreshold(1e-10);
  qr.compute(A);
  out.sparse_rank = qr.info() == Eigen::Success ? static_cast<int>(qr.rank()) : 0;
  return out;
}

}  // namespace

ActiveConstraints active_constraints_at_end(const LagrangianScene& scene, const RunSummary& s) {
  ActiveConstraints out;
  const CompiledLagrangian* c = scene.compiled.get();
  const int n = scene.n, m = static_cast<int>(scene.constraint_names.size());
  if (!c || m == 0 || static_cast<int>(s.q_final.size()) != n) return out;
  if (!c->dense) return large_contact_path_at_end(scene, s);
  // The tapes read (t, q, v); at rest v = 0.
  std::vector<double> slots(static_cast<std::size_t>(1 + 2 * n), 0.0);
  slots[0] = s.t_final;
  for (int i = 0; i < n; ++i) slots[static_cast<std::size_t>(1 + i)] = s.q_final[static_cast<std::size_t>(i)];
  std::vector<double> split(static_cast<std::size_t>(2 * n));
  ForceTerms(*c).split(s.t_final, slots.data() + 1, slots.data() + 1 + n, split.data(), split.data() + n);
  // The constraint tape's outputs: the m gaps h_i(q), then the m gradients, n entries each.
  std::vector<double> cons(c->constraint_tape.num_outputs()), scratch(c->constraint_tape.scratch_size());
  c->constraint_tape.eval(slots.data(), cons.data(), scratch.data());
  out.grad_u = Eigen::Map<const Eigen::VectorXd>(split.data(), n);
  const double h = scene.settings.h;
  out.gap_tolerance = 10.0 * h * h * out.grad_u.norm() / std::max(s.mass.lambda_min, 1e-300) + 1e-12;
  for (int i = 0; i < m; ++i) {
    const double gap = cons[static_cast<std::size_t>(i)];
    if (std::isfinite(gap) && gap <= out.gap_tolerance) out.active.push_back(i);
  }
  out.gradients.resize(static_cast<Eigen::Index>(out.active.size()), n);
  for (std::size_t a = 0; a < out.active.size(); ++a)
    for (int j = 0; j < n; ++j) out.gradients(static_cast<Eigen::Index>(a), j) = cons[static_cast<std::size_t>(m + out.active[a] * n + j)];
  out.evaluated = true;
  return out;
}

}  // namespace moreau::scene::detail
