// Robots from URDF (scene/urdf.h, /system/urdf) against independent references:
// - planar chains written by scripts/make-chain-urdf.py against the closed form of tests/support/
//   planar_arm.h (M, C, G to 1e-12), and whole trajectories against the same chain written as an
//   expression scene;
// - the 7-joint KUKA iiwa (scenes/robots/kuka-iiwa14.urdf) against KDL (orocos-kdl), whose chain this
//   test builds from urdfdom's parse by hand, as kdl_parser does: M, C(q, v) v, G at random states;
// - where every link of the iiwa is (link_poses, what GET /v1/jobs/{id}/kinematics serves) against KDL's
//   forward kinematics of the same chain, to 1e-12; and the <visual> primitives a viewer draws, as written;
// - the 6-joint PUMA 560 (scenes/robots/puma560.urdf) against the textbook Jacobian model built from its
//   published Denavit-Hartenberg table (M and G), which also checks the table's conversion to URDF;
// - energy of a free, frictionless swing conserved to O(h), with the measured order;
// - bad URDF of every kind named in the issue: a clear error naming the element, no crash, no hang.
#include <gtest/gtest.h>

#include <pthread.h>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chaindynparam.hpp>
#include <kdl/jntspaceinertiamatrix.hpp>
#include <urdf_parser/urdf_parser.h>

#include "moreau/core/rigid_body.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/urdf.h"
#include "support/planar_arm.h"
#include "xml_shape.h"  // scene/input: the URDF module's shape check

namespace moreau::scene {
namespace {

using moreau::testing::PlanarArm;
using moreau::testing::relative;

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_TRUE(in.good() || in.eof()) << path;
  return s.str();
}

std::string chain_path(int n) { return std::string(MOREAU_CHAIN_DIR) + "/chain-" + std::to_string(n) + ".urdf"; }
std::string iiwa_path() { return std::string(MOREAU_SOURCE_DIR) + "/scenes/robots/kuka-iiwa14.urdf"; }

// The chain of make-chain-urdf.py's defaults: rods of 0.1 m and 0.1 kg.
PlanarArm uniform_chain(int n) {
  const double m = 0.1, l = 0.1;
  PlanarArm arm;
  for (int k = 0; k < n; ++k) {
    arm.m.push_back(m);
    arm.l.push_back(l);
    arm.lc.push_back(l / 2);
    arm.I.push_back(m * l * l / 12.0);
  }
  return arm;
}

TEST(Urdf, PlanarChainsMatchTheirClosedForm) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int n : {2, 3, 7}) {
    UrdfRobot robot = read_urdf(read_text(chain_path(n)));
    robot.model.gravity_m_s2 = Eigen::Vector3d(0.0, -9.81, 0.0);
    ASSERT_EQ(robot.model.dof(), n);
    EXPECT_EQ(robot.model.bodies[0].joint_name, "joint1");
    EXPECT_TRUE(robot.limits.empty()) << "continuous joints have no limits";
    const PlanarArm arm = uniform_chain(n);
    RigidBodyData data(robot.model);
    for (int trial = 0; trial < 10; ++trial) {
      Eigen::VectorXd q(n), v(n);
      for (int i = 0; i < n; ++i) {
        q(i) = u(rng);
        v(i) = u(rng);
      }
      Eigen::MatrixXd M(n, n), C(n, n);
      Eigen::VectorXd G(n);
      rigid_body_terms(robot.model, data, q.data(), v.data(), M, C, G);
      EXPECT_LT(relative(M, arm.mass(q)), 1e-12) << "n = " << n;
      EXPECT_LT(relative(C, arm.coriolis(q, v)), 1e-12) << "n = " << n;
      EXPECT_LT(relative(G, arm.gravity(q)), 1e-12) << "n = " << n;
    }
  }
}

// The double pendulum of chain-2.urdf as an expression scene: M and V written out, C by Christoffel.
nlohmann::json expression_double_pendulum() {
  const PlanarArm a = uniform_chain(2);
  const double m = a.m[0], l = a.l[0], lc = a.lc[0], I = a.I[0], g = 9.81;
  auto num = [](double x) {
    std::ostringstream s;
    s.precision(17);
    s << x;
    return s.str();
  };
  const std::string m11 = num(2 * I + m * lc * lc + m * l * l + m * lc * lc) + " + " + num(2 * m * l * lc) + "*cos(joint2)";
  const std::string m12 = num(I + m * lc * lc) + " + " + num(m * l * lc) + "*cos(joint2)";
  const std::string m22 = num(I + m * lc * lc);
  const std::string V = num(g * (m * lc + m * l)) + "*sin(joint1) + " + num(g * m * lc) + "*sin(joint1 + joint2)";
  return {{"name", "double-pendulum"},
          {"system",
           {{"type", "lagrangian"},
            {"coordinates", {"joint1", "joint2"}},
            {"mass", nlohmann::json::array({nlohmann::json::array({m11, m12}), nlohmann::json::array({m12, m22})})},
            {"potential", V},
            {"controller", {{{"type", "quadratic"}, {"weights", {0.002, 0.001}}}, {{"type", "abs"}, {"gains", {0.01, 0.005}}}}}}},
          {"initial", {{"q", {-1.2, 0.7}}, {"v", {2.0, -1.0}}}},
          {"integrator", {{"scheme", "abl"}, {"h", 1e-3}, {"t_end", 1.0}}}};
}

struct Recorder : RunObserver {
  std::vector<std::vector<double>> states;
  void on_sample(const Sample& s) override {
    std::vector<double> x(s.q, s.q + s.n);
    x.insert(x.end(), s.v, s.v + s.n);
    states.push_back(x);
  }
};

TEST(Urdf, DoublePendulumTrajectoryEqualsTheExpressionScene) {
  nlohmann::json urdf_doc = expression_double_pendulum();
  urdf_doc["system"].erase("coordinates");
  urdf_doc["system"].erase("mass");
  urdf_doc["system"].erase("potential");
  urdf_doc["system"]["urdf"] = {{"text", read_text(chain_path(2))}, {"gravity", {0.0, -9.81, 0.0}}};
  const LagrangianScene from_urdf = load_scene(urdf_doc);
  const LagrangianScene from_expressions = load_scene(expression_double_pendulum());
  EXPECT_EQ(from_urdf.coordinates, from_expressions.coordinates);
  Recorder a, b;
  const RunSummary sa = run_scene(from_urdf, &a), sb = run_scene(from_expressions, &b);
  ASSERT_EQ(sa.status, RunStatus::kCompleted) << sa.message;
  ASSERT_EQ(sb.status, RunStatus::kCompleted) << sb.message;
  ASSERT_EQ(a.states.size(), b.states.size());
  ASSERT_EQ(a.states.size(), 1001u);
  double worst = 0.0;
  for (std::size_t k = 0; k < a.states.size(); ++k)
    for (std::size_t i = 0; i < 4; ++i)
      worst = std::max(worst, std::abs(a.states[k][i] - b.states[k][i]) / (1.0 + std::abs(b.states[k][i])));
  EXPECT_LT(worst, 1e-12);
  // The pendulum moved (the comparison is not between two resting states).
  EXPECT_GT(std::abs(b.states.back()[0] - b.states.front()[0]), 0.1);
}

// ---- KDL, built from urdfdom's parse as kdl_parser does ----------------------------------------------
KDL::Frame to_kdl(const urdf::Pose& p) {
  return KDL::Frame(KDL::Rotation::Quaternion(p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w),
                    KDL::Vector(p.position.x, p.position.y, p.position.z));
}

KDL::RigidBodyInertia to_kdl(const urdf::InertialSharedPtr& i) {
  if (!i) return KDL::RigidBodyInertia();
  const KDL::Frame origin = to_kdl(i->origin);
  const KDL::RotationalInertia in_frame(i->ixx, i->iyy, i->izz, i->ixy, i->ixz, i->iyz);
  // Rotate the inertia (about the centre of mass) into the link frame; KDL rotates only rigid-body inertias.
  const KDL::RigidBodyInertia rotated = origin.M * KDL::RigidBodyInertia(0.0, KDL::Vector::Zero(), in_frame);
  return KDL::RigidBodyInertia(i->mass, origin.p, rotated.getRotationalInertia());
}

KDL::Chain kdl_chain(const std::string& text, const std::string& root, const std::string& tip) {
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDF(text);
  EXPECT_TRUE(model);
  std::vector<urdf::LinkConstSharedPtr> path;
  for (urdf::LinkConstSharedPtr l = model->getLink(tip); l && l->name != root; l = l->getParent()) path.push_back(l);
  KDL::Chain chain;
  for (auto it = path.rbegin(); it != path.rend(); ++it) {
    const urdf::Joint& j = *(*it)->parent_joint;
    const KDL::Frame f = to_kdl(j.parent_to_joint_origin_transform);
    const KDL::Vector axis(j.axis.x, j.axis.y, j.axis.z);
    KDL::Joint joint;
    if (j.type == urdf::Joint::REVOLUTE || j.type == urdf::Joint::CONTINUOUS)
      joint = KDL::Joint(j.name, f.p, f.M * axis, KDL::Joint::RotAxis);
    else if (j.type == urdf::Joint::PRISMATIC)
      joint = KDL::Joint(j.name, f.p, f.M * axis, KDL::Joint::TransAxis);
    else
      joint = KDL::Joint(j.name, KDL::Joint::Fixed);
    chain.addSegment(KDL::Segment((*it)->name, joint, f, to_kdl((*it)->inertial)));
  }
  return chain;
}

TEST(Urdf, SevenJointArmMatchesKdl) {
  const std::string text = read_text(iiwa_path());
  const UrdfRobot robot = read_urdf(text);
  ASSERT_EQ(robot.model.dof(), 7);
  EXPECT_EQ(robot.limits.size(), 7u);
  EXPECT_EQ(robot.damping, std::vector<double>(7, 0.5));
  const KDL::Chain chain = kdl_chain(text, "base", "iiwa_link_ee");
  ASSERT_EQ(chain.getNrOfJoints(), 7u);
  const Eigen::Vector3d g = robot.model.gravity_m_s2;
  KDL::ChainDynParam dyn(chain, KDL::Vector(g.x(), g.y(), g.z()));
  RigidBodyData data(robot.model);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  for (int trial = 0; trial < 50; ++trial) {
    KDL::JntArray q(7), v(7), cv(7), G(7);
    KDL::JntSpaceInertiaMatrix Mk(7);
    for (unsigned i = 0; i < 7; ++i) {
      q(i) = u(rng);
      v(i) = u(rng);
    }
    ASSERT_EQ(dyn.JntToMass(q, Mk), 0);
    ASSERT_EQ(dyn.JntToCoriolis(q, v, cv), 0);
    ASSERT_EQ(dyn.JntToGravity(q, G), 0);
    Eigen::MatrixXd M(7, 7), C(7, 7);
    Eigen::VectorXd Gm(7);
    rigid_body_terms(robot.model, data, q.data.data(), v.data.data(), M, C, Gm);
    EXPECT_LT(relative(M, Mk.data), 1e-12);
    EXPECT_LT(relative(C * v.data, cv.data), 1e-12);
    EXPECT_LT(relative(Gm, G.data), 1e-12);
    EXPECT_EQ(M, M.transpose());
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues()(0), 0.0);
    // Polarization against KDL: C(q, v) w = (c(v + w) - c(v - w)) / 4, exact for the Christoffel form.
    KDL::JntArray w(7), vp(7), vm(7), cp(7), cm(7);
    for (unsigned i = 0; i < 7; ++i) w(i) = u(rng);
    vp.data = v.data + w.data;
    vm.data = v.data - w.data;
    ASSERT_EQ(dyn.JntToCoriolis(q, vp, cp), 0);
    ASSERT_EQ(dyn.JntToCoriolis(q, vm, cm), 0);
    EXPECT_LT(relative(C * w.data, (cp.data - cm.data) / 4.0), 1e-11);
  }
}

// The tracking controller on a URDF arm (the explicit law, sampled at every step, so that each sample's u
// is the continuous law's at that state): u = 0.9 (M a_r + C(q, v) v_r + G) - A sgn(sigma), its model
// part from KDL (M, gravity, and C(q, v) v_r by polarization of KDL's Coriolis vector), the reference
// sin(t + i) and its derivatives written here, against the u the run's samples carry.
TEST(Urdf, LinkPosesMatchKdlForwardKinematics) {
  const std::string text = read_text(iiwa_path());
  const UrdfRobot robot = read_urdf(text);
  const KDL::Chain chain = kdl_chain(text, "base", "iiwa_link_ee");
  KDL::ChainFkSolverPos_recursive fk(chain);
  // The root, the fixed iiwa_link_0 on the base, the seven moving links, and iiwa_link_ee merged into the last.
  ASSERT_EQ(robot.links.size(), 10u);
  EXPECT_EQ(robot.links.front().name, "base");
  EXPECT_EQ(robot.links.front().parent, "");
  EXPECT_EQ(robot.links.back().name, "iiwa_link_ee");
  EXPECT_EQ(robot.links.back().parent, "iiwa_link_7");
  EXPECT_EQ(robot.links.back().body, 6);
  EXPECT_NEAR(robot.links.back().joint_origin.z(), 0.045, 0.0);
  RigidBodyData data(robot.model);
  std::vector<UrdfFrame> poses;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  for (int trial = 0; trial < 20; ++trial) {
    KDL::JntArray qk(7);
    std::vector<double> q(7);
    for (unsigned i = 0; i < 7; ++i) q[i] = qk(i) = u(rng);
    link_poses(robot, data, q.data(), poses);
    ASSERT_EQ(poses.size(), robot.links.size());
    for (std::size_t k = 0; k < robot.links.size(); ++k) {
      KDL::Frame want;  // the root: the world frame
      for (unsigned s = 0; s < chain.getNrOfSegments(); ++s) {
        if (chain.getSegment(s).getName() == robot.links[k].name) {
          ASSERT_GE(fk.JntToCart(qk, want, static_cast<int>(s + 1)), 0);
        }
      }
      for (int r = 0; r < 3; ++r) {
        EXPECT_NEAR(poses[k].position(r), want.p(r), 1e-12) << robot.links[k].name;
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(poses[k].rotation(r, c), want.M(r, c), 1e-12) << robot.links[k].name;
      }
    }
  }
}

TEST(Urdf, VisualPrimitivesAreDescribedAndMeshesCounted) {
  const std::string text = R"(<robot name="shapes">
  <link name="a"><visual><geometry><box size="0.1 0.2 0.3"/></geometry></visual></link>
  <joint name="j" type="continuous"><parent link="a"/><child link="b"/><origin xyz="0 0 0.5"/><axis xyz="0 1 0"/></joint>
  <link name="b">
    <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><origin xyz="0 0 0.25" rpy="0 0 0"/><geometry><cylinder radius="0.05" length="0.5"/></geometry></visual>
    <visual><geometry><sphere radius="0.07"/></geometry></visual>
    <visual><geometry><mesh filename="package://x/b.stl"/></geometry></visual>
  </link>
</robot>)";
  const UrdfRobot robot = read_urdf(text);
  ASSERT_EQ(robot.links.size(), 2u);
  const UrdfLink& a = robot.links[0];
  const UrdfLink& b = robot.links[1];
  ASSERT_EQ(a.visuals.size(), 1u);
  EXPECT_EQ(a.visuals[0].shape, UrdfVisual::Shape::kBox);
  EXPECT_EQ(a.visuals[0].size, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(b.joint, "j");
  EXPECT_EQ(b.joint_origin, Eigen::Vector3d(0, 0, 0.5));
  ASSERT_EQ(b.visuals.size(), 2u);
  EXPECT_EQ(b.visuals[0].shape, UrdfVisual::Shape::kCylinder);
  EXPECT_EQ(b.visuals[0].radius, 0.05);
  EXPECT_EQ(b.visuals[0].length, 0.5);
  EXPECT_EQ(b.visuals[0].origin.position, Eigen::Vector3d(0, 0, 0.25));
  EXPECT_EQ(b.visuals[1].shape, UrdfVisual::Shape::kSphere);
  EXPECT_EQ(b.visuals[1].radius, 0.07);
  EXPECT_EQ(b.meshes, 1);
}

TEST(Urdf, TrackingControllerModelPartMatchesKdl) {
  const std::string text = read_text(iiwa_path());
  const double h = 1e-4, lambda = 10.0, scale = 0.9;
  const std::vector<double> gains = {10, 20, 10, 10, 5, 5, 2};
  nlohmann::json reference = nlohmann::json::array();
  for (int i = 0; i < 7; ++i) reference.push_back("0.2*sin(t + " + std::to_string(i) + ")");
  const nlohmann::json doc = {{"name", "iiwa-tracking-kdl"},
                              {"system",
                               {{"type", "lagrangian"},
                                {"urdf", {{"text", text}, {"gravity", {0.0, 0.0, -9.81}}}},
                                {"tracking",
                                 {{"reference", reference},
                                  {"lambda", std::vector<double>(7, lambda)},
                                  {"controller", {{{"type", "abs"}, {"gains", gains}}}},
                                  {"law", "explicit"},
                                  {"period", h},
                                  {"nominal", {{"scale", scale}}}}}}},
                              {"initial", {{"q", {0.3, 0.8, -0.1, -1.2, 0.1, 1.0, 0.0}}, {"v", {0.5, -0.4, 0.3, 0.2, -0.6, 0.1, 0.7}}}},
                              {"integrator", {{"h", h}, {"t_end", 50 * h}}}};
  struct Samples : RunObserver {
    std::vector<double> t;
    std::vector<Eigen::VectorXd> q, v, u;
    void on_sample(const Sample& s) override {
      t.push_back(s.t);
      q.push_back(Eigen::Map<const Eigen::VectorXd>(s.q, s.n));
      v.push_back(Eigen::Map<const Eigen::VectorXd>(s.v, s.n));
      Eigen::VectorXd uk(s.n);
      for (int i = 0; i < s.n; ++i) uk(i) = s.signals[4 * i + 3];
      u.push_back(uk);
    }
  } samples;
  const RunSummary run = run_scene(load_scene(doc), &samples);
  ASSERT_EQ(run.status, RunStatus::kCompleted) << run.message;
  ASSERT_EQ(samples.t.size(), 51u);
  const KDL::Chain chain = kdl_chain(text, "base", "iiwa_link_ee");
  KDL::ChainDynParam dyn(chain, KDL::Vector(0.0, 0.0, -9.81));
  for (std::size_t k = 0; k + 1 < samples.t.size(); ++k) {  // the last state applies no control of its own
    const double t = samples.t[k];
    Eigen::VectorXd qd(7), vd(7), ad(7);
    for (int i = 0; i < 7; ++i) {
      qd(i) = 0.2 * std::sin(t + i);
      vd(i) = 0.2 * std::cos(t + i);
      ad(i) = -0.2 * std::sin(t + i);
    }
    const Eigen::VectorXd& q = samples.q[k];
    const Eigen::VectorXd& v = samples.v[k];
    const Eigen::VectorXd v_r = vd - lambda * (q - qd), a_r = ad - lambda * (v - vd), sigma = v - v_r;
    KDL::JntArray qk(7), vp(7), vm(7), cp(7), cm(7), G(7);
    KDL::JntSpaceInertiaMatrix Mk(7);
    qk.data = q;
    vp.data = v + v_r;
    vm.data = v - v_r;
    ASSERT_EQ(dyn.JntToMass(qk, Mk), 0);
    ASSERT_EQ(dyn.JntToCoriolis(qk, vp, cp), 0);
    ASSERT_EQ(dyn.JntToCoriolis(qk, vm, cm), 0);
    ASSERT_EQ(dyn.JntToGravity(qk, G), 0);
    Eigen::VectorXd expected = scale * (Mk.data * a_r + (cp.data - cm.data) / 4.0 + G.data);
    for (int i = 0; i < 7; ++i) expected(i) -= gains[static_cast<std::size_t>(i)] * (sigma(i) > 0.0 ? 1.0 : (sigma(i) < 0.0 ? -1.0 : 0.0));
    EXPECT_LT(relative(samples.u[k], expected), 1e-10) << "t = " << t;
  }
}

// The 6-joint PUMA 560 (scenes/robots/puma560.urdf, written by scripts/make-puma560-urdf.py) against the
// textbook model built here from the published standard Denavit-Hartenberg table itself (Corke and
// Armstrong-Helouvry 1994, with the three deviations the script documents): frames
// T_i = T_{i-1} Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i), M(q) = sum_i m_i Jv_i^T Jv_i + Jw_i^T R_i I_i R_i^T Jw_i
// and G(q) = -sum_i m_i Jv_i^T g with Jv_i column j = z_{j-1} x (c_i - o_{j-1}), Jw_i column j = z_{j-1}.
// This checks the DH-to-URDF conversion as well as the algorithms.
TEST(Urdf, SixJointArmMatchesItsDenavitHartenbergTable) {
  struct DhLink {
    double d, a, alpha, m;
    Eigen::Vector3d r, I;
  };
  const double pi = 3.14159265358979323846;
  const std::vector<DhLink> table = {
      {0.672, 0.0, pi / 2, 1.0, {0, 0, 0}, {0.35, 0.35, 0.35}},  // m and I_xx, I_zz: see the script
      {0.0, 0.4318, 0.0, 17.4, {-0.3638, 0.006, 0.2275}, {0.13, 0.524, 0.539}},
      {0.15005, 0.0203, -pi / 2, 4.8, {-0.0203, -0.0141, 0.070}, {0.066, 0.086, 0.020}},  // I_zz: see the script
      {0.4318, 0.0, pi / 2, 0.82, {0, 0.019, 0}, {1.8e-3, 1.3e-3, 1.8e-3}},
      {0.0, 0.0, -pi / 2, 0.34, {0, 0, 0}, {0.3e-3, 0.4e-3, 0.3e-3}},
      {0.0, 0.0, 0.0, 0.09, {0, 0, 0.032}, {0.15e-3, 0.15e-3, 0.04e-3}}};
  const UrdfRobot robot = read_urdf(read_text(std::string(MOREAU_SOURCE_DIR) + "/scenes/robots/puma560.urdf"));
  ASSERT_EQ(robot.model.dof(), 6);
  ASSERT_EQ(robot.limits.size(), 6u);
  EXPECT_NEAR(robot.limits[1].upper, 225.0 * pi / 180.0, 1e-15);
  const Eigen::Vector3d g = robot.model.gravity_m_s2;
  ASSERT_EQ(g, Eigen::Vector3d(0, 0, -9.81));
  RigidBodyData data(robot.model);
  std::mt19937 rng(560);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 50; ++trial) {
    Eigen::VectorXd q(6), v = Eigen::VectorXd::Zero(6), Gm(6);
    for (int i = 0; i < 6; ++i) q(i) = u(rng);
    std::vector<Eigen::Matrix4d> T(7, Eigen::Matrix4d::Identity());  // T[i]: DH frame i in the base
    for (int i = 0; i < 6; ++i) {
      const DhLink& l = table[static_cast<std::size_t>(i)];
      const double ct = std::cos(q(i)), st = std::sin(q(i)), ca = std::cos(l.alpha), sa = std::sin(l.alpha);
      Eigen::Matrix4d A;
      A << ct, -st * ca, st * sa, l.a * ct, st, ct * ca, -ct * sa, l.a * st, 0, sa, ca, l.d, 0, 0, 0, 1;
      T[static_cast<std::size_t>(i) + 1] = T[static_cast<std::size_t>(i)] * A;
    }
    Eigen::MatrixXd Mref = Eigen::MatrixXd::Zero(6, 6);
    Eigen::VectorXd Gref = Eigen::VectorXd::Zero(6);
    for (int i = 0; i < 6; ++i) {
      const DhLink& l = table[static_cast<std::size_t>(i)];
      const Eigen::Matrix4d& Ti = T[static_cast<std::size_t>(i) + 1];
      const Eigen::Vector3d c = Ti.topLeftCorner<3, 3>() * l.r + Ti.topRightCorner<3, 1>();
      Eigen::MatrixXd Jv = Eigen::MatrixXd::Zero(3, 6), Jw = Eigen::MatrixXd::Zero(3, 6);
      for (int j = 0; j <= i; ++j) {
        const Eigen::Vector3d z = T[static_cast<std::size_t>(j)].block<3, 1>(0, 2), o = T[static_cast<std::size_t>(j)].block<3, 1>(0, 3);
        Jv.col(j) = z.cross(c - o);
        Jw.col(j) = z;
      }
      const Eigen::Matrix3d R = Ti.topLeftCorner<3, 3>();
      const Eigen::Matrix3d Iw = R * l.I.asDiagonal() * R.transpose();
      Mref += l.m * Jv.transpose() * Jv + Jw.transpose() * Iw * Jw;
      Gref -= l.m * Jv.transpose() * g;
    }
    Eigen::MatrixXd M(6, 6), C(6, 6);
    rigid_body_terms(robot.model, data, q.data(), v.data(), M, C, Gm);
    EXPECT_LT(relative(M, Mref), 1e-12) << "trial " << trial;
    EXPECT_LT(relative(Gm, Gref), 1e-12) << "trial " << trial;
  }
}

// E = 1/2 <M v, v> of a free swing (no gravity, no friction, no controller) is a first integral; the
// scheme (0.2), explicit in position, keeps it to O(h): the drift at t = 1 halves with h.
TEST(Urdf, FreeSwingConservesEnergyToFirstOrder) {
  std::vector<double> drift;
  for (double h : {4e-4, 2e-4, 1e-4}) {
    nlohmann::json doc = {{"name", "free-swing"},
                          {"system", {{"type", "lagrangian"}, {"urdf", {{"text", read_text(iiwa_path())}, {"gravity", {0, 0, 0}}}}}},
                          {"initial", {{"q", {0.3, 0.6, -0.4, -1.2, 0.5, 0.8, 0.0}}, {"v", {1.0, -0.8, 1.2, 1.0, -1.5, 2.0, 3.0}}}},
                          {"integrator", {{"scheme", "abl"}, {"h", h}, {"t_end", 1.0}}}};
    const LagrangianScene sc = load_scene(doc);
    Recorder r;
    const RunSummary s = run_scene(sc, &r);
    ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
    drift.push_back(std::abs(s.energy_final - s.energy_initial) / s.energy_initial);
  }
  const double order1 = std::log2(drift[0] / drift[1]), order2 = std::log2(drift[1] / drift[2]);
  EXPECT_NEAR(order1, 1.0, 0.15) << "drifts " << drift[0] << ", " << drift[1] << ", " << drift[2];
  EXPECT_NEAR(order2, 1.0, 0.15) << "drifts " << drift[0] << ", " << drift[1] << ", " << drift[2];
  EXPECT_LT(drift[2], 0.05);
}

// The arm falls onto joint 2's upper limit with Coulomb friction on the same joint
// (scenes/iiwa14-joint-limit.json). At rest on the limit, friction and the limit act on one velocity and
// the reaction does not divide uniquely between two rows: the Moreau-Jean step merges them into one law.
// The run completes and ends at rest, v == 0.0 exactly, against the limit; every impact obeys Newton's
// law U+ = -e U- to round-off; the gap never goes below the velocity-level scheme's O(h^2 g).
TEST(Urdf, JointLimitWithCoulombFrictionRestsExactlyOnTheLimit) {
  const LagrangianScene sc = load_scene(read_scene_file(std::string(MOREAU_SOURCE_DIR) + "/scenes/iiwa14-joint-limit.json"));
  ASSERT_GT(sc.controller.gains(1), 0.0) << "the scene must put Coulomb friction on the limited joint 2";
  ContactDiagnostics diag;
  const RunSummary s = run_scene(sc, nullptr, &diag);
  ASSERT_EQ(s.status, RunStatus::kCompleted) << s.message;
  ASSERT_TRUE(s.converged_step.has_value()) << "the arm must come to rest";
  for (double v : s.v_final) EXPECT_EQ(v, 0.0);
  int upper2 = -1;
  for (std::size_t i = 0; i < sc.constraint_names.size(); ++i)
    if (sc.constraint_names[i] == "iiwa_joint_2_upper") upper2 = static_cast<int>(i);
  ASSERT_GE(upper2, 0);
  EXPECT_GE(diag.settle_step[static_cast<std::size_t>(upper2)], 0) << "joint 2 must end held by its upper limit";
  EXPECT_NEAR(s.q_final[1], 2.09439510239, 1e-5);
  ASSERT_GT(diag.impacts.size(), 0u);
  for (const ImpactEvent& ev : diag.impacts)
    EXPECT_NEAR(ev.post, -sc.restitution[static_cast<std::size_t>(ev.constraint)] * ev.pre, 1e-12 * std::abs(ev.pre)) << "t = " << ev.t;
  EXPECT_GT(diag.smallest_gap, -1e-5);
}

// ---- bad URDF -------------------------------------------------------------------------------------------
std::string error_of(const std::string& text) {
  try {
    read_urdf(text);
  } catch (const UrdfError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string one_link(const std::string& inertial, const std::string& joint_type = "revolute", const std::string& extra = "") {
  return "<robot name=\"r\">\n<link name=\"base\"/>\n<joint name=\"j1\" type=\"" + joint_type +
         "\">\n<parent link=\"base\"/><child link=\"l1\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" "
         "velocity=\"1\"/>\n</joint>\n<link name=\"l1\">\n" +
         inertial + "\n</link>\n" + extra + "</robot>\n";
}

std::string inertial(const std::string& mass, const std::string& diag) {
  std::istringstream d(diag);
  std::string a, b, c;
  d >> a >> b >> c;
  return "<inertial><mass value=\"" + mass + "\"/><inertia ixx=\"" + a + "\" ixy=\"0\" ixz=\"0\" iyy=\"" + b + "\" iyz=\"0\" izz=\"" + c +
         "\"/></inertial>";
}

TEST(Urdf, BadUrdfGetsAnErrorNamingTheElement) {
  const std::string good = inertial("1", "0.1 0.1 0.1");
  const std::string limit = "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/>";
  ASSERT_EQ(error_of(one_link(good)), "(no error)");
  struct Case {
    std::string name, text, expected;
  };
  const std::vector<Case> cases = {
      {"malformed XML", "<robot name=\"r\">\n<link name=\"a\">\n</robot>", "malformed XML at line"},
      {"not a robot", "<model/>", "not <robot>"},
      {"missing inertial", one_link(""), "link 'l1' (line 6) is moved by joint 'j1' (line 3) but has no <inertial>"},
      {"zero mass", one_link(inertial("0", "0.1 0.1 0.1")), "link 'l1' (line 6): <mass value> must be a positive number"},
      {"negative mass", one_link(inertial("-2", "0.1 0.1 0.1")), "link 'l1' (line 6): <mass value> must be a positive number"},
      {"inertia not positive definite", one_link(inertial("1", "0.1 -0.1 0.1")), "link 'l1' (line 6): <inertia> is not positive definite"},
      {"triangle inequality", one_link(inertial("1", "0.1 0.1 0.5")), "link 'l1' (line 6): <inertia> breaks the triangle inequality"},
      {"unknown joint type", one_link(good, "helical"), "no known type"},
      {"floating joint", one_link(good, "floating"), "joint 'j1' (line 3) is floating: joints of more than one degree of freedom"},
      // Joints that are not a tree, refused before urdfdom builds one: it would keep a loop's links forever
      // (shared pointers in a cycle), and a link with two parent joints on a loop sent the walk from the
      // root round it without end (a scene that never loaded).
      {"joint loop",
       one_link(
           good, "revolute",
           "<joint name=\"j2\" type=\"revolute\"><parent link=\"l1\"/><child link=\"base\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" "
           "velocity=\"1\"/></joint>\n"),
       "the joints 'j1' (line 3), 'j2' (line 9) form a loop"},
      {"a link with two parent joints, on a loop",
       one_link(good, "revolute",
                "<link name=\"b\">" + good +
                    "</link>\n"
                    "<joint name=\"j2\" type=\"revolute\"><parent link=\"l1\"/><child link=\"b\"/>" +
                    limit +
                    "</joint>\n"
                    "<joint name=\"j3\" type=\"revolute\"><parent link=\"b\"/><child link=\"l1\"/>" +
                    limit + "</joint>\n"),
       "link 'l1' is the child of two joints, 'j1' (line 3) and 'j3' (line 11)"},
      {"a loop apart from the root",
       one_link(good, "revolute",
                "<link name=\"x\"/>\n<link name=\"y\"/>\n"
                "<joint name=\"j2\" type=\"fixed\"><parent link=\"x\"/><child link=\"y\"/></joint>\n"
                "<joint name=\"j3\" type=\"fixed\"><parent link=\"y\"/><child link=\"x\"/></joint>\n"),
       "the joints 'j2' (line 11), 'j3' (line 12) form a loop"},
      {"joint to a missing link",
       one_link(good, "revolute",
                "<joint name=\"j2\" type=\"revolute\"><parent link=\"l1\"/><child link=\"nowhere\"/><limit lower=\"-1\" upper=\"1\" "
                "effort=\"1\" velocity=\"1\"/></joint>\n"),
       "nowhere"},
      {"revolute without limit",
       "<robot name=\"r\"><link name=\"base\"/><joint name=\"j1\" type=\"revolute\"><parent link=\"base\"/><child link=\"l1\"/></joint>"
       "<link name=\"l1\">" +
           good + "</link></robot>",
       "j1"},
      {"inverted limit",
       one_link(good, "revolute").replace(one_link(good).find("lower=\"-1\" upper=\"1\""), 20, "lower=\"1\" upper=\"-1\""),
       "joint 'j1' (line 3): <limit> needs finite lower <= upper"},
      {"zero axis", one_link(good).replace(one_link(good).find("xyz=\"0 0 1\""), 11, "xyz=\"0 0 0\""), "joint 'j1' (line 3): <axis xyz>"},
  };
  for (const Case& c : cases) {
    const std::string e = error_of(c.text);
    EXPECT_NE(e.find(c.expected), std::string::npos) << c.name << ": " << e;
  }
}

TEST(Urdf, HugeAndDeepUrdfAreRefusedBeforeParsing) {
  // 100 MB: refused by size, not read into a parser.
  const std::string huge(100u << 20, ' ');
  EXPECT_NE(error_of(huge).find("larger than 16 MiB"), std::string::npos);
  // A tree of 10,000 links: refused by count, with the line of the first link over the limit.
  std::string deep = "<robot name=\"r\">\n<link name=\"l0\"/>\n";
  for (int k = 1; k < 10000; ++k)
    deep += "<joint name=\"j" + std::to_string(k) + "\" type=\"continuous\"><parent link=\"l" + std::to_string(k - 1) +
            "\"/><child link=\"l" + std::to_string(k) + "\"/></joint>\n<link name=\"l" + std::to_string(k) + "\">" +
            inertial("1", "0.1 0.1 0.1") + "</link>\n";
  deep += "</robot>\n";
  EXPECT_NE(error_of(deep).find("more than 1024 links"), std::string::npos) << error_of(deep).substr(0, 200);
}

// XML nested deeper than kMaxXmlDepth is refused before TinyXML or urdfdom, both of which recurse once per
// level: 40,000 levels overflowed the stack (SIGSEGV) of the thread that read them.
TEST(Urdf, DeepXmlIsRefusedBeforeAnyRecursiveParser) {
  auto nested = [](int depth, const std::string& inner = "") {
    std::string text = "<robot name=\"r\">";  // depth 1
    for (int k = 1; k < depth; ++k) text += "<a>";
    text += inner;
    for (int k = 1; k < depth; ++k) text += "</a>";
    return text + "</robot>";
  };
  EXPECT_EQ(error_of(nested(40000)).rfind("elements nested deeper than 64 levels (line 1)", 0), 0u)
      << error_of(nested(40000)).substr(0, 200);
  EXPECT_EQ(error_of(nested(65)).rfind("elements nested deeper than 64 levels", 0), 0u);
  // 64 levels pass the shape check: what refuses this one is urdfdom (no link), not the depth.
  EXPECT_EQ(error_of(nested(64)).find("nested deeper"), std::string::npos) << error_of(nested(64));
  EXPECT_EQ(detail::check_xml_shape(nested(64)).depth, 64);
  EXPECT_EQ(detail::check_xml_shape(nested(64)).elements, 64u);
  // Self-closing siblings are not nesting, and a '>' inside an attribute value closes nothing.
  std::string wide = "<robot>";
  for (int k = 0; k < 5000; ++k) wide += "<link name='x>y'/>";
  EXPECT_EQ(detail::check_xml_shape(wide + "</robot>").depth, 2);
  // Element count: bounded too (each element costs TinyXML memory).
  std::string many = "<robot>";
  for (std::size_t k = 0; k < detail::kMaxXmlElements; ++k) many += "<b/>";
  EXPECT_EQ(error_of(many + "</robot>").rfind("more than 100000 XML elements", 0), 0u) << error_of(many + "</robot>").substr(0, 200);
}

// Found by the URDF fuzzer: TinyXML ends a processing instruction at its first '>', Expat at "?>", so
// nesting inside a PI was invisible to the shape check and recursed in TinyXML. PIs are refused; the XML
// declaration still passes.
TEST(Urdf, ProcessingInstructionsCannotHideNesting) {
  std::string hidden = "<robot name=\"r\"><?pi <a\"r\">";
  for (int k = 0; k < 40000; ++k) hidden += "<gazebo>";
  hidden += "?></robot>";
  EXPECT_EQ(error_of(hidden).rfind("a processing instruction <?pi ...?> (line 1): processing instructions are not accepted in a URDF", 0),
            0u)
      << error_of(hidden).substr(0, 200);
  const std::string declared = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n" + one_link(inertial("1", "0.1 0.1 0.1"));
  EXPECT_EQ(error_of(declared), "(no error)");
}

TEST(Urdf, DoctypeIsRefusedByName) {
  const std::string e = error_of("<?xml version=\"1.0\"?>\n<!DOCTYPE robot SYSTEM \"file:///etc/passwd\">\n<robot name=\"r\"/>");
  EXPECT_EQ(e, "a DOCTYPE declaration (line 2): DOCTYPE and entity declarations are not accepted in a URDF");
}

// The worst text the shape check lets through (64 levels, the most elements) is read without trouble on a
// thread with a small stack: 256 KiB, a 32nd of the default 8 MiB that the server's and the campaigns'
// worker threads get.
TEST(Urdf, TheDeepestAcceptedUrdfReadsOnASmallStack) {
  std::string gazebo;  // levels 2 to 64 under <robot>
  for (int k = 1; k < detail::kMaxXmlDepth; ++k) gazebo += "<gazebo reference=\"x\" a=\"1\" b=\"2\">";
  for (int k = 1; k < detail::kMaxXmlDepth; ++k) gazebo += "</gazebo>";
  const std::string text = one_link(inertial("1", "0.1 0.1 0.1"), "revolute", gazebo + "\n");
  ASSERT_EQ(detail::check_xml_shape(text).depth, detail::kMaxXmlDepth);
  struct Arg {
    const std::string* text;
    std::string error;
  } arg{&text, ""};
  pthread_attr_t attr;
  ASSERT_EQ(pthread_attr_init(&attr), 0);
  ASSERT_EQ(pthread_attr_setstacksize(&attr, 256u << 10), 0);
  pthread_t thread;
  ASSERT_EQ(pthread_create(
                &thread, &attr,
                [](void* p) -> void* {
                  Arg& a = *static_cast<Arg*>(p);
                  a.error = error_of(*a.text);
                  return nullptr;
                },
                &arg),
            0);
  ASSERT_EQ(pthread_join(thread, nullptr), 0);
  pthread_attr_destroy(&attr);
  EXPECT_EQ(arg.error, "(no error)");
}

TEST(Urdf, SceneErrorsNameTheirField) {
  auto scene_error = [](nlohmann::json doc) {
    try {
      load_scene(doc);
    } catch (const SceneError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  nlohmann::json doc = {{"name", "arm"},
                        {"system", {{"type", "lagrangian"}, {"urdf", {{"text", read_text(iiwa_path())}}}}},
                        {"initial", {{"q", std::vector<double>(7, 0.1)}}},
                        {"integrator", {{"h", 1e-3}, {"t_end", 0.01}}}};
  ASSERT_EQ(scene_error(doc), "(no error)");
  auto with = [&](const std::string& pointer, nlohmann::json value) {
    nlohmann::json d = doc;
    d[nlohmann::json::json_pointer(pointer)] = value;
    return d;
  };
  EXPECT_EQ(scene_error(with("/system/urdf/text", "<robot name=\"x\"><link")).rfind("/system/urdf/text: malformed XML at line 1", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/urdf/file", "arm.urdf")).rfind("/system/urdf/file: ", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/urdf/gravity", {0, 0})).rfind("/system/urdf/gravity: ", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/urdf/tip", "no_such_link")).rfind("/system/urdf/text: tip link 'no_such_link'", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/mass", {{"1"}})).rfind("/system/mass: a URDF system", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/urdf/friction", {{"coulomb", {1, 1, 1}}})).rfind("/system/urdf/friction/coulomb: ", 0), 0u);
  EXPECT_EQ(scene_error(with("/system/urdf/limits/joints", {"iiwa_joint_9"})).rfind("/system/urdf/limits/joints/0: ", 0), 0u);
  // With the limits as constraints, a start beyond one is refused; without them it is not.
  EXPECT_EQ(scene_error(with("/initial/q", std::vector<double>(7, 2.5))), "(no error)");
  doc["system"]["urdf"]["limits"] = {{"restitution", 0.5}};
  EXPECT_EQ(scene_error(with("/initial/q", std::vector<double>(7, 2.5))).rfind("/initial/q: violates constraint 'iiwa_joint_2_upper'", 0),
            0u)
      << scene_error(with("/initial/q", std::vector<double>(7, 2.5)));
}

}  // namespace
}  // namespace moreau::scene
