// moreau inspect SCENE [--set PATH=VALUE]...: what a scene compiles to, without running it. For a
// Lagrangian scene: the coordinates, and for a robot from URDF each joint (type, parent, axis, the mass
// it moves, limits, friction in Phi), then the compiled sizes (coordinates, constraints, band of M and
// C), the scheme and the linear solver the step will use. For a Lur'e scene: states, outputs, feedback.

#include <iostream>

#include "commands.h"
#include "moreau/core/one_step_solver.h"
#include "moreau/platform/number_text.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/scene_model.h"
#include "moreau/scene/scheme.h"

namespace moreau::cli {
namespace {

struct InspectOptions {
  std::string scene_path;
  std::vector<std::string> overrides;
};

std::string vec3(const Eigen::Vector3d& v) {
  using platform::significant;
  return "(" + significant(v.x(), 6) + ", " + significant(v.y(), 6) + ", " + significant(v.z(), 6) + ")";
}

// The factorisation OneStepSolver will choose for this scene (its own rule, applied by configuring one).
std::string linear_solver(const scene::LagrangianScene& sc) {
  if (scene::is_fixed_dof(sc.n)) return "dense LU with partial pivoting (fixed-size, n = " + std::to_string(sc.n) + ")";
  OneStepSolver<Eigen::Dynamic> solver;
  solver.configure(sc.controller.gains, sc.controller.norm_gain, sc.settings.bandwidth);
  if (solver.banded_width() < 0) return "dense LU with partial pivoting (dynamic size)";
  return "banded LU with partial pivoting, bandwidth " + std::to_string(solver.banded_width());
}

void inspect_lagrangian(const scene::LagrangianScene& sc, std::ostream& os) {
  const RigidBodyModel* robot = sc.compiled ? sc.compiled->robot.get() : nullptr;
  os << "scene        " << sc.name << ": lagrangian, " << sc.n << " coordinates"
     << (robot ? " from URDF robot '" + sc.robot_name + "'" : "") << "\n";
  if (robot) {
    os << "gravity      " << vec3(robot->gravity_m_s2) << " m/s^2 (base frame)\n";
    os << "joints       (coordinate, type, moves link, parent body, axis in joint frame, mass moved kg, Phi: w_i, a_i)\n";
    for (int i = 0; i < robot->dof(); ++i) {
      const RigidBody& b = robot->bodies[static_cast<std::size_t>(i)];
      os << "  " << std::left << std::setw(18) << sc.coordinates[static_cast<std::size_t>(i)] << std::setw(10)
         << (b.joint == JointType::kRevolute ? "revolute" : "prismatic") << std::setw(18) << b.link_name << std::setw(18)
         << (b.parent < 0 ? std::string("(base)") : robot->bodies[static_cast<std::size_t>(b.parent)].link_name) << std::setw(30)
         << vec3(b.axis) << std::setw(10) << b.inertia.mass_kg << sc.controller.weights(i) << ", " << sc.controller.gains(i) << std::right
         << "\n";
    }
  } else {
    // A large scene: its first 8 and last 2 coordinates and constraints (--json of `moreau run` lists all).
    const std::size_t n = sc.coordinates.size();
    os << "coordinates  ";
    for (std::size_t i = 0; i < n; ++i) {
      if (n > 16 && i == 8) {
        os << ", ...";
        i = n - 2;
      }
      os << (i ? ", " : "") << sc.coordinates[i];
    }
    os << "\n";
  }
  const std::size_t nc = sc.constraint_names.size();
  os << "constraints  " << nc << "\n";
  for (std::size_t i = 0; i < nc; ++i) {
    if (nc > 16 && i == 8) {
      os << "  ... " << nc - 10 << " more\n";
      i = nc - 2;
    }
    os << "  " << sc.constraint_names[i] << ": " << sc.constraint_gaps[i] << " >= 0, e = " << sc.restitution[i] << "\n";
  }
  os << "model        M " << (sc.compiled && sc.compiled->constant_mass ? "constant" : "depends on q") << ", C "
     << scene::to_string(sc.coriolis) << (robot ? " (rigid-body algorithms)" : "") << ", M and C zero beyond "
     << (sc.compiled ? sc.compiled->bandwidth : -1) << " from the diagonal" << (sc.has_force ? ", F given" : ", no F") << "\n";
  os << "scheme       " << scene::scheme_name(sc.scheme) << ", h = " << sc.settings.h << ", t in [" << sc.settings.t0 << ", "
     << sc.settings.t_end << "]\n";
  if (scene::uses_large_contact_path(sc)) {
    const LargeContactSystem& sys = *sc.compiled->large_contacts;
    os << "solver       the large-contact path (large_contact_integrator.h): constant diagonal M, "
       << (sys.linear() ? "linear gaps (H constant: " : "nonlinear gaps (H(q) evaluated each step: ") << sys.gradients.nonZeros()
       << " nonzeros); the Delassus operator H M^-1 H^T "
       << (sys.linear() ? "formed once" : "formed on the active contacts when H or they change") << ", sparse; the step's LCP by block "
       << "principal pivoting with Murty's rule over a sparse LDL^T of the closed contacts' block, reused while they stay closed\n";
  } else if (scene::uses_large_abl_path(sc)) {
    const LargeAblSystem& sys = *sc.compiled->large_abl;
    os << "solver       the large ABL path (large_abl_integrator.h): constant sparse M (" << sys.mass.nonZeros() << " nonzeros, bandwidth "
       << sys.bandwidth() << "), P = M/h + W formed once; " << (sys.gradient ? "grad V from its terms (tapes)" : "constant grad V + F")
       << "; the inclusion (6.5) by block principal pivoting with Murty's rule over a sparse LDL^T of the moving block, reused "
          "while it stays\n";
  } else if (sc.scheme == scene::Scheme::kMoreauJean) {
    os << "solver       the Moreau-Jean one-step problem (graph_inclusion_solver.h) over dense LU of M + h (C + W)\n";
  } else {
    os << "solver       the one-step inclusion (6.5): active set, then principal pivoting; " << linear_solver(sc) << "\n";
  }
}

void inspect_lure(const scene::LureScene& sc, std::ostream& os) {
  os << "scene        " << sc.name << ": lure, " << sc.n << " states, " << sc.m << " outputs\n";
  os << "states       ";
  for (std::size_t i = 0; i < sc.states.size(); ++i) os << (i ? ", " : "") << sc.states[i];
  os << "\nfeedback     ";
  for (std::size_t i = 0; i < sc.feedback_types.size(); ++i) os << (i ? ", " : "") << sc.feedback_types[i];
  os << "\nscheme       " << scene::scheme_name(sc.scheme) << "\n";
}

}  // namespace

void register_inspect_command(CLI::App& app, Actions& actions) {
  auto opt = std::make_shared<InspectOptions>();
  CLI::App* cmd = app.add_subcommand("inspect", "Show what a scene compiles to (joints, sizes, scheme, solver) without running it");
  cmd->add_option("scene", opt->scene_path, "Scene file")->required();
  cmd->add_option("--set", opt->overrides, "Override a scene field: PATH=VALUE");
  actions[cmd] = [opt]() {
    try {
      nlohmann::json doc = scene::read_scene_file(opt->scene_path);
      for (const std::string& o : opt->overrides) scene::apply_override(doc, o);
      if (scene::system_type(doc) == "lure")
        inspect_lure(scene::load_lure_scene(doc), std::cout);
      else
        inspect_lagrangian(scene::load_scene(doc), std::cout);
      return 0;
    } catch (const scene::SceneError& e) {
      std::cerr << "moreau: invalid scene " << opt->scene_path << ": " << e.what() << "\n";
      return 2;
    } catch (const std::exception& e) {
      std::cerr << "moreau: " << e.what() << "\n";
      return 2;
    }
  };
}

}  // namespace moreau::cli
