#include "moreau/analysis/stress.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string_view>

#include "moreau/platform/number_text.h"
#include "moreau/platform/text_columns.h"
#include "moreau/scene/simulation.h"

namespace moreau::scene {
namespace detail {
extern const std::string_view kIiwa14ControllerScene;   // scenes/iiwa14-controller.json (shipped_robot.cc.in)
extern const std::string_view kIiwa14Urdf;              // scenes/robots/kuka-iiwa14.urdf
extern const std::string_view kPuma560ControllerScene;  // scenes/puma560-controller.json
extern const std::string_view kPuma560Urdf;             // scenes/robots/puma560.urdf
}  // namespace detail
namespace {

using nlohmann::json;

json one_dof(double m, double c, double a, double f, double v0, double h, double t_end) {
  json s = {{"name", "stress"},
            {"parameters", {{"m", m}, {"c", c}, {"a", a}, {"f", f}}},
            {"system",
             {{"type", "lagrangian"},
              {"coordinates", {"x"}},
              {"mass", json::array({json::array({"m"})})},
              {"force", {"-f"}},
              {"controller", {{{"type", "quadratic"}, {"weights", {"c"}}}, {{"type", "abs"}, {"gains", {"a"}}}}}}},
            {"initial", {{"q", {0}}, {"v", {v0}}}},
            {"integrator", {{"h", h}, {"t_end", t_end}}},
            {"output", {{"every", 1000}}}};
  return s;
}

json manipulator(double g, std::vector<double> v0, double h, double t_end, const std::string& rule) {
  json s = {{"name", "stress-manipulator"},
            {"parameters", {{"m1", 1}, {"m2", 1}, {"b", 0.5}, {"I", 0.1}, {"g", g}}},
            {"system",
             {{"type", "lagrangian"},
              {"coordinates", {"x1", "th2"}},
              {"mass", json::array({json::array({"m1 + m2", "m2*b*cos(th2)"}), json::array({"m2*b*cos(th2)", "I + m2*b^2"})})},
              {"potential", "-b*m2*g*cos(th2)"},
              {"controller", {{{"type", "quadratic"}, {"weights", {1, 1}}}, {{"type", "abs"}, {"gains", {1, 1}}}}}}},
            {"initial", {{"q", {3, -1}}, {"v", v0}}},
            {"integrator", {{"h", h}, {"t_end", t_end}, {"step_rule", rule}}},
            {"output", {{"every", 100}}}};
  return s;
}

// A shipped robot scene (an arm from URDF, the controller on every joint) and its URDF, compiled in.
struct ShippedRobot {
  std::string_view scene, urdf;
  const char* name;
};
const ShippedRobot kIiwa14{detail::kIiwa14ControllerScene, detail::kIiwa14Urdf, "stress-iiwa14"};
const ShippedRobot kPuma560{detail::kPuma560ControllerScene, detail::kPuma560Urdf, "stress-puma560"};

// The robot's scene with its URDF given inline, its initial velocity scaled by speed, with the given step rule.
json shipped_robot(const ShippedRobot& robot, double speed, const std::string& rule, double t_end) {
  json s = json::parse(robot.scene);
  s["name"] = robot.name;
  s["system"]["urdf"].erase("file");
  s["system"]["urdf"]["text"] = std::string(robot.urdf);
  for (auto& v : s["initial"]["v"]) v = speed * v.get<double>();
  s["integrator"]["step_rule"] = rule;
  s["integrator"]["t_end"] = t_end;
  s["output"] = {{"every", 1000}};
  return s;
}

}  // namespace

std::vector<StressCase> stress_cases() {
  // What a robot at a fixed step is: outside Theorem 4.1 at its fast start.
  const char* kFixedStepRobotTheory =
      "outside Thm 4.1 where (4.2) fails (its first steps): a step's solution is not guaranteed unique; the report counts those steps";
  std::vector<StressCase> cases;
  auto add = [&](StressCase c) { cases.push_back(std::move(c)); };
  add({"tiny-mass-high-gain", "m = 1e-6, relay gain 1e4, v0 = 1e3: stiffness a/m = 1e10", one_dof(1e-6, 1.0, 1e4, 0.0, 1e3, 1e-3, 1.0),
       true, true, true, true, "constant M, F = 0: E_k non-increasing (Thm 4.2, eps_k = 0) and rest in finitely many steps (Thm 4.3)"});
  add({"huge-mass-low-gain", "m = 1e6, relay gain 1e-2: would need t = m v0 / a = 1e8 s to stop",
       one_dof(1e6, 0.0, 1e-2, 0.0, 1.0, 1e-1, 100.0), true, true, false, true,
       "Thm 4.3 holds, but the rest time 1e8 s lies beyond t_end: still moving at the end"});
  add({"large-step-h10", "the manipulator with h = 10 under the Theorem 4.1 rule", manipulator(9.81, {-1, 1}, 10.0, 200.0, "theorem-4.1"),
       true, std::nullopt, true, true, "Thm 4.1: the rule keeps P = M/h + C + W positive definite, so every step is well posed"});
  add({"large-step-fixed", "the manipulator with a fixed h = 1 at high speed", manipulator(9.81, {-20, 30}, 1.0, 50.0, "fixed"), true,
       std::nullopt, std::nullopt, false,
       "outside Thm 4.1 (h > k1 / (2 k3 norm(V))): uniqueness is not guaranteed; the report shows what happened"});
  add({"tiny-step", "h = 1e-9 over 1e-3 s: 1e6 steps of 1 ns", one_dof(1.0, 1.0, 1.0, 0.0, 1.0, 1e-9, 1e-3), true, true, false, true,
       "constant M: E_k non-increasing; the horizon is far shorter than the rest time ln(2) s"});
  {
    // M = R diag(1, 1e-12) R^T, R a rotation by 0.5 rad: condition number 1e12, coupled.
    json s = one_dof(1.0, 1.0, 1.0, 0.0, 1.0, 1e-3, 2.0);
    s["system"]["coordinates"] = {"y1", "y2"};
    s["parameters"] = {{"c", 1.0}, {"a", 1.0}, {"r", 0.5}, {"eps", 1e-12}};
    s["system"]["mass"] = json::array({json::array({"cos(r)^2 + eps*sin(r)^2", "(1 - eps)*cos(r)*sin(r)"}),
                                       json::array({"(1 - eps)*cos(r)*sin(r)", "sin(r)^2 + eps*cos(r)^2"})});
    s["system"].erase("force");
    s["system"]["controller"] = {{{"type", "quadratic"}, {"weights", {"c", "c"}}}, {{"type", "abs"}, {"gains", {"a", "a"}}}};
    s["initial"] = {{"q", {0, 0}}, {"v", {1, -2}}};
    add({"near-singular-mass", "M with condition number 1e12 (eigenvalues 1 and 1e-12), coupled", s, true, true, true, true,
         "constant M, F = 0: Thms 4.2 and 4.3 hold; the one-step solver must stay at round-off"});
  }
  add({"theorem-4.2-rule-shrinks-h", "the manipulator at |v0| ~ 100 with h = 0.1 under the Theorem 4.2 rule, g = 0.9",
       manipulator(0.9, {60, 80}, 0.1, 60.0, "theorem-4.2"), true, true, true, true,
       "Assumption 4.1 holds (b m2 g = 0.45 <= 1/2): E_k non-increasing, finite-step rest; h_k must shrink"});
  add({"perturbation-just-below-gain", "a constant force f = a (1 - 1e-9) against the relay a, with damping c = 1",
       one_dof(1.0, 1.0, 1.0, 1.0 - 1e-9, 1.0, 1e-3, 30.0), true, std::nullopt, true, true,
       "-F lies (barely) inside int dPhi(0) = (-a, a): Thm 4.3, rest in finitely many steps (exact: t = ln(1 + 1e9) = 20.7 s)"});
  add({"perturbation-just-above-gain", "a constant force f = a (1 + 1e-9) against the relay a, with damping c = 1",
       one_dof(1.0, 1.0, 1.0, 1.0 + 1e-9, 1.0, 1e-3, 30.0), true, std::nullopt, false, true,
       "-F lies outside dPhi(0): no equilibrium at rest; it slides on at the terminal speed (f - a)/c = 1e-9"});
  add({"robot-iiwa-fixed-step", "the 7-joint iiwa (URDF) from its moving start with a fixed h = 1e-3; lambda_min(M) ~ 1e-3 kg m^2",
       shipped_robot(kIiwa14, 1.0, "fixed", 3.0), true, std::nullopt, std::nullopt, false, kFixedStepRobotTheory});
  add({"robot-iiwa-10x-speed", "the iiwa at 10 times its scene's initial speed (up to 30 rad/s), the Theorem 4.1 rule",
       shipped_robot(kIiwa14, 10.0, "theorem-4.1", 3.0), true, std::nullopt, std::nullopt, true,
       "Thm 4.1: the rule keeps each step uniquely solvable, so h_k must shrink; Assumption 4.1 fails under gravity, so "
       "Thms 4.2 and 4.3 promise nothing"});
  add({"robot-puma560-fixed-step",
       "the 6-joint PUMA 560 (URDF) from its moving start with a fixed h = 1e-3; its wrist makes lambda_min(M) ~ 4e-5 kg m^2",
       shipped_robot(kPuma560, 1.0, "fixed", 3.0), true, std::nullopt, std::nullopt, false, kFixedStepRobotTheory});
  add({"robot-puma560-5x-speed", "the PUMA 560 at 5 times its scene's initial speed (up to 15 rad/s), the Theorem 4.1 rule",
       shipped_robot(kPuma560, 5.0, "theorem-4.1", 3.0), true, std::nullopt, std::nullopt, true,
       "Thm 4.1: the rule keeps each step uniquely solvable, so h_k must shrink (to a few us: the wrist's small inertia); "
       "Assumption 4.1 fails under gravity, so Thms 4.2 and 4.3 promise nothing"});
  {
    json s = one_dof(2.0, 0.5, 1.0, 0.0, 3.0, 1e-7, 10.0);
    s["output"]["every"] = 1000000;
    add({"long-run-1e8-steps", "the damped relay for 1e8 steps with output every 1e6 steps", s, true, true, true, true,
         "constant M, F = 0: Thms 4.2 and 4.3; memory independent of the step count"});
  }
  return cases;
}

StressOutcome run_stress_case(const StressCase& c) {
  StressOutcome o;
  o.c = &c;
  const auto start = std::chrono::steady_clock::now();
  try {
    const Simulation sim = Simulation::from_json(c.scene);
    o.summary = sim.run(nullptr);
  } catch (const SceneError& e) {
    o.summary.status = RunStatus::kFailed;
    o.summary.message = e.what();
  }
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  for (double x : o.summary.q_final) o.finite = o.finite && std::isfinite(x);
  for (double x : o.summary.v_final) o.finite = o.finite && std::isfinite(x);
  o.finite = o.finite && std::isfinite(o.summary.energy_final) && std::isfinite(o.summary.energy_initial);
  if (!o.finite) o.failures.push_back("non-finite state or energy");
  const bool completed = o.summary.status == RunStatus::kCompleted;
  if (c.expect_completed && !completed) o.failures.push_back("did not complete: " + o.summary.message);
  if (c.expect_energy_nonincreasing && o.summary.energy_nonincreasing != *c.expect_energy_nonincreasing)
    o.failures.push_back(std::string("energy ") + (o.summary.energy_nonincreasing ? "non-increasing" : "not monotone") +
                         ", expected otherwise");
  if (c.expect_converged && o.summary.converged_step.has_value() != *c.expect_converged)
    o.failures.push_back(std::string(o.summary.converged_step ? "came to rest" : "did not come to rest") + ", expected otherwise");
  return o;
}

std::string format_outcome(const StressOutcome& o) {
  using platform::significant;
  // Columns padded on the right to a width (a table for people; numbers to a few significant digits).
  const auto column = platform::pad_right;
  const std::string conv = o.summary.converged_time ? "rest from t = " + significant(*o.summary.converged_time, 4) : "moving at t_end";
  const std::string seconds = platform::pad_left(platform::fixed(o.seconds, 2), 6);
  std::string s = column(o.c->name, 30) + " abl  " + column(to_string(o.summary.status), 9) + " " +
                  column(o.finite ? "finite" : "NON-FINITE", 14) + " energy " +
                  column(o.summary.energy_nonincreasing ? "non-increasing" : "not monotone", 14) + " " + column(conv, 22) + " solver max " +
                  std::to_string(o.summary.solver.max_iterations) + " it, res " + significant(o.summary.solver.max_residual, 2) +
                  ", h_k in [" + significant(o.summary.h_min, 2) + ", " + significant(o.summary.h_max, 2) + "]  " + seconds + " s  " +
                  (o.failures.empty() ? (o.c->within_theory ? "PASS" : "PASS (outside theory)") : "FAIL");
  for (const auto& f : o.failures) s += "\n    " + f;
  return s;
}

}  // namespace moreau::scene
