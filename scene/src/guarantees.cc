#include "moreau/scene/guarantees.h"

#include <cstdio>
#include <sstream>

namespace moreau::scene {
namespace {

std::string fmt(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// Assumption 3.1 (M_1) at the states the run visited.
HypothesisCheck mass_check(const RunSummary& s) {
  HypothesisCheck h{"Assumption 3.1: M(Q^k) positive definite at every step (lambda_min(M) > 0)", s.mass.verdict(), ""};
  if (s.mass.checked == 0) {
    h.detail = "no step was taken";
  } else if (h.verdict == Verdict::kHolds) {
    h.detail = "checked at " + std::to_string(s.mass.checked) + " steps; smallest lambda_min(M) " + fmt(s.mass.lambda_min) +
               " at t = " + fmt(s.mass.at_time) + " (the global bound k1 of the assumption is not checked, only the visited states)";
  } else {
    h.detail = "lambda_min(M) = " + fmt(s.mass.lambda_min) + " at t = " + fmt(s.mass.at_time) + ": the run stopped there";
  }
  return h;
}

Guarantee theorem41(const RunSummary& s) {
  Guarantee g{"Theorem 4.1", "each step of (0.2) has exactly one solution (Q^{k+1}, V^{k+1})", true, {}};
  g.hypotheses.push_back(mass_check(s));
  const StepConditionTrack& c = s.theorem41;
  HypothesisCheck h{"(4.2): h_k k3 ||V^k|| <= k1 / 2 at every step, with k1 = lambda_min(M(Q^k)) and k3 ||V^k|| = ||C(Q^k, V^k)||_2",
                    c.verdict(), ""};
  if (c.checked == 0) {
    h.detail = "no step was taken";
  } else if (c.violations == 0) {
    h.detail = "checked at " + std::to_string(c.checked) + " steps; r_k = 2 h_k ||C||_2 / lambda_min(M) <= " + fmt(c.worst_ratio()) +
               " at every step (largest at t = " + fmt(c.worst_time) + ")";
  } else {
    h.detail = "fails at " + std::to_string(c.violations) + " of " + std::to_string(c.checked) + " steps, first at t = " +
               fmt(c.first_violation_time) + " (step " + std::to_string(c.first_violation_step) + "); largest r_k = " + fmt(c.worst_ratio()) +
               " at t = " + fmt(c.worst_time) + " (r_k <= 1 required; the step rule theorem-4.1 enforces it)";
  }
  g.hypotheses.push_back(h);
  return g;
}

// Assumption 4.1 2)-3) from the largest ||F|| and ||grad V|| at the recorded states. Any beta the
// assumption could use is at least the largest ||F|| seen, so a failure found here is a failure of the
// assumption; "holds" covers the recorded states only.
HypothesisCheck assumption41_forces(const RunSummary& s, double alpha) {
  const ForceBoundTrack& f = s.force_bounds;
  HypothesisCheck h{"Assumption 4.1 2)-3): sup ||F|| <= beta < alpha and ||grad V(q)|| <= (alpha - beta) / 2 for all q",
                    Verdict::kNotChecked, ""};
  if (f.samples == 0) {
    h.detail = "no state was recorded";
    return h;
  }
  const std::string where = " (checked at " + std::to_string(f.samples) + " recorded states, every 16th of those the run recorded (every /output/every-th step)" +
                            (f.failed ? ", until this failure" : "") + ")";
  if (f.max_force >= alpha) {
    h.verdict = Verdict::kFails;
    h.detail = "||F|| reaches " + fmt(f.max_force) + " >= alpha = " + fmt(alpha) + " at t = " + fmt(f.max_force_time) + where;
  } else if (f.max_gradient > 0.5 * (alpha - f.max_force)) {
    h.verdict = Verdict::kFails;
    h.detail = "||grad V|| reaches " + fmt(f.max_gradient) + " at t = " + fmt(f.max_gradient_time) + " > (alpha - beta) / 2 = " +
               fmt(0.5 * (alpha - f.max_force)) + " even with the smallest beta = max ||F|| = " + fmt(f.max_force) + where;
  } else {
    h.verdict = Verdict::kHolds;
    h.detail = "max ||F|| = " + fmt(f.max_force) + " < alpha = " + fmt(alpha) + ", max ||grad V|| = " + fmt(f.max_gradient) +
               " <= (alpha - max ||F||) / 2" + where + "; the sup over all states is not checked";
  }
  return h;
}

Guarantee theorem42(const LagrangianScene& scene, const RunSummary& s, const Guarantee& t41) {
  const bool rule = scene.settings.step_rule == StepRule::kTheorem42;
  Guarantee g{"Theorem 4.2", "E_k = 1/2 <M(Q^k) V^k, V^k> non-increasing, Q^k convergent and V^k -> 0", rule, {}};
  g.hypotheses.push_back({"the hypotheses of Theorem 4.1 (Assumptions 3.1, 3.2)", t41.verdict(), "see Theorem 4.1"});
  g.hypotheses.push_back({"the step rule of Theorem 4.2 (h_k <= h_{k-1}, ||eps_k|| <= 2 eta of (4.9))", rule ? Verdict::kHolds : Verdict::kFails,
                          rule ? "step_rule theorem-4.2 enforces it at every step"
                               : std::string("the run used step_rule ") +
                                     (scene.settings.step_rule == StepRule::kFixed ? "fixed" : "theorem-4.1") +
                                     ", which does not (use theorem-4.2 for this guarantee)"});
  const double eta = scene.controller.eta(), alpha = scene.controller.alpha();
  const bool a1 = eta > 0.0 && alpha > 0.0;
  g.hypotheses.push_back({"Assumption 4.1 1): Phi(v) >= eta ||v||^2 + alpha ||v|| + Phi(0) with eta > 0, alpha > 0",
                          a1 ? Verdict::kHolds : Verdict::kFails,
                          "from the controller's coefficients: eta = min w_i / 2 = " + fmt(eta) + ", alpha = min a_i + a_norm = " + fmt(alpha)});
  g.hypotheses.push_back(assumption41_forces(s, alpha));
  g.hypotheses.push_back({"Assumption 3.3: F continuous and locally Lipschitz, grad V locally Lipschitz", Verdict::kNotChecked,
                          "expressions may use abs, sign, min or max; their regularity is not analysed"});
  return g;
}

Guarantee theorem43(const LagrangianScene& scene, const RunSummary& s, const Guarantee& t42) {
  // Theorem 4.3 is stated for the algorithm of Theorem 4.2, under its assumptions.
  Guarantee g{"Theorem 4.3", "Q^k = Q* for every k >= some N (finite-step convergence to an equilibrium)", t42.relied_on, {}};
  g.hypotheses.push_back({"the hypotheses of Theorem 4.2", t42.verdict(), "see Theorem 4.2"});
  g.hypotheses.push_back({"(4.16): F independent of t", scene.force_depends_on_time ? Verdict::kFails : Verdict::kHolds,
                          scene.force_depends_on_time ? "a force expression reads t" : "no force expression reads t (from the scene's expressions)"});
  HypothesisCheck in{"-F(Q*, 0) - grad V(Q*) in int dPhi(0) at the final position", Verdict::kNotChecked, ""};
  if (s.equilibrium.evaluated) {
    in.verdict = s.equilibrium.interior ? Verdict::kHolds : Verdict::kFails;
    in.detail = "dist(-F - grad V, dPhi(0)) = " + fmt(s.equilibrium.residual) + (s.equilibrium.interior ? ", in the interior" : ", not in the interior");
  } else {
    in.detail = "the forces are not finite at the final state";
  }
  g.hypotheses.push_back(in);
  return g;
}

}  // namespace

Verdict Guarantee::verdict() const {
  if (hypotheses.empty()) return Verdict::kNotChecked;
  Verdict v = hypotheses.front().verdict;
  for (std::size_t i = 1; i < hypotheses.size(); ++i) v = all_of(v, hypotheses[i].verdict);
  return v;
}

std::string Guarantees::relied_on_failure() const {
  for (const Guarantee& g : items) {
    if (!g.relied_on) continue;
    for (const HypothesisCheck& h : g.hypotheses)
      if (h.verdict == Verdict::kFails) return g.result + ": " + h.name + " fails (" + h.detail + ")";
  }
  return "";
}

const Guarantee* Guarantees::find(const std::string& result) const {
  for (const Guarantee& g : items)
    if (g.result == result) return &g;
  return nullptr;
}

const char* describe(ConvergenceFinding f) {
  switch (f) {
    case ConvergenceFinding::kNotAtRest: return "not at rest at the end";
    case ConvergenceFinding::kAtRestAtEnd: return "at rest at the end only";
    case ConvergenceFinding::kConvergedTheorem: return "converged (Theorem 4.3, hypotheses hold)";
    case ConvergenceFinding::kConvergedNotGuaranteed: return "converged (Theorem 4.3's hypotheses fail or are not checked)";
  }
  return "?";
}

ConvergenceFinding convergence_finding(const RunSummary& s, const Guarantees& g, const char* theorem) {
  if (!s.rest_step) return ConvergenceFinding::kNotAtRest;
  if (!s.converged_step) return ConvergenceFinding::kAtRestAtEnd;
  const Guarantee* t = g.find(theorem);
  return t && t->verdict() == Verdict::kHolds ? ConvergenceFinding::kConvergedTheorem : ConvergenceFinding::kConvergedNotGuaranteed;
}

Guarantees lagrangian_guarantees(const LagrangianScene& scene, const RunSummary& s) {
  Guarantees g;
  if (scene.scheme == Scheme::kAbl && scene.settings.velocity_update == VelocityUpdate::kImplicit) {
    g.items.push_back(theorem41(s));
    g.items.push_back(theorem42(scene, s, g.items.back()));
    g.items.push_back(theorem43(scene, s, g.items.back()));
  } else {
    // Moreau-Jean (and the explicit peer) are not the scheme (0.2): the theorems of Adly, Brogliato and
    // Le do not apply; what still holds of the model is checked.
    Guarantee m{"Assumption 3.1", "the kinetic energy 1/2 <M v, v> is a norm of v (a mass matrix)", true, {mass_check(s)}};
    g.items.push_back(m);
  }
  return g;
}

nlohmann::json guarantees_json(const Guarantees& g) {
  nlohmann::json out = nlohmann::json::array();
  for (const Guarantee& x : g.items) {
    nlohmann::json hs = nlohmann::json::array();
    for (const HypothesisCheck& h : x.hypotheses) hs.push_back({{"hypothesis", h.name}, {"verdict", to_string(h.verdict)}, {"detail", h.detail}});
    out.push_back({{"result", x.result}, {"claim", x.claim}, {"verdict", to_string(x.verdict())}, {"relied_on", x.relied_on}, {"hypotheses", hs}});
  }
  return out;
}

std::string guarantees_text(const Guarantees& g) {
  std::ostringstream os;
  bool first = true;
  for (const Guarantee& x : g.items) {
    os << (first ? "  guarantees    " : "                ") << x.result << " (" << x.claim << "): " << to_string(x.verdict())
       << (x.relied_on ? "" : " [not relied on by this run]") << "\n";
    first = false;
    for (const HypothesisCheck& h : x.hypotheses) os << "                  " << to_string(h.verdict) << ": " << h.name << "; " << h.detail << "\n";
  }
  return os.str();
}

}  // namespace moreau::scene
