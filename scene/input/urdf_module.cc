// The URDF module, libmoreau_urdf.so: parses URDF text with urdfdom and describes the robot as plain
// records (urdf_description.h). It is loaded at the first URDF scene (urdf.cc), so that a process that
// never reads one never maps urdfdom, console_bridge and TinyXML.
//
// Before any of that, Expat checks the text's shape (xml_shape.h): well-formed, at most kMaxXmlDepth levels
// of nesting and kMaxXmlElements elements, no DOCTYPE. TinyXML and urdfdom's parser recurse once per level
// of nesting, so without that bound a deeply nested text overflows the reading thread's stack.
//
// Before urdfdom sees the text, TinyXML parses it once more to name the line of a syntax error and of each
// <link> and <joint> (urdfdom reports neither), to refuse a robot of more than kMaxUrdfLinks links or
// joints before urdfdom builds it, and to refuse joints that do not form a tree (check_tree). urdfdom prints
// its errors through console_bridge; a handler collects them for the message instead (console_bridge's
// handler is global: one parse at a time).
#include <algorithm>
#include <cstddef>
#include <map>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include <console_bridge/console.h>
#include <tinyxml.h>
#include <urdf_parser/urdf_parser.h>

#include "urdf_description.h"
#include "xml_shape.h"
#include "moreau/scene/urdf.h"

namespace {

using moreau::scene::detail::UrdfDescription;
using moreau::scene::detail::UrdfInertial;
using moreau::scene::detail::UrdfJoint;
using moreau::scene::detail::UrdfJointType;
using moreau::scene::detail::UrdfPose;
using moreau::scene::detail::UrdfShape;
using moreau::scene::detail::UrdfVisuals;

class CollectErrors : public console_bridge::OutputHandler {
 public:
  void log(const std::string& text, console_bridge::LogLevel level, const char*, int) override {
    if (level < console_bridge::CONSOLE_BRIDGE_LOG_ERROR) return;  // warnings: not a reason to refuse
    if (!messages.empty()) messages += "; ";
    messages += text;
  }
  std::string messages;
};

UrdfPose pose(const urdf::Pose& p) {
  UrdfPose out;
  out.xyz[0] = p.position.x;
  out.xyz[1] = p.position.y;
  out.xyz[2] = p.position.z;
  out.quaternion_xyzw[0] = p.rotation.x;
  out.quaternion_xyzw[1] = p.rotation.y;
  out.quaternion_xyzw[2] = p.rotation.z;
  out.quaternion_xyzw[3] = p.rotation.w;
  return out;
}

UrdfJointType joint_type(int type) {
  switch (type) {
    case urdf::Joint::REVOLUTE: return UrdfJointType::kRevolute;
    case urdf::Joint::CONTINUOUS: return UrdfJointType::kContinuous;
    case urdf::Joint::PRISMATIC: return UrdfJointType::kPrismatic;
    case urdf::Joint::FIXED: return UrdfJointType::kFixed;
    case urdf::Joint::FLOATING: return UrdfJointType::kFloating;
    case urdf::Joint::PLANAR: return UrdfJointType::kPlanar;
    default: return UrdfJointType::kUnknown;
  }
}

// A link's <visual> elements as drawing needs them: boxes, cylinders and spheres, and how many meshes.
UrdfVisuals visuals(const urdf::Link& link) {
  UrdfVisuals out;
  for (const urdf::VisualSharedPtr& v : link.visual_array) {
    if (!v || !v->geometry) continue;
    moreau::scene::detail::UrdfVisual r;
    r.origin = pose(v->origin);
    switch (v->geometry->type) {
      case urdf::Geometry::BOX: {
        const auto& box = static_cast<const urdf::Box&>(*v->geometry);
        r.shape = UrdfShape::kBox;
        r.size[0] = box.dim.x;
        r.size[1] = box.dim.y;
        r.size[2] = box.dim.z;
        break;
      }
      case urdf::Geometry::CYLINDER: {
        const auto& cylinder = static_cast<const urdf::Cylinder&>(*v->geometry);
        r.shape = UrdfShape::kCylinder;
        r.radius = cylinder.radius;
        r.length = cylinder.length;
        break;
      }
      case urdf::Geometry::SPHERE:
        r.shape = UrdfShape::kSphere;
        r.radius = static_cast<const urdf::Sphere&>(*v->geometry).radius;
        break;
      default: ++out.meshes; continue;
    }
    out.primitives.push_back(r);
  }
  return out;
}

// Lines of the <link> and <joint> elements under <robot>, by name; the number of links.
struct ElementLines {
  std::map<std::string, int> links, joints;
  std::size_t link_count = 0;
};

// A <joint> as the file gives it: its parent and child link names (empty where the element has none).
struct JointEdge {
  std::string name, parent, child;
  int line = 0;
};

std::string named(const JointEdge& j) { return "'" + j.name + "' (line " + std::to_string(j.line) + ")"; }

// The joints must form a tree: each link the child of at most one joint, and no loop. urdfdom does not
// check either before it links its tree, and both break what follows. It links each parent to its
// children with shared pointers (Link::child_links), so a loop of joints is a cycle of shared pointers
// that is never freed, whether urdfdom then refuses the model ("no root link") or accepts it with the
// loop apart from the root; and a link with two parent joints under a loop sends the walk down the tree
// in describe() round the loop without end. Each link is walked up once.
void check_tree(const std::vector<JointEdge>& joints) {
  std::map<std::string, const JointEdge*> parent_joint;  // child link -> the joint it hangs from
  for (const JointEdge& j : joints) {
    if (j.parent.empty() || j.child.empty()) continue;  // urdfdom names the joint itself
    const auto [it, fresh] = parent_joint.emplace(j.child, &j);
    if (!fresh)
      throw std::runtime_error("link '" + j.child + "' is the child of two joints, " + named(*it->second) + " and " + named(j) +
                               ": the joints of a URDF form a tree");
  }
  std::set<std::string> done;  // links whose chain of parents is known to end at a root
  for (const JointEdge& start : joints) {
    std::vector<std::string> path;  // links walked up from start.child, not yet known to end at a root
    std::set<std::string> on_path;
    std::string link = start.child;
    while (!done.count(link)) {
      if (on_path.count(link)) {
        std::string loop;
        for (auto it = std::find(path.begin(), path.end(), link); it != path.end(); ++it)
          loop += (loop.empty() ? "" : ", ") + named(*parent_joint.at(*it));
        throw std::runtime_error("the joints " + loop + " form a loop: the joints of a URDF form a tree");
      }
      const auto up = parent_joint.find(link);
      if (up == parent_joint.end()) break;  // a root (or a link urdfdom will find missing)
      path.push_back(link);
      on_path.insert(link);
      link = up->second->parent;
    }
    done.insert(path.begin(), path.end());
  }
}

void describe(const std::string& text, UrdfDescription& out) {
  moreau::scene::detail::check_xml_shape(text);  // before TinyXML and urdfdom recurse over it
  TiXmlDocument doc;
  doc.Parse(text.c_str(), nullptr, TIXML_ENCODING_UTF8);
  if (doc.Error())
    throw std::runtime_error("malformed XML at line " + std::to_string(doc.ErrorRow()) + ", column " + std::to_string(doc.ErrorCol()) +
                             ": " + doc.ErrorDesc());
  const TiXmlElement* robot = doc.RootElement();
  if (!robot || std::string(robot->Value()) != "robot")
    throw std::runtime_error("the document element is not <robot> (line " + std::to_string(robot ? robot->Row() : 0) + ")");
  ElementLines lines;
  std::vector<JointEdge> edges;
  // The name of the `link` attribute of e's first <tag> child, or "".
  auto link_of = [](const TiXmlElement* e, const char* tag) {
    const TiXmlElement* c = e->FirstChildElement(tag);
    const char* link = c ? c->Attribute("link") : nullptr;
    return std::string(link ? link : "");
  };
  for (const TiXmlElement* e = robot->FirstChildElement(); e; e = e->NextSiblingElement()) {
    const std::string tag = e->Value();
    const char* name = e->Attribute("name");
    if (tag == "link") {
      if (++lines.link_count > moreau::scene::kMaxUrdfLinks)
        throw std::runtime_error("more than " + std::to_string(moreau::scene::kMaxUrdfLinks) + " links (the " +
                                 std::to_string(moreau::scene::kMaxUrdfLinks + 1) + "th is at line " + std::to_string(e->Row()) + ")");
      if (name) lines.links.emplace(name, e->Row());
    } else if (tag == "joint") {
      if (edges.size() == moreau::scene::kMaxUrdfLinks)
        throw std::runtime_error("more than " + std::to_string(moreau::scene::kMaxUrdfLinks) + " joints (the " +
                                 std::to_string(moreau::scene::kMaxUrdfLinks + 1) + "th is at line " + std::to_string(e->Row()) + ")");
      if (name) lines.joints.emplace(name, e->Row());
      edges.push_back(JointEdge{name ? name : "", link_of(e, "parent"), link_of(e, "child"), e->Row()});
    }
  }
  check_tree(edges);

  urdf::ModelInterfaceSharedPtr model;
  {
    static std::mutex mu;
    std::lock_guard lock(mu);
    CollectErrors errors;
    console_bridge::useOutputHandler(&errors);
    model = urdf::parseURDF(text);
    console_bridge::restorePreviousOutputHandler();
    if (!model) throw std::runtime_error(errors.messages.empty() ? std::string("urdfdom refused the model") : errors.messages);
  }
  const urdf::LinkConstSharedPtr root = model->getRoot();
  if (!root) throw std::runtime_error("the model has no root link");
  out.robot_name = model->getName();
  out.root_link = root->name;
  if (auto it = lines.links.find(root->name); it != lines.links.end()) out.root_line = it->second;
  out.root_visuals = visuals(*root);

  // Depth first, without recursion (a chain can be as long as kMaxUrdfLinks).
  std::vector<urdf::LinkConstSharedPtr> stack{root};
  std::set<std::string> visited;  // check_tree made the joints a tree; this keeps the walk finite regardless
  while (!stack.empty()) {
    const urdf::LinkConstSharedPtr link = stack.back();
    stack.pop_back();
    if (!visited.insert(link->name).second) throw std::runtime_error("link '" + link->name + "' is reached twice from the root");
    // Children pushed in reverse, so that they come out in the order the file gives them.
    for (auto it = link->child_joints.rbegin(); it != link->child_joints.rend(); ++it) {
      const urdf::Joint& j = **it;
      UrdfJoint r;
      r.name = j.name;
      r.parent_link = j.parent_link_name;
      r.child_link = j.child_link_name;
      r.type = joint_type(j.type);
      r.origin = pose(j.parent_to_joint_origin_transform);
      r.axis[0] = j.axis.x;
      r.axis[1] = j.axis.y;
      r.axis[2] = j.axis.z;
      if (j.limits) {
        r.has_limits = true;
        r.lower = j.limits->lower;
        r.upper = j.limits->upper;
      }
      if (j.dynamics) {
        r.damping = j.dynamics->damping;
        r.friction = j.dynamics->friction;
      }
      const urdf::LinkConstSharedPtr child = model->getLink(j.child_link_name);
      if (child && child->inertial) {
        const urdf::Inertial& in = *child->inertial;
        r.child_inertial.present = true;
        r.child_inertial.mass = in.mass;
        r.child_inertial.origin = pose(in.origin);
        r.child_inertial.ixx = in.ixx;
        r.child_inertial.ixy = in.ixy;
        r.child_inertial.ixz = in.ixz;
        r.child_inertial.iyy = in.iyy;
        r.child_inertial.iyz = in.iyz;
        r.child_inertial.izz = in.izz;
      }
      if (child) r.child_visuals = visuals(*child);
      if (auto l = lines.joints.find(j.name); l != lines.joints.end()) r.line = l->second;
      if (auto l = lines.links.find(j.child_link_name); l != lines.links.end()) r.child_line = l->second;
      out.joints.push_back(std::move(r));
    }
    // Visit order must match the records: push children so that the first child is visited first.
    for (auto it = link->child_links.rbegin(); it != link->child_links.rend(); ++it) stack.push_back(*it);
  }
}

}  // namespace

// Returns 0 with *out filled, or 1 with the reason in *error. No exception leaves the module.
extern "C" __attribute__((visibility("default"))) int moreau_urdf_describe(const char* text, std::size_t size, UrdfDescription* out,
                                                                           std::string* error) noexcept {
  try {
    describe(std::string(text, size), *out);
    return 0;
  } catch (const std::exception& e) {
    *error = e.what();
  } catch (...) {
    *error = "unknown failure in the URDF module";
  }
  return 1;
}
