// Rigid-body dynamics of a kinematic tree with one-degree-of-freedom joints (revolute, prismatic) on a
// fixed base: the terms of (0.1) that a robot description gives,
//
//   M(q) q'' + C(q, q') q' + grad V(q) = tau,
//
// with M the joint-space inertia matrix, C the Coriolis matrix in its Christoffel form (the one the paper
// assumes, (1.4)-(1.5): dM/dt - 2C is skew-symmetric and C(q, v) w = C(q, w) v) and V the gravity
// potential. No finite differences anywhere: every term is exact up to round-off.
//
// Algorithms (free functions over an immutable model and a per-run data struct, in the manner of
// Featherstone, "Rigid Body Dynamics Algorithms", 2008):
// - kinematics: each body's pose, its joint's motion subspace S_j and velocity V_j, all as Pluecker
//   vectors in the base frame at the base origin (angular part first);
// - M by the composite rigid-body algorithm (Featherstone, ch. 6): M_aj = S_a^T Ic_j S_j for a an
//   ancestor of j (or j), Ic_j the composite inertia of the subtree at j;
// - C from M = sum_i J_i^T I_i J_i: C = sum_i J_i^T (I_i dJ_i/dt + B_i J_i), with
//   B_i = 1/2 ((V_i x*) I_i - I_i (V_i x) + X(I_i V_i)) and X(h) w = w x* h. This is the
//   Christoffel-consistent factorisation of Echeandia and Wensing ("Numerical methods to compute the
//   Coriolis matrix and Christoffel symbols for rigid-body systems", J. Comput. Nonlinear Dynam., 2021),
//   also the one of Pinocchio's computeCoriolisMatrix. Composite sums over subtrees make it O(n^2):
//   C_aj = S_a^T (Ic_j dS_j/dt + Bc_j S_j) for a an ancestor of j (or j), and
//   C_jb = (Ic_j S_j)^T dS_b/dt + (Bc_j^T S_j)^T S_b for b a strict ancestor of j.
//   Bc_j is never formed: A_i + A_i^T has the blocks [T_i, p_i x; -p_i x, 0] (p_i the body's linear
//   momentum), so a 3 x 3 sum T over the subtree and the composite momentum give Bc_j S_j and Bc_j^T S_j;
// - grad V = G: G_j = -S_j^T sum_{i in subtree(j)} (c_i x m_i g, m_i g);
// - inverse dynamics by the recursive Newton-Euler algorithm (for cross-checks and tests).
// tests/core/rigid_body_test.cc checks each against closed forms, against each other and against KDL.
//
// Floating bases are out of scope: the root link is fixed to the world.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Dense>

namespace moreau {

using Vector6d = Eigen::Matrix<double, 6, 1>;

enum class JointType { kRevolute, kPrismatic };

// The inertia of a rigid body about its centre of mass, in its own frame.
struct RigidBodyInertia {
  double mass_kg = 0.0;
  Eigen::Vector3d com_m = Eigen::Vector3d::Zero();              // centre of mass, body frame
  Eigen::Matrix3d inertia_com_kg_m2 = Eigen::Matrix3d::Zero();  // about the centre of mass, body axes
};

// One moving body and the joint that moves it relative to its parent.
struct RigidBody {
  std::string joint_name;  // names the coordinate q_j
  std::string link_name;   // the link the joint moves
  int parent = -1;         // index of the parent body, -1 for the fixed base; always below this index
  JointType joint = JointType::kRevolute;
  // The joint frame at q_j = 0, relative to the parent body's frame.
  Eigen::Matrix3d rotation_in_parent = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position_in_parent_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit vector in the joint frame
  // Everything rigidly attached to the body (links behind fixed joints merged in), in the body frame, which
  // is the joint frame moved by q_j.
  RigidBodyInertia inertia;
};

struct RigidBodyModel {
  std::vector<RigidBody> bodies;                                    // parents before children
  Eigen::Vector3d gravity_m_s2 = Eigen::Vector3d(0.0, 0.0, -9.81);  // in the base frame
  int dof() const { return static_cast<int>(bodies.size()); }
  // True when body `a` is `j` or one of its ancestors.
  bool supports(int a, int j) const {
    while (j > a) j = bodies[static_cast<std::size_t>(j)].parent;
    return j == a;
  }
};

// Buffers and intermediate results of the algorithms, sized once for a model: no allocation afterwards.
struct RigidBodyData {
  explicit RigidBodyData(const RigidBodyModel& model);
  // Derived once from the model: joint j's frame at q_j is rotation_in_parent + sin q_j sin_term +
  // (1 - cos q_j) versine_term in its parent's frame (Rodrigues' formula with rotation_in_parent folded
  // in), and its axis in the parent's frame.
  struct JointFrame {
    Eigen::Matrix3d sin_term, versine_term;
    Eigen::Vector3d axis_in_parent;
  };
  std::vector<JointFrame> joint_frame;
  std::vector<Eigen::Matrix3d> rotation;  // body frame -> base frame
  std::vector<Eigen::Vector3d> position;  // body frame origin in the base frame
  std::vector<Vector6d> S;                // motion subspace of joint j (base-frame Pluecker)
  std::vector<Vector6d> S_dot;            // dS_j/dt = V_j x S_j
  std::vector<Vector6d> V;                // spatial velocity of body j
  // Composite quantities of the subtree at j: mass, first moment m c, rotational inertia about the base
  // origin (together the spatial inertia Ic_j), momentum sum I_i V_i, and T, the top-left block of
  // sum (A_i + A_i^T) with A_i = (V_i x*) I_i (the rest of that sum is the momentum's, rigid_body.cc).
  std::vector<double> mass;
  std::vector<Eigen::Vector3d> first_moment;
  std::vector<Eigen::Matrix3d> rotational;
  std::vector<Vector6d> momentum;
  std::vector<Eigen::Matrix3d> T;
  std::vector<Vector6d> F;  // per-body force or auxiliary vector
};

// Forward kinematics: poses, S, dS/dt and V (v may be null: V = 0).
void update_kinematics(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v);

// M(q) (n x n), by the composite rigid-body algorithm.
void mass_matrix(const RigidBodyModel& model, RigidBodyData& data, const double* q, Eigen::Ref<Eigen::MatrixXd> M);

// M(q), C(q, v) (Christoffel form) and G(q) = grad V(q) in one pass. The step of scheme (0.2) calls this.
void rigid_body_terms(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v, Eigen::Ref<Eigen::MatrixXd> M,
                      Eigen::Ref<Eigen::MatrixXd> C, Eigen::Ref<Eigen::VectorXd> G);

// G(q) = grad V(q), the torque that holds the robot against gravity.
void gravity_torque(const RigidBodyModel& model, RigidBodyData& data, const double* q, Eigen::Ref<Eigen::VectorXd> G);

// V(q) = -sum_i m_i <g, c_i(q)>, zero at the base origin.
double potential_energy(const RigidBodyModel& model, RigidBodyData& data, const double* q);

// tau = M(q) a + C(q, v) v + G(q) by the recursive Newton-Euler algorithm (with_gravity = false: G left
// out). An independent route to the same quantities, for checks.
void inverse_dynamics(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v, const double* a,
                      bool with_gravity, Eigen::Ref<Eigen::VectorXd> tau);

}  // namespace moreau
