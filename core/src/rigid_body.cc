// Rigid-body algorithms of rigid_body.h. Pluecker vectors in the base frame at the base origin, angular
// part first: a motion V = (w, u) (u: velocity of the body point at the origin), a force f = (n, f).
#include "moreau/core/rigid_body.h"

#include <cmath>

#include <Eigen/Geometry>

namespace moreau {
namespace {

Eigen::Vector3d top(const Vector6d& x) { return x.head<3>(); }
Eigen::Vector3d bottom(const Vector6d& x) { return x.tail<3>(); }

Vector6d pack(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  Vector6d x;
  x.head<3>() = a;
  x.tail<3>() = b;
  return x;
}

// V x S (motion cross product): (w x s, w x s_u + u x s).
Vector6d cross_motion(const Vector6d& V, const Vector6d& S) {
  const Eigen::Vector3d w = top(V), u = bottom(V), s = top(S), su = bottom(S);
  return pack(w.cross(s), w.cross(su) + u.cross(s));
}

// V x* f (force cross product): (w x n + u x f, w x f).
Vector6d cross_force(const Vector6d& V, const Vector6d& f) {
  const Eigen::Vector3d w = top(V), u = bottom(V), n = top(f), fl = bottom(f);
  return pack(w.cross(n) + u.cross(fl), w.cross(fl));
}

// The spatial inertia (m, h = m c, Ibar = rotational inertia about the origin) times a motion:
// (Ibar s + h x s_u, m s_u - h x s).
Vector6d inertia_times(double m, const Eigen::Vector3d& h, const Eigen::Matrix3d& Ibar, const Vector6d& S) {
  const Eigen::Vector3d s = top(S), su = bottom(S);
  return pack(Ibar * s + h.cross(su), m * su - h.cross(s));
}

Eigen::Matrix3d skew(const Eigen::Vector3d& a) {
  Eigen::Matrix3d x;
  x << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return x;
}

// T_i, the top-left 3 x 3 block of A_i + A_i^T for A_i = (V_i x*) I_i, with V_i = (w, u) and the spatial
// inertia I_i = [Ibar, hx; hx^T, m E] (hx = skew(h)). By 3 x 3 blocks, (V x*) = [wx, ux; 0, wx] gives
// A = [wx Ibar - ux hx, wx hx + m ux; -wx hx, m wx], so that
//   A + A^T = [T, px; -px, 0],  T = wx Ibar - Ibar wx - (h u^T + u h^T) + 2 (u . h) E,
// with p = m u + w x h the body's linear momentum (wx hx - hx wx = skew(w x h)): T and the momentum I V
// carry all of A + A^T, and both add over subtrees.
void twice_symmetric_part(const Vector6d& V, const Eigen::Vector3d& h, const Eigen::Matrix3d& Ibar, Eigen::Matrix3d& T) {
  const Eigen::Vector3d w = V.head<3>(), u = V.tail<3>();
  Eigen::Matrix3d K;  // wx Ibar, column by column; Ibar wx = -(wx Ibar)^T since Ibar is symmetric
  for (int c = 0; c < 3; ++c) K.col(c) = w.cross(Ibar.col(c));
  T.noalias() = K + K.transpose();
  T.noalias() -= h * u.transpose() + u * h.transpose();
  T.diagonal().array() += 2.0 * u.dot(h);
}

// Body i's own inertia in the base frame: mass, first moment m c and rotational inertia about the origin
// (the parallel-axis theorem: I_com + m (|c|^2 E - c c^T)).
void world_inertia(const RigidBody& body, const Eigen::Matrix3d& R, const Eigen::Vector3d& p, double& m, Eigen::Vector3d& h,
                   Eigen::Matrix3d& Ibar) {
  const RigidBodyInertia& in = body.inertia;
  m = in.mass_kg;
  const Eigen::Vector3d c = p + R * in.com_m;
  h = m * c;
  Ibar = R * in.inertia_com_kg_m2 * R.transpose();
  Ibar += m * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
}

// Poses only (V and dS/dt untouched). A revolute joint's frame is R_p (Rip Rot(a, q_j)) with, by Rodrigues'
// formula, Rip Rot(a, q) = Rip + sin q (Rip ax) + (1 - cos q) (Rip ax^2): the three constant matrices
// are RigidBodyData::JointFrame, derived once from the model, so a pose costs one 3 x 3 product and one
// sincos.
void update_poses(const RigidBodyModel& model, RigidBodyData& data, const double* q) {
  const int n = model.dof();
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const RigidBody& b = model.bodies[k];
    const RigidBodyData::JointFrame& f = data.joint_frame[k];
    Eigen::Matrix3d local;  // the joint frame moved by q_j, in the parent's frame
    if (b.joint == JointType::kRevolute) {
      const double sn = std::sin(q[j]), versine = 1.0 - std::cos(q[j]);
      local = b.rotation_in_parent + sn * f.sin_term + versine * f.versine_term;
    } else {
      local = b.rotation_in_parent;
    }
    Eigen::Vector3d p0, axis;  // the joint frame's origin and axis in the base frame
    if (b.parent < 0) {
      data.rotation[k] = local;
      p0 = b.position_in_parent_m;
      axis = f.axis_in_parent;
    } else {
      const std::size_t pk = static_cast<std::size_t>(b.parent);
      const Eigen::Matrix3d& Rp = data.rotation[pk];
      data.rotation[k].noalias() = Rp * local;
      p0 = data.position[pk] + Rp * b.position_in_parent_m;
      axis.noalias() = Rp * f.axis_in_parent;
    }
    if (b.joint == JointType::kRevolute) {
      data.position[k] = p0;
      data.S[k] = pack(axis, p0.cross(axis));  // rotation about the line through p0
    } else {
      data.position[k] = p0 + q[j] * axis;
      data.S[k] = pack(Eigen::Vector3d::Zero(), axis);
    }
  }
}

// Composite mass, first moment and rotational inertia of every subtree (children have higher indices).
void composite_inertias(const RigidBodyModel& model, RigidBodyData& data) {
  const int n = model.dof();
  for (int j = 0; j < n; ++j)
    world_inertia(model.bodies[static_cast<std::size_t>(j)], data.rotation[static_cast<std::size_t>(j)],
                  data.position[static_cast<std::size_t>(j)], data.mass[static_cast<std::size_t>(j)],
                  data.first_moment[static_cast<std::size_t>(j)], data.rotational[static_cast<std::size_t>(j)]);
  for (int j = n - 1; j >= 0; --j) {
    const int p = model.bodies[static_cast<std::size_t>(j)].parent;
    if (p < 0) continue;
    data.mass[static_cast<std::size_t>(p)] += data.mass[static_cast<std::size_t>(j)];
    data.first_moment[static_cast<std::size_t>(p)] += data.first_moment[static_cast<std::size_t>(j)];
    data.rotational[static_cast<std::size_t>(p)] += data.rotational[static_cast<std::size_t>(j)];
  }
}

// G_j = -S_j^T (hc_j x g, mc_j g), from the composite mass and first moment.
void gravity_from_composites(const RigidBodyModel& model, const RigidBodyData& data, Eigen::Ref<Eigen::VectorXd> G) {
  const Eigen::Vector3d& g = model.gravity_m_s2;
  for (int j = 0; j < model.dof(); ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const Vector6d f = pack(data.first_moment[k].cross(g), data.mass[k] * g);
    G(j) = -data.S[k].dot(f);
  }
}

// Every body's parent is the body before it (a serial arm): then the loops over (ancestor, body) pairs
// below visit every entry of M and C, and nothing needs zeroing first.
bool is_chain(const RigidBodyModel& model) {
  for (int j = 0; j < model.dof(); ++j)
    if (model.bodies[static_cast<std::size_t>(j)].parent != j - 1) return false;
  return true;
}

}  // namespace

RigidBodyData::RigidBodyData(const RigidBodyModel& model) {
  const std::size_t n = static_cast<std::size_t>(model.dof());
  joint_frame.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const RigidBody& b = model.bodies[k];
    const Eigen::Matrix3d ax = skew(b.axis);
    JointFrame& f = joint_frame[k];
    f.sin_term.noalias() = b.rotation_in_parent * ax;
    f.versine_term.noalias() = f.sin_term * ax;
    f.axis_in_parent.noalias() = b.rotation_in_parent * b.axis;
  }
  rotation.assign(n, Eigen::Matrix3d::Identity());
  position.assign(n, Eigen::Vector3d::Zero());
  S.assign(n, Vector6d::Zero());
  S_dot.assign(n, Vector6d::Zero());
  V.assign(n, Vector6d::Zero());
  mass.assign(n, 0.0);
  first_moment.assign(n, Eigen::Vector3d::Zero());
  rotational.assign(n, Eigen::Matrix3d::Zero());
  momentum.assign(n, Vector6d::Zero());
  T.assign(n, Eigen::Matrix3d::Zero());
  F.assign(n, Vector6d::Zero());
}

void update_kinematics(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v) {
  update_poses(model, data, q);
  for (int j = 0; j < model.dof(); ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const int p = model.bodies[k].parent;
    const Vector6d parent_v = p < 0 ? Vector6d::Zero() : data.V[static_cast<std::size_t>(p)];
    data.V[k] = v ? Vector6d(parent_v + data.S[k] * v[j]) : Vector6d::Zero();
    data.S_dot[k] = cross_motion(data.V[k], data.S[k]);  // S_j is fixed in body j: dS/dt = V_j x S_j
  }
}

void mass_matrix(const RigidBodyModel& model, RigidBodyData& data, const double* q, Eigen::Ref<Eigen::MatrixXd> M) {
  update_poses(model, data, q);
  composite_inertias(model, data);
  const int n = model.dof();
  if (!is_chain(model)) M.setZero();  // a tree leaves M(a, j) = 0 where neither supports the other
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const Vector6d F2 = inertia_times(data.mass[k], data.first_moment[k], data.rotational[k], data.S[k]);
    for (int a = j; a >= 0; a = model.bodies[static_cast<std::size_t>(a)].parent) {
      const double value = data.S[static_cast<std::size_t>(a)].dot(F2);
      M(a, j) = value;
      M(j, a) = value;
    }
  }
}

void rigid_body_terms(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v, Eigen::Ref<Eigen::MatrixXd> M,
                      Eigen::Ref<Eigen::MatrixXd> C, Eigen::Ref<Eigen::VectorXd> G) {
  update_kinematics(model, data, q, v);
  const int n = model.dof();
  // Each body's own inertia, momentum I_i V_i and T_i (twice_symmetric_part); then the sums over subtrees.
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    world_inertia(model.bodies[k], data.rotation[k], data.position[k], data.mass[k], data.first_moment[k], data.rotational[k]);
    data.momentum[k] = inertia_times(data.mass[k], data.first_moment[k], data.rotational[k], data.V[k]);
    twice_symmetric_part(data.V[k], data.first_moment[k], data.rotational[k], data.T[k]);
  }
  for (int j = n - 1; j >= 0; --j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const int p = model.bodies[k].parent;
    if (p < 0) continue;
    const std::size_t pk = static_cast<std::size_t>(p);
    data.mass[pk] += data.mass[k];
    data.first_moment[pk] += data.first_moment[k];
    data.rotational[pk] += data.rotational[k];
    data.momentum[pk] += data.momentum[k];
    data.T[pk] += data.T[k];
  }
  if (!is_chain(model)) {  // a tree leaves M(a, j) = C(a, j) = 0 where neither body supports the other
    M.setZero();
    C.setZero();
  }
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const Vector6d& S = data.S[k];
    const Eigen::Vector3d s = S.head<3>(), su = S.tail<3>();
    // Bc_j = 1/2 (Ac + Ac^T + X(hc)) with X(hc) S = S x* hc for the composite momentum hc = (nc, pc), and
    // Ac + Ac^T = [Tc, pcx; -pcx, 0] (twice_symmetric_part), so that
    //   Bc S = (1/2 (Tc s + s x nc), s x pc),  Bc^T S = (1/2 (Tc s - s x nc) + pc x su, 0).
    const Eigen::Vector3d nc = data.momentum[k].head<3>(), pc = data.momentum[k].tail<3>();
    const Eigen::Vector3d Ts = data.T[k] * s, s_x_nc = s.cross(nc);
    const Vector6d BS = pack(0.5 * (Ts + s_x_nc), s.cross(pc));
    const Eigen::Vector3d BtS = 0.5 * (Ts - s_x_nc) + pc.cross(su);  // its bottom half is 0
    const Vector6d IS = inertia_times(data.mass[k], data.first_moment[k], data.rotational[k], S);
    const Vector6d F1 = inertia_times(data.mass[k], data.first_moment[k], data.rotational[k], data.S_dot[k]) + BS;
    for (int a = j; a >= 0; a = model.bodies[static_cast<std::size_t>(a)].parent) {
      const std::size_t ak = static_cast<std::size_t>(a);
      const double m = data.S[ak].dot(IS);
      M(a, j) = m;
      M(j, a) = m;
      C(a, j) = data.S[ak].dot(F1);
      if (a != j) C(j, a) = IS.dot(data.S_dot[ak]) + BtS.dot(data.S[ak].head<3>());
    }
  }
  gravity_from_composites(model, data, G);
}

void gravity_torque(const RigidBodyModel& model, RigidBodyData& data, const double* q, Eigen::Ref<Eigen::VectorXd> G) {
  update_poses(model, data, q);
  composite_inertias(model, data);
  gravity_from_composites(model, data, G);
}

double potential_energy(const RigidBodyModel& model, RigidBodyData& data, const double* q) {
  update_poses(model, data, q);
  double V = 0.0;
  for (int j = 0; j < model.dof(); ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const RigidBodyInertia& in = model.bodies[k].inertia;
    const Eigen::Vector3d c = data.position[k] + data.rotation[k] * in.com_m;
    V -= in.mass_kg * model.gravity_m_s2.dot(c);
  }
  return V;
}

void inverse_dynamics(const RigidBodyModel& model, RigidBodyData& data, const double* q, const double* v, const double* a,
                      bool with_gravity, Eigen::Ref<Eigen::VectorXd> tau) {
  update_kinematics(model, data, q, v);
  const int n = model.dof();
  // Spatial accelerations: the base accelerates at -g, which puts gravity on every body.
  const Vector6d base_acc = with_gravity ? pack(Eigen::Vector3d::Zero(), -model.gravity_m_s2) : Vector6d::Zero();
  std::vector<Vector6d>& acc = data.F;  // accelerations first, then forces (same buffer, body by body)
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    const int p = model.bodies[k].parent;
    const Vector6d parent_acc = p < 0 ? base_acc : acc[static_cast<std::size_t>(p)];
    acc[k] = parent_acc + data.S[k] * a[j] + data.S_dot[k] * v[j];
  }
  for (int j = 0; j < n; ++j) {
    const std::size_t k = static_cast<std::size_t>(j);
    double m;
    Eigen::Vector3d h;
    Eigen::Matrix3d Ibar;
    world_inertia(model.bodies[k], data.rotation[k], data.position[k], m, h, Ibar);
    const Vector6d IV = inertia_times(m, h, Ibar, data.V[k]);
    data.F[k] = inertia_times(m, h, Ibar, acc[k]) + cross_force(data.V[k], IV);  // f_j = I a + V x* I V
  }
  for (int j = n - 1; j >= 0; --j) {
    const std::size_t k = static_cast<std::size_t>(j);
    tau(j) = data.S[k].dot(data.F[k]);
    const int p = model.bodies[k].parent;
    if (p >= 0) data.F[static_cast<std::size_t>(p)] += data.F[k];
  }
}

}  // namespace moreau
