// What the URDF module (urdf_module.cc, libmoreau_urdf.so) hands to its loader (urdf.cc): the robot's
// joints in tree order (every parent link before its children), each with the link it moves. Plain data only: the module links
// urdfdom and the shared C++ runtime, the loader may carry a runtime of its own (moreau links libstdc++
// statically), so nothing but these records and a message crosses between them, and no exception does.
#pragma once

#include <string>
#include <vector>

namespace moreau::scene::detail {

struct UrdfPose {
  double xyz[3] = {0.0, 0.0, 0.0};
  double quaternion_xyzw[4] = {0.0, 0.0, 0.0, 1.0};
};

struct UrdfInertial {
  bool present = false;
  double mass = 0.0;
  UrdfPose origin;  // the inertial frame in the link frame (its origin is the centre of mass)
  double ixx = 0.0, ixy = 0.0, ixz = 0.0, iyy = 0.0, iyz = 0.0, izz = 0.0;  // about the centre of mass
};

// A link's <visual> whose <geometry> is a primitive; a <mesh> is counted, not described (the viewer has no
// mesh files to load).
enum class UrdfShape { kBox, kCylinder, kSphere };
struct UrdfVisual {
  UrdfShape shape = UrdfShape::kBox;
  UrdfPose origin;                    // the visual frame in the link frame
  double size[3] = {0.0, 0.0, 0.0};   // a box's edges
  double radius = 0.0, length = 0.0;  // a cylinder's (along its z axis), a sphere's radius
};
struct UrdfVisuals {
  std::vector<UrdfVisual> primitives;
  int meshes = 0;
};

enum class UrdfJointType { kRevolute, kContinuous, kPrismatic, kFixed, kFloating, kPlanar, kUnknown };

struct UrdfJoint {
  std::string name, parent_link, child_link;
  UrdfJointType type = UrdfJointType::kUnknown;
  UrdfPose origin;  // the joint frame in the parent link's frame
  double axis[3] = {1.0, 0.0, 0.0};
  bool has_limits = false;  // <limit> given (revolute and prismatic joints must have one)
  double lower = 0.0, upper = 0.0;
  double damping = 0.0, friction = 0.0;  // <dynamics>
  UrdfInertial child_inertial;           // of child_link
  UrdfVisuals child_visuals;             // of child_link
  int line = 0;                          // of the <joint> element (0: unknown)
  int child_line = 0;                    // of the child's <link> element
};

struct UrdfDescription {
  std::string robot_name, root_link;
  int root_line = 0;
  UrdfVisuals root_visuals;
  std::vector<UrdfJoint> joints;  // from the root: every parent link before its children
};

}  // namespace moreau::scene::detail
