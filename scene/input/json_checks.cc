#include "json_checks.h"

#include <algorithm>

#include "moreau/platform/number_text.h"
#include "moreau/scene/scene.h"

namespace moreau::scene::detail {

using nlohmann::json;

std::string format(double v) { return platform::significant(v, 12); }

std::string type_name(const json& j) {
  if (j.is_null()) return "null";
  if (j.is_boolean()) return "a boolean";
  if (j.is_number()) return "a number";
  if (j.is_string()) return "a string";
  if (j.is_array()) return "an array";
  return "an object";
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : ", ") + s;
  return out;
}

std::string utf8_prefix(const std::string& s, std::size_t max_bytes) {
  if (s.size() <= max_bytes) return s;
  std::size_t end = max_bytes;
  while (end > 0 && (static_cast<unsigned char>(s[end]) & 0xC0) == 0x80) --end;
  return s.substr(0, end);
}

std::string brief(const json& j) {
  const std::string text = j.dump(-1, ' ', false, json::error_handler_t::replace);
  return text.size() <= 200 ? text : utf8_prefix(text, 200) + "...";
}

void require_object(const json& j, const std::string& ptr) {
  if (!j.is_object()) throw SceneError(ptr, "expected an object, got " + type_name(j));
}

void check_fields(const json& obj, const std::string& ptr, const std::vector<std::string>& allowed) {
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end()) {
      throw SceneError(ptr + "/" + json_pointer_token(it.key()),
                       "unknown field '" + utf8_prefix(it.key(), 200) + "' (expected one of: " + join(allowed) + ")");
    }
  }
}

const json& required_field(const json& obj, const std::string& ptr, const char* name) {
  if (!obj.contains(name)) throw SceneError(ptr, std::string("missing '") + name + "'");
  return obj[name];
}

std::string path_as_pointer(const std::string& path) {
  if (!path.empty() && path[0] == '/') return path;
  std::string ptr, token;
  // Appended piece by piece: `"/" + std::string` trips a false -Wrestrict in GCC 12 (bug 105329).
  auto end_token = [&] {
    ptr += '/';
    ptr += json_pointer_token(token);
    token.clear();
  };
  for (char c : path) {
    if (c == '.' || c == '/')
      end_token();
    else
      token += c;
  }
  end_token();
  return ptr;
}

}  // namespace moreau::scene::detail
