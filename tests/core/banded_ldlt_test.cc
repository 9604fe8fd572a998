// BandedLdlt (banded_ldlt.h) against Eigen's dense LDL^T of the same principal submatrix: random banded
// symmetric positive definite matrices of bandwidth 0 to 8, random increasing row sets, and an indefinite
// matrix refused.
#include "moreau/core/banded_ldlt.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>
#include <vector>

namespace moreau {
namespace {

TEST(BandedLdlt, SolvesEveryPrincipalSubmatrixAsTheDenseFactorisationDoes) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 1 + trial % 60, b = trial % 9;
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = std::max(0, i - b); j < i; ++j) A(i, j) = A(j, i) = u(rng);
    for (int i = 0; i < n; ++i) A(i, i) = 2.0 * b + 0.5 + std::abs(u(rng));  // diagonally dominant: positive definite
    const Eigen::SparseMatrix<double> S = A.sparseView();
    std::vector<int> F, local(static_cast<std::size_t>(n), -1);
    for (int i = 0; i < n; ++i)
      if (u(rng) > -0.6) F.push_back(i);
    if (F.empty()) F.push_back(0);
    BandedLdlt ldlt;
    ldlt.reserve(n, b);
    ASSERT_TRUE(ldlt.factorise(S, F, local)) << "trial " << trial;
    for (int r : local) ASSERT_EQ(r, -1);  // the caller's scratch, as it was
    const int f = static_cast<int>(F.size());
    Eigen::MatrixXd AFF(f, f);
    for (int a = 0; a < f; ++a)
      for (int c = 0; c < f; ++c) AFF(a, c) = A(F[static_cast<std::size_t>(a)], F[static_cast<std::size_t>(c)]);
    const Eigen::VectorXd rhs = Eigen::VectorXd::Random(f);
    Eigen::VectorXd x = rhs;
    ldlt.solve(x);
    const Eigen::VectorXd expected = AFF.ldlt().solve(rhs);
    EXPECT_LE((x - expected).cwiseAbs().maxCoeff(), 1e-12 * (1.0 + expected.cwiseAbs().maxCoeff())) << "trial " << trial;
  }
}

TEST(BandedLdlt, RefusesAMatrixThatIsNotPositiveDefinite) {
  const int n = 6;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) A(i, i) = 1.0;
  for (int i = 0; i + 1 < n; ++i) A(i, i + 1) = A(i + 1, i) = 0.9;  // tridiag(0.9, 1, 0.9): indefinite
  const Eigen::SparseMatrix<double> S = A.sparseView();
  std::vector<int> F = {0, 1, 2, 3, 4, 5}, local(static_cast<std::size_t>(n), -1);
  BandedLdlt ldlt;
  ldlt.reserve(n, 1);
  EXPECT_FALSE(ldlt.factorise(S, F, local));
  const std::vector<int> two = {0, 1};  // its 2 x 2 leading block is positive definite
  EXPECT_TRUE(ldlt.factorise(S, two, local));
}

}  // namespace
}  // namespace moreau
