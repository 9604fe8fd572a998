// The contact system of the large-contact path (large_contact_integrator.h): thousands of coordinates
// and contacts, stored in memory linear in their number.
//
//   M dv = -g dt + grad h(q) dP,   0 <= h(q) perp P >= 0,   Newton's law U+ = -e U- on impacts,
//
// with M constant and diagonal, g = grad V + F constant, and the gaps h either
//  - linear, h(q) = H q + c with a constant sparse H (a stack of balls on a floor, a Newton's cradle), or
//  - nonlinear (balls against balls in a plane: h = |p_i - p_j| - r_i - r_j), given by a
//    SparseVectorFunction that returns h(q) and grad h(q) at any q, with a fixed sparsity pattern: each gap
//    reads a few coordinates, always the same ones (a granular column, a packing).
// No I/O here: the scene compiles its expressions into a SparseVectorFunction (scene/input/sparse_vector_tapes.h).
#pragma once

#include <Eigen/SparseCore>
#include <memory>
#include <string>
#include <vector>

#include "moreau/core/sparse_vector_function.h"

namespace moreau {

// The largest system this path takes: memory is linear in these (a few hundred bytes per coordinate and
// per contact), and so is a step; the bound keeps one request's memory and step time bounded (10,000
// balls: about 4 MB and under a millisecond a step).
inline constexpr int kMaxLargeContactDof = 10000;
inline constexpr int kMaxLargeContacts = 10000;
// The coupling the path takes: the Delassus operator's nonzeros at most this many per contact (plus 4096,
// a dense 64 x 64); a ball in a packing couples each of its contacts with about 2 x 12 others.
inline constexpr long long kMaxDelassusNonzerosPerContact = 32;

struct LargeContactSystem {
  Eigen::VectorXd mass;                                    // the diagonal of M: n entries, each > 0
  Eigen::VectorXd force;                                   // g = grad V + F, constant (n entries)
  bool force_is_potential = true;                          // V(q) = g^T q is the potential in W (Lemma 3)
  Eigen::SparseMatrix<double, Eigen::RowMajor> gradients;  // H: nc x n, row i = grad h_i^T (see below)
  Eigen::VectorXd offsets;                                 // c: h(q) = H q + c (nc entries; linear gaps)
  std::vector<double> restitution;                         // e_i in [0, 1] (nc entries)
  // Null: the gaps are linear, H and c constant. Otherwise h(q) and grad h(q) come from it; `gradients`
  // holds the pattern of grad h(q)^T (every coordinate a gap reads, an entry even where the value is 0)
  // and the values at the initial position, and `offsets` is not used.
  // (evaluate(q, h, the values of grad h(q)^T in that pattern, scratch)).
  std::shared_ptr<const SparseVectorFunction> nonlinear_gaps;

  int dof() const { return static_cast<int>(mass.size()); }
  int num_constraints() const { return static_cast<int>(gradients.rows()); }
  bool linear() const { return nonlinear_gaps == nullptr; }
  // h(q), and with nonlinear gaps grad h(q)^T into `H` (which must have the pattern of `gradients`; with
  // linear gaps H is not touched). `scratch`: nonlinear_gaps->make_scratch(), or empty for linear gaps.
  void evaluate(const Eigen::VectorXd& q, Eigen::VectorXd& gap, Eigen::SparseMatrix<double, Eigen::RowMajor>& H,
                std::vector<double>& scratch) const;
  // "" when the system is valid for the integrator, else what is wrong (sizes, a mass <= 0, a gradient
  // row that is zero (linear gaps) or empty (nonlinear), a restitution outside [0, 1], a value that is
  // not finite, a size above the limits, contacts that couple too densely).
  std::string validate() const;
};

}  // namespace moreau
