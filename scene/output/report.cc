#include "moreau/scene/report.h"

#include "moreau/platform/number_text.h"
#include "moreau/platform/text_columns.h"
#include "moreau/scene/guarantees.h"
#include "moreau/scene/json_number.h"
#include "moreau/scene/scene_model.h"

#include <algorithm>
#include <cstdio>
#include <functional>
#include <sstream>

#include <Eigen/Dense>

#include "active_constraints.h"

namespace moreau::scene {
namespace {

const char* rule_name(StepRule r) {
  switch (r) {
    case StepRule::kFixed: return "fixed";
    case StepRule::kTheorem41: return "theorem-4.1";
    case StepRule::kTheorem42: return "theorem-4.2";
  }
  return "?";
}

// Numbers in the text report: 10 significant digits.
std::string fmt(double v) { return platform::significant(v, 10); }

std::string vec(const std::vector<double>& v) {
  std::string out = "(";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + fmt(v[i]);
  return out + ")";
}

nlohmann::json num(double v) { return finite_or_null(v); }

// A list of a large scene in the text report: its first 8 and last 2 entries when it has more than
// kListedInText (the JSON report and the trajectory have them all).
constexpr std::size_t kListedInText = 16;
template <class Item>
std::string listed(const std::vector<Item>& items, const std::function<std::string(const Item&)>& text) {
  std::string out;
  const bool cut = items.size() > kListedInText;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (cut && i == 8) {
      out += ", ...";
      i = items.size() - 2;
    }
    out += (i ? ", " : "") + text(items[i]);
  }
  if (cut) out += " (" + std::to_string(items.size()) + " in all; every one in --json)";
  return out;
}
std::string listed_names(const std::vector<std::string>& names) {
  return listed<std::string>(names, [](const std::string& x) { return x; });
}
std::string listed_vec(const std::vector<double>& v) {
  return v.size() <= kListedInText ? vec(v) : "(" + listed<double>(v, [](const double& x) { return fmt(x); }) + ")";
}

nlohmann::json energy_json(const EnergyTrack& e) {
  if (!e.evaluated) return nullptr;
  nlohmann::json j = {{"initial", num(e.initial)},
                      {"final", num(e.final)},
                      {"nonincreasing", e.nonincreasing},
                      {"increases", e.increases},
                      {"max_increase", num(e.max_increase)}};
  if (e.first_increase_step >= 0) {
    j["first_increase_step"] = e.first_increase_step;
    j["first_increase_time"] = num(e.first_increase_time);
  }
  return j;
}

nlohmann::json matrix_json(const Eigen::MatrixXd& M) {
  nlohmann::json rows = nlohmann::json::array();
  for (int i = 0; i < M.rows(); ++i) {
    nlohmann::json row = nlohmann::json::array();
    for (int k = 0; k < M.cols(); ++k) row.push_back(num(M(i, k)));
    rows.push_back(row);
  }
  return rows;
}

// Which update the run used, named for what it is (a conservative part gains or keeps energy by it).
std::string update_description(const LagrangianScene& scene) {
  if (traits(scene.scheme).contacts)
    return std::string(
               "Moreau-Jean as implemented: impulses and dPhi implicit at V^{k+1}, smooth forces explicit at (Q^k, V^k), "
               "position Q^{k+1} = Q^k + h V^{k+1} (") +
           to_string(scene.contact_settings.position_update) +
           "): a symplectic Euler for the smooth part, not the theta-method with implicit smooth forces";
  if (scene.tracking)
    return scene.tracking->sampled ? "the digital controller held over the plant's steps of (0.2) (velocity implicit, position explicit)"
                                   : "(0.2) in sigma: sigma_{k+1} implicit in the inclusion, position explicit Q^{k+1} = Q^k + h V^k";
  if (traits(scene.scheme).theorems_4_1_to_4_3)
    return "(0.2): velocity implicit (V^{k+1} in the inclusion), position explicit Q^{k+1} = Q^k + h V^k: a conservative part "
           "(a spring) gains energy at O(h)";
  return "explicit peer of (0.2): velocity and position explicit, with the single-valued sign";
}

// The scene's declared exact values (/exact) against the run, whenever a scene declares them: the rest
// state, the rest time, and the exact solution at the final time. Errors are absolute, relative to the
// declared value's size, and (for times) in steps.
struct ExactComparison {
  nlohmann::json json;  // null when the scene declares nothing
  std::vector<std::string> lines;
};

ExactComparison compare_with_exact(const char* var, const std::vector<double>& declared_rest, std::optional<double> declared_rest_time,
                                   const expr::Tape* tape, int tape_slots, const std::vector<double>& final_state,
                                   const std::optional<double>& run_rest_time, double t_final, double h) {
  ExactComparison c;
  if (declared_rest.empty() && !declared_rest_time && !tape) return c;
  c.json = nlohmann::json::object();
  auto max_diff = [](const std::vector<double>& a, const std::vector<double>& b) {
    double e = 0.0, size = 0.0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      e = std::max(e, std::abs(a[i] - b[i]));
      size = std::max(size, std::abs(b[i]));
    }
    return std::pair<double, double>{e, size};
  };
  auto percent = [](double e, double size) {
    return size > 0.0 ? " (" + platform::significant(100.0 * e / size, 3) + "% of its size)" : std::string();
  };
  if (!declared_rest.empty()) {
    const auto [e, size] = max_diff(final_state, declared_rest);
    c.json["rest_" + std::string(var)] = {{"declared", declared_rest},
                                          {"final", final_state},
                                          {"max_error", num(e)},
                                          {"relative_error", size > 0.0 ? num(e / size) : nlohmann::json(nullptr)}};
    c.lines.push_back(std::string("declared rest ") + var + " = " + vec(declared_rest) + "; the run ends at " + vec(final_state) +
                      ": off by " + fmt(e) + percent(e, size));
  }
  if (declared_rest_time) {
    nlohmann::json j = {{"declared", num(*declared_rest_time)}};
    if (run_rest_time) {
      const double e = std::abs(*run_rest_time - *declared_rest_time);
      j["run"] = num(*run_rest_time);
      j["error"] = num(e);
      j["error_steps"] = num(e / h);
      c.lines.push_back("declared rest time " + fmt(*declared_rest_time) + "; the run rests from t = " + fmt(*run_rest_time) + ": off by " +
                        fmt(e) + " (" + fmt(e / h) + " steps)");
    } else {
      j["run"] = nullptr;
      c.lines.push_back("declared rest time " + fmt(*declared_rest_time) + "; the run is not at rest at its end");
    }
    c.json["rest_time"] = j;
  }
  if (tape) {
    std::vector<double> slots(static_cast<std::size_t>(tape_slots), 0.0), out(tape->num_outputs()), scratch(tape->scratch_size());
    slots[0] = t_final;
    tape->eval(slots.data(), out.data(), scratch.data());
    out.resize(std::min(out.size(), final_state.size()));
    const auto [e, size] = max_diff(final_state, out);
    c.json["at_t_final"] = {{"t", num(t_final)}, {"exact", out}, {"max_error", num(e)}};
    c.lines.push_back(std::string("exact solution at t = ") + fmt(t_final) + ": " + var + " = " + vec(out) + "; off by " + fmt(e) +
                      percent(e, size));
  }
  return c;
}

void exact_text(std::ostream& os, const ExactComparison& c) {
  for (std::size_t i = 0; i < c.lines.size(); ++i) os << (i == 0 ? "  exact         " : "                ") << c.lines[i] << "\n";
}

// The run's rest time: the summary's for (0.2); for moreau-jean the contact diagnostics' (V == 0.0 to the end).
ExactComparison lagrangian_exact(const LagrangianScene& scene, const RunSummary& s, const ContactDiagnostics* contacts) {
  std::optional<double> rest = s.rest_time;
  if (traits(scene.scheme).contacts) {
    rest.reset();
    if (contacts && contacts->rest_step >= 0) rest = contacts->rest_time;
  }
  return compare_with_exact("q", scene.exact_rest_q, scene.exact_rest_time, scene.exact_tape.get(), 1 + 2 * scene.n, s.q_final, rest,
                            s.t_final, scene.settings.h);
}

ExactComparison lure_exact(const LureScene& sc, const RunSummary& s) {
  return compare_with_exact("x", sc.exact_rest_x, sc.exact_rest_time, sc.exact_tape.get(), 1, s.q_final, s.converged_time, s.t_final,
                            sc.settings.h);
}

// Total mechanical energy E = 1/2 <M v, v> + V(q) at the start and at the end, when the scene gives V,
// and its balance. Along a solution of (0.1), dE/dt = -<xi, v> - <F, v> with xi in dPhi(v), so
// E(t) - E(t0) + D(t) = -(work of F), D the work done against dPhi (RunSummary::dissipated_work): 0 when
// F = 0 (no /system/force), and then E cannot rise either (D >= 0). What the run shows beyond that is the
// scheme's doing (its explicit position update).
struct MechanicalEnergy {
  bool known = false;
  double initial = 0.0, final = 0.0;
  bool rose = false;         // beyond round-off, at the end or at a recorded state checked on the way
  bool cannot_rise = false;  // F = 0: a rise is the scheme's doing
  bool dissipation_tracked = false;
  std::string why_not_tracked;  // when it is not
  double dissipated = 0.0;      // D at the end
  double balance = 0.0;         // E(t_N) - E(t0) + D(t_N)
  MechanicalEnergyTrack along;  // at the recorded states checked on the way (samples 0: none)
};

MechanicalEnergy mechanical_energy(const LagrangianScene& scene, const RunSummary& s, double kinetic_initial, double kinetic_final) {
  MechanicalEnergy e;
  if (!scene.compiled || !scene.compiled->has_potential) return e;
  ForceTerms terms(*scene.compiled);
  auto potential = [&](const std::vector<double>& q) {
    std::vector<double> full(static_cast<std::size_t>(scene.n), 0.0);
    std::copy(q.begin(), q.begin() + std::min<std::size_t>(q.size(), full.size()), full.begin());
    return terms.potential(full.data());
  };
  e.known = true;
  e.initial = kinetic_initial + potential(scene.q0);
  e.final = kinetic_final + potential(s.q_final);
  const double tolerance = 1e-12 * std::max(1.0, std::abs(e.initial));
  e.along = s.mechanical;
  e.rose = e.final > e.initial + tolerance || (e.along.samples > 0 && e.along.max_rise > tolerance);
  e.cannot_rise = !scene.has_force;
  e.dissipation_tracked = s.dissipation_tracked;
  if (!e.dissipation_tracked)
    e.why_not_tracked = traits(scene.scheme).contacts ? "the contact scheme does not separate its impulses' work"
                        : s.status == RunStatus::kFailed
                            ? "the run failed before its end"
                            : "only the implicit scheme (0.2) tracks it (the explicit peer's xi is not in dPhi(V^{k+1}))";
  e.dissipated = s.dissipated_work;
  e.balance = e.final - e.initial + e.dissipated;
  return e;
}

// What E(t) - E(t0) + D(t) is for the continuous system.
const char* balance_meaning(const MechanicalEnergy& e) {
  return e.cannot_rise ? "0 for the continuous system (F = 0): what the run shows is the scheme's energy error"
                       : "minus the work of F for the continuous system, plus the scheme's energy error (F's work is not evaluated apart)";
}

nlohmann::json mechanical_json(const MechanicalEnergy& e) {
  if (!e.known) return {{"kind", "1/2 <M v, v> + V(q)"}, {"evaluated", false}, {"why", "the scene gives no potential"}};
  nlohmann::json j = {
      {"kind", "1/2 <M v, v> + V(q)"}, {"evaluated", true}, {"initial", num(e.initial)}, {"final", num(e.final)}, {"rose", e.rose}};
  if (e.dissipation_tracked) {
    j["dissipated_work"] = num(e.dissipated);
    j["dissipated_work_kind"] = "D = sum_k h_k <xi_k, V^{k+1}>, xi_k in dPhi(V^{k+1}): the work done against the controller and friction";
    j["balance"] = num(e.balance);
    j["balance_kind"] = std::string("E(t_N) - E(t0) + D: ") + balance_meaning(e);
  } else {
    j["dissipated_work"] = "not tracked";
    j["dissipated_work_why"] = e.why_not_tracked;
  }
  if (e.along.samples > 0) {
    nlohmann::json a = {{"states_checked", e.along.samples},
                        {"which", "every " + std::to_string(RecordedStateChecks::kEnergyStride) + "th recorded state"},
                        {"max_rise", num(e.along.max_rise)},
                        {"max_rise_time", e.along.max_rise > 0.0 ? num(e.along.max_rise_time) : nlohmann::json(nullptr)}};
    if (e.dissipation_tracked) {
      a["max_abs_balance"] = num(e.along.max_balance);
      a["max_abs_balance_time"] = num(e.along.max_balance_time);
    }
    j["along_the_run"] = a;
  }
  if (e.rose && e.cannot_rise)
    j["warning"] = "rose although F = 0 and dPhi dissipates: the scheme's explicit position update gains energy at O(h)";
  return j;
}

void mechanical_text(std::ostream& os, const MechanicalEnergy& e) {
  if (!e.known) {
    os << "                E = 1/2 <M v, v> + V(q): not evaluated (the scene gives no potential)\n";
    return;
  }
  os << "                E = 1/2 <M v, v> + V(q): E(t0) = " << fmt(e.initial) << ", E(t_N) = " << fmt(e.final);
  if (e.along.samples > 0)
    os << "; largest rise above E(t0) at " << e.along.samples << " recorded states checked (every " << RecordedStateChecks::kEnergyStride
       << "th): " << (e.along.max_rise > 0.0 ? fmt(e.along.max_rise) + " at t = " + fmt(e.along.max_rise_time) : std::string("none"));
  if (e.rose && e.cannot_rise) os << ": ROSE although F = 0 and dPhi dissipates (the explicit position update gains energy at O(h))";
  os << "\n";
  if (e.dissipation_tracked) {
    os << "                work against dPhi D = " << fmt(e.dissipated) << "; E(t_N) - E(t0) + D = " << fmt(e.balance) << ", "
       << balance_meaning(e);
    if (e.along.samples > 0)
      os << " (largest |.| on the way " << fmt(e.along.max_balance) << " at t = " << fmt(e.along.max_balance_time) << ")";
    os << "\n";
  } else {
    os << "                work against dPhi: not tracked (" << e.why_not_tracked << ")\n";
  }
}

// What the report warns of: the parameters that no expression reads (a misspelt name?).
std::vector<std::string> scene_warnings(const std::vector<std::string>& unread_parameters) {
  std::vector<std::string> out;
  for (const std::string& p : unread_parameters) out.push_back("parameter '" + p + "' is not read by any expression of the scene");
  return out;
}

void warnings_text(std::ostream& os, const std::vector<std::string>& unread_parameters) {
  bool first = true;
  for (const std::string& w : scene_warnings(unread_parameters)) {
    os << (first ? "  warnings      " : "                ") << w << "\n";
    first = false;
  }
}

// Rest and convergence as the report states them (guarantees.h: ConvergenceFinding).
nlohmann::json convergence_json(const RunSummary& s, const Guarantees& g) {
  nlohmann::json j = {{"finding", describe(convergence_finding(s, g, "Theorem 4.3"))},
                      {"rest_step", s.rest_step ? nlohmann::json(*s.rest_step) : nlohmann::json(nullptr)},
                      {"rest_time", s.rest_time ? num(*s.rest_time) : nlohmann::json(nullptr)},
                      {"rest_steps_to_end", s.rest_step ? nlohmann::json(s.steps - *s.rest_step) : nlohmann::json(nullptr)},
                      {"min_rest_steps", RunSummary::kMinRestSteps}};
  if (s.below_normal_step) {  // only when it happened: V decayed below the smallest normal double, not a rest
    j["below_normal_step"] = *s.below_normal_step;
    j["below_normal_time"] = num(*s.below_normal_time);
  }
  return j;
}

// A state that decayed below the smallest normal double without the law holding it (RunSummary::
// below_normal_step): not a rest, said so; empty when there is none.
std::string below_normal_text(const RunSummary& s, const char* what) {
  if (!s.below_normal_step) return "";
  return std::string(what) + " decayed below the smallest normal number (2.2e-308) from step " + std::to_string(*s.below_normal_step) +
         " (t = " + fmt(*s.below_normal_time) + ") to the end, and the set-valued law does not hold it at 0: not a rest";
}

// The convergence line of the text report.
std::string convergence_text(const RunSummary& s, const Guarantees& g, const char* what) {
  std::ostringstream os;
  const ConvergenceFinding f = convergence_finding(s, g, "Theorem 4.3");
  if (f == ConvergenceFinding::kNotAtRest) {
    const std::string below = below_normal_text(s, what);
    return below.empty() ? std::string(what) + " is not exactly 0 at the last step" : below;
  }
  const std::int64_t window = s.steps - *s.rest_step;
  os << describe(f) << ": " << what << " == 0.0 exactly from step " << *s.rest_step << " (t = " << fmt(*s.rest_time) << ") to the end, "
     << window << " step" << (window == 1 ? "" : "s");
  if (f == ConvergenceFinding::kAtRestAtEnd) {
    if (window < RunSummary::kMinRestSteps)
      os << " (converged needs at least " << RunSummary::kMinRestSteps << " steps at rest to the end)";
    else
      os << " (the final position is not an equilibrium of the scheme)";
  }
  return os.str();
}

std::string name_of(const LagrangianScene& scene, int i) {
  return i >= 0 && i < static_cast<int>(scene.constraint_names.size()) ? scene.constraint_names[i] : "?";
}

// The contacts active at the end of the run (gap within ten times one step's fall, h^2 |M^-1 grad U|, as
// Lemma 3's check takes it) and the rank of their gradients: with dependent gradients (two identical
// constraints y >= 0) the motion is determined but the reactions are not: the solver's split of the
// impulse between those contacts is one of many.
struct ActiveContacts {
  std::vector<int> active;
  int rank = 0;
  bool unique() const { return rank == static_cast<int>(active.size()); }
};

ActiveContacts active_contacts_at_end(const LagrangianScene& scene, const RunSummary& s) {
  ActiveContacts out;
  const detail::ActiveConstraints at_end = detail::active_constraints_at_end(scene, s);
  out.active = at_end.active;
  if (out.active.empty()) return out;
  if (at_end.sparse_rank >= 0) {  // the large-contact path ranks its sparse gradients itself
    out.rank = at_end.sparse_rank;
    return out;
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(at_end.gradients);
  qr.setThreshold(1e-10);
  out.rank = static_cast<int>(qr.rank());
  return out;
}

std::string reactions_text(const LagrangianScene& scene, const ActiveContacts& a) {
  std::string names;
  for (std::size_t k = 0; k < a.active.size(); ++k)
    names += (k ? ", " : "") + scene.constraint_names[static_cast<std::size_t>(a.active[k])];
  if (a.unique()) return "unique at the final state (active: " + (names.empty() ? std::string("none") : names) + ")";
  return "not unique at the final state: the gradients of the active contacts " + names + " are linearly dependent (rank " +
         std::to_string(a.rank) + " of " + std::to_string(a.active.size()) +
         "); the motion is determined, the split of the reactions between them is not (the solver's is one of many)";
}

void add_contacts(nlohmann::json& j, const LagrangianScene& scene, const RunSummary& s, const ContactDiagnostics* c) {
  nlohmann::json cons = nlohmann::json::array();
  for (std::size_t i = 0; i < scene.constraint_names.size(); ++i)
    cons.push_back({{"name", scene.constraint_names[i]}, {"gap", scene.constraint_gaps[i]}, {"restitution", scene.restitution[i]}});
  j["constraints"] = cons;
  j["position_update"] = to_string(scene.contact_settings.position_update);
  if (!c) return;
  nlohmann::json impacts = nlohmann::json::array();
  for (const ImpactEvent& e : c->impacts) {
    impacts.push_back({{"step", e.step},
                       {"t", num(e.t)},
                       {"constraint", name_of(scene, e.constraint)},
                       {"pre_velocity", num(e.pre)},
                       {"post_velocity", num(e.post)},
                       {"impulse", num(e.impulse)},
                       {"kinetic_energy_change", num(e.kinetic_change)},
                       {"eq9_kinetic_energy_change", e.reference_evaluated ? num(e.eq9_change) : nlohmann::json("not evaluated")},
                       {"reference_impulse", e.reference_evaluated ? num(e.reference_impulse) : nlohmann::json("not evaluated")},
                       {"simultaneous", e.simultaneous},
                       {"closed_contacts_carrying_impulse", e.closed_carrying}});
  }
  nlohmann::json settle = nlohmann::json::array();
  for (int i = 0; i < c->constraints; ++i) {
    settle.push_back({{"constraint", name_of(scene, i)},
                      {"step", c->settle_step[i] >= 0 ? nlohmann::json(c->settle_step[i]) : nlohmann::json(nullptr)},
                      {"time", c->settle_step[i] >= 0 ? num(c->settle_time[i]) : nlohmann::json(nullptr)}});
  }
  const ActiveContacts at_end = active_contacts_at_end(scene, s);
  nlohmann::json active_names = nlohmann::json::array();
  for (int i : at_end.active) active_names.push_back(name_of(scene, i));
  j["contacts"] = {
      {"active_at_end", active_names},
      {"active_gradient_rank", at_end.rank},
      {"reactions_unique_at_end", at_end.unique()},
      {"impact_law",
       "moreau: Newton restitution at each contact; simultaneous impacts and the closed contacts carrying impulse solved together as one "
       "LCP"},
      {"impact_count", c->impact_count},
      {"impacts", impacts},
      {"impacts_truncated", c->impacts_truncated},
      {"max_eq9_mismatch", num(c->max_eq9_mismatch)},
      {"rest_step", c->rest_step >= 0 ? nlohmann::json(c->rest_step) : nlohmann::json(nullptr)},
      {"rest_time", c->rest_step >= 0 ? num(c->rest_time) : nlohmann::json(nullptr)},
      {"closed_from", settle},
      {"smallest_gap",
       {{"value", num(c->smallest_gap)}, {"t", num(c->smallest_gap_time)}, {"constraint", name_of(scene, c->smallest_gap_constraint)}}},
      {"active_steps", c->active_steps},
      {"impulse_steps", c->impulse_steps},
      {"position_correction",
       {{"mode", position_correction_name(scene.contact_settings.correct_positions)},
        {"corrected_steps", c->corrected_steps},
        {"max_correction", num(c->max_correction)},
        {"largest_violation_removed", num(c->largest_violation)},
        {"potential_energy_added", num(c->correction_energy)}}}};
  nlohmann::json ld = energy_json(c->lagrange_dirichlet);
  if (ld.is_object()) ld["potential_known"] = c->potential_known;
  j["lagrange_dirichlet"] = ld;
}

std::string contact_text(const LagrangianScene& scene, const RunSummary& s, const ContactDiagnostics* c) {
  std::ostringstream os;
  const std::string names = listed_names(scene.coordinates);
  os << "Moreau: " << (scene.name.empty() ? "scene" : scene.name) << " (" << scene.n << " DOF: " << names << "), scheme "
     << scheme_name(scene.scheme) << ", fixed h = " << fmt(scene.settings.h) << ", t in [" << fmt(scene.settings.t0) << ", "
     << fmt(scene.settings.t_end) << "]\n";
  warnings_text(os, scene.unread_parameters);
  os << "  status        " << to_string(s.status) << ": " << s.steps << " steps to t = " << fmt(s.t_final) << "\n";
  if (!s.message.empty()) os << "  message       " << s.message << "\n";
  os << "  final state   q = " << listed_vec(s.q_final) << "\n";
  os << "                v = " << listed_vec(s.v_final) << "\n";
  const std::size_t nc = scene.constraint_names.size();
  for (std::size_t i = 0; i < nc; ++i) {
    if (nc > kListedInText && i == 8) {
      os << "                ... " << nc - 10 << " more (" << nc << " in all; every one in --json)\n";
      i = nc - 2;
    }
    os << (i == 0 ? "  constraints   " : "                ") << scene.constraint_names[i] << ": " << scene.constraint_gaps[i]
       << " >= 0, e = " << fmt(scene.restitution[i]) << "\n";
  }
  if (c) {
    os << "  reactions     " << reactions_text(scene, active_contacts_at_end(scene, s)) << "\n";
    os << "  impacts       " << c->impact_count << " impact" << (c->impact_count == 1 ? "" : "s");
    if (!c->impacts.empty()) os << " (t, constraint, U-, U+, impulse, the step's dT, dT of eq. 9)";
    os << "\n";
    const std::size_t shown = std::min<std::size_t>(c->impacts.size(), 12);
    for (std::size_t k = 0; k < shown; ++k) {
      const ImpactEvent& e = c->impacts[k];
      // A table for people: each column padded on the right, numbers to 5 or 6 significant digits.
      const auto column = platform::pad_right;
      const auto g5 = [&](double v) { return column(platform::significant(v, 5), 11); };
      os << "                t = " << column(platform::significant(e.t, 6), 10) << " " << column(name_of(scene, e.constraint), 8)
         << " U- = " << g5(e.pre) << " U+ = " << g5(e.post) << " P = " << g5(e.impulse) << " dT = " << g5(e.kinetic_change) << " eq.9 "
         << (e.reference_evaluated ? platform::significant(e.eq9_change, 5) : "not evaluated") << "\n";
    }
    if (c->impact_count > static_cast<std::int64_t>(shown))
      os << "                ... " << c->impact_count - static_cast<std::int64_t>(shown) << " more (all in --json"
         << (c->impacts_truncated ? ", up to the recording limit" : "") << ")\n";
    if (!c->impacts.empty()) {
      std::int64_t multiple = 0;
      for (const ImpactEvent& e : c->impacts) multiple += e.closed_carrying > 0;
      os << "                impact law: Moreau's, Newton's U+ = -e U- at each contact, the contacts impacting together and\n"
         << "                the closed ones the impulse passes through solved as one LCP (a touching Newton's cradle gives\n"
         << "                the simultaneous-impact answer, not the sequential one)";
      if (multiple > 0) os << "; " << multiple << " recorded impact(s) passed impulse through closed contacts";
      os << "\n";
      os << "                eq. (9): that law solved apart from V^k over every contact carrying impulse (an independent\n"
         << "                LCP), against the step's dT in M(Q^k): largest difference " << fmt(c->max_eq9_mismatch)
         << " (the step also integrates the smooth forces and the controller over h)\n";
    }
    if (c->rest_step >= 0) {
      os << "  rest          v == 0.0 exactly from step " << c->rest_step << " (t = " << fmt(c->rest_time) << ") to the end\n";
    } else if (s.below_normal_step) {
      os << "  rest          " << below_normal_text(s, "v") << "\n";
    } else {
      os << "  rest          v is not exactly 0 at the last step\n";
    }
    std::vector<int> settled;
    for (int i = 0; i < c->constraints; ++i)
      if (c->settle_step[i] >= 0) settled.push_back(i);
    const bool cut = settled.size() > kListedInText;
    double last = 0.0;
    for (int i : settled) last = std::max(last, c->settle_time[static_cast<std::size_t>(i)]);
    for (std::size_t k = 0; k < settled.size(); ++k) {
      if (cut && k == 8) {
        os << "                ... " << settled.size() - 8 << " more contacts closed, the last from t = " << fmt(last) << " ("
           << settled.size() << " of " << c->constraints << " closed; every one in --json)\n";
        break;
      }
      const int i = settled[k];
      os << "                contact " << name_of(scene, i)
         << " closed (impulse every step, U == 0.0) from t = " << fmt(c->settle_time[static_cast<std::size_t>(i)]) << "\n";
    }
    os << "  smallest gap  " << fmt(c->smallest_gap) << " (" << name_of(scene, c->smallest_gap_constraint)
       << ", t = " << fmt(c->smallest_gap_time) << ")" << (c->smallest_gap < 0.0 ? ": penetration" : "") << "\n";
    os << "  positions     update " << to_string(scene.contact_settings.position_update) << "; correction "
       << position_correction_name(scene.contact_settings.correct_positions);
    if (c->correction_enabled) {
      os << ": " << c->corrected_steps << " steps projected onto h >= 0";
      if (c->corrected_steps > 0)
        os << " (largest violation " << fmt(c->largest_violation) << ", largest |dq|_M " << fmt(c->max_correction)
           << ", potential energy added " << fmt(c->correction_energy) << ")";
    }
    os << "\n";
    const EnergyTrack& w = c->lagrange_dirichlet;
    os << "  Lemma 3       W = 1/2 <M v, v> + U(q)" << (c->potential_known ? "" : " (no potential given: kinetic only)") << " "
       << (w.nonincreasing ? "non-increasing" : "not monotone") << " including impacts: ";
    if (!w.nonincreasing)
      os << w.increases << " rises, largest " << fmt(w.max_increase) << ", first at t = " << fmt(w.first_increase_time) << "; ";
    os << "W_0 = " << fmt(w.initial) << ", W_N = " << fmt(w.final) << "\n";
  }
  os << "  update        " << update_description(scene) << "\n";
  exact_text(os, lagrangian_exact(scene, s, c));
  os << guarantees_text(lagrangian_guarantees(scene, s));
  os << "  solver        max " << s.solver.max_iterations << " iterations per step, " << s.solver.total_iterations
     << " in all, max residual " << fmt(s.solver.max_residual) << ", " << s.solver.fallback_steps << " fallback steps\n";
  os << "  wall time     ";
  for (const auto& [name, seconds] : s.phase_seconds) os << name << " " << fmt(seconds * 1e3) << " ms, ";
  os << "total " << fmt(s.wall_seconds() * 1e3) << " ms\n";
  return os.str();
}

}  // namespace

namespace {

// A tracking run's results (TrackingSummary; docs/tracking.md).
nlohmann::json tracking_json(const LagrangianScene& scene, const RunSummary& s) {
  const TrackingSpec& spec = *scene.tracking;
  nlohmann::json j;
  j["law"] = spec.law_name();
  j["reference"] = spec.reference_text;
  j["lambda"] = spec.lambda;
  j["nominal"] = {{"scale", spec.nominal_scale}, {"parameters", nlohmann::json::object()}};
  for (const auto& [name, value] : spec.nominal_parameters) j["nominal"]["parameters"][name] = value;
  if (!s.tracking) return j;
  const TrackingSummary& t = *s.tracking;
  j["period"] = num(t.period);
  j["steps_per_sample"] = t.steps_per_sample;
  j["samples"] = t.samples;
  j["reached"] = t.reached;
  j["reaching_time"] = t.reached ? num(t.reaching_time) : nlohmann::json(nullptr);
  j["reaching"] = spec.sampled ? "||sigma_k||_inf <= band at every sample from reaching_time to the end"
                               : "sigma == 0.0 exactly (the one-step solver's closed form) at every step from reaching_time to the end";
  if (spec.sampled) j["band"] = num(t.band);
  if (t.predicted_on_surface_time) j["predicted_on_surface_time"] = num(*t.predicted_on_surface_time);
  if (t.reached) {
    j["after_reaching"] = {{"samples", t.after_samples},
                           {"error_max", num(t.error_max)},
                           {"error_rms", num(t.error_rms)},
                           {"sigma_max", num(t.sigma_max)},
                           {"sign_changes", t.sign_changes},
                           {"sign_changes_per_second", num(t.sign_changes_per_second)},
                           {"total_variation", num(t.total_variation)}};
  }
  j["effort"] = {{"u_max", num(t.u_max)}, {"u_energy", num(t.u_energy)}};
  j["run_chattering"] = {{"sign_changes", t.run_sign_changes}, {"total_variation", num(t.run_total_variation)}};
  j["error_final"] = num(t.error_final);
  j["perturbation"] = {{"max", num(t.perturbation_max)}, {"at", num(t.perturbation_max_time)}, {"alpha", num(t.alpha)}};
  return j;
}

std::string tracking_report_text(const LagrangianScene& scene, const RunSummary& s) {
  const TrackingSpec& spec = *scene.tracking;
  std::ostringstream os;
  std::string names;
  for (std::size_t i = 0; i < scene.coordinates.size(); ++i) names += (i ? ", " : "") + scene.coordinates[i];
  os << "Moreau: " << (scene.name.empty() ? "scene" : scene.name) << " (" << scene.n << " DOF: " << names << "), scheme tracking, law "
     << spec.law_name();
  if (spec.sampled) os << " at T_s = " << fmt(spec.period);
  os << ", plant h = " << fmt(scene.settings.h) << ", t in [" << fmt(scene.settings.t0) << ", " << fmt(scene.settings.t_end) << "]\n";
  warnings_text(os, scene.unread_parameters);
  os << "  status        " << to_string(s.status) << ": " << s.steps << " steps to t = " << fmt(s.t_final) << "\n";
  if (!s.message.empty()) os << "  message       " << s.message << "\n";
  os << "  final state   q = " << vec(s.q_final) << "\n";
  os << "                v = " << vec(s.v_final) << "\n";
  os << "  reference     q_d = (";
  for (std::size_t i = 0; i < spec.reference_text.size(); ++i) os << (i ? ", " : "") << spec.reference_text[i];
  os << "), Lambda = diag" << vec(spec.lambda) << "\n";
  os << "  model         the controller's: scale " << fmt(spec.nominal_scale);
  for (const auto& [name, value] : spec.nominal_parameters) os << ", " << name << " = " << fmt(value);
  os << "\n";
  if (s.tracking) {
    const TrackingSummary& t = *s.tracking;
    os << "  reaching      ";
    if (!t.reached)
      os << "not reached";
    else if (spec.sampled)
      os << "||sigma_k||_inf <= " << fmt(t.band) << " from t = " << fmt(t.reaching_time) << " to the end";
    else
      os << "sigma == 0.0 exactly from t = " << fmt(t.reaching_time) << " to the end (the one-step solver's closed form)";
    if (t.predicted_on_surface_time) os << "; the controller's prediction on the surface from t = " << fmt(*t.predicted_on_surface_time);
    os << "\n";
    if (t.reached) {
      os << "  after it      max |e| " << fmt(t.error_max) << ", RMS e " << fmt(t.error_rms) << ", max |sigma| " << fmt(t.sigma_max)
         << " over " << t.after_samples << " samples\n";
      os << "  chattering    " << t.sign_changes << " sign changes of u (" << fmt(t.sign_changes_per_second)
         << " per second), total variation " << fmt(t.total_variation) << "\n";
    }
    os << "  over the run  " << t.run_sign_changes << " sign changes of u, total variation " << fmt(t.run_total_variation) << "\n";
    os << "  effort        max |u| " << fmt(t.u_max) << ", integral of ||u||^2 " << fmt(t.u_energy) << "; final max |e| "
       << fmt(t.error_final) << "\n";
    os << "  perturbation  max ||rho|| " << fmt(t.perturbation_max) << " at t = " << fmt(t.perturbation_max_time) << " against alpha "
       << fmt(t.alpha) << "\n";
  }
  os << guarantees_text(lagrangian_guarantees(scene, s));
  os << "  solver        max " << s.solver.max_iterations << " iterations per step, " << s.solver.total_iterations
     << " in all, max residual " << fmt(s.solver.max_residual) << "\n";
  os << "  wall time     ";
  for (const auto& [name, seconds] : s.phase_seconds) os << name << " " << fmt(seconds * 1e3) << " ms, ";
  os << "total " << fmt(s.wall_seconds() * 1e3) << " ms\n";
  return os.str();
}

}  // namespace

nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& s) { return report_json(scene, s, nullptr); }
std::string report_text(const LagrangianScene& scene, const RunSummary& s) { return report_text(scene, s, nullptr); }

nlohmann::json report_json(const LagrangianScene& scene, const RunSummary& s, const ContactDiagnostics* contacts) {
  nlohmann::json j;
  j["scene"] = scene.name;
  if (!scene.unread_parameters.empty()) j["warnings"] = scene_warnings(scene.unread_parameters);
  j["status"] = to_string(s.status);
  if (!s.message.empty()) j["message"] = s.message;
  j["scheme"] = scheme_name(scene.scheme);
  j["step_rule"] = rule_name(scene.settings.step_rule);
  j["h"] = scene.settings.h;
  j["coordinates"] = scene.coordinates;
  j["steps"] = s.steps;
  j["t_final"] = num(s.t_final);
  j["converged_step"] = s.converged_step ? nlohmann::json(*s.converged_step) : nlohmann::json(nullptr);
  j["converged_time"] = s.converged_time ? num(*s.converged_time) : nlohmann::json(nullptr);
  const Guarantees g = lagrangian_guarantees(scene, s);
  j["convergence"] = convergence_json(s, g);
  j["final"] = {{"q", s.q_final}, {"v", s.v_final}};
  j["energy_nonincreasing"] = s.energy_nonincreasing;
  j["energy"] = {{"initial", num(s.energy_initial)},
                 {"final", num(s.energy_final)},
                 {"max_increase", num(s.energy_max_increase)},
                 {"increases", s.energy_increases}};
  j["mechanical_energy"] = mechanical_json(mechanical_energy(scene, s, s.energy_initial, s.energy_final));
  j["update"] = update_description(scene);
  if (const ExactComparison ex = lagrangian_exact(scene, s, contacts); !ex.json.is_null()) j["exact"] = ex.json;
  if (traits(scene.scheme).contacts) {
    j["system"] = "lagrangian";
    // E_k here is the kinetic energy, which falls and rises with the potential; Lemma 3's W is below.
    j["energy"]["kind"] = "kinetic 1/2 <M v, v>; the Lagrange-Dirichlet W is lagrange_dirichlet";
    add_contacts(j, scene, s, contacts);
  } else if (scene.tracking) {
    j["tracking"] = tracking_json(scene, s);
  } else {
    j["equilibrium"] = {{"residual", num(s.equilibrium.residual)}, {"interior", s.equilibrium.interior}};
  }
  j["solver"] = {{"max_iterations", s.solver.max_iterations},
                 {"max_residual", num(s.solver.max_residual)},
                 {"total_iterations", s.solver.total_iterations},
                 {"fallback_steps", s.solver.fallback_steps},
                 {"rest_steps", s.solver.rest_steps}};
  if (!s.solver.linear_solver.empty()) j["solver"]["linear_solver"] = s.solver.linear_solver;
  j["h_min"] = num(s.h_min);
  j["h_max"] = num(s.h_max);
  j["guarantees"] = guarantees_json(g);
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, seconds] : s.phase_seconds) phases[name] = seconds;
  j["phase_seconds"] = phases;
  j["wall_seconds"] = s.wall_seconds();
  return j;
}

std::string report_text(const LagrangianScene& scene, const RunSummary& s, const ContactDiagnostics* contacts) {
  if (traits(scene.scheme).contacts) return contact_text(scene, s, contacts);
  if (scene.tracking) return tracking_report_text(scene, s);
  std::ostringstream os;
  std::string names;
  for (std::size_t i = 0; i < scene.coordinates.size(); ++i) names += (i ? ", " : "") + scene.coordinates[i];
  os << "Moreau: " << (scene.name.empty() ? "scene" : scene.name) << " (" << scene.n << " DOF: " << names << "), scheme "
     << scheme_name(scene.scheme) << ", " << rule_name(scene.settings.step_rule) << " h = " << fmt(scene.settings.h) << ", t in ["
     << fmt(scene.settings.t0) << ", " << fmt(scene.settings.t_end) << "]\n";
  warnings_text(os, scene.unread_parameters);
  os << "  status        " << to_string(s.status) << ": " << s.steps << " steps to t = " << fmt(s.t_final);
  if (scene.settings.step_rule != StepRule::kFixed) os << " (h_k from " << fmt(s.h_min) << " to " << fmt(s.h_max) << ")";
  os << "\n";
  if (!s.message.empty()) os << "  message       " << s.message << "\n";
  os << "  final state   q = " << vec(s.q_final) << "\n";
  os << "                v = " << vec(s.v_final) << "\n";
  const Guarantees g = lagrangian_guarantees(scene, s);
  os << "  convergence   " << convergence_text(s, g, "v") << "\n";
  if (s.equilibrium.evaluated) {
    os << "  equilibrium   dist(-F(t,Q,0) - grad V(Q), dPhi(0)) = " << fmt(s.equilibrium.residual)
       << (s.equilibrium.residual == 0.0 ? " (an equilibrium)" : " (not an equilibrium)")
       << "; in the interior: " << (s.equilibrium.interior ? "yes" : "no") << "\n";
  }
  // "Not monotone", with the rises first: E_N may well be below E_0 (a rise is one step's E_{k+1} > E_k).
  os << "  energy        E_k = 1/2 <M(Q^k) V^k, V^k> ";
  if (s.energy_nonincreasing)
    os << "non-increasing: ";
  else
    os << "not monotone: " << s.energy_increases << " rises, largest " << fmt(s.energy_max_increase) << "; ";
  os << "E_0 = " << fmt(s.energy_initial) << ", E_N = " << fmt(s.energy_final) << "\n";
  mechanical_text(os, mechanical_energy(scene, s, s.energy_initial, s.energy_final));
  os << "  update        " << update_description(scene) << "\n";
  exact_text(os, lagrangian_exact(scene, s, contacts));
  os << guarantees_text(g);
  os << "  solver        max " << s.solver.max_iterations << " iterations per step, " << s.solver.total_iterations
     << " in all, max residual " << fmt(s.solver.max_residual) << ", " << s.solver.rest_steps << " steps at rest, "
     << s.solver.fallback_steps << " fallback steps";
  if (!s.solver.linear_solver.empty()) os << "; " << s.solver.linear_solver;
  os << "\n";
  os << "  wall time     ";
  for (const auto& [name, seconds] : s.phase_seconds) os << name << " " << fmt(seconds * 1e3) << " ms, ";
  os << "total " << fmt(s.wall_seconds() * 1e3) << " ms\n";
  return os.str();
}

namespace {

bool graphs_contain_origin(const LureScene& sc) {
  for (const MonotoneGraph& g : sc.feedback)
    if (!g.contains_origin()) return false;
  return true;
}

// Lemmas 1-2, assumption a): each condition with its verdict and the numbers it was decided on.
nlohmann::json stability_json(const LureScene& sc, const Guarantees& g) {
  nlohmann::json j;
  j["graphs_contain_origin"] = graphs_contain_origin(sc);  // Lemma 2 assumes (0, 0) on the graph of d phi
  const MinimalityCheck& mc = sc.minimality;
  j["minimal"] = {{"verdict", to_string(mc.verdict())},
                  {"controllable", to_string(mc.controllable)},
                  {"controllability_margin", num(mc.controllability_margin)},
                  {"observable", to_string(mc.observable)},
                  {"observability_margin", num(mc.observability_margin)},
                  {"exact", mc.exact},
                  {"decided_by", mc.method},
                  {"test", "Kalman ranks in exact rational arithmetic (n <= " + std::to_string(kExactMaxStates) +
                               "); margins: Popov-Belevitch-Hautus on the balanced realisation, min over the eigenvalues l of A of "
                               "sigma_min([A - l I, B]) and of [A - l I; C], relative to max(|A|, |B|) and max(|A|, |C|)"}};
  if (mc.exact) {
    j["minimal"]["controllability_rank"] = mc.controllability_rank;
    j["minimal"]["observability_rank"] = mc.observability_rank;
  }
  if (sc.P) {
    const StorageMatrixCheck& c = sc.p_check;
    j["P"] = "given";
    j["P_symmetric"] = {{"verdict", to_string(c.symmetric_verdict())}, {"asymmetry", num(c.asymmetry)}};
    j["P_positive_definite"] = {{"verdict", to_string(c.positive_definite_verdict())}, {"min_eigenvalue", num(c.min_eigenvalue)}};
    j["PA_plus_AtP_negative_definite"] = {{"verdict", to_string(c.dissipative_verdict())}, {"max_eigenvalue", num(c.max_eigenvalue_pa)}};
    j["BtP_equals_C"] = {{"verdict", to_string(c.output_verdict())}, {"relative_residual", num(c.output_residual)}};
    j["strictly_positive_real"] = to_string(c.verdict());  // by the KYP lemma's sufficiency
    j["lemma_hypotheses"] = to_string(g.find("Lemma 1")->verdict());
    return j;
  }
  const PositiveRealnessTest& t = sc.spr;
  j["P"] = "not given";
  j["strictly_positive_real"] = to_string(t.spr);
  if (!t.witness.empty()) j["witness"] = t.witness;
  j["test"] = t.method;
  j["exact"] = t.exact;
  j["A_hurwitz"] = {{"verdict", to_string(t.hurwitz)},
                    {"decided_by", t.hurwitz_method},
                    {"spectral_abscissa", num(t.spectral_abscissa)},
                    {"tolerance", num(t.hurwitz_tolerance)}};
  nlohmann::json freq = {{"verdict", to_string(t.frequency)},
                         {"min_scaled_eigenvalue", num(t.min_frequency_eigenvalue)},
                         {"at_omega", num(t.argmin_omega)},
                         {"tolerance", num(t.frequency_tolerance)},
                         {"wc", num(t.wc)},
                         {"crossing_candidates", t.crossing_candidates},
                         {"evaluations", t.frequencies}};
  if (!t.frequency_method.empty()) freq["decided_by"] = t.frequency_method;
  if (t.frequency_exact != Verdict::kNotChecked) freq["exact_sturm"] = to_string(t.frequency_exact);
  if (t.frequency_pencil != Verdict::kNotChecked) freq["popov_pencil"] = to_string(t.frequency_pencil);
  if (t.frequency_exact != Verdict::kNotChecked) freq["crossings"] = t.crossings;
  if (t.witness_omega >= 0.0) freq["witness"] = {{"omega", num(t.witness_omega)}, {"scaled_eigenvalue", num(t.witness_value)}};
  j["frequency_condition"] = freq;
  j["CB_symmetric_positive_definite"] = {
      {"verdict", to_string(t.cb)}, {"min_eigenvalue", num(t.cb_min_eigenvalue)}, {"asymmetry", num(t.cb_asymmetry)}};
  j["high_frequency_condition"] = {{"verdict", to_string(t.high_frequency)}, {"min_eigenvalue", num(t.high_frequency_min_eigenvalue)}};
  nlohmann::json cert = {{"verdict", to_string(t.certificate)}, {"method", t.storage_method}};
  if (t.storage_found()) {
    cert["P"] = matrix_json(t.P);
    cert["min_eigenvalue_P"] = num(t.storage_check.min_eigenvalue);
    cert["max_eigenvalue_PA_plus_AtP"] = num(t.storage_check.max_eigenvalue_pa);
    cert["BtP_minus_C_relative_residual"] = num(t.storage_check.output_residual);
  }
  j["certificate"] = cert;
  j["lemma_hypotheses"] = to_string(g.find("Lemma 1")->verdict());
  return j;
}

}  // namespace

nlohmann::json report_json(const LureScene& sc, const RunSummary& s, const LureDiagnostics* d) {
  nlohmann::json j;
  j["scene"] = sc.name;
  if (!sc.unread_parameters.empty()) j["warnings"] = scene_warnings(sc.unread_parameters);
  j["system"] = "lure";
  j["status"] = to_string(s.status);
  if (!s.message.empty()) j["message"] = s.message;
  j["scheme"] = scheme_name(sc.scheme);
  j["theta"] = sc.settings.theta;
  j["h"] = sc.settings.h;
  j["states"] = sc.states;
  j["feedback"] = sc.feedback_types;
  j["steps"] = s.steps;
  j["t_final"] = num(s.t_final);
  j["converged_step"] = s.converged_step ? nlohmann::json(*s.converged_step) : nlohmann::json(nullptr);
  j["converged_time"] = s.converged_time ? num(*s.converged_time) : nlohmann::json(nullptr);
  nlohmann::json fin = {{"x", s.q_final}, {"x_dot", s.v_final}};
  if (d) {
    fin["y"] = d->y_final;
    fin["y_L"] = d->y_l_final;
    nlohmann::json rest = nlohmann::json::array();
    for (std::size_t i = 0; i < d->output_rest_step.size(); ++i)
      rest.push_back({{"output", i},
                      {"step", d->output_rest_step[i] >= 0 ? nlohmann::json(d->output_rest_step[i]) : nlohmann::json(nullptr)},
                      {"time", d->output_rest_step[i] >= 0 ? num(d->output_rest_time[i]) : nlohmann::json(nullptr)}});
    j["outputs_at_rest"] = rest;
  }
  j["final"] = fin;
  if (const ExactComparison ex = lure_exact(sc, s); !ex.json.is_null()) j["exact"] = ex.json;
  const Guarantees g = lure_guarantees(sc);
  j["absolute_stability"] = stability_json(sc, g);
  j["guarantees"] = guarantees_json(g);
  nlohmann::json w = d ? energy_json(d->storage) : nlohmann::json(nullptr);
  if (w.is_object()) {
    w["P_source"] = sc.storage_source;
    w["P"] = matrix_json(*sc.storage);
  }
  j["storage_function"] = w;
  j["solver"] = {{"max_iterations", s.solver.max_iterations},
                 {"max_residual", num(s.solver.max_residual)},
                 {"total_iterations", s.solver.total_iterations},
                 {"fallback_steps", s.solver.fallback_steps}};
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, seconds] : s.phase_seconds) phases[name] = seconds;
  j["phase_seconds"] = phases;
  j["wall_seconds"] = s.wall_seconds();
  return j;
}

std::string report_text(const LureScene& sc, const RunSummary& s, const LureDiagnostics* d) {
  std::ostringstream os;
  std::string names, fb;
  for (std::size_t i = 0; i < sc.states.size(); ++i) names += (i ? ", " : "") + sc.states[i];
  for (std::size_t i = 0; i < sc.feedback_types.size(); ++i) fb += (i ? ", " : "") + sc.feedback_types[i];
  os << "Moreau: " << (sc.name.empty() ? "scene" : sc.name) << " (Lur'e system, " << sc.n << (sc.n == 1 ? " state: " : " states: ") << names
     << "; " << sc.m << " output" << (sc.m == 1 ? "" : "s") << ", feedback " << fb << "), scheme " << scheme_name(sc.scheme)
     << ", theta = " << fmt(sc.settings.theta) << ", h = " << fmt(sc.settings.h) << ", t in [" << fmt(sc.settings.t0) << ", "
     << fmt(sc.settings.t_end) << "]\n";
  warnings_text(os, sc.unread_parameters);
  os << "  status        " << to_string(s.status) << ": " << s.steps << " steps to t = " << fmt(s.t_final) << "\n";
  if (!s.message.empty()) os << "  message       " << s.message << "\n";
  os << "  final state   x = " << vec(s.q_final) << "\n";
  if (d) {
    os << "                y = " << vec(d->y_final) << ", y_L = " << vec(d->y_l_final) << "\n";
  }
  if (s.converged_step) {
    os << "  rest          x == 0.0 exactly from step " << *s.converged_step << " (t = " << fmt(*s.converged_time) << ") to the end\n";
  } else if (s.below_normal_step) {
    os << "  rest          " << below_normal_text(s, "x") << "\n";
  } else if (d) {
    bool any = false;
    for (std::size_t i = 0; i < d->output_rest_step.size(); ++i) {
      if (d->output_rest_step[i] < 0) continue;
      os << (any ? "                " : "  rest          ") << "y_" << i + 1 << " == 0.0 exactly from step " << d->output_rest_step[i]
         << " (t = " << fmt(d->output_rest_time[i]) << ")\n";
      any = true;
    }
    if (!any) os << "  rest          neither x nor any output is exactly 0 at the last step\n";
  }
  exact_text(os, lure_exact(sc, s));
  if (sc.P) {
    const StorageMatrixCheck& c = sc.p_check;
    os << "  Lemmas 1-2    P given: P = P^T " << to_string(c.symmetric_verdict()) << "; P > 0 " << to_string(c.positive_definite_verdict())
       << " (lambda_min " << fmt(c.min_eigenvalue) << "); PA + A^T P < 0 " << to_string(c.dissipative_verdict()) << " (lambda_max "
       << fmt(c.max_eigenvalue_pa) << "); B^T P = C " << to_string(c.output_verdict()) << " (residual " << fmt(c.output_residual) << ")\n";
  } else {
    const PositiveRealnessTest& t = sc.spr;
    os << "  Lemmas 1-2    P not given; (A, B, C) strictly positive real: " << to_string(t.spr)
       << (t.witness.empty() ? "" : " (" + t.witness + ")") << "\n";
    os << "                A Hurwitz " << to_string(t.hurwitz) << " (" << t.hurwitz_method << "; max Re lambda " << fmt(t.spectral_abscissa)
       << "); G(jw) + G(jw)^H > 0 " << to_string(t.frequency)
       << (t.frequency_method.empty() ? std::string() : " (decided by " + t.frequency_method + ")")
       << " (smallest (1 + (w/wc)^2) lambda_min " << fmt(t.min_frequency_eigenvalue) << " at w = " << fmt(t.argmin_omega)
       << "); CB = (CB)^T > 0 " << to_string(t.cb) << "; -(CAB + (CAB)^T) > 0 " << to_string(t.high_frequency)
       << (t.exact ? " (both exact)" : "") << "\n";
    os << "                how: " << t.method << "\n";
    os << "                certificate: " << to_string(t.certificate) << ": " << t.storage_method << "\n";
  }
  os << "                minimal: " << to_string(sc.minimality.verdict()) << " (" << sc.minimality.method
     << "; PBH margins of the balanced realisation " << fmt(sc.minimality.controllability_margin) << ", "
     << fmt(sc.minimality.observability_margin) << ")\n";
  if (!graphs_contain_origin(sc))
    os << "                (0, 0) is not on every feedback graph: Lemma 2 (x = 0 exponentially stable, W non-increasing) "
          "does not apply\n";
  if (d && d->storage.evaluated) {
    const EnergyTrack& w = d->storage;
    os << "  storage       W = 1/2 x^T P x (P " << (sc.storage_source == "scene" ? "from the scene" : "found by the test") << ") "
       << (w.nonincreasing ? "non-increasing: " : "not monotone: ");
    if (!w.nonincreasing)
      os << w.increases << " rises, largest " << fmt(w.max_increase) << ", first at t = " << fmt(w.first_increase_time) << "; ";
    os << "W_0 = " << fmt(w.initial) << ", W_N = " << fmt(w.final) << "\n";
  } else {
    os << "  storage       no storage matrix P: W not evaluated\n";
  }
  os << guarantees_text(lure_guarantees(sc));
  os << "  solver        max " << s.solver.max_iterations << " iterations per step, " << s.solver.total_iterations
     << " in all, max residual " << fmt(s.solver.max_residual) << ", " << s.solver.fallback_steps << " fallback steps\n";
  os << "  wall time     ";
  for (const auto& [name, seconds] : s.phase_seconds) os << name << " " << fmt(seconds * 1e3) << " ms, ";
  os << "total " << fmt(s.wall_seconds() * 1e3) << " ms\n";
  return os.str();
}

}  // namespace moreau::scene
