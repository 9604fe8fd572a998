// The guarantees section of a report: for each theorem or lemma a run's claims rest on, its hypotheses,
// how each was checked on this run, and the verdict (verdict.h): holds, fails (with the numbers and the
// first time), undetermined, or not checked (with why). Nothing else in a report may claim more than this
// section supports: a convergence is called "Theorem 4.3" only when Theorem 4.3's hypotheses hold here.
//
// Adly, Brogliato and Le (2016), for the scheme (0.2) ("abl"):
//   Theorem 4.1  each step has exactly one solution: Assumption 3.1 and (4.2), checked at every step
//                (core/step_conditions.h);
//   Theorem 4.2  E_k non-increasing, Q^k convergent, V^k -> 0: the Theorem 4.2 step rule, Assumption 4.1;
//   Theorem 4.3  finite-step convergence: Theorem 4.2's hypotheses, F independent of t (4.16), and
//                -F(Q*, 0) - grad V(Q*) in int dPhi(0) at the final position.
// Brogliato (2003) for Lur'e systems: Lemma 1 (existence, uniqueness) and Lemma 2 (stability); for
// unilateral constraints with impacts, Lemma 3 (Lyapunov stability of the rest position).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "moreau/core/run_summary.h"
#include "moreau/core/verdict.h"
#include "moreau/scene/scene.h"

namespace moreau::scene {

// What a "holds" covers, for a hypothesis that quantifies over all states ("for all q"): proved for every
// state, or seen on the states the run visited only. Empty for a hypothesis about the run itself ("at
// every step") or one decided exactly.
inline const std::string kForAllStates = "for all states";
inline const std::string kOnVisitedStates = "on the states visited";

struct HypothesisCheck {
  std::string name;  // e.g. "Assumption 3.1: M(Q^k) positive definite at every step"
  Verdict verdict = Verdict::kNotChecked;
  std::string detail;      // the numbers (margin, first failure, worst value), or why it was not checked
  std::string scope = {};  // kForAllStates, kOnVisitedStates, or empty (see above)
};

struct Guarantee {
  std::string result;  // "Theorem 4.1"
  std::string claim;   // what it guarantees when its hypotheses hold
  // Whether the run relies on it: its conclusion is used (the well-posedness of every step), or the scene
  // asked for it (the Theorem 4.2 step rule). `moreau run --strict` fails when one of these fails.
  bool relied_on = false;
  std::vector<HypothesisCheck> hypotheses;
  Verdict verdict() const;  // all_of over the hypotheses
};

struct Guarantees {
  std::vector<Guarantee> items;
  // The first hypothesis that fails in a guarantee the run relies on, as "<result>: <name>", or "".
  std::string relied_on_failure() const;
  const Guarantee* find(const std::string& result) const;
};

// What the report says about rest and convergence: never "converged" on a velocity that is 0 only at
// the last step, and "Theorem 4.3" only when its hypotheses hold.
enum class ConvergenceFinding {
  kNotAtRest,               // V^N != 0
  kAtRestAtEnd,             // V == 0.0 at the end, but too briefly or not at an equilibrium
  kConvergedTheorem,        // converged, and the theorem that promises it has its hypotheses hold
  kConvergedNotGuaranteed,  // converged, but the theorem's hypotheses fail or were not checked
  kConvergedNoTheorem       // converged, and no result of the run's guarantees promises it (another scheme)
};
const char* describe(ConvergenceFinding f);

// What a check writes: each hypothesis with its numbers (reports), or the verdicts alone (empty details,
// and the guarantees no run relies on left out), for callers that only ask whether a hypothesis the run
// relies on fails (Simulation::hypothesis_failure, once per sample of a campaign).
enum class Detail { kFull, kVerdicts };

Guarantees lagrangian_guarantees(const LagrangianScene& scene, const RunSummary& s, Detail detail = Detail::kFull);
// Lemmas 1 and 2 of Brogliato (2003): assumption a) (SPR, exactly decided or from the scene's P; minimal),
// b) (by construction of the feedback graphs), C x(0) in dom d phi, and for Lemma 2 (0, 0) on the graph.
Guarantees lure_guarantees(const LureScene& scene);
ConvergenceFinding convergence_finding(const RunSummary& s, const Guarantees& g, const char* theorem);

nlohmann::json guarantees_json(const Guarantees& g);
// Indented lines for the text report, starting with "  guarantees    ".
std::string guarantees_text(const Guarantees& g);

}  // namespace moreau::scene
