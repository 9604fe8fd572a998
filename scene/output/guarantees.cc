#include "moreau/scene/guarantees.h"

#include <cmath>
#include <sstream>

#include <Eigen/Dense>

#include "active_constraints.h"
#include "moreau/platform/number_text.h"

namespace moreau::scene {
namespace {

// Numbers in the hypotheses' details: 6 significant digits.
std::string fmt(double v) { return platform::significant(v, 6); }

// A hypothesis's detail text, built only when asked for.
template <class Text>
std::string detail_text(Detail detail, Text&& text) {
  return detail == Detail::kFull ? std::string(text()) : std::string();
}

// Assumption 3.1 (M_1): M(q) symmetric positive definite for all q. Proved for all q when M is constant
// (the scene's M reads no coordinate, and no robot adds its own): every step then checks the one M. Otherwise
// only the states the run visited are checked, and a "holds" says so (scope).
HypothesisCheck mass_check(const LagrangianScene& scene, const RunSummary& s, Detail detail) {
  HypothesisCheck h{"Assumption 3.1: M(q) positive definite (lambda_min(M) > 0)", s.mass.verdict(), ""};
  const bool constant = scene.compiled && scene.compiled->constant_mass && !scene.compiled->robot;
  if (h.verdict == Verdict::kHolds) h.scope = constant ? kForAllStates : kOnVisitedStates;
  if (detail == Detail::kVerdicts) return h;
  if (s.mass.checked == 0) {
    h.detail = "no step was taken";
  } else if (h.verdict == Verdict::kHolds) {
    const std::string smallest = std::string(s.mass.lambda_min_exact ? "" : ">= ") + fmt(s.mass.lambda_min);
    const std::string bound = s.mass.lambda_min_exact ? "" : " (a certified lower bound: Gershgorin's, or M - s I has a Cholesky factor)";
    h.detail = constant ? "M is constant (no entry reads q): lambda_min(M) " + smallest + bound + ", so k1 = lambda_min(M) for every q"
                        : "checked at the " + std::to_string(s.mass.checked) + " steps' Q^k; smallest lambda_min(M) " + smallest +
                              " at t = " + fmt(s.mass.at_time) + bound +
                              " (the global bound k1 of the assumption is not checked, only the visited states)";
  } else {
    h.detail = "lambda_min(M) = " + fmt(s.mass.lambda_min) + " at t = " + fmt(s.mass.at_time) + ": the run stopped there";
  }
  return h;
}

Guarantee theorem41(const LagrangianScene& scene, const RunSummary& s, Detail detail) {
  Guarantee g{"Theorem 4.1", "each step of (0.2) has exactly one solution (Q^{k+1}, V^{k+1})", true, {}};
  g.hypotheses.push_back(mass_check(scene, s, detail));
  const StepConditionTrack& c = s.theorem41;
  HypothesisCheck h{"(4.2): h_k k3 ||V^k|| <= k1 / 2 at every step, with k1 = lambda_min(M(Q^k)) and k3 ||V^k|| = ||C(Q^k, V^k)||_2",
                    c.verdict(), ""};
  if (detail == Detail::kVerdicts) {
  } else if (c.checked == 0) {
    h.detail = "no step was taken";
  } else if (c.violations == 0) {
    h.detail = "checked at " + std::to_string(c.checked) + " steps; r_k = 2 h_k ||C||_2 / lambda_min(M) <= " + fmt(c.worst_ratio()) +
               " at every step (largest at t = " + fmt(c.worst_time) + ")";
  } else {
    h.detail = "fails at " + std::to_string(c.violations) + " of " + std::to_string(c.checked) +
               " steps, first at t = " + fmt(c.first_violation_time) + " (step " + std::to_string(c.first_violation_step) +
               "); largest r_k " + (c.worst_kind == BoundKind::kLowerBound ? ">= " : "= ") + fmt(c.worst_ratio()) +
               " at t = " + fmt(c.worst_time) + " (r_k <= 1 required; the step rule theorem-4.1 enforces it)";
  }
  g.hypotheses.push_back(h);
  return g;
}

// Assumption 4.1 2)-3), for all states when the expressions' interval bounds prove it
// (CompiledLagrangian::gradient_bound, force_bound), else from the largest ||F|| and ||grad V|| at the
// recorded states. Any beta the assumption could use is at least the largest ||F|| seen, so a failure found
// at a recorded state is a failure of the assumption; a "holds" from them covers the states visited only,
// and says so (scope).
HypothesisCheck assumption41_forces(const LagrangianScene& scene, const RunSummary& s, double alpha, Detail detail) {
  HypothesisCheck h{"Assumption 4.1 2)-3): sup ||F|| <= beta < alpha and ||grad V(q)|| <= (alpha - beta) / 2 for all q",
                    Verdict::kNotChecked, ""};
  const CompiledLagrangian* c = scene.compiled.get();
  if (c && c->gradient_bound && c->force_bound && *c->force_bound < alpha && *c->gradient_bound <= 0.5 * (alpha - *c->force_bound)) {
    h.verdict = Verdict::kHolds;
    h.scope = kForAllStates;
    h.detail = detail_text(detail, [&] {
      return "for every q, v and t in [t0, t_end], by interval bounds of the expressions: ||F|| <= " + fmt(*c->force_bound) +
             " = beta < alpha = " + fmt(alpha) + ", ||grad V|| <= " + fmt(*c->gradient_bound) +
             " <= (alpha - beta) / 2 = " + fmt(0.5 * (alpha - *c->force_bound));
    });
    return h;
  }
  const ForceBoundTrack& f = s.force_bounds;
  if (f.samples == 0) {
    h.detail = "no state was recorded";
    return h;
  }
  const bool force_too_large = f.max_force >= alpha;
  const bool gradient_too_large = !force_too_large && f.max_gradient > 0.5 * (alpha - f.max_force);
  h.verdict = force_too_large || gradient_too_large ? Verdict::kFails : Verdict::kHolds;
  if (h.verdict == Verdict::kHolds) h.scope = kOnVisitedStates;
  if (detail == Detail::kVerdicts) return h;
  const std::string where = " (checked at " + std::to_string(f.samples) +
                            " recorded states, every 16th of those the run recorded (every /output/every-th step)" +
                            (f.failed ? ", until this failure" : "") + ")";
  if (force_too_large) {
    h.detail = "||F|| reaches " + fmt(f.max_force) + " >= alpha = " + fmt(alpha) + " at t = " + fmt(f.max_force_time) + where;
  } else if (gradient_too_large) {
    h.detail = "||grad V|| reaches " + fmt(f.max_gradient) + " at t = " + fmt(f.max_gradient_time) +
               " > (alpha - beta) / 2 = " + fmt(0.5 * (alpha - f.max_force)) +
               " even with the smallest beta = max ||F|| = " + fmt(f.max_force) + where;
  } else {
    const std::string why_not_all =
        c && c->gradient_bound && c->force_bound
            ? "; over all states the interval bounds give ||F|| <= " + fmt(*c->force_bound) +
                  " and ||grad V|| <= " + fmt(*c->gradient_bound) + ", which do not prove it"
            : std::string("; not proved for all states (") +
                  (c && c->robot ? "a robot's gravity is not bounded here" : "an expression has no finite interval bound") + ")";
    h.detail = "max ||F|| = " + fmt(f.max_force) + " < alpha = " + fmt(alpha) + ", max ||grad V|| = " + fmt(f.max_gradient) +
               " <= (alpha - max ||F||) / 2" + where + why_not_all;
  }
  return h;
}

// Whether eps_k of (4.9) is 0 at every step of every run of the scene, whatever h: M constant (so its
// difference quotient is 0) and C identically 0 (no Coriolis matrix, or Christoffel symbols of a constant
// M). Decided from the scene's structure, not from the states visited.
bool eps_identically_zero(const LagrangianScene& scene) {
  if (!scene.compiled || !scene.compiled->constant_mass || scene.compiled->robot) return false;
  return scene.coriolis == CoriolisSource::kNone || scene.coriolis == CoriolisSource::kChristoffel;
}

Guarantee theorem42(const LagrangianScene& scene, const RunSummary& s, const Guarantee& t41, Detail detail) {
  // The rule's condition is checked on the run actually made, whatever /integrator/step_rule says: the
  // proof uses only h_k <= h_{k-1}, ||eps_k(h_k)|| <= 2 eta at the h_k taken ((4.10)) and (4.2) (Theorem
  // 4.1's condition, checked at every step). With eps_k = 0 identically, every h satisfies the first two
  // on a fixed grid (its last step is only shorter) and k3 = 0 makes k1 / (2 k3 ||V^k||) infinite: a
  // fixed h is exactly the h_k the rule chooses (docs/stress.md).
  const bool rule = scene.settings.step_rule == StepRule::kTheorem42;
  const bool fixed = scene.settings.step_rule == StepRule::kFixed;
  const bool eps_zero = eps_identically_zero(scene);
  const bool holds_here = rule || (eps_zero && fixed);
  // Relied on only when the scene asked for the rule: a fixed run that satisfies it gains the theorem's
  // verdict, not a requirement that `--strict` would enforce.
  Guarantee g{"Theorem 4.2", "E_k = 1/2 <M(Q^k) V^k, V^k> non-increasing, Q^k convergent and V^k -> 0", rule, {}};
  g.hypotheses.push_back(
      {"the hypotheses of Theorem 4.1 (Assumptions 3.1, 3.2)", t41.verdict(), detail_text(detail, [] { return "see Theorem 4.1"; })});
  const char* rule_name = fixed ? "fixed" : rule ? "theorem-4.2" : "theorem-4.1";
  // A rule that is not enforced and not shown to hold on this run is not checked: "fails" would claim a
  // step where ||eps_k|| > 2 eta, which nothing computed.
  g.hypotheses.push_back({"the step rule of Theorem 4.2 (h_k <= h_{k-1}, ||eps_k|| <= 2 eta of (4.9))",
                          holds_here ? Verdict::kHolds : Verdict::kNotChecked, detail_text(detail, [&] {
                            if (rule) return std::string("step_rule theorem-4.2 enforces it at every step");
                            if (holds_here)
                              return std::string(
                                         "M is constant and C = 0, so eps_k = 0 at every step for every h, and the "
                                         "run's h_k (step_rule ") +
                                     rule_name + ") are one h, shorter only to land on t_end: the rule's condition holds on this run";
                            return std::string("the run used step_rule ") + rule_name +
                                   " and M depends on q (or C is not 0): ||eps_k|| was not computed at its steps (use theorem-4.2 "
                                   "for this guarantee)";
                          })});
  const double eta = scene.controller.eta(), alpha = scene.controller.alpha();
  const bool a1 = eta > 0.0 && alpha > 0.0;
  // For every v, from Phi's form (a sum of weighted |v_i|, w_i v_i^2 / 2 and a_norm ||v||): proved, not sampled.
  g.hypotheses.push_back({"Assumption 4.1 1): Phi(v) >= eta ||v||^2 + alpha ||v|| + Phi(0) with eta > 0, alpha > 0",
                          a1 ? Verdict::kHolds : Verdict::kFails,
                          detail_text(detail,
                                      [&] {
                                        return "from the controller's coefficients, for every v: eta = min w_i / 2 = " + fmt(eta) +
                                               ", alpha = min a_i + a_norm = " + fmt(alpha);
                                      }),
                          a1 ? kForAllStates : std::string()});
  g.hypotheses.push_back(assumption41_forces(scene, s, alpha, detail));
  if (scene.forces_smooth_everywhere) {
    const bool robot = scene.compiled && scene.compiled->robot;
    // From the expressions' operations, over all of R^(1+2n): proved for all states.
    g.hypotheses.push_back(
        {"Assumption 3.3: F continuous and locally Lipschitz, grad V locally Lipschitz", Verdict::kHolds,
         detail_text(detail,
                     [&] {
                       return std::string(robot ? "gravity's part of grad V comes from the URDF robot (a polynomial in the joint "
                                                  "positions and their sines and cosines: C-infinity); the expressions' part of "
                                                : "") +
                              "grad V and F are built only from +, -, *, integer powers, sin, cos, atan, sinh, cosh, tanh and exp: "
                              "C-infinity on all of R^(1+2n), so locally Lipschitz, uniformly in t on [t0, t_end]; Phi convex by "
                              "construction";
                     }),
         kForAllStates});
  } else {
    g.hypotheses.push_back(
        {"Assumption 3.3: F continuous and locally Lipschitz, grad V locally Lipschitz", Verdict::kNotChecked, detail_text(detail, [] {
           return "the expressions use an operation that is smooth only on a domain or not smooth (/, log, sqrt, tan, "
                  "asin, acos, atan2, a non-integer power, abs, min, max), or the scene gives potential_gradient; "
                  "their regularity is not analysed";
         })});
  }
  return g;
}

bool final_state_finite(const RunSummary& s) {
  for (double x : s.q_final)
    if (!std::isfinite(x)) return false;
  for (double x : s.v_final)
    if (!std::isfinite(x)) return false;
  return !s.q_final.empty();
}

Guarantee theorem43(const LagrangianScene& scene, const RunSummary& s, const Guarantee& t42, Detail detail) {
  // Theorem 4.3 is stated for the algorithm of Theorem 4.2, under its assumptions.
  Guarantee g{"Theorem 4.3", "Q^k = Q* for every k >= some N (finite-step convergence to an equilibrium)", t42.relied_on, {}};
  g.hypotheses.push_back({"the hypotheses of Theorem 4.2", t42.verdict(), detail_text(detail, [] { return "see Theorem 4.2"; })});
  g.hypotheses.push_back(
      {"(4.16): F independent of t", scene.force_depends_on_time ? Verdict::kFails : Verdict::kHolds, detail_text(detail, [&] {
         return scene.force_depends_on_time ? "a force expression reads t" : "no force expression reads t (from the scene's expressions)";
       })});
  HypothesisCheck in{"-F(Q*, 0) - grad V(Q*) in int dPhi(0) at the final position", Verdict::kNotChecked, ""};
  if (s.equilibrium.evaluated) in.verdict = s.equilibrium.interior ? Verdict::kHolds : Verdict::kFails;
  in.detail = detail_text(detail, [&] {
    return s.equilibrium.evaluated ? "dist(-F - grad V, dPhi(0)) = " + fmt(s.equilibrium.residual) +
                                         (s.equilibrium.interior ? ", in the interior" : ", not in the interior")
           : final_state_finite(s) ? std::string("-F(Q*, 0) - grad V(Q*) is not finite at the final position")
                                   : std::string("the run's final state is not finite: no position to check");
  });
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
    case ConvergenceFinding::kConvergedNoTheorem: return "converged (no result among the guarantees promises convergence for this scheme)";
  }
  return "?";
}

ConvergenceFinding convergence_finding(const RunSummary& s, const Guarantees& g, const char* theorem) {
  if (!s.rest_step) return ConvergenceFinding::kNotAtRest;
  if (!s.converged_step) return ConvergenceFinding::kAtRestAtEnd;
  const Guarantee* t = g.find(theorem);
  if (!t) return ConvergenceFinding::kConvergedNoTheorem;  // a Moreau-Jean or tracking run: Theorem 4.3 is about (0.2)
  return t->verdict() == Verdict::kHolds ? ConvergenceFinding::kConvergedTheorem : ConvergenceFinding::kConvergedNotGuaranteed;
}

namespace {

// A basis of the null space of the rows of `A` (k x n, k may be 0): the directions d with A d = 0.
Eigen::MatrixXd null_space(const Eigen::MatrixXd& A, int n) {
  if (A.rows() == 0) return Eigen::MatrixXd::Identity(n, n);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  svd.setThreshold(1e-10);
  const int rank = static_cast<int>(svd.rank());
  return svd.matrixV().rightCols(n - rank);
}

// The second-order condition of Lemma 3's strict minimum at q*, where grad U(q*) = sum lambda_i grad h_i(q*)
// over the active constraints (lambda >= 0) but the first-order test did not decide (the active gradients
// do not span R^n, or a multiplier is 0). With L = U - sum lambda_i h_i (Hessians exact, from the compiled
// second derivatives):
//  - sufficient: d^T L''(q*) d > 0 for every d != 0 with <grad h_i, d> = 0 for the i with lambda_i > 0.
//    That subspace contains the critical cone, so q* is a strict local minimum of U on {h >= 0}
//    (Nocedal and Wright, Theorem 12.6);
//  - necessary (when the active gradients are linearly independent, LICQ): d^T L''(q*) d >= 0 for every d
//    tangent to all active constraints, which lie in the critical cone (Theorem 12.5): a negative
//    curvature there means q* is not a local minimum;
//  - otherwise (curvature 0 within round-off, or a degenerate multiplier): higher-order terms decide.
void second_order(const CompiledLagrangian& c, const RunSummary& s, const std::vector<int>& active, const Eigen::MatrixXd& Ht,
                  const Eigen::VectorXd& lambda, double multiplier_tol, HypothesisCheck& strict) {
  const int n = c.n;
  if (c.hessian_tape.num_outputs() == 0) {
    strict.verdict = Verdict::kNotChecked;
    strict.detail += "; the second-order condition needs Hessians, compiled only for an expression scene with n <= " +
                     std::to_string(CompiledLagrangian::kMaxHessianDof) + " (not for a URDF robot): not checked";
    return;
  }
  std::vector<double> slots(static_cast<std::size_t>(1 + 2 * n), 0.0), out(c.hessian_tape.num_outputs()),
      scratch(c.hessian_tape.scratch_size());
  slots[0] = s.t_final;
  for (int i = 0; i < n; ++i) slots[1 + i] = s.q_final[i];
  c.hessian_tape.eval(slots.data(), out.data(), scratch.data());
  auto hessian = [&](int which) { return Eigen::Map<const Eigen::MatrixXd>(out.data() + static_cast<std::size_t>(which) * n * n, n, n); };
  Eigen::MatrixXd L = hessian(0);
  for (std::size_t a = 0; a < active.size(); ++a) L -= lambda(static_cast<int>(a)) * hessian(1 + active[a]);
  L = 0.5 * (L + L.transpose()).eval();  // exact Hessians are symmetric; this removes round-off only
  const double tol = 1e-9 * std::max(1.0, L.norm());

  std::vector<int> strong;
  for (int a = 0; a < lambda.size(); ++a)
    if (lambda(a) > multiplier_tol) strong.push_back(a);
  Eigen::MatrixXd strong_rows(static_cast<int>(strong.size()), n);
  for (std::size_t r = 0; r < strong.size(); ++r) strong_rows.row(static_cast<int>(r)) = Ht.col(strong[r]).transpose();
  const Eigen::MatrixXd Z = null_space(strong_rows, n);
  if (Z.cols() == 0) {
    strict.verdict = Verdict::kHolds;
    strict.detail += "; the gradients with lambda_i > 0 span R^" + std::to_string(n) + ": every feasible direction increases U";
    return;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> reduced(Z.transpose() * L * Z);
  const double mu = reduced.eigenvalues().minCoeff();
  if (mu > tol) {
    strict.verdict = Verdict::kHolds;
    strict.detail += "; second-order sufficient condition: the Hessian of U - sum lambda_i h_i is positive definite on the " +
                     std::to_string(Z.cols()) + "-dimensional subspace tangent to the constraints with lambda_i > 0 (smallest eigenvalue " +
                     fmt(mu) + " > round-off " + fmt(tol) + ")";
    return;
  }
  const Eigen::MatrixXd all_rows = Ht.transpose();
  const bool licq = Ht.cols() == 0 || Eigen::FullPivLU<Eigen::MatrixXd>(all_rows).rank() == Ht.cols();
  const Eigen::MatrixXd Z0 = null_space(all_rows, n);
  if (licq && Z0.cols() > 0) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tangent(Z0.transpose() * L * Z0);
    const double mu0 = tangent.eigenvalues().minCoeff();
    if (mu0 < -tol) {
      const Eigen::VectorXd d = Z0 * tangent.eigenvectors().col(0);
      std::string ds;
      for (int i = 0; i < n; ++i) ds += (i ? ", " : "") + fmt(d(i));
      strict.verdict = Verdict::kFails;
      strict.detail += "; second-order necessary condition fails: along d = (" + ds +
                       "), tangent to every active constraint, d^T (U - sum lambda_i h_i)'' d = " + fmt(mu0) +
                       " < 0: q* is not a local minimum";
      return;
    }
  }
  strict.verdict = Verdict::kUndetermined;
  strict.detail += "; second order: the Hessian of U - sum lambda_i h_i has smallest eigenvalue " + fmt(mu) + " (round-off " + fmt(tol) +
                   ") on the subspace tangent to the constraints with lambda_i > 0" +
                   (licq ? "" : ", and the active gradients are dependent") + ": higher-order terms decide, undetermined";
}

// Lemma 3 of Brogliato (2003) for a scene with unilateral constraints: the system is (8) (F = C q' +
// grad U, one restitution e), Phi = {h >= 0} regular (Remark 4), and psi_Phi + U has a strict minimum at
// q0, checked at the run's rest position q*. First order (sufficient): the active gradients grad h_i(q*)
// span R^n and grad U(q*) = sum lambda_i grad h_i(q*) with every lambda_i > 0; then every feasible
// direction d != 0 has <grad U, d> > 0 (it cannot be orthogonal to all active gradients), so q* is a
// strict local minimum. When that does not decide, the second-order conditions (second_order above).
// Not relied on: the run does not use the conclusion (Lyapunov stability).
Guarantee lemma3(const LagrangianScene& scene, const RunSummary& s) {
  Guarantee g{"Lemma 3", "(q*, 0) is a Lyapunov stable equilibrium, with W = 1/2 <M v, v> + U(q) its Lyapunov function", false, {}};
  const int n = scene.n, m = static_cast<int>(scene.constraint_names.size());
  g.hypotheses.push_back({"(8): no external force F(t, q, v) beyond C q' + grad U", scene.has_force ? Verdict::kFails : Verdict::kHolds,
                          scene.has_force ? "the scene gives /system/force" : "no /system/force"});
  const bool controlled = scene.controller.has_quadratic() || scene.controller.has_nonsmooth();
  g.hypotheses.push_back({"(8): no set-valued controller dPhi (the lemma is stated without one)",
                          controlled ? Verdict::kFails : Verdict::kHolds, controlled ? "the scene has a controller" : "no controller"});
  bool same_e = true;
  for (double e : scene.restitution) same_e = same_e && e == scene.restitution.front();
  g.hypotheses.push_back({"(8): one restitution coefficient e for every constraint", same_e ? Verdict::kHolds : Verdict::kFails,
                          same_e ? "e = " + fmt(scene.restitution.front()) : "the constraints have different e"});
  g.hypotheses.push_back(
      {"Phi = {h(q) >= 0} regular (Remark 4)", m == 1 ? Verdict::kHolds : Verdict::kNotChecked,
       m == 1 ? "a single constraint" : std::to_string(m) + " constraints: convexity at the corners of Phi is not analysed"});
  HypothesisCheck strict{"psi_Phi + U has a strict minimum at q0 = the rest position q*", Verdict::kNotChecked, ""};
  const CompiledLagrangian* c = scene.compiled.get();
  if (!s.rest_step) {
    strict.detail = "the run is not at rest at its end: no rest position to check";
  } else if (!c || !c->has_potential) {
    strict.detail = "the scene gives no potential U";
  } else if (!c->dense) {
    strict.detail = "a scene on the large-contact path keeps its gap gradients sparse; this first-order test runs on dense scenes only";
  } else {
    const detail::ActiveConstraints at_end = detail::active_constraints_at_end(scene, s);
    const Eigen::VectorXd& grad_u = at_end.grad_u;
    const double scale = 1.0 + grad_u.norm();
    const double gap_tol = at_end.gap_tolerance;
    const std::vector<int>& active = at_end.active;
    const Eigen::MatrixXd Ht = at_end.gradients.transpose();
    if (active.empty()) {
      if (grad_u.norm() > 1e-9 * scale) {
        strict.verdict = Verdict::kFails;
        strict.detail = "no constraint active at q*: grad U(q*) != 0 (norm " + fmt(grad_u.norm()) + "), q* is not a minimum of U";
      } else {
        strict.detail = "no constraint active at q* and grad U(q*) = 0 (norm " + fmt(grad_u.norm()) + ")";
        second_order(*c, s, active, Ht, Eigen::VectorXd(0), 1e-9 * scale, strict);
      }
    } else {
      Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(Ht);
      qr.setThreshold(1e-10);
      const Eigen::VectorXd lambda = qr.solve(grad_u);
      const double residual = (Ht * lambda - grad_u).norm();
      std::string ls;
      for (int a = 0; a < lambda.size(); ++a) ls += (a ? ", " : "") + fmt(lambda(a));
      if (residual > 1e-9 * scale || lambda.minCoeff() < -1e-9 * scale) {
        strict.verdict = Verdict::kFails;
        strict.detail = "grad U(q*) is not a non-negative combination of the active constraint gradients (residual " + fmt(residual) +
                        ", multipliers " + ls + "): a feasible direction decreases U, q* is not a minimum";
      } else if (qr.rank() < n || lambda.minCoeff() <= 1e-9 * scale) {
        strict.detail = "at q* = the rest position (gaps below " + fmt(gap_tol) +
                        " count as active), grad U(q*) = sum lambda_i grad h_i(q*) with lambda = (" + ls + "), but the " +
                        std::to_string(active.size()) + " active gradient(s) do not span R^" + std::to_string(n) +
                        " or a multiplier is 0: first order does not decide";
        second_order(*c, s, active, Ht, lambda, 1e-9 * scale, strict);
      } else {
        strict.verdict = Verdict::kHolds;
        strict.detail = "at q* = the rest position (gaps below " + fmt(gap_tol) + " count as active), " + std::to_string(active.size()) +
                        " active constraint(s) spanning R^" + std::to_string(n) +
                        ", grad U(q*) = sum lambda_i grad h_i(q*) with lambda = (" + ls +
                        ") > 0: every feasible direction increases U (a sufficient condition)";
      }
    }
  }
  g.hypotheses.push_back(strict);
  return g;
}

}  // namespace

// The tracking scheme's guarantees (docs/tracking.md, derived there: the TAC 2017 paper's own statements
// were not available to check against). One-step well-posedness: (4.2) for P = M/h + C + W, on the plant
// at every step (continuous), or the strong monotonicity of the implicit controller's problem on its
// nominal model at every sample. Reaching, for the continuous loop: with V = 1/2 sigma^T M sigma and
// M' = C + C^T, V' <= -(alpha - ||rho||) ||sigma|| while ||rho|| < alpha, rho the perturbation of the sigma
// dynamics (model error and F), checked on the samples visited.
namespace {

std::vector<Guarantee> tracking_guarantees(const LagrangianScene& scene, const RunSummary& s, Detail detail) {
  std::vector<Guarantee> out;
  const TrackingSpec& spec = *scene.tracking;
  const TrackingSummary* tr = s.tracking ? &*s.tracking : nullptr;
  if (!spec.sampled) {
    Guarantee g = theorem41(scene, s, detail);
    g.claim = "each step of (0.2) in sigma has exactly one solution sigma_{k+1} (Theorem 4.1 with V^k replaced by sigma)";
    out.push_back(g);
  } else {
    out.push_back(Guarantee{
        "Assumption 3.1", "the kinetic energy 1/2 <M v, v> is a norm of v (a mass matrix)", true, {mass_check(scene, s, detail)}});
    if (*spec.sampled == SampledTrackingLaw::kImplicit) {
      HypothesisCheck h{"P = M^/T_s + C^ + W strongly monotone (P + P^T positive definite) at every sample, which (4.2) implies",
                        Verdict::kNotChecked, ""};
      if (tr && tr->condition_checked > 0) {
        h.verdict = tr->monotone_violations == 0 ? Verdict::kHolds : Verdict::kFails;
        if (h.verdict == Verdict::kHolds) h.scope = kOnVisitedStates;
        h.detail = detail_text(detail, [&] {
          const std::string c42 = "; (4.2), 2 T_s ||C^||_2 <= lambda_min(M^), held at " +
                                  std::to_string(tr->condition_checked - tr->condition42_violations) + " of them";
          return tr->monotone_violations == 0
                     ? "a Cholesky factor of (P + P^T) / 2 at each of " + std::to_string(tr->condition_checked) + " samples" + c42
                     : "not positive definite at " + std::to_string(tr->monotone_violations) + " of " +
                           std::to_string(tr->condition_checked) + " samples, first at t = " + fmt(tr->first_monotone_violation_time) + c42;
        });
      }
      out.push_back(
          Guarantee{"Well-posedness of u_k (implicit controller)",
                    "u_k is uniquely defined: the inclusion in sigma_{k+1} has one solution (as Theorem 4.1 concludes under (4.2))",
                    true,
                    {h}});
    }
  }
  // The reaching argument is the continuous loop's; a sampled loop's band is measured (the report's
  // reaching line), not promised here.
  if (spec.sampled) return out;
  HypothesisCheck alpha{"alpha = min_i a_i + a_norm > 0 (Phi on sigma has a corner at 0)",
                        spec.phi.alpha() > 0.0 ? Verdict::kHolds : Verdict::kFails,
                        detail_text(detail, [&] { return "alpha = " + fmt(spec.phi.alpha()); })};
  if (alpha.verdict == Verdict::kHolds) alpha.scope = kForAllStates;
  HypothesisCheck rho{"||rho|| < alpha, rho = (M a_r + C v_r + g) - (M^ a_r + C^ v_r + g^) (model error and F)", Verdict::kNotChecked, ""};
  if (tr && tr->samples > 0) {
    rho.verdict = tr->perturbation_max < tr->alpha ? Verdict::kHolds : Verdict::kFails;
    if (rho.verdict == Verdict::kHolds) rho.scope = kOnVisitedStates;
    rho.detail = detail_text(detail, [&] {
      return "largest ||rho|| " + fmt(tr->perturbation_max) + " at t = " + fmt(tr->perturbation_max_time) + " over " +
             std::to_string(tr->samples) + " samples, against alpha = " + fmt(tr->alpha) +
             (rho.verdict == Verdict::kFails ? " (a sup over all states is at least this: the bound fails)" : " (the states visited only)");
    });
  }
  // V' = sigma^T (M sigma' + M' sigma / 2) drops C's part only when M' = C + C^T (ABL (1.3)).
  const CompiledLagrangian* c = scene.compiled.get();
  const bool christoffel =
      scene.coriolis == CoriolisSource::kChristoffel || (scene.coriolis == CoriolisSource::kNone && c && c->constant_mass && !c->robot);
  HypothesisCheck skew{"M' = C + C^T (C from the Christoffel symbols, or C = 0 with a constant M)",
                       christoffel ? Verdict::kHolds : Verdict::kNotChecked, detail_text(detail, [&] {
                         return christoffel ? std::string("C is ") + to_string(scene.coriolis) + " (ABL (1.3))"
                                            : std::string("the scene's own C is not checked against dM/dt");
                       })};
  if (christoffel) skew.scope = kForAllStates;
  out.push_back(Guarantee{"Reaching (V = 1/2 sigma^T M sigma)",
                          "sigma reaches 0 in finite time t_r <= lambda_max(M) ||sigma(0)|| / (alpha - sup ||rho||), then e decays as "
                          "exp(-Lambda t)",
                          false,
                          {skew, alpha, rho}});
  return out;
}

}  // namespace

Guarantees lagrangian_guarantees(const LagrangianScene& scene, const RunSummary& s, Detail detail) {
  Guarantees g;
  if (scene.tracking) {
    g.items = tracking_guarantees(scene, s, detail);
  } else if (traits(scene.scheme).theorems_4_1_to_4_3) {
    g.items.push_back(theorem41(scene, s, detail));
    g.items.push_back(theorem42(scene, s, g.items.back(), detail));
    g.items.push_back(theorem43(scene, s, g.items.back(), detail));
  } else {
    // Moreau-Jean (and the explicit peer) are not the scheme (0.2): the theorems of Adly, Brogliato and
    // Le do not apply; what still holds of the model is checked.
    Guarantee m{"Assumption 3.1", "the kinetic energy 1/2 <M v, v> is a norm of v (a mass matrix)", true, {mass_check(scene, s, detail)}};
    g.items.push_back(m);
    // Lemma 3 is not relied on: with the verdicts alone it is left out.
    if (!scene.constraint_names.empty() && detail == Detail::kFull) g.items.push_back(lemma3(scene, s));
  }
  return g;
}

namespace {

// Assumption a) of Brogliato (2003), first half: G(s) strictly positive real, from the scene's P (the KYP
// lemma's sufficiency: P = P^T > 0, PA + A^T P < 0, B^T P = C imply SPR) or from the exact test.
HypothesisCheck spr_check(const LureScene& sc) {
  HypothesisCheck h{"a) G(s) = C (sI - A)^{-1} B strictly positive real", Verdict::kNotChecked, ""};
  if (sc.P) {
    const StorageMatrixCheck& c = sc.p_check;
    h.verdict = c.verdict();
    h.detail = "by the scene's P (KYP lemma): P = P^T " + std::string(to_string(c.symmetric_verdict())) + ", P > 0 " +
               to_string(c.positive_definite_verdict()) + " (lambda_min " + fmt(c.min_eigenvalue) + "), PA + A^T P < 0 " +
               to_string(c.dissipative_verdict()) + " (lambda_max " + fmt(c.max_eigenvalue_pa) + "), B^T P = C " +
               to_string(c.output_verdict()) + " (relative residual " + fmt(c.output_residual) + ")";
    return h;
  }
  const PositiveRealnessTest& t = sc.spr;
  h.verdict = t.spr;
  const char* how = t.exact ? ", exact" : ", floating point";
  if (t.spr == Verdict::kFails) {
    h.detail = t.witness + " (decided " + (t.exact ? "exactly, in rational arithmetic" : "in floating point") + ")";
  } else {
    h.detail = "A Hurwitz " + std::string(to_string(t.hurwitz)) + " (" + t.hurwitz_method + "; max Re lambda " + fmt(t.spectral_abscissa) +
               "); G(jw) + G(jw)^H > 0 for all w " + to_string(t.frequency) +
               (t.frequency_method.empty() ? std::string() : " (decided by " + t.frequency_method + ")") +
               (t.exact && t.frequency_pencil != Verdict::kNotChecked
                    ? "; the Popov pencil in floating point says " + std::string(to_string(t.frequency_pencil))
                    : std::string()) +
               " (smallest (1 + (w/wc)^2) lambda_min found " + fmt(t.min_frequency_eigenvalue) + " at w = " + fmt(t.argmin_omega) +
               ", round-off " + fmt(t.frequency_tolerance) + "); CB = (CB)^T > 0 " + to_string(t.cb) + how + "; -(CAB + (CAB)^T) > 0 " +
               to_string(t.high_frequency) + how + "; certificate P " + (t.storage_found() ? "found and checked" : "not found");
  }
  return h;
}

HypothesisCheck minimality_check(const LureScene& sc) {
  const MinimalityCheck& m = sc.minimality;
  return {"a) (A, B, C) minimal (controllable and observable)", m.verdict(),
          "controllable " + std::string(to_string(m.controllable)) + ", observable " + to_string(m.observable) + ": " + m.method +
              "; PBH margins of the balanced realisation " + fmt(m.controllability_margin) + ", " + fmt(m.observability_margin)};
}

}  // namespace

Guarantees lure_guarantees(const LureScene& sc) {
  std::string y0;
  {
    const Eigen::VectorXd x0 = Eigen::Map<const Eigen::VectorXd>(sc.x0.data(), sc.n);
    const Eigen::VectorXd y = sc.C * x0;
    for (int i = 0; i < y.size(); ++i) y0 += (i ? ", " : "") + fmt(y(i));
  }
  const std::vector<HypothesisCheck> lemma1_hypotheses{
      spr_check(sc),
      minimality_check(sc),
      {"b) phi convex, proper, lower semicontinuous (d phi maximal monotone)", Verdict::kHolds,
       "each feedback component is a piecewise-linear complete non-decreasing graph, checked when the scene was read: the "
       "subdifferential of a convex lsc function of one variable"},
      {"C x(0) in dom d phi", Verdict::kHolds,
       "y0 = C x0 = (" + y0 + "), checked when the scene was read (scenes that break it are refused)"}};
  // The run does not use these conclusions: each step's generalized equation is solved and its residual
  // reported (the solver section). They are what the report's stability statements rest on.
  Guarantee lemma1{"Lemma 1", "(4) has a unique absolutely continuous solution on [0, +inf)", false, lemma1_hypotheses};
  Guarantee lemma2{"Lemma 2", "x = 0 is the unique equilibrium and is exponentially stable; W = 1/2 x^T P x non-increasing", false,
                   lemma1_hypotheses};
  bool origin = true;
  std::string off;
  for (std::size_t i = 0; i < sc.feedback.size(); ++i)
    if (!sc.feedback[i].contains_origin()) {
      origin = false;
      off += (off.empty() ? "" : ", ") + std::to_string(i);
    }
  lemma2.hypotheses.push_back(
      {"(0, 0) on the graph of d phi", origin ? Verdict::kHolds : Verdict::kFails,
       origin ? "every feedback component's graph contains (0, 0)" : "not on the graph of /system/feedback/" + off});
  return Guarantees{{lemma1, lemma2}};
}

nlohmann::json guarantees_json(const Guarantees& g) {
  nlohmann::json out = nlohmann::json::array();
  for (const Guarantee& x : g.items) {
    nlohmann::json hs = nlohmann::json::array();
    for (const HypothesisCheck& h : x.hypotheses) {
      nlohmann::json one = {{"hypothesis", h.name}, {"verdict", to_string(h.verdict)}, {"detail", h.detail}};
      if (!h.scope.empty()) one["scope"] = h.scope;  // only for a hypothesis over all states
      hs.push_back(one);
    }
    out.push_back(
        {{"result", x.result}, {"claim", x.claim}, {"verdict", to_string(x.verdict())}, {"relied_on", x.relied_on}, {"hypotheses", hs}});
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
    for (const HypothesisCheck& h : x.hypotheses)
      os << "                  " << to_string(h.verdict) << (h.scope.empty() ? "" : " (" + h.scope + ")") << ": " << h.name << "; "
         << h.detail << "\n";
  }
  return os.str();
}

}  // namespace moreau::scene
