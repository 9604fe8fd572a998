// Reading scene JSON: text (with the JSON pointer and byte of a number out of range), files (bounded in
// size), and `--set PATH=VALUE` overrides.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "json_checks.h"
#include "moreau/scene/scene.h"
#include "moreau/scene/urdf.h"

namespace moreau::scene {

std::string json_pointer_token(std::string_view key) {
  std::string out;
  for (char c : key) {
    if (c == '~')
      out += "~0";
    else if (c == '/')
      out += "~1";
    else
      out += c;
  }
  return out;
}

namespace {

using nlohmann::json;
using namespace detail;

// Splits a dotted path or a JSON pointer into tokens.
std::vector<std::string> path_tokens(const std::string& path) {
  std::vector<std::string> tokens;
  if (!path.empty() && path[0] == '/') {
    const json::json_pointer ptr(path);  // throws on a malformed pointer
    std::string rest = path.substr(1);
    std::size_t start = 0;
    while (true) {
      const std::size_t slash = rest.find('/', start);
      std::string tok = rest.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
      std::string unescaped;
      for (std::size_t i = 0; i < tok.size(); ++i) {
        if (tok[i] == '~' && i + 1 < tok.size()) {
          unescaped += tok[i + 1] == '1' ? '/' : '~';
          ++i;
        } else {
          unescaped += tok[i];
        }
      }
      tokens.push_back(unescaped);
      if (slash == std::string::npos) break;
      start = slash + 1;
    }
    return tokens;
  }
  std::stringstream ss(path);
  std::string tok;
  while (std::getline(ss, tok, '.')) tokens.push_back(tok);
  return tokens;
}

// A SAX pass over JSON text that builds nothing: where and why the text fails to parse, and the JSON
// pointer of the value being read at that point. Only run once a parse has failed.
class JsonErrorFinder : public nlohmann::json_sax<json> {
 public:
  std::size_t position = 0;  // characters read when the error was found
  std::string token;         // the last token read (for a number out of range: the number)
  int id = 0;                // nlohmann's exception id: 1xx syntax errors, 406 a number out of range
  std::string message;
  std::string pointer;  // of the value being read; "" for the whole document

  bool null() override { return value(); }
  bool boolean(bool) override { return value(); }
  bool number_integer(number_integer_t) override { return value(); }
  bool number_unsigned(number_unsigned_t) override { return value(); }
  bool number_float(number_float_t, const string_t&) override { return value(); }
  bool string(string_t&) override { return value(); }
  bool binary(binary_t&) override { return value(); }
  bool start_object(std::size_t) override {
    frames_.push_back({false, "", 0});
    return true;
  }
  bool key(string_t& k) override {
    frames_.back().key = k;
    return true;
  }
  bool end_object() override {
    frames_.pop_back();
    return value();
  }
  bool start_array(std::size_t) override {
    frames_.push_back({true, "", 0});
    return true;
  }
  bool end_array() override {
    frames_.pop_back();
    return value();
  }
  bool parse_error(std::size_t pos, const std::string& last_token, const json::exception& ex) override {
    position = pos;
    token = last_token;
    id = ex.id;
    message = ex.what();
    if (const std::size_t bracket = message.find("] "); message.rfind("[json.exception.", 0) == 0 && bracket != std::string::npos)
      message = message.substr(bracket + 2);
    pointer.clear();
    for (const Frame& f : frames_) pointer += "/" + (f.array ? std::to_string(f.index) : json_pointer_token(f.key));
    return false;
  }

 private:
  struct Frame {
    bool array;
    std::string key;
    std::size_t index;
  };
  // A value is complete: the next one in an array has the next index.
  bool value() {
    if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    return true;
  }
  std::vector<Frame> frames_;
};

// Why `text` is not JSON (it must not be: call after a failed parse).
JsonErrorFinder find_json_error(std::string_view text) {
  JsonErrorFinder finder;
  json::sax_parse(text.begin(), text.end(), &finder);
  return finder;
}

// "line L, column C" of the byte at `offset` (0-based; lines and columns count from 1).
std::string line_and_column(std::string_view text, std::size_t offset) {
  std::size_t line = 1, col = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++line;
      col = 1;
    } else {
      ++col;
    }
  }
  return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

constexpr int kNumberOutOfRange = 406;  // nlohmann::json's out_of_range.406: "number overflow parsing"

// The error of a failed parse of `text`: a number out of range at its pointer (prefixed with `pointer`,
// the pointer of the text itself), with where it starts; else a syntax error at `pointer`.
SceneError json_error(std::string_view text, const JsonErrorFinder& e, const std::string& source, const std::string& pointer) {
  if (e.id == kNumberOutOfRange) {
    const std::size_t start = e.position >= e.token.size() ? e.position - e.token.size() : 0;
    return SceneError(pointer + e.pointer, source + ": number out of range at byte " + std::to_string(start) + " (" +
                                               line_and_column(text, start) + "): " + e.message);
  }
  // nlohmann's message of a syntax error says the line and column itself.
  return SceneError(pointer, source + " is not valid JSON: " + e.message);
}

}  // namespace

nlohmann::json parse_json_text(std::string_view text, const std::string& source) {
  if (const auto at = json_depth_exceeded(text)) {
    throw SceneError("/", source + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) + " levels at byte " + std::to_string(*at));
  }
  // No exceptions from the parser: an out-of-range number is nlohmann's out_of_range, not its
  // parse_error, and one missed catch aborts the process.
  json doc = json::parse(text.begin(), text.end(), nullptr, /*allow_exceptions=*/false);
  if (!doc.is_discarded()) return doc;
  throw json_error(text, find_json_error(text), source, "");
}

std::optional<std::size_t> json_depth_exceeded(std::string_view text, int max_depth) {
  int depth = 0;
  bool in_string = false, escaped = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (c == '\\')
        escaped = true;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return std::nullopt;
}

void apply_override(nlohmann::json& doc, const std::string& assignment) {
  const std::size_t eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw SceneError("/", "override '" + assignment + "' is not of the form PATH=VALUE (e.g. integrator.h=1e-4)");
  const std::string path = assignment.substr(0, eq);
  const std::string text = assignment.substr(eq + 1);
  if (json_depth_exceeded(text)) throw SceneError(path, "override value nested deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  std::vector<std::string> tokens;
  try {
    tokens = path_tokens(path);
  } catch (const nlohmann::json::exception&) {
    throw SceneError(path, "override path is not a valid JSON pointer");
  }
  if (tokens.size() > static_cast<std::size_t>(kMaxJsonDepth))
    throw SceneError("/", "override path deeper than " + std::to_string(kMaxJsonDepth) + " levels");
  nlohmann::json value = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value.is_discarded()) {
    // Not JSON: an expression or a bare word, kept as a string. But a number that overflows a double is
    // an error, not a string: "[0, 1e999]" would otherwise reach the scene as text.
    const JsonErrorFinder e = find_json_error(text);
    if (e.id == kNumberOutOfRange) {
      std::string target;
      for (const auto& tok : tokens) target += "/" + json_pointer_token(tok);
      throw json_error(text, e, "override value '" + utf8_prefix(text, 200) + "'", target);
    }
    value = text;
  }
  nlohmann::json* node = &doc;
  std::string ptr;
  for (std::size_t i = 0; i < tokens.size(); ++i) {
    const std::string& tok = tokens[i];
    if (tok.empty()) throw SceneError(ptr + "/", "override path '" + path + "' has an empty component");
    ptr += "/" + json_pointer_token(tok);
    if (node->is_array()) {
      std::size_t idx = 0;
      try {
        std::size_t used = 0;
        idx = std::stoul(tok, &used);
        if (used != tok.size()) throw std::invalid_argument("index");
      } catch (const std::exception&) {
        throw SceneError(ptr, "override path: '" + tok + "' is not an array index");
      }
      if (idx >= node->size())
        throw SceneError(ptr, "override path: index " + tok + " is out of range (size " + std::to_string(node->size()) + ")");
      node = &(*node)[idx];
    } else if (node->is_object() || node->is_null()) {
      // A parameter is set, never created: `--set parameters.M1=5` for m1 would otherwise add a parameter
      // that nothing reads and run the nominal scene.
      if (i == 1 && tokens[0] == "parameters" && node->is_object() && !node->contains(tok)) {
        std::string names;
        for (auto it = node->begin(); it != node->end(); ++it) names += (names.empty() ? "" : ", ") + it.key();
        throw SceneError(ptr, "override sets parameter '" + tok +
                                  "', which the scene does not have (its parameters: " + (names.empty() ? "none" : names) + ")");
      }
      node = &(*node)[tok];
    } else {
      throw SceneError(ptr, "override path goes through " + type_name(*node) + ", not an object or array");
    }
  }
  *node = value;
}

namespace {

// A whole file of at most `limit` bytes, read as at most the limit and one byte whatever the file is: a
// FIFO or a device has no size to trust (and /dev/zero never ends), and a regular file may grow while it
// is read. `what` names the file in messages ("scene file 'a.json'"), `pointer` the field they are about.
std::string read_bounded_file(const std::string& path, std::size_t limit, const std::string& what, const std::string& pointer) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw SceneError(pointer, what + " is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SceneError(pointer, "cannot open " + what);
  // The chunk is left uninitialised: zeroing 64 KiB would touch 16 fresh pages, a visible share of the
  // start-up of `moreau run` (README, "Performance"); read() fills only what the file holds.
  std::string text;
  constexpr std::size_t kChunk = std::size_t{1} << 16;
  const auto chunk = std::make_unique_for_overwrite<char[]>(kChunk);
  while (text.size() <= limit && in) {
    const std::size_t want = std::min(kChunk, limit + 1 - text.size());
    in.read(chunk.get(), static_cast<std::streamsize>(want));
    text.append(chunk.get(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw SceneError(pointer, "cannot read " + what);
  if (text.size() > limit) throw SceneError(pointer, what + " is larger than " + std::to_string(limit >> 20) + " MiB, the limit for it");
  return text;
}

// Way points from CSV text, one row [t, q_1, ..., q_n] per line; a first line that is not all numbers
// is a header and skipped, blank lines are skipped. Every cell a finite number, every row as long as the
// first; errors name the file and the line.
nlohmann::json way_points_from_csv(const std::string& text, const std::string& file) {
  const std::string where = "/system/tracking/reference/csv";
  nlohmann::json rows = nlohmann::json::array();
  std::istringstream in(text);
  std::string line;
  std::size_t number = 0, width = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    nlohmann::json row = nlohmann::json::array();
    bool numbers = true;
    std::string bad;
    std::stringstream cells(line);
    for (std::string cell; std::getline(cells, cell, ',');) {
      const std::size_t first = cell.find_first_not_of(" \t"), last = cell.find_last_not_of(" \t");
      const std::string c = first == std::string::npos ? "" : cell.substr(first, last - first + 1);
      double v = 0.0;
      const auto [end, ec] = std::from_chars(c.data(), c.data() + c.size(), v);
      if (ec != std::errc() || end != c.data() + c.size() || !std::isfinite(v)) {
        numbers = false;
        bad = c.substr(0, 40);
        break;
      }
      row.push_back(v);
    }
    if (!numbers) {
      if (rows.empty() && number == 1) continue;  // a header
      // The cell as a JSON string: a control character in the file reaches no terminal unescaped.
      throw SceneError(where,
                       "'" + file + "' line " + std::to_string(number) + ": " + brief(nlohmann::json(bad)) + " is not a finite number");
    }
    if (width == 0) width = row.size();
    if (row.size() != width)
      throw SceneError(where, "'" + file + "' line " + std::to_string(number) + ": " + std::to_string(row.size()) +
                                  " values, the first row has " + std::to_string(width));
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace

nlohmann::json read_scene_file(const std::string& path) {
  const std::string what = "scene file '" + path + "'";
  nlohmann::json doc = parse_json_text(read_bounded_file(path, kMaxSceneFileBytes, what, "/"), what);
  // /system/urdf/file: read here, relative to the scene file, and put in the scene as its text, so that
  // the compiler (and a server the scene is sent to) never opens a path itself.
  if (doc.is_object() && doc.contains("system") && doc["system"].is_object() && doc["system"].contains("urdf") &&
      doc["system"]["urdf"].is_object() && doc["system"]["urdf"].contains("file")) {
    nlohmann::json& urdf = doc["system"]["urdf"];
    if (!urdf["file"].is_string() || urdf["file"].get<std::string>().empty())
      throw SceneError("/system/urdf/file", "expected the path of a URDF file, relative to the scene file");
    if (urdf.contains("text")) throw SceneError("/system/urdf", "give 'file' or 'text', not both");
    const std::filesystem::path file = std::filesystem::path(path).parent_path() / urdf["file"].get<std::string>();
    urdf["text"] = read_bounded_file(file.string(), kMaxUrdfBytes, "URDF file '" + file.string() + "'", "/system/urdf/file");
    urdf.erase("file");
  }
  // /system/tracking/reference/csv: way points read here, relative to the scene file, into "points".
  if (doc.is_object() && doc.contains("system") && doc["system"].is_object() && doc["system"].contains("tracking") &&
      doc["system"]["tracking"].is_object() && doc["system"]["tracking"].contains("reference") &&
      doc["system"]["tracking"]["reference"].is_object() && doc["system"]["tracking"]["reference"].contains("csv")) {
    nlohmann::json& ref = doc["system"]["tracking"]["reference"];
    if (!ref["csv"].is_string() || ref["csv"].get<std::string>().empty())
      throw SceneError("/system/tracking/reference/csv", "expected the path of a CSV file, relative to the scene file");
    if (ref.contains("points")) throw SceneError("/system/tracking/reference", "give 'csv' or 'points', not both");
    const std::filesystem::path file = std::filesystem::path(path).parent_path() / ref["csv"].get<std::string>();
    ref["points"] = way_points_from_csv(
        read_bounded_file(file.string(), kMaxSceneFileBytes, "way point file '" + file.string() + "'", "/system/tracking/reference/csv"),
        file.string());
    ref.erase("csv");
  }
  return doc;
}

}  // namespace moreau::scene
