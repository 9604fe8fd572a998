// The checks and quoting every reader of scene JSON uses (the compilers, the text and file readers, and
// analysis/src/campaign.cc for a campaign's spec): one home, so that every error names its field and
// quotes input the same way.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace moreau::scene::detail {

// A number as error messages quote it: 12 significant digits, "nan", "inf", "-inf"
// (moreau/platform/number_text.h).
std::string format(double v);
// "a number", "an array", ...: what a JSON value is, for error messages.
std::string type_name(const nlohmann::json& j);
std::string join(const std::vector<std::string>& items);
// The first `max_bytes` bytes of `s`, shortened so as not to end inside a UTF-8 sequence: error
// messages quote input text, and a cut multi-byte character would make the message invalid UTF-8
// (which a JSON serializer refuses).
std::string utf8_prefix(const std::string& s, std::size_t max_bytes);
// A JSON value as quoted in an error message: its serialization, at most about 200 bytes of it.
std::string brief(const nlohmann::json& j);
// Throw SceneError at `ptr` unless `j` is an object / has only the `allowed` fields.
void require_object(const nlohmann::json& j, const std::string& ptr);
void check_fields(const nlohmann::json& obj, const std::string& ptr, const std::vector<std::string>& allowed);
// The field `name` of the object `obj` (at `ptr`); SceneError "missing 'name'" at `ptr` when absent.
const nlohmann::json& required_field(const nlohmann::json& obj, const std::string& ptr, const char* name);
// A path into a document as a JSON pointer: "/parameters/m2" as it is, or dotted, "parameters.m2" and
// "initial.q.0" (also "initial.q/0"), each token escaped (json_pointer_token).
std::string path_as_pointer(const std::string& path);

}  // namespace moreau::scene::detail
