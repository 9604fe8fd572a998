// The report's one-sentence summary (report.h: plain_summary): what happened to the run, and whether the
// paper's result about it covers the run, with the first reason it does not in words a student reads.
// It is read off the report itself, so it never says more than the report's own sections (the status,
// the convergence finding, the guarantees and their verdicts) say.
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "moreau/platform/number_text.h"
#include "moreau/scene/report.h"

namespace moreau::scene {
namespace {

using nlohmann::json;

std::string number(const json& v) { return v.is_number() ? platform::significant(v.get<double>(), 6) : std::string("?"); }

std::string at_time(const json& t, const std::string& unit) { return "t = " + number(t) + (unit.empty() ? "" : " " + unit); }

// A hypothesis in plain words, when it fails: what it means for this kind of system. Matched on the start
// of the hypothesis' name as guarantees.cc writes it; others are quoted as they are.
struct Plain {
  std::string_view starts;
  std::string_view words;
};
constexpr Plain kPlain[] = {
    {"Assumption 4.1 2)-3)", "the potential's force (gravity) is too strong for the controller's gain (||grad V|| > (alpha - beta) / 2)"},
    {"Assumption 4.1 1)", "the controller lacks a viscous or a dry part (Assumption 4.1 needs eta > 0 and alpha > 0)"},
    {"(4.16)", "the applied force depends on time, and the theorem needs it constant in time"},
    {"-F(Q*, 0) - grad V(Q*) in int dPhi(0)",
     "the force at the final position is at the edge of what the controller holds, not strictly inside"},
    {"the step rule of Theorem 4.2",
     "the run's steps were not checked against Theorem 4.2's step rule (integrator.step_rule = \"theorem-4.2\" checks them)"},
    {"Assumption 3.1", "the mass matrix is not positive definite at some visited state"},
    {"(4.2)", "the step is too large for the speeds reached (condition (4.2))"},
    {"(8): no set-valued controller", "the lemma is stated for a system without a set-valued controller, and this scene has one"},
    {"psi_Phi + U has a strict minimum", "the rest position is not a strict minimum of the potential within the constraints"},
    {"Phi = {h(q) >= 0} regular", "the constraint set's regularity was not checked"},
    {"a) G(s) = C (sI - A)^{-1} B strictly positive real", "the linear part is not strictly positive real"},
    {"a) (A, B, C) minimal", "the linear part is not minimal (not controllable or not observable)"},
};

// The array `key` of `object`, in place (pointers into it stay valid), or an empty one.
const json& array_at(const json& object, const char* key) {
  static const json empty = json::array();
  if (!object.is_object()) return empty;
  const auto it = object.find(key);
  return it != object.end() && it->is_array() ? *it : empty;
}

const json* find_guarantee(const json& report, std::string_view result) {
  for (const json& item : array_at(report, "guarantees"))
    if (item.is_object() && item.value("result", "") == result) return &item;
  return nullptr;
}

// The first hypothesis of `guarantee` whose verdict is `wanted` ("fails"; or any but "holds" when
// `wanted` is empty), followed into the guarantee it names ("the hypotheses of Theorem 4.2"), in plain
// words; "" if there is none.
std::string reason(const json& report, const json& guarantee, const std::string& wanted, int depth = 0) {
  for (const json& h : array_at(guarantee, "hypotheses")) {
    if (!h.is_object()) continue;
    const std::string verdict = h.value("verdict", ""), name = h.value("hypothesis", "");
    if (verdict == "holds" || (!wanted.empty() && verdict != wanted)) continue;
    constexpr std::string_view kOf = "the hypotheses of ";
    if (depth < 3 && name.rfind(kOf, 0) == 0) {
      std::string inner = name.substr(kOf.size());
      if (const auto paren = inner.find(" ("); paren != std::string::npos) inner.resize(paren);
      if (const json* g = find_guarantee(report, inner)) {
        const std::string why = reason(report, *g, wanted, depth + 1);
        if (!why.empty()) return why;
      }
    }
    for (const Plain& p : kPlain)
      if (name.rfind(p.starts, 0) == 0) return verdict == "fails" ? std::string(p.words) : std::string(p.words) + " (" + verdict + ")";
    return verdict == "fails" ? name + " fails" : name + " is " + verdict;
  }
  return "";
}

// Why `guarantee` does not hold: a hypothesis that fails if there is one, before one left unchecked.
std::string first_reason(const json& report, const json& guarantee) {
  const std::string fails = reason(report, guarantee, "fails");
  return fails.empty() ? reason(report, guarantee, "") : fails;
}

// The result about the run's long-time behaviour, for the kind of system: finite-step convergence
// (Adly, Brogliato and Le 2016), the stability of a rest with impacts or of a Lur'e system (Brogliato 2003).
struct Result {
  std::string_view result, what;
};
constexpr Result kResults[] = {{"Theorem 4.3", "the finite-step convergence theorem (Theorem 4.3)"},
                               {"Lemma 3", "the stability lemma for a rest with impacts (Lemma 3)"},
                               {"Lemma 2", "the absolute stability lemma (Lemma 2)"}};

}  // namespace

std::string plain_summary(const json& report, const std::string& t_unit) {
  if (!report.is_object()) return "";
  const std::string status = report.value("status", "");
  std::string s;
  if (status == "failed") {
    s = "The run failed at " + at_time(report.value("t_final", json()), t_unit);
    if (report.contains("message") && report["message"].is_string()) s += ": " + report["message"].get<std::string>();
    return s + ".";
  }
  if (status == "cancelled") return "The run was cancelled at " + at_time(report.value("t_final", json()), t_unit) + ".";

  const json& tracking = report.value("tracking", json::object());
  const std::string finding =
      report.contains("convergence") && report["convergence"].is_object() ? report["convergence"].value("finding", "") : std::string();
  if (tracking.is_object() && tracking.contains("reached")) {
    if (tracking.value("reached", false)) {
      s = "The tracking error's sliding variable sigma reached ";
      s += tracking.contains("band") ? "its band (" + number(tracking["band"]) + ")" : std::string("exactly zero");
      s += " at " + at_time(tracking.value("reaching_time", json()), t_unit) + " and stayed there to the end";
    } else {
      s = "The tracking error's sliding variable sigma did not reach " +
          (tracking.contains("band") ? "its band (" + number(tracking["band"]) + ")" : std::string("zero")) + " by " +
          at_time(report.value("t_final", json()), t_unit);
    }
  } else if (report.value("converged_time", json()).is_number()) {
    // A Lur'e system's rest is its state's: dx/dt == 0.0; a mechanical system's, its velocity's.
    s = std::string("Came to rest exactly (") + (report.contains("absolute_stability") ? "dx/dt" : "velocity") + " 0.0) at " +
        at_time(report["converged_time"], t_unit);
  } else if (finding == "at rest at the end only") {
    s = "At rest exactly at the end, at " + at_time(report.value("t_final", json()), t_unit) + ", but not long enough to call it converged";
  } else if (report.contains("absolute_stability")) {
    s = "Ran to " + at_time(report.value("t_final", json()), t_unit);
  } else {
    s = "Ran to " + at_time(report.value("t_final", json()), t_unit) + " without coming to rest";
  }

  // A result the run's steps rely on comes first: when it fails, nothing else is guaranteed.
  for (const json& g : array_at(report, "guarantees")) {
    if (!g.is_object() || !g.value("relied_on", false) || g.value("verdict", "") == "holds") continue;
    const std::string why = first_reason(report, g);
    return s + "; but the run's steps are not guaranteed: " + g.value("result", "") + " does not hold here" +
           (why.empty() ? std::string() : " because " + why) + ".";
  }
  for (const Result& r : kResults) {
    const json* g = find_guarantee(report, r.result);
    if (!g) continue;
    const std::string verdict = g->value("verdict", "");
    if (verdict == "holds") {
      // "for all states" or "on the states visited": the weakest scope of its hypotheses is the claim's.
      bool visited_only = false;
      for (const json& h : array_at(*g, "hypotheses")) visited_only |= h.is_object() && h.value("scope", "") == "on the states visited";
      return s + "; " + std::string(r.what) + " covers this run" +
             (visited_only ? " (some hypotheses checked on the states visited only)" : "") + ".";
    }
    const std::string why = first_reason(report, *g);
    return s + "; " + std::string(r.what) + (verdict == "fails" ? " does not cover this run" : " is not established for this run") +
           (why.empty() ? std::string() : " because " + why) + ".";
  }
  return s + ".";
}

}  // namespace moreau::scene
