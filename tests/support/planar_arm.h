// The closed form of a planar n-link arm, an independent reference for the rigid-body algorithms
// (tests/core/rigid_body_test.cc) and for robots read from URDF (tests/scene/urdf_test.cc).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "moreau/core/rigid_body.h"

namespace moreau::testing {

// A planar arm in the x-y plane: joints about z, link k of length l[k], centre of mass at lc[k] along it,
// inertia I[k] about the centre's z axis; gravity -g along y.
struct PlanarArm {
  std::vector<double> m, l, lc, I;
  double g = 9.81;
  int n() const { return static_cast<int>(m.size()); }

  RigidBodyModel model() const {
    RigidBodyModel r;
    r.gravity_m_s2 = Eigen::Vector3d(0.0, -g, 0.0);
    for (int k = 0; k < n(); ++k) {
      RigidBody b;
      b.joint_name = std::string("j").append(std::to_string(k));  // not "j" + ...: GCC 12's false -Wrestrict (bug 105329)
      b.parent = k - 1;
      b.position_in_parent_m = Eigen::Vector3d(k == 0 ? 0.0 : l[k - 1], 0.0, 0.0);
      b.axis = Eigen::Vector3d::UnitZ();
      b.inertia.mass_kg = m[k];
      b.inertia.com_m = Eigen::Vector3d(lc[k], 0.0, 0.0);
      b.inertia.inertia_com_kg_m2 = Eigen::Vector3d(0.3 * I[k], 0.7 * I[k], I[k]).asDiagonal();
      r.bodies.push_back(b);
    }
    return r;
  }

  // Length used from joint a towards the centre of link k (a <= k).
  double arm(int a, int k) const { return a < k ? l[a] : lc[k]; }
  static std::vector<double> absolute_angles(const Eigen::VectorXd& q) {
    std::vector<double> th(q.size());
    double s = 0.0;
    for (int i = 0; i < q.size(); ++i) th[i] = s += q(i);
    return th;
  }
  // M_ij = sum_k [ m_k J_k,i . J_k,j + I_k ] over k >= max(i, j), with the Jacobian of the centre of link k
  // J_k,i = sum_{a=i..k} arm(a, k) (-sin th_a, cos th_a).
  Eigen::MatrixXd mass(const Eigen::VectorXd& q) const {
    const auto th = absolute_angles(q);
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n(), n());
    for (int i = 0; i < n(); ++i)
      for (int j = 0; j < n(); ++j)
        for (int k = std::max(i, j); k < n(); ++k) {
          double s = I[k];
          for (int a = i; a <= k; ++a)
            for (int b = j; b <= k; ++b) s += m[k] * arm(a, k) * arm(b, k) * std::cos(th[a] - th[b]);
          M(i, j) += s;
        }
    return M;
  }
  // dM_ij/dq_p, exactly: d cos(th_a - th_b)/dq_p = -sin(th_a - th_b) ([p <= a] - [p <= b]).
  double mass_derivative(const Eigen::VectorXd& q, int i, int j, int p) const {
    const auto th = absolute_angles(q);
    double s = 0.0;
    for (int k = std::max(i, j); k < n(); ++k)
      for (int a = i; a <= k; ++a)
        for (int b = j; b <= k; ++b)
          s -= m[k] * arm(a, k) * arm(b, k) * std::sin(th[a] - th[b]) * ((p <= a ? 1.0 : 0.0) - (p <= b ? 1.0 : 0.0));
    return s;
  }
  // (1.5): C_ij = sum_p 1/2 (dM_ij/dq_p + dM_ip/dq_j - dM_pj/dq_i) v_p.
  Eigen::MatrixXd coriolis(const Eigen::VectorXd& q, const Eigen::VectorXd& v) const {
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n(), n());
    for (int i = 0; i < n(); ++i)
      for (int j = 0; j < n(); ++j)
        for (int p = 0; p < n(); ++p)
          C(i, j) += 0.5 * (mass_derivative(q, i, j, p) + mass_derivative(q, i, p, j) - mass_derivative(q, p, j, i)) * v(p);
    return C;
  }
  // G_i = dV/dq_i with V = g sum_k m_k y_k: g sum_{k >= i} m_k sum_{a=i..k} arm(a, k) cos th_a.
  Eigen::VectorXd gravity(const Eigen::VectorXd& q) const {
    const auto th = absolute_angles(q);
    Eigen::VectorXd G = Eigen::VectorXd::Zero(n());
    for (int i = 0; i < n(); ++i)
      for (int k = i; k < n(); ++k)
        for (int a = i; a <= k; ++a) G(i) += g * m[k] * arm(a, k) * std::cos(th[a]);
    return G;
  }
};

// max |a - b| / max(|a|, |b|) over the entries.
inline double relative(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const double scale = std::max(a.cwiseAbs().maxCoeff(), b.cwiseAbs().maxCoeff());
  return scale == 0.0 ? 0.0 : (a - b).cwiseAbs().maxCoeff() / scale;
}

}  // namespace moreau::testing
