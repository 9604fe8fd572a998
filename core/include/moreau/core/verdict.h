// The answer a report gives for one hypothesis of a theorem or lemma. A report never says more than
// its checks support: "holds" only with the numbers that show it, "undetermined" when the margin is
// below round-off (never "holds"), "not checked" with the reason when nothing was computed.
#pragma once

namespace moreau {

enum class Verdict { kHolds, kFails, kUndetermined, kNotChecked };

constexpr const char* to_string(Verdict v) {
  switch (v) {
    case Verdict::kHolds: return "holds";
    case Verdict::kFails: return "fails";
    case Verdict::kUndetermined: return "undetermined";
    case Verdict::kNotChecked: return "not checked";
  }
  return "unknown";
}

// Every verdict must hold for a conjunction to hold; one failure fails it; otherwise it is undetermined
// (or not checked, when nothing in it was checked).
constexpr Verdict all_of(Verdict a, Verdict b) {
  if (a == Verdict::kFails || b == Verdict::kFails) return Verdict::kFails;
  if (a == Verdict::kHolds && b == Verdict::kHolds) return Verdict::kHolds;
  if (a == Verdict::kNotChecked || b == Verdict::kNotChecked) return Verdict::kNotChecked;
  return Verdict::kUndetermined;
}

}  // namespace moreau
