// Robots from URDF: the text of a <robot> -> a RigidBodyModel (core/rigid_body.h) with its joints named,
// their limits and their <dynamics> friction, and the links as a viewer draws them (UrdfLink: where each
// sits on the model's bodies, its primitive <visual> geometry; link_poses places them in the world). Revolute, continuous and prismatic
// joints are coordinates; fixed joints merge their child link into the parent body; floating and planar joints (floating bases) are out of
// scope and refused. Parsing is urdfdom's, in a module loaded at the first URDF (libmoreau_urdf.so, see urdf_module.cc).
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "moreau/core/rigid_body.h"

namespace moreau::scene {

// Largest URDF text read (a file or inline), and most links in one robot: a robot of a lab has tens.
inline constexpr std::size_t kMaxUrdfBytes = std::size_t{16} << 20;
inline constexpr std::size_t kMaxUrdfLinks = 1024;

// A URDF that cannot be used, with a message that names the element (its line, its link or joint name).
class UrdfError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct UrdfJointLimit {
  int coordinate = 0;  // index into the model's bodies
  double lower = 0.0, upper = 0.0;
};

// A pose as a 3 x 4 matrix [R | p]: the frame's axes and origin in the frame it is given in.
struct UrdfFrame {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
};

// A <visual> with primitive geometry, in its link's frame. Description only: no numerics read it.
struct UrdfVisual {
  enum class Shape { kBox, kCylinder, kSphere };
  Shape shape = Shape::kBox;
  UrdfFrame origin;                                // the geometry's frame in the link frame (a cylinder's axis is its z)
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // a box's edges, m
  double radius = 0.0, length = 0.0;               // a cylinder's radius and length, a sphere's radius, m
};

// A link of the selection, for drawing. Its frame is fixed to one body of the model (or to the base), so
// its pose at q is that body's pose times `in_body` (link_poses).
struct UrdfLink {
  std::string name;
  std::string parent;  // the parent link ("" for the root link)
  std::string joint;   // the joint from the parent ("" for the root link)
  int body = -1;       // the model body the link is fixed to (-1: the base, fixed to the world)
  UrdfFrame in_body;   // the link frame in that body's frame (identity for the link a joint moves)
  // The joint's origin (the link frame at q = 0) in the parent link's frame: where a viewer without
  // geometry draws the segment from the parent's origin to this link's.
  Eigen::Vector3d joint_origin = Eigen::Vector3d::Zero();
  std::vector<UrdfVisual> visuals;  // boxes, cylinders and spheres
  int meshes = 0;                   // <mesh> visuals, not described
};

struct UrdfRobot {
  std::string name;
  std::string root_link;
  RigidBodyModel model;                   // gravity: the model's default until the caller sets it
  std::vector<UrdfJointLimit> limits;     // revolute and prismatic joints (URDF requires <limit> there)
  std::vector<double> damping, friction;  // per coordinate, from <dynamics> (0 when absent)
  std::vector<std::string> merged_links;  // links merged into a body through fixed joints
  std::vector<int> joint_lines;           // per body: the line of its <joint> in the URDF (0: unknown)
  std::vector<UrdfLink> links;            // every link of the selection, parents before children
};

// Which part of the tree becomes the model: the subtree at `root_link` (empty: the URDF's root), or only
// the chain from it to `tip_link` when one is named.
struct UrdfSelection {
  std::string root_link, tip_link;
};

// Parses and checks a URDF. Throws UrdfError.
UrdfRobot read_urdf(std::string_view text, const UrdfSelection& selection = {});

// The world (base) pose of every link of `robot.links` at joint positions q (dof() values), by the
// model's forward kinematics (update_kinematics): `poses` gets one frame per link, in order.
void link_poses(const UrdfRobot& robot, RigidBodyData& data, const double* q, std::vector<UrdfFrame>& poses);

}  // namespace moreau::scene
