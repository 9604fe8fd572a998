#include "active_constraints.h"

#include <algorithm>
#include <cmath>

#include "moreau/scene/scene_model.h"

namespace moreau::scene::detail {

ActiveConstraints active_constraints_at_end(const LagrangianScene& scene, const RunSummary& s) {
  ActiveConstraints out;
  const CompiledLagrangian* c = scene.compiled.get();
  const int n = scene.n, m = static_cast<int>(scene.constraint_names.size());
  if (!c || m == 0 || static_cast<int>(s.q_final.size()) != n) return out;
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
