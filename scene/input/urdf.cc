// URDF -> RigidBodyModel (urdf.h). The module libmoreau_urdf.so parses (urdf_module.cc); this file loads
// it at the first URDF (found as install_paths.h says, $MOREAU_URDF_MODULE first), selects the part of
// the tree asked for, merges fixed joints and checks every inertia.
#include "moreau/scene/urdf.h"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <mutex>
#include <set>

#include <Eigen/Geometry>

#include "moreau/platform/install_paths.h"
#include "moreau/platform/number_text.h"
#include "urdf_description.h"

namespace moreau::scene {
namespace {

using detail::UrdfDescription;
using detail::UrdfInertial;
using detail::UrdfJoint;
using detail::UrdfJointType;
using detail::UrdfPose;

using DescribeFn = int (*)(const char*, std::size_t, UrdfDescription*, std::string*);
constexpr const char* kModule = "libmoreau_urdf.so";

DescribeFn load_module() {
  std::string tried;  // MOREAU_URDF_MODULE_BUILD_PATH: defined by scene/CMakeLists.txt
  void* handle = platform::open_module(platform::install_candidates(kModule, "MOREAU_URDF_MODULE", MOREAU_URDF_MODULE_BUILD_PATH),
                                       {"moreau_urdf_describe"}, tried);
  if (!handle)
    throw UrdfError(std::string("URDF scenes need the module ") + kModule + ", which was not found or could not be loaded:" + tried);
  return reinterpret_cast<DescribeFn>(::dlsym(handle, "moreau_urdf_describe"));
}

DescribeFn describe_fn() {
  static std::mutex mu;
  static DescribeFn fn = nullptr;
  std::lock_guard lock(mu);
  if (!fn) fn = load_module();
  return fn;
}

std::string number(double x) { return platform::significant(x, 10); }

std::string at_line(int line) { return line > 0 ? " (line " + std::to_string(line) + ")" : std::string(); }

struct Frame {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
};

Frame frame(const UrdfPose& pose) {
  Frame f;
  const Eigen::Quaterniond quat(pose.quaternion_xyzw[3], pose.quaternion_xyzw[0], pose.quaternion_xyzw[1], pose.quaternion_xyzw[2]);
  f.R = quat.normalized().toRotationMatrix();
  f.p = Eigen::Vector3d(pose.xyz[0], pose.xyz[1], pose.xyz[2]);
  return f;
}

Frame compose(const Frame& a, const Frame& b) {  // b given in a
  Frame f;
  f.R = a.R * b.R;
  f.p = a.p + a.R * b.p;
  return f;
}

bool finite(const UrdfPose& p) {
  for (double x : p.xyz)
    if (!std::isfinite(x)) return false;
  for (double x : p.quaternion_xyzw)
    if (!std::isfinite(x)) return false;
  return true;
}

// A link's <inertial> in the frame of the body it belongs to (`link`: the link frame in the body frame).
// Checks what a physical rigid body must satisfy: positive mass, a symmetric positive definite inertia
// whose principal moments obey the triangle inequality (each at most the sum of the other two).
RigidBodyInertia link_inertia(const UrdfInertial& in, const Frame& link, const std::string& link_name, int line) {
  const std::string where = "link '" + link_name + "'" + at_line(line);
  if (!(std::isfinite(in.mass) && in.mass > 0.0))
    throw UrdfError(where + ": <mass value> must be a positive number of kg, got " + number(in.mass));
  const double entries[] = {in.ixx, in.ixy, in.ixz, in.iyy, in.iyz, in.izz};
  for (double x : entries)
    if (!std::isfinite(x)) throw UrdfError(where + ": <inertia> has a non-finite entry");
  if (!finite(in.origin)) throw UrdfError(where + ": <inertial><origin> is not finite");
  Eigen::Matrix3d I;
  I << in.ixx, in.ixy, in.ixz, in.ixy, in.iyy, in.iyz, in.ixz, in.iyz, in.izz;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(I, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d d = eig.eigenvalues();  // ascending
  const double scale = std::max(std::abs(d(2)), 1e-300);
  if (!(d(0) > 1e-12 * scale))
    throw UrdfError(where + ": <inertia> is not positive definite (principal moments " + number(d(0)) + ", " + number(d(1)) + ", " +
                    number(d(2)) + " kg m^2)");
  if (d(2) > (d(0) + d(1)) * (1.0 + 1e-9))
    throw UrdfError(where + ": <inertia> breaks the triangle inequality of a rigid body (largest principal moment " + number(d(2)) + " > " +
                    number(d(0)) + " + " + number(d(1)) + " kg m^2)");
  const Frame inertial = compose(link, frame(in.origin));
  RigidBodyInertia out;
  out.mass_kg = in.mass;
  out.com_m = inertial.p;
  out.inertia_com_kg_m2 = inertial.R * I * inertial.R.transpose();
  return out;
}

// Two rigid bodies in one frame as one: mass, centre of mass, inertia about the new centre (parallel axes).
void merge(RigidBodyInertia& a, const RigidBodyInertia& b) {
  const double m = a.mass_kg + b.mass_kg;
  const Eigen::Vector3d c = (a.mass_kg * a.com_m + b.mass_kg * b.com_m) / m;
  auto shifted = [&](const RigidBodyInertia& x) {
    const Eigen::Vector3d d = x.com_m - c;
    return Eigen::Matrix3d(x.inertia_com_kg_m2 + x.mass_kg * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose()));
  };
  a.inertia_com_kg_m2 = shifted(a) + shifted(b);
  a.com_m = c;
  a.mass_kg = m;
}

}  // namespace

UrdfRobot read_urdf(std::string_view text, const UrdfSelection& selection) {
  if (text.size() > kMaxUrdfBytes)
    throw UrdfError("the URDF is larger than " + std::to_string(kMaxUrdfBytes >> 20) + " MiB (" + std::to_string(text.size()) + " bytes)");
  UrdfDescription d;
  std::string error;
  if (describe_fn()(text.data(), text.size(), &d, &error) != 0) throw UrdfError(error);

  // The links of the selection: the subtree at the root link, or the chain from it to the tip.
  const std::string root = selection.root_link.empty() ? d.root_link : selection.root_link;
  std::map<std::string, const UrdfJoint*> joint_of_child;
  std::set<std::string> links{d.root_link};
  for (const UrdfJoint& j : d.joints) {
    joint_of_child[j.child_link] = &j;
    links.insert(j.child_link);
  }
  if (!links.count(root)) throw UrdfError("root link '" + root + "' is not a link of the robot");
  std::set<std::string> chain;  // joints from root to tip, when a tip is named
  if (!selection.tip_link.empty()) {
    if (!links.count(selection.tip_link)) throw UrdfError("tip link '" + selection.tip_link + "' is not a link of the robot");
    std::string link = selection.tip_link;
    while (link != root) {
      auto it = joint_of_child.find(link);
      if (it == joint_of_child.end()) throw UrdfError("tip link '" + selection.tip_link + "' is not below root link '" + root + "'");
      chain.insert(it->second->name);
      link = it->second->parent_link;
    }
  }

  UrdfRobot robot;
  robot.name = d.robot_name;
  robot.root_link = root;
  // The links as a viewer draws them: placement, joint origin and primitive visuals.
  auto add_link = [&robot](const std::string& name, const std::string& parent, const std::string& joint, int body, const Frame& in_body,
                           const Eigen::Vector3d& joint_origin, const detail::UrdfVisuals& visuals) {
    UrdfLink link;
    link.name = name;
    link.parent = parent;
    link.joint = joint;
    link.body = body;
    link.in_body.rotation = in_body.R;
    link.in_body.position = in_body.p;
    link.joint_origin = joint_origin;
    link.meshes = visuals.meshes;
    for (const detail::UrdfVisual& v : visuals.primitives) {
      // A dimension that is not a finite number >= 0 describes nothing to draw: left out, and the robot
      // kept (its dynamics do not depend on how it looks).
      const double dims[] = {v.size[0], v.size[1], v.size[2], v.radius, v.length};
      if (!finite(v.origin) || !std::all_of(std::begin(dims), std::end(dims), [](double x) { return std::isfinite(x) && x >= 0.0; }))
        continue;
      UrdfVisual out;
      out.shape = v.shape == detail::UrdfShape::kBox        ? UrdfVisual::Shape::kBox
                  : v.shape == detail::UrdfShape::kCylinder ? UrdfVisual::Shape::kCylinder
                                                            : UrdfVisual::Shape::kSphere;
      const Frame origin = frame(v.origin);
      out.origin.rotation = origin.R;
      out.origin.position = origin.p;
      out.size = Eigen::Vector3d(v.size[0], v.size[1], v.size[2]);
      out.radius = v.radius;
      out.length = v.length;
      link.visuals.push_back(out);
    }
    robot.links.push_back(std::move(link));
  };
  // Each selected link: the body it is part of (-1: the base, fixed to the world) and its frame there.
  struct Placement {
    int body;
    Frame in_body;
  };
  std::map<std::string, Placement> placed{{root, Placement{-1, Frame{}}}};
  {
    // The root's own visuals: the URDF's root link has them in the description; a root chosen below it, in
    // the record of the joint above it.
    const detail::UrdfVisuals* root_visuals = &d.root_visuals;
    if (auto it = joint_of_child.find(root); it != joint_of_child.end()) root_visuals = &it->second->child_visuals;
    add_link(root, "", "", -1, Frame{}, Eigen::Vector3d::Zero(), *root_visuals);
  }
  for (const UrdfJoint& j : d.joints) {
    auto parent = placed.find(j.parent_link);
    if (parent == placed.end()) continue;  // outside the subtree at the root
    if (!selection.tip_link.empty() && !chain.count(j.name)) continue;
    const std::string where = "joint '" + j.name + "'" + at_line(j.line);
    if (j.type == UrdfJointType::kFloating || j.type == UrdfJointType::kPlanar)
      throw UrdfError(where + " is " + (j.type == UrdfJointType::kFloating ? "floating" : "planar") +
                      ": joints of more than one degree of freedom (floating bases) are out of scope");
    if (j.type == UrdfJointType::kUnknown) throw UrdfError(where + " has a joint type Moreau does not know");
    if (!finite(j.origin)) throw UrdfError(where + ": <origin> is not finite");
    const Frame origin = compose(parent->second.in_body, frame(j.origin));
    if (j.type == UrdfJointType::kFixed) {
      placed[j.child_link] = Placement{parent->second.body, origin};
      add_link(j.child_link, j.parent_link, j.name, parent->second.body, origin, frame(j.origin).p, j.child_visuals);
      if (parent->second.body >= 0) {
        robot.merged_links.push_back(j.child_link);
        if (j.child_inertial.present)
          merge(robot.model.bodies[static_cast<std::size_t>(parent->second.body)].inertia,
                link_inertia(j.child_inertial, origin, j.child_link, j.child_line));
      }
      continue;
    }
    RigidBody body;
    body.joint_name = j.name;
    body.link_name = j.child_link;
    body.parent = parent->second.body;
    body.joint = j.type == UrdfJointType::kPrismatic ? JointType::kPrismatic : JointType::kRevolute;
    body.rotation_in_parent = origin.R;
    body.position_in_parent_m = origin.p;
    const Eigen::Vector3d axis(j.axis[0], j.axis[1], j.axis[2]);
    if (!axis.allFinite() || !(axis.norm() > 0.0)) throw UrdfError(where + ": <axis xyz> must be a non-zero finite vector");
    body.axis = axis.normalized();
    if (!j.child_inertial.present)
      throw UrdfError("link '" + j.child_link + "'" + at_line(j.child_line) + " is moved by " + where +
                      " but has no <inertial>: a moving body needs a mass and an inertia");
    body.inertia = link_inertia(j.child_inertial, Frame{}, j.child_link, j.child_line);
    const int index = static_cast<int>(robot.model.bodies.size());
    robot.model.bodies.push_back(body);
    robot.joint_lines.push_back(j.line);
    placed[j.child_link] = Placement{index, Frame{}};
    add_link(j.child_link, j.parent_link, j.name, index, Frame{}, frame(j.origin).p, j.child_visuals);
    if (j.type != UrdfJointType::kContinuous) {
      if (!j.has_limits) throw UrdfError(where + ": a revolute or prismatic joint needs <limit lower upper>");
      if (!(std::isfinite(j.lower) && std::isfinite(j.upper) && j.lower <= j.upper))
        throw UrdfError(where + ": <limit> needs finite lower <= upper, got " + number(j.lower) + " and " + number(j.upper));
      robot.limits.push_back(UrdfJointLimit{index, j.lower, j.upper});
    }
    if (!(std::isfinite(j.damping) && j.damping >= 0.0 && std::isfinite(j.friction) && j.friction >= 0.0))
      throw UrdfError(where + ": <dynamics damping friction> must be finite and >= 0");
    robot.damping.push_back(j.damping);
    robot.friction.push_back(j.friction);
  }
  if (robot.model.bodies.empty()) throw UrdfError("the selected part of the robot has no moving joint (revolute, continuous or prismatic)");
  return robot;
}

void link_poses(const UrdfRobot& robot, RigidBodyData& data, const double* q, std::vector<UrdfFrame>& poses) {
  update_kinematics(robot.model, data, q, nullptr);
  poses.resize(robot.links.size());
  for (std::size_t i = 0; i < robot.links.size(); ++i) {
    const UrdfLink& link = robot.links[i];
    if (link.body < 0) {  // on the base, whose frame is the world's
      poses[i] = link.in_body;
      continue;
    }
    const auto b = static_cast<std::size_t>(link.body);
    poses[i].rotation = data.rotation[b] * link.in_body.rotation;
    poses[i].position = data.position[b] + data.rotation[b] * link.in_body.position;
  }
}

}  // namespace moreau::scene
