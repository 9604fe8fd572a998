// A double in Moreau's JSON: one rule for every writer (the report, studies, campaigns, the server) and
// its reverse for every reader of that JSON.
//
// JSON has no NaN or infinity. A value that is not finite is written as null: never an invalid document,
// never a string such as "nan" (text formats spell it that way: moreau/platform/number_text.h). Writing
// null explicitly, rather than leaving NaN in the json value for the serializer to print as null, keeps the
// value in memory equal to the document that is read back (a json holding NaN is not even equal to itself).
#pragma once

#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

namespace moreau::scene {

// v as a JSON number, or null when v is NaN or infinite.
inline nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// The reverse: a JSON number as a double, anything else (null, as written for a non-finite value) as NaN.
inline double number_or_nan(const nlohmann::json& j) { return j.is_number() ? j.get<double>() : std::numeric_limits<double>::quiet_NaN(); }

}  // namespace moreau::scene
