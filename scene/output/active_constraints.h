// The unilateral constraints active at a run's final position: one evaluation, for the report's
// reactions ("unique at the final state" or not) and for Lemma 3 of Brogliato (2003) in the hypotheses
// ledger, so that the two never disagree on which contacts are closed.
#pragma once

#include <vector>

#include <Eigen/Dense>

#include "moreau/core/run_summary.h"
#include "moreau/scene/scene.h"

namespace moreau::scene::detail {

struct ActiveConstraints {
  bool evaluated = false;     // false without compiled constraints, or without a final state of n coordinates
  std::vector<int> active;    // the active constraints, in the scene's order
  Eigen::MatrixXd gradients;  // row a: grad h_i(q*) of the a-th active constraint (active.size() x n); empty on the large-contact path
  // The rank of the active gradients when it is computed here (a scene on the large-contact path, whose
  // gradients stay sparse: sparse QR); -1 otherwise (the caller ranks `gradients`).
  int sparse_rank = -1;
  Eigen::VectorXd grad_u;  // grad U(q*), the potential's part of the forces
  double gap_tolerance = 0.0;
};

// At q* = the run's final position: a velocity-level scheme rests with a gap of up to about one step's
// fall, h^2 |M^{-1} grad U| <= h^2 |grad U| / lambda_min(M) (lambda_min over the run, RunSummary::mass).
// A constraint whose gap h_i(q*) is finite and within ten times that (plus 1e-12) is active.
ActiveConstraints active_constraints_at_end(const LagrangianScene& scene, const RunSummary& s);

}  // namespace moreau::scene::detail
