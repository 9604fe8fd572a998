// Robots from URDF: the text of a <robot> -> a RigidBodyModel (core/rigid_body.h) with its joints named,
// their limits and their <dynamics> friction. Revolute, continuous and prismatic joints are coordinates;
// fixed joints merge their child link into the parent body; floating and planar joints (floating bases)
// are out of scope and refused. Parsing is urdfdom's, in a module loaded at the first URDF
// (libmoreau_urdf.so, see urdf_module.cc).
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

struct UrdfRobot {
  std::string name;
  std::string root_link;
  RigidBodyModel model;                   // gravity: the model's default until the caller sets it
  std::vector<UrdfJointLimit> limits;     // revolute and prismatic joints (URDF requires <limit> there)
  std::vector<double> damping, friction;  // per coordinate, from <dynamics> (0 when absent)
  std::vector<std::string> merged_links;  // links merged into a body through fixed joints
  std::vector<int> joint_lines;           // per body: the line of its <joint> in the URDF (0: unknown)
};

// Which part of the tree becomes the model: the subtree at `root_link` (empty: the URDF's root), or only
// the chain from it to `tip_link` when one is named.
struct UrdfSelection {
  std::string root_link, tip_link;
};

// Parses and checks a URDF. Throws UrdfError.
UrdfRobot read_urdf(std::string_view text, const UrdfSelection& selection = {});

}  // namespace moreau::scene
