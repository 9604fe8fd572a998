// Variance-based sensitivity: Sobol indices from Saltelli's design, with bootstrap intervals.
//
// For Y = f(X_1, ..., X_k) with independent inputs, the first-order index of input i is the share of
// Var(Y) that X_i explains alone, S_i = Var(E[Y | X_i]) / Var(Y), and the total index the share that
// involves X_i in any way, ST_i = E[Var(Y | X_~i)] / Var(Y) = 1 - Var(E[Y | X_~i]) / Var(Y) (Sobol 1993;
// Homma and Saltelli 1996). ST_i - S_i is the share X_i takes through its interactions with the other
// inputs; S_i = ST_i = 0 means Y does not depend on X_i. Unlike a rank correlation these see effects that
// are not monotone: for the Ishigami function Y = sin x1 + 7 sin^2 x2 + 0.1 x3^4 sin x1 (x uniform on
// [-pi, pi]) Spearman's rho of Y with x2 and with x3 is about 0, while S_2 = 0.4424 and ST_3 = 0.2437.
//
// The design (Saltelli 2002; Saltelli et al. 2010, Section 3), as SALib's sobol/saltelli sample lays it
// out without second-order indices: N base rows, each a point (a, b) of [0, 1)^(2k) split into two points
// a, b of [0, 1)^k (the rows of the matrices A and B), give the N (k + 2) points
//   row j:  a_j,  then A_B^(1)_j, ..., A_B^(k)_j,  then b_j
// where A_B^(i)_j is a_j with its coordinate i taken from b_j. The unit points are mapped to the inputs by
// their inverse CDFs (the caller's business), so any independent input distributions apply.
//
// The estimators (Saltelli et al. 2010, Table 2), with f_A, f_B, f_AB^(i) the model at those points:
//   first order, their estimator (b):  V_i  = 1/N sum_j f_B,j (f_AB^(i),j - f_A,j)
//   total, Jansen's (1999) (f):        VT_i = 1/(2N) sum_j (f_A,j - f_AB^(i),j)^2
// each divided by Var(Y), the variance (1/n, numpy's default) of the 2N values f_A and f_B. As SALib does,
// Y is centred first by the mean of all N (k + 2) values (the first-order estimator is not invariant to a
// shift of Y sample by sample; its variance grows with E[Y]^2 otherwise).
//
// Intervals: the bootstrap of the N rows (Archer, Saltelli and Sobol 1997), as SALib computes it:
// R resamples of N rows drawn with replacement, each estimate computed again on the resample (its variance
// included), and the interval estimate -+ z sd, z = Phi^-1(1/2 + c/2) for confidence c, sd the standard
// deviation (1/(R - 1)) of the R estimates. The rows of a Monte Carlo base are independent, so this is the
// interval of the estimator; for a Sobol (quasi-Monte Carlo) base the rows are not, and the interval is
// typically wider than the estimator's actual error. The resamples are drawn from a seed (SplitMix64),
// so the intervals are the same on every run and platform.
//
// References: I. M. Sobol (1993), Sensitivity estimates for nonlinear mathematical models, Math. Model.
// Comput. Exp. 1, 407-414. A. Saltelli (2002), Making best use of model evaluations to compute
// sensitivity indices, Comput. Phys. Commun. 145, 280-297. A. Saltelli, P. Annoni, I. Azzini,
// F. Campolongo, M. Ratto, S. Tarantola (2010), Variance based sensitivity analysis of model output.
// Design and estimator for the total sensitivity index, Comput. Phys. Commun. 181, 259-270.
// M. J. W. Jansen (1999), Analysis of variance designs for model output, Comput. Phys. Commun. 117, 35-43.
// G. E. B. Archer, A. Saltelli, I. M. Sobol (1997), Sensitivity measures, ANOVA-like techniques and the
// use of bootstrap, J. Stat. Comput. Simul. 58, 99-120. T. Ishigami, T. Homma (1990), An importance
// quantification technique in uncertainty analysis for computer models, ISUMA '90, 398-403.
//
// Numerics only: no JSON, no I/O (the campaign's summary, campaign.h, reports these).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace moreau::scene {

// ---- the design ----

// Points of Saltelli's design for `base_rows` rows and `inputs` inputs: base_rows (inputs + 2).
std::int64_t saltelli_points(std::int64_t base_rows, int inputs);

// Where point i of the design sits: its row j = i / (k + 2), and its block within the row: 0 for a_j,
// 1..k for A_B^(block)_j (input block - 1 taken from b_j), k + 1 for b_j.
struct SaltelliPlace {
  std::int64_t row = 0;
  int block = 0;
};
SaltelliPlace saltelli_place(std::int64_t i, int inputs);

// The point of `block` in a row whose base point is `base` (2k coordinates: a, then b).
std::vector<double> saltelli_point(const std::vector<double>& base, int block);

// The whole design, in the order above, from the rows of A and B (each N points of [0, 1)^k).
std::vector<std::vector<double>> saltelli_design(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b);

// Point `index` of the Sobol sequence in [0, 1)^dimension with Joe and Kuo's direction numbers
// (Boost.Random), the origin as point 0: the unscrambled sequence scipy's qmc.Sobol gives.
std::vector<double> sobol_sequence_point(std::uint64_t index, int dimension);

// The design with the 2k-dimensional Sobol sequence as its base, points skip .. skip + N - 1 split into
// A (the first k coordinates) and B (the last k), as SALib's sample with scramble off and skip_values =
// skip. Saltelli et al. (2010) recommend a power of 2 for N (and for skip, when not 0).
std::vector<std::vector<double>> saltelli_design_sobol(std::int64_t base_rows, int inputs, std::uint64_t skip = 0);

// ---- the estimators ----

struct SobolOptions {
  double confidence = 0.95;  // of the bootstrap intervals
  int resamples = 100;       // bootstrap resamples of the rows (SALib's default)
  std::uint64_t seed = 0;    // of the resamples
};

// An index's estimate and its bootstrap interval [estimate - half_width, estimate + half_width].
struct SobolInterval {
  double estimate = 0.0, half_width = 0.0;
  double low() const { return estimate - half_width; }
  double high() const { return estimate + half_width; }
};

struct SobolIndices {
  int inputs = 0;
  std::int64_t rows = 0;  // N
  double mean = 0.0;      // of Y over the A and B points
  double variance = 0.0;  // Var(Y) over the A and B points (1/(2N))
  // Var(Y) > 0: otherwise Y is constant over the A and B points and no index is defined (they are left 0).
  bool defined = false;
  std::vector<SobolInterval> first, total;
  std::vector<SobolInterval> interaction;  // ST_i - S_i, its interval from the same resamples
  double confidence = 0.0;
  int resamples = 0;
};

// The indices of the model values `y`, one per point of Saltelli's design in its order (N (k + 2) values,
// N >= 2). Throws std::invalid_argument for a size that is not a multiple of k + 2, fewer than 2 rows,
// a value that is not finite, or options out of range (confidence in (0, 1), resamples >= 2).
SobolIndices sobol_indices(const std::vector<double>& y, int inputs, const SobolOptions& options = {});

// ---- which inputs matter, by which measure ----

// An input matters by an index when the index's whole interval lies above `threshold` (0.05 by default: a
// twentieth of the variance). By rank correlation it matters when rho^2 >= threshold: for a linear model
// with normal inputs rho^2 (Pearson's) is S_i, so the two measures are held to the same share.
struct InputImportance {
  bool first_order = false;   // S_i's interval lies above the threshold
  bool total = false;         // ST_i's interval lies above it
  bool interactions = false;  // ST_i - S_i's interval lies above it
  std::optional<bool> rank;   // rho_i^2 >= threshold, when a rank correlation was given
};
std::vector<InputImportance> input_importance(const SobolIndices& indices, const std::vector<std::optional<double>>& rank_correlations,
                                              double threshold = 0.05);

// One sentence: which inputs matter by Sobol indices (and how: first order, through interactions) and
// which by rank correlation, and what one measure finds that the other misses. `names` per input.
std::string describe_importance(const std::vector<std::string>& names, const std::vector<InputImportance>& importance,
                                double threshold = 0.05);

}  // namespace moreau::scene
