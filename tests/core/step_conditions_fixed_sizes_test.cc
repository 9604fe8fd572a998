// StepConditions.AgreeWithEigenSolvers (step_conditions_test.cc) at the fixed sizes n = 3 and 4, where the
// checker of core/step_conditions.h may answer with bounds (Gershgorin, the Rayleigh quotients with their
// Cholesky certificates, ||C||_1 ||C||_inf) instead of eigenvalues: its comparison with Eigen's
// SelfAdjointEigenSolver and JacobiSVD on random M and C (step_conditions_support.h: lambda_min a lower
// bound with the same sign, the ratio what its label says) is instantiated here, in a translation unit of
// its own, so that no translation unit instantiates the checker at every size.
#include <random>

#include "step_conditions_support.h"

namespace moreau {

template void CompareWithEigen<3>(int n, std::mt19937& rng);
template void CompareWithEigen<4>(int n, std::mt19937& rng);

}  // namespace moreau
