// An exact solver of the linear complementarity problem of a contact step at scale,
//
//   w = D z + q,   0 <= z  perp  w >= 0,                                                    (LCP)
//
// D symmetric positive definite and sparse: the Delassus operator H M^{-1} H^T of contacts with linearly
// independent gradients (the stack, the cradle, a column of balls), restricted to the rows of the step's
// predicted active set. The one-step problem of Moreau-Jean (eq. (8) of Brogliato 2003) is this LCP in
// the contact impulses z = P and the post-step normal velocities w = U+ + e min(U-, 0).
//
// Method: block principal pivoting (Judice and Pires, "A block principal pivoting algorithm for
// large-scale strictly monotone linear complementarity problems", Computers & Operations Research 21,
// 1994). A complementary set F (z free, w_F = 0) gives z_F = -D_FF^{-1} q_F and w_G = q_G + D_GF z_F on
// the rest (z_G = 0). The rows where z_F < 0 or w_G < 0 are infeasible; while their number falls, they
// change sides at once (the rows of G all of them; the rows of F those with z at least
// Options::removal_fraction = 0.99 as negative as the most negative, in practice the most negative alone:
// one wrong row in F pulls a whole chain of contacts negative, and removing the chain would throw away a
// warm start that was right but for that row); when it has not fallen for Options::block_retries passes, one pivot of Murty's
// least-index rule is taken instead (the infeasible row of largest index changes sides; Murty, "Note on a
// Bard-type scheme for solving the complementarity problem", Opsearch 11, 1974), which visits no set
// twice and ends for every P-matrix, so the method terminates in finitely many passes with the exact
// solution, unique since D is positive definite. No enumeration of the 2^m sets and no iteration to a
// tolerance: each pass solves a linear system, and the answer is a complementary set's exact solution
// (w_F == 0.0 by construction, z_G == 0.0).
//
// Guess: when the warm start's pass fails, projected Gauss-Seidel sweeps (forward and backward) from the
// z the caller gave (the previous step's impulses) pick the set the passes go on from, and again, with 4
// times the sweeps from the last pass's z, after every kPassesBeforeNewGuess passes that did not end
// (Options::guess_sweeps, guess_restarts: 1, 4, 16, 64 sweeps). An impact wave through a column of closed
// contacts otherwise makes the block rule close one contact per pass (154 passes, each a factorisation,
// in one step of a dropped stack of 1024). The guesses are bounded in number, so termination is still
// that of the rules above, and the answer is still a pass's exact solution. Measured (docs/scaling.md):
// the landing granular column of 1024 took 521 passes in one step when the first guess started from the
// failed pass's z and the removal fraction was 0.5 (the chain that one wrong row had pulled negative was
// lost to both).
//
// Cost: one sparse LDL^T factorisation of D_FF per pass whose set differs from the last one factorised
// (a banded D, as a stack's tridiagonal one, factorises in O(|F|)); a step whose answer has the set of
// the previous step (a system at rest, contacts that stay closed) starts from it, is accepted at the first
// pass and reuses the factor: two triangular solves.
//
// Accepting a pass: z_F >= -tol_z and w_G >= -tol_w, the round-off of the solve (tol_w = 64 eps (|q|_inf
// + |D|_inf |z|_inf), tol_z = 64 eps |z|_inf, the allowance the dense solvers use); the residual reported
// is max_i |min(z_i, w_i)| relative to |q|_inf. A D_FF that is not positive definite within round-off
// (dependent gradients) ends the solve with `singular` set: the problem is outside this solver.
#pragma once

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <vector>

namespace moreau {

struct SparseLcpStats {
  int passes = 0;          // complementary sets tried
  int murty_pivots = 0;    // passes that changed one row (the least-index rule)
  int factorisations = 0;  // passes whose D_FF was factorised (the others reused the factor)
  double residual = 0.0;   // max_i |min(z_i, w_i)| / |q|_inf over the problem's rows
  double tolerance = 0.0;  // tol_w / |q|_inf of the accepted pass
  bool singular = false;   // some D_FF was not positive definite
};

class SparseLcpSolver {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;  // column-major

  struct Options {
    int block_retries = 3;           // passes without fewer infeasible rows before Murty's rule (Judice-Pires use 3)
    bool least_index_only = false;   // Murty's rule from the first pass (slower; the reference of the block phase)
    double removal_fraction = 0.99;  // block passes move out of F the rows with z below this times the most negative z
    // When the warm start's pass is not the answer, and again after every kPassesBeforeNewGuess passes
    // that did not end (at most guess_restarts times more, each with 4 times the sweeps), projected
    // Gauss-Seidel sweeps guess the set the passes go on from (0: none).
    int guess_sweeps = 1;
    int guess_restarts = 3;
  };
  Options options;

  // D: m x m, symmetric positive definite on the sets it is asked about (both triangles stored).
  void set_matrix(const SparseMatrix& D);
  int size() const { return static_cast<int>(D_.rows()); }

  // Solves (LCP) on the rows `rows` of D (distinct, increasing; the other rows are not part of the
  // problem). q, z and w are indexed by D's rows; z and w are written at `rows` only. `in_F[r]` says
  // whether row r starts in the complementary set (the previous answer: a warm start) and holds the
  // answer's set on return. False when the problem is outside the solver (stats.singular) or, which
  // termination rules out in exact arithmetic, no pass was accepted within the pass budget.
  bool solve(const std::vector<int>& rows, const Eigen::VectorXd& q, Eigen::VectorXd& z, Eigen::VectorXd& w, std::vector<char>& in_F,
             SparseLcpStats& stats);

  // D_SS for the rows S (increasing) of a symmetric sparse D, both triangles stored: the principal
  // submatrix each pass factorises, and the Schur complement the impact step's position update solves
  // with. `local` (one entry per row of D, all -1) and `scratch` are the caller's, reused between calls;
  // `local` is all -1 again on return.
  static void principal_submatrix(const SparseMatrix& D, const std::vector<int>& rows, std::vector<int>& local,
                                  std::vector<Eigen::Triplet<double>>& scratch, SparseMatrix& out);

  // The passes one solve may take before it gives up: 2^m bounds Murty's rule, far beyond any problem
  // met; a budget linear in m (plus a margin) keeps a step's cost bounded.
  static int pass_budget(int m) { return 50 + 10 * m; }

 private:
  bool factorise(SparseLcpStats& stats);
  void guess_by_gauss_seidel(const std::vector<int>& rows, const Eigen::VectorXd& q, Eigen::VectorXd& z, int sweeps);

  static constexpr int kPassesBeforeNewGuess = 4;
  // A D whose nonzeros lie within this distance of its diagonal (a stack's or a cradle's tridiagonal D)
  // is factorised in its own order: no fill beyond the band, and no minimum-degree ordering to compute
  // at every factorisation (measured: the dropped stack of 1024, 113 -> 65 us per step median).
  static constexpr int kNaturalOrderingBandwidth = 8;

  SparseMatrix D_;
  double d_norm_inf_ = 0.0;      // max row sum of |D|
  std::vector<int> F_, G_;       // this pass's complementary set and its complement (row indices of D)
  std::vector<int> factored_F_;  // the set whose D_FF is in ldlt_
  bool factor_valid_ = false;
  std::vector<int> local_;  // per row of D: its index in F_, -1 outside F_
  std::vector<char> role_;  // per row of D: 0 outside the problem, 1 in G, 2 in F
  SparseMatrix dff_;
  bool banded_ = false;                                                                         // the ordering below
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt_;                                      // AMD ordering: 2D patterns
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> banded_ldlt_;  // banded D
  Eigen::VectorXd rhs_, zf_;
  Eigen::VectorXd z_start_;  // z on the problem's rows as the caller gave it: where the first guess starts
  std::vector<Eigen::Triplet<double>> triplets_;
};

}  // namespace moreau
