// The rigid-body algorithms (core/rigid_body.h) against independent references: the closed form of a
// planar n-link arm (M from the Jacobians of the centres of mass, C from the exact derivatives of that M
// by the Christoffel formula (1.5), G from the potential), and, on a branched tree with prismatic joints
// and tilted axes, against each other: CRBA against RNEA columns, C v against RNEA, C(v) w = C(w) v,
// dM/dt - 2C skew-symmetric (dM/dt by a central difference of M: a test oracle, not product code),
// G against the gradient of V.
#include "moreau/core/rigid_body.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Geometry>

#include "support/planar_arm.h"

namespace moreau {
namespace {

using testing::PlanarArm;
using testing::relative;

PlanarArm double_pendulum() { return PlanarArm{{1.3, 0.8}, {0.9, 0.7}, {0.45, 0.3}, {0.09, 0.04}}; }
PlanarArm three_link() { return PlanarArm{{2.0, 1.5, 0.6}, {0.8, 0.6, 0.4}, {0.35, 0.3, 0.15}, {0.11, 0.05, 0.01}}; }

TEST(RigidBody, DoublePendulumMatchesTextbookClosedForm) {
  // The textbook form (e.g. Spong, Hutchinson, Vidyasagar, "Robot Modeling and Control", 7.4.2), written out.
  const PlanarArm arm = double_pendulum();
  const RigidBodyModel model = arm.model();
  RigidBodyData data(model);
  const double m1 = arm.m[0], m2 = arm.m[1], l1 = arm.l[0], lc1 = arm.lc[0], lc2 = arm.lc[1], I1 = arm.I[0], I2 = arm.I[1], g = arm.g;
  for (const auto& [q1, q2, v1, v2] :
       std::vector<std::array<double, 4>>{{0.3, -1.1, 0.7, -2.0}, {2.5, 0.4, -1.3, 0.2}, {0.0, 0.0, 1.0, 1.0}}) {
    Eigen::Matrix2d M, C;
    Eigen::Vector2d G;
    const double q[] = {q1, q2}, v[] = {v1, v2};
    rigid_body_terms(model, data, q, v, M, C, G);
    Eigen::Matrix2d M_ref, C_ref;
    const double c2 = std::cos(q2), h = -m2 * l1 * lc2 * std::sin(q2);
    M_ref << I1 + I2 + m1 * lc1 * lc1 + m2 * (l1 * l1 + lc2 * lc2 + 2 * l1 * lc2 * c2), I2 + m2 * (lc2 * lc2 + l1 * lc2 * c2),
        I2 + m2 * (lc2 * lc2 + l1 * lc2 * c2), I2 + m2 * lc2 * lc2;
    C_ref << h * v2, h * (v1 + v2), -h * v1, 0.0;
    const Eigen::Vector2d G_ref((m1 * lc1 + m2 * l1) * g * std::cos(q1) + m2 * lc2 * g * std::cos(q1 + q2),
                                m2 * lc2 * g * std::cos(q1 + q2));
    EXPECT_LT(relative(M, M_ref), 1e-14) << M << "\nvs\n" << M_ref;
    EXPECT_LT((C - C_ref).cwiseAbs().maxCoeff(), 1e-14 * (1.0 + C_ref.cwiseAbs().maxCoeff())) << C << "\nvs\n" << C_ref;
    EXPECT_LT(relative(G, G_ref), 1e-14) << G.transpose() << " vs " << G_ref.transpose();
  }
}

TEST(RigidBody, PlanarArmsMatchClosedFormsTo1e12) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (const PlanarArm& arm :
       {double_pendulum(), three_link(),
        PlanarArm{{1, 2, 1, 3, 1, 2}, {1, .5, .7, .3, .9, .4}, {.5, .2, .3, .1, .4, .2}, {.1, .2, .1, .3, .1, .2}}}) {
    const RigidBodyModel model = arm.model();
    RigidBodyData data(model);
    const int n = arm.n();
    for (int trial = 0; trial < 20; ++trial) {
      Eigen::VectorXd q(n), v(n);
      for (int i = 0; i < n; ++i) {
        q(i) = u(rng);
        v(i) = u(rng);
      }
      Eigen::MatrixXd M(n, n), C(n, n), Mc(n, n);
      Eigen::VectorXd G(n), Gc(n);
      rigid_body_terms(model, data, q.data(), v.data(), M, C, G);
      EXPECT_LT(relative(M, arm.mass(q)), 1e-12) << "n = " << n;
      EXPECT_LT(relative(C, arm.coriolis(q, v)), 1e-12) << "n = " << n;
      EXPECT_LT(relative(G, arm.gravity(q)), 1e-12) << "n = " << n;
      // The single-purpose functions agree with the one pass.
      mass_matrix(model, data, q.data(), Mc);
      gravity_torque(model, data, q.data(), Gc);
      EXPECT_EQ(Mc, M);
      EXPECT_EQ(Gc, G);
    }
  }
}

// A branched tree in 3-D: revolute joints about tilted axes, two prismatic joints, rotated joint frames,
// off-centre centres of mass with full inertia tensors.
RigidBodyModel branched_tree() {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int parents[] = {-1, 0, 1, 1, 3, 0, 5, 2};
  RigidBodyModel model;
  model.gravity_m_s2 = Eigen::Vector3d(0.3, -1.2, -9.6);
  for (int k = 0; k < 8; ++k) {
    RigidBody b;
    b.parent = parents[k];
    b.joint_name = std::string("j").append(std::to_string(k));  // not "j" + ...: GCC 12's false -Wrestrict (bug 105329)
    b.joint = (k == 3 || k == 6) ? JointType::kPrismatic : JointType::kRevolute;
    b.rotation_in_parent = Eigen::AngleAxisd(u(rng) * 3.0, Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
    b.position_in_parent_m = Eigen::Vector3d(u(rng), u(rng), u(rng));
    b.axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    b.inertia.mass_kg = 1.0 + 0.5 * u(rng);
    b.inertia.com_m = 0.4 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Matrix3d R = Eigen::AngleAxisd(u(rng) * 3.0, Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized()).toRotationMatrix();
    b.inertia.inertia_com_kg_m2 =
        R * Eigen::Vector3d(0.05 + 0.02 * u(rng), 0.06 + 0.02 * u(rng), 0.08 + 0.02 * u(rng)).asDiagonal() * R.transpose();
    model.bodies.push_back(b);
  }
  return model;
}

class TreeCrossChecks : public ::testing::Test {
 protected:
  RigidBodyModel model = branched_tree();
  RigidBodyData data{model};
  int n = model.dof();
  std::mt19937 rng{3};
  Eigen::VectorXd random_vector() {
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    Eigen::VectorXd x(n);
    for (int i = 0; i < n; ++i) x(i) = u(rng);
    return x;
  }
  Eigen::VectorXd rnea(const Eigen::VectorXd& q, const Eigen::VectorXd& v, const Eigen::VectorXd& a, bool gravity) {
    Eigen::VectorXd tau(n);
    inverse_dynamics(model, data, q.data(), v.data(), a.data(), gravity, tau);
    return tau;
  }
  void terms(const Eigen::VectorXd& q, const Eigen::VectorXd& v, Eigen::MatrixXd& M, Eigen::MatrixXd& C, Eigen::VectorXd& G) {
    M.resize(n, n);
    C.resize(n, n);
    G.resize(n);
    rigid_body_terms(model, data, q.data(), v.data(), M, C, G);
  }
};

TEST_F(TreeCrossChecks, MassMatrixEqualsRneaColumnsAndIsPositiveDefinite) {
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = random_vector(), zero = Eigen::VectorXd::Zero(n);
    Eigen::MatrixXd M, C, R(n, n);
    Eigen::VectorXd G;
    terms(q, zero, M, C, G);
    for (int k = 0; k < n; ++k) R.col(k) = rnea(q, zero, Eigen::VectorXd::Unit(n, k), false);
    EXPECT_LT(relative(M, R), 1e-12);
    EXPECT_EQ(M, M.transpose());
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues()(0), 0.0);
    EXPECT_EQ(C, Eigen::MatrixXd::Zero(n, n)) << "C(q, 0) must vanish";
  }
}

TEST_F(TreeCrossChecks, CoriolisTimesVelocityEqualsRneaAndIsSymmetricBilinear) {
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = random_vector(), v = random_vector(), w = random_vector(), zero = Eigen::VectorXd::Zero(n);
    Eigen::MatrixXd M, Cv, Cw;
    Eigen::VectorXd G;
    terms(q, v, M, Cv, G);
    terms(q, w, M, Cw, G);
    const Eigen::VectorXd c = rnea(q, v, zero, false);
    EXPECT_LT(relative(Cv * v, c), 1e-12);
    // Christoffel form: C(q, v) w = C(q, w) v, and the polarization identity against RNEA.
    EXPECT_LT(relative(Cv * w, Cw * v), 1e-12);
    const Eigen::VectorXd polar = (rnea(q, v + w, zero, false) - rnea(q, v - w, zero, false)) / 4.0;
    EXPECT_LT(relative(Cv * w, polar), 1e-12);
  }
}

TEST_F(TreeCrossChecks, MassDerivativeMinusTwiceCoriolisIsSkewSymmetric) {
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = random_vector(), v = random_vector();
    Eigen::MatrixXd M, C, Mp(n, n), Mm(n, n);
    Eigen::VectorXd G;
    terms(q, v, M, C, G);
    const double eps = 1e-6;  // central difference: error O(eps^2) ~ 1e-12, round-off ~ 1e-16 / eps
    const Eigen::VectorXd qp = q + eps * v, qm = q - eps * v;
    mass_matrix(model, data, qp.data(), Mp);
    mass_matrix(model, data, qm.data(), Mm);
    const Eigen::MatrixXd N = (Mp - Mm) / (2.0 * eps) - 2.0 * C;
    EXPECT_LT((N + N.transpose()).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + C.cwiseAbs().maxCoeff()));
    // And dM/dt = C + C^T, which the skew-symmetry says, checked directly.
    EXPECT_LT(relative((Mp - Mm) / (2.0 * eps), C + C.transpose()), 1e-8);
  }
}

TEST_F(TreeCrossChecks, GravityTorqueIsTheGradientOfThePotentialAndEqualsRnea) {
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::VectorXd q = random_vector(), zero = Eigen::VectorXd::Zero(n);
    Eigen::VectorXd G(n);
    gravity_torque(model, data, q.data(), G);
    EXPECT_LT(relative(G, rnea(q, zero, zero, true)), 1e-12);
    Eigen::VectorXd fd(n);
    const double eps = 1e-6;
    for (int i = 0; i < n; ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp(i) += eps;
      qm(i) -= eps;
      fd(i) = (potential_energy(model, data, qp.data()) - potential_energy(model, data, qm.data())) / (2.0 * eps);
    }
    EXPECT_LT(relative(G, fd), 1e-7);
  }
}

TEST_F(TreeCrossChecks, InverseDynamicsIsMassTimesAccelerationPlusBiasPlusGravity) {
  const Eigen::VectorXd q = random_vector(), v = random_vector(), a = random_vector();
  Eigen::MatrixXd M, C;
  Eigen::VectorXd G;
  terms(q, v, M, C, G);
  EXPECT_LT(relative(rnea(q, v, a, true), M * a + C * v + G), 1e-12);
}

// M and C are written whole whatever the output buffers held: a chain's (ancestor, body) pairs cover every
// entry, and a tree's entries between bodies on different branches are set to 0 (the tree here has them:
// its M has exact zeros that RNEA's columns reproduce).
TEST_F(TreeCrossChecks, EveryEntryIsWrittenWhateverTheBuffersHeld) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const PlanarArm arm = three_link();
  const RigidBodyModel chain = arm.model();
  for (const RigidBodyModel* m : std::initializer_list<const RigidBodyModel*>{&model, &chain}) {
    RigidBodyData d(*m);
    const int k = m->dof();
    const Eigen::VectorXd q = random_vector().head(k), v = random_vector().head(k);
    Eigen::MatrixXd M0 = Eigen::MatrixXd::Zero(k, k), C0 = M0, M1 = Eigen::MatrixXd::Constant(k, k, nan), C1 = M1, M2 = M1;
    Eigen::VectorXd G0(k), G1(k);
    rigid_body_terms(*m, d, q.data(), v.data(), M0, C0, G0);
    rigid_body_terms(*m, d, q.data(), v.data(), M1, C1, G1);
    mass_matrix(*m, d, q.data(), M2);
    EXPECT_EQ(M1, M0);
    EXPECT_EQ(C1, C0);
    EXPECT_EQ(M2, M0);
  }
  Eigen::MatrixXd M, C;
  Eigen::VectorXd G;
  terms(random_vector(), random_vector(), M, C, G);
  EXPECT_GT((M.array() == 0.0).count(), 0) << "the tree must have bodies on different branches";
}

}  // namespace
}  // namespace moreau
