// Bad input over HTTP: one table of malformed scenes and requests, each sent as raw bytes over a fresh
// TCP connection to a real in-process moreau-server (127.0.0.1, ephemeral port). Every case must get its
// expected status, a JSON body with "error", the exact JSON pointer (or none) and a message naming the
// problem, within a few seconds; the server must stay healthy after each one, and after the whole table
// a valid scene must still run to "done" with finite results. docs/reliability.md, "Bad input".
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "loopback_socket.h"
#include "server_fixture.h"

namespace {

using json = nlohmann::json;
using moreau::server::ServerConfig;
using moreau::server::testing::TestServer;
using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxBody = 1u << 20;  // the server's body limit in this test
constexpr double kMaxCaseSeconds = 5.0;     // no case may take longer: a hang is a failure
constexpr int kReadTimeoutSeconds = 10;     // and cannot block the test for more than this

// ---- A minimal HTTP/1.1 client over a POSIX socket: the bytes go out exactly as given (no header
// normalization, no URL encoding, no default Content-Type), with "Connection: close".

struct Reply {
  bool ok = false;  // a complete status line and headers arrived
  int status = 0;
  std::string content_type, body, error;
};

Reply exchange(int port, const std::string& request) {
  Reply r;
  const int fd = moreau::server::testing::connect_loopback(port, kReadTimeoutSeconds * 1000);
  if (fd < 0) {
    r.error = "connect() failed";
    return r;
  }
  moreau::server::testing::send_all(fd, request);
  // Reads until the server closes, or until the Content-Length it announced has arrived (a server may
  // keep the connection open despite "Connection: close").
  std::string in;
  char buf[65536];
  for (;;) {
    const std::size_t head = in.find("\r\n\r\n");
    if (head != std::string::npos) {
      std::string lower_head = in.substr(0, head);
      for (char& c : lower_head) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      const auto cl = lower_head.find("\r\ncontent-length:");
      if (cl != std::string::npos && in.size() >= head + 4 + std::strtoull(lower_head.c_str() + cl + 17, nullptr, 10)) break;
    }
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      if (n < 0) r.error = "recv() failed or timed out after " + std::to_string(kReadTimeoutSeconds) + " s";
      break;
    }
    in.append(buf, static_cast<std::size_t>(n));
  }
  ::close(fd);
  const std::size_t head_end = in.find("\r\n\r\n");
  if (head_end == std::string::npos || in.compare(0, 9, "HTTP/1.1 ") != 0) {
    if (r.error.empty()) r.error = "no HTTP response (" + std::to_string(in.size()) + " bytes)";
    return r;
  }
  r.ok = true;
  r.status = std::atoi(in.c_str() + 9);
  std::istringstream head(in.substr(0, head_end));
  std::string line;
  std::size_t length = std::string::npos;
  while (std::getline(head, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string key = line.substr(0, colon), value = line.substr(colon + 1);
    for (char& c : key) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    while (!value.empty() && value.front() == ' ') value.erase(0, 1);
    if (key == "content-type") r.content_type = value;
    if (key == "content-length") length = std::strtoull(value.c_str(), nullptr, 10);
  }
  r.body = in.substr(head_end + 4);
  if (length != std::string::npos && r.body.size() > length) r.body.resize(length);
  return r;
}

// content_type: nullopt sends no Content-Type header at all.
std::string http_request(const std::string& method, const std::string& path, const std::optional<std::string>& content_type,
                         const std::string& body) {
  std::string out = method + " " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n";
  if (content_type) out += "Content-Type: " + *content_type + "\r\n";
  if (!body.empty() || method == "POST" || method == "PUT" || method == "PATCH")
    out += "Content-Length: " + std::to_string(body.size()) + "\r\n";
  return out + "\r\n" + body;
}

// ---- The bodies.

// A valid 1-DOF scene: a unit mass with a relay (Phi = |v|), from v = 1 to rest at t = 1.
json tiny_scene() {
  return {{"name", "tiny"},
          {"system", {{"type", "lagrangian"}, {"mass", {{1}}}, {"controller", {{{"type", "abs"}, {"gains", {1}}}}}}},
          {"initial", {{"q", {0}}, {"v", {1}}}},
          {"integrator", {{"h", 0.01}, {"t_end", 2}}}};
}

// A valid Lur'e scene: x' = -x - y_L, y = x, y_L on the identity graph through three vertices.
json lure_scene() {
  return {{"system",
           {{"type", "lure"},
            {"A", {{-1}}},
            {"B", {{1}}},
            {"C", {{1}}},
            {"feedback", {{{"type", "graph"}, {"vertices", {{-1, -1}, {0, 0}, {1, 1}}}}}}}},
          {"initial", {{"x", {0.5}}}},
          {"integrator", {{"h", 0.01}, {"t_end", 1}}}};
}

std::string scene_body(const std::function<void(json&)>& edit) {
  json s = tiny_scene();
  edit(s);
  return json({{"scene", s}}).dump();
}

std::string lure_body(const std::function<void(json&)>& edit) {
  json s = lure_scene();
  edit(s);
  return json({{"scene", s}}).dump();
}

std::string request_body(const std::function<void(json&)>& edit) {
  json r = {{"scene", tiny_scene()}};
  edit(r);
  return r.dump();
}

// Replaces the first occurrence of `marker` (e.g. "\"@H@\"", a string put in by an edit) by raw bytes
// that json cannot produce: an overflowing literal, invalid UTF-8.
std::string splice(std::string body, const std::string& marker, const std::string& bytes) {
  const auto at = body.find(marker);
  if (at == std::string::npos) throw std::logic_error("marker " + marker + " not in body");
  return body.replace(at, marker.size(), bytes);
}

std::string repeat(const std::string& s, int n) {
  std::string out;
  for (int i = 0; i < n; ++i) out += s;
  return out;
}

// ---- The table.

struct Case {
  std::string name;
  std::string method, path;                 // "{id}" in path: a finished job of this server
  std::optional<std::string> content_type;  // nullopt: no Content-Type header
  std::string body;
  int status;
  std::string pointer;  // the exact "pointer", or "" when the body must have none
  std::string message;  // a substring of "reason" or "error"
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

const std::string kJson = "application/json";

Case post(std::string name, std::string body, int status, std::string pointer, std::string message) {
  return {std::move(name), "POST", "/v1/jobs", kJson, std::move(body), status, std::move(pointer), std::move(message)};
}
Case get(std::string name, std::string path, int status, std::string message) {
  return {std::move(name), "GET", std::move(path), std::nullopt, "", status, "", std::move(message)};
}

std::vector<Case> cases() {
  std::vector<Case> t;
  const std::string valid = request_body([](json&) {});

  // Wrong types and sizes.
  t.push_back(post("MassTwoByTwoForOneCoordinate", scene_body([](json& s) {
                     s["system"]["coordinates"] = {"x"};
                     s["system"]["mass"] = {{1, 0}, {0, 1}};
                   }),
                   400, "/system/mass", "expected 1 rows (one per coordinate), got 2"));
  t.push_back(post("MassRowTooShort", scene_body([](json& s) {
                     s["system"]["mass"] = {{1, 0}, {0}};
                     s["system"].erase("controller");
                     s["initial"] = {{"q", {0, 0}}};
                   }),
                   400, "/system/mass/1", "expected 2 entries"));
  t.push_back(post("InitialQWrongLength", scene_body([](json& s) {
                     s["initial"]["q"] = {0, 1};
                   }),
                   400, "/initial/q", "expected 1 entries (one per coordinate), got 2"));
  t.push_back(post("InitialQString", scene_body([](json& s) { s["initial"]["q"] = "zero"; }), 400, "/initial/q", "got a string"));
  t.push_back(post("MassIsANumber", scene_body([](json& s) { s["system"]["mass"] = 1e9; }), 400, "/system/mass",
                   "expected a square array of arrays"));
  t.push_back(post("StepIsBoolean", scene_body([](json& s) { s["integrator"]["h"] = true; }), 400, "/integrator/h",
                   "expected a number or an expression string, got a boolean"));

  // Unknown names.
  t.push_back(post("UnknownSceneField", scene_body([](json& s) {
                     s["integrater"] = {{"h", 0.1}};
                   }),
                   400, "/integrater", "unknown field 'integrater'"));
  t.push_back(post("UnknownScheme", scene_body([](json& s) { s["integrator"]["scheme"] = "rk4"; }), 400, "/integrator/scheme",
                   "unknown scheme 'rk4'"));
  t.push_back(post("UnknownStepRule", scene_body([](json& s) { s["integrator"]["step_rule"] = "adaptive"; }), 400, "/integrator/step_rule",
                   "got \"adaptive\""));
  t.push_back(post("UnknownVariable", scene_body([](json& s) { s["system"]["potential"] = "q1^2 + zz"; }), 400, "/system/potential",
                   "unknown name 'zz'"));
  t.push_back(post("UnknownFunction", scene_body([](json& s) { s["system"]["potential"] = "foo(q1)"; }), 400, "/system/potential",
                   "unknown function 'foo'"));
  t.push_back(post("VelocityInMassMatrix", scene_body([](json& s) { s["system"]["mass"] = {{"1 + v1^2"}}; }), 400, "/system/mass/0/0",
                   "'v1' cannot appear in the mass matrix"));
  // A URDF whose joints are not a tree: link a hangs from base (j1) and from b (j3), and b from a (j2).
  // It once sent the walk down the robot's tree round the loop without end, holding a worker and growing
  // its memory (urdf_module.cc, check_tree).
  t.push_back(
      post("UrdfJointsThatLoop", scene_body([](json& s) {
             const std::string lim = "<limit lower=\"-1\" upper=\"1\" effort=\"1\" velocity=\"1\"/><axis xyz=\"0 0 1\"/>";
             const std::string in =
                 "<inertial><mass value=\"1\"/><inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" izz=\"0.1\"/></inertial>";
             const std::string urdf =
                 "<robot name=\"r\"><link name=\"base\"/>\n"
                 "<joint name=\"j1\" type=\"revolute\"><parent link=\"base\"/><child link=\"a\"/>" +
                 lim +
                 "</joint>\n"
                 "<link name=\"a\">" +
                 in + "</link>\n<link name=\"b\">" + in +
                 "</link>\n"
                 "<joint name=\"j2\" type=\"revolute\"><parent link=\"a\"/><child link=\"b\"/>" +
                 lim +
                 "</joint>\n"
                 "<joint name=\"j3\" type=\"revolute\"><parent link=\"b\"/><child link=\"a\"/>" +
                 lim + "</joint>\n</robot>\n";
             s["system"] = {{"type", "lagrangian"}, {"urdf", {{"text", urdf}}}};
             s["initial"] = {{"q", {0, 0}}, {"v", {0, 0}}};
           }),
           400, "/system/urdf/text", "link 'a' is the child of two joints, 'j1' (line 2) and 'j3' (line 6)"));
  // A URDF string nested 40,000 elements deep (280 KB, under the body limit) overflowed the stack of the
  // thread that parsed it (TinyXML and urdfdom recurse once per level) and killed the server. The nesting
  // is inside a JSON string, so the JSON depth limit never saw it: the URDF's own shape check refuses it
  // before any recursive parser runs (xml_shape.h).
  t.push_back(post("UrdfNested40000Deep", scene_body([](json& s) {
                     std::string urdf = "<robot name=\"r\">";
                     for (int k = 0; k < 40000; ++k) urdf += "<a>";
                     for (int k = 0; k < 40000; ++k) urdf += "</a>";
                     s["system"] = {{"type", "lagrangian"}, {"urdf", {{"text", urdf + "</robot>"}}}};
                   }),
                   400, "/system/urdf/text", "elements nested deeper than 64 levels (line 1)"));
  // The same without closing tags (not even well-formed): refused by depth at the 65th level, not parsed on.
  t.push_back(post("UrdfNestedDeepUnclosed", scene_body([](json& s) {
                     std::string urdf = "<robot>";
                     for (int k = 0; k < 50000; ++k) urdf += "<a x='>'>";
                     s["system"] = {{"type", "lagrangian"}, {"urdf", {{"text", urdf}}}};
                   }),
                   400, "/system/urdf/text", "elements nested deeper than 64 levels"));
  // Nesting hidden inside a processing instruction, which TinyXML ends at its first '>' and Expat at "?>"
  // (found by the URDF fuzzer): processing instructions are refused.
  t.push_back(post("UrdfNestingHiddenInAProcessingInstruction", scene_body([](json& s) {
                     std::string urdf = "<robot name=\"r\"><?pi <a\"r\">";
                     for (int k = 0; k < 40000; ++k) urdf += "<a>";
                     s["system"] = {{"type", "lagrangian"}, {"urdf", {{"text", urdf + "?></robot>"}}}};
                   }),
                   400, "/system/urdf/text", "a processing instruction <?pi ...?> (line 1): processing instructions are not accepted"));
  t.push_back(post("UrdfWithDoctype", scene_body([](json& s) {
                     s["system"] = {
                         {"type", "lagrangian"},
                         {"urdf", {{"text", "<?xml version=\"1.0\"?>\n<!DOCTYPE robot [<!ENTITY x \"y\">]>\n<robot name=\"r\"/>"}}}};
                   }),
                   400, "/system/urdf/text", "a DOCTYPE declaration (line 2): DOCTYPE and entity declarations are not accepted"));
  // Names that collide with the trajectory's own columns (t, h, <q>, <q>_dot, energy): a CSV header
  // t,h,h,... and duplicate JSON keys before. Refused for each way coordinates are named.
  t.push_back(post("CoordinateNamedH", scene_body([](json& s) { s["system"]["coordinates"] = {"h"}; }), 400, "/system/coordinates/0",
                   "'h' is reserved: the trajectory has its own column 'h' (the step size)"));
  t.push_back(post("CoordinateNamedAsAnotherCoordinatesVelocity", scene_body([](json& s) {
                     s["system"]["coordinates"] = {"a", "a_dot"};
                     s["system"]["mass"] = {{1, 0}, {0, 1}};
                     s["system"].erase("controller");
                     s["initial"] = {{"q", {0, 0}}};
                   }),
                   400, "/system/coordinates/1", "'a_dot' is the name of the velocity of coordinate 'a'"));
  t.push_back(
      post("UrdfJointNamedEnergy", scene_body([](json& s) {
             const std::string urdf =
                 "<robot name=\"r\"><link name=\"base\"/>\n"
                 "<joint name=\"energy\" type=\"continuous\"><parent link=\"base\"/><child link=\"a\"/><axis xyz=\"0 0 1\"/></joint>\n"
                 "<link name=\"a\"><inertial><mass value=\"1\"/><inertia ixx=\"0.1\" ixy=\"0\" ixz=\"0\" iyy=\"0.1\" iyz=\"0\" "
                 "izz=\"0.1\"/></inertial></link>\n</robot>\n";
             s["system"] = {{"type", "lagrangian"}, {"urdf", {{"text", urdf}}}};
             s["initial"] = {{"q", {0}}, {"v", {0}}};
           }),
           400, "/system/urdf/text", "joint 'energy' (line 2): 'energy' is reserved: the trajectory has its own column 'energy'"));
  t.push_back(post("LureStateNamedT", lure_body([](json& s) { s["system"]["states"] = {"t"}; }), 400, "/system/states/0",
                   "'t' is reserved: the trajectory has its own column 't' (the time)"));
  t.push_back(post("UnknownControllerTerm", scene_body([](json& s) {
                     s["system"]["controller"] = {{{"type", "pid"}}};
                   }),
                   400, "/system/controller/0/type", "unknown controller term 'pid'"));
  t.push_back(post("UnknownFeedbackType", lure_body([](json& s) {
                     s["system"]["feedback"] = {{{"type", "magic"}}};
                   }),
                   400, "/system/feedback/0/type", "unknown feedback type 'magic'"));

  // M not positive definite or not symmetric.
  t.push_back(post("MassNegative", scene_body([](json& s) { s["system"]["mass"] = {{-1}}; }), 400, "/system/mass",
                   "not positive definite at the initial state (smallest eigenvalue -1)"));
  t.push_back(post("MassIndefinite", scene_body([](json& s) {
                     s["system"]["mass"] = {{1, 2}, {2, 1}};
                     s["system"].erase("controller");
                     s["initial"] = {{"q", {0, 0}}};
                   }),
                   400, "/system/mass", "not positive definite"));
  t.push_back(post("MassNotSymmetric", scene_body([](json& s) {
                     s["system"]["mass"] = {{2, 1}, {"1 + q1", 2}};
                     s["system"].erase("controller");
                     s["initial"] = {{"q", {1, 0}}};
                   }),
                   400, "/system/mass/1/0", "M is not symmetric"));

  // Non-monotone Lur'e graphs and a start outside the domain.
  t.push_back(post("LureGraphDecreasingW", lure_body([](json& s) {
                     s["system"]["feedback"][0]["vertices"] = {{-1, -1}, {0, 0.5}, {1, -0.5}};
                   }),
                   400, "/system/feedback/0/vertices/2/1", "not monotone: w decreases from 0.5 to -0.5"));
  t.push_back(post("LureGraphDecreasingU", lure_body([](json& s) {
                     s["system"]["feedback"][0]["vertices"] = {{1, -1}, {0, 0}, {1, 1}};
                   }),
                   400, "/system/feedback/0/vertices/1/0", "not monotone: u decreases from 1 to 0"));
  t.push_back(post("LureGraphNegativeRay", lure_body([](json& s) { s["system"]["feedback"][0]["right"] = -1; }), 400,
                   "/system/feedback/0/right", "slope of the right ray must be finite and >= 0"));
  t.push_back(post("LureStartOutsideDomain", lure_body([](json& s) {
                     s["system"]["feedback"][0]["vertices"] = {{0, 0}, {1, 1}};
                     s["system"]["feedback"][0]["left"] = "wall";
                     s["initial"]["x"] = {-3};
                   }),
                   400, "/initial/x", "outside the domain of /system/feedback/0"));

  // NaN and Inf: JSON has no NaN, so an overflowing literal, the string "nan", and expressions that
  // evaluate to NaN or Inf at the initial state. An overflowing literal in the body is a syntax error
  // like any other: 400 "malformed JSON", not 500 (docs/reliability.md, "Bad input").
  t.push_back(post("LiteralOverflowsDouble", splice(scene_body([](json& s) { s["integrator"]["h"] = "@H@"; }), "\"@H@\"", "1e999"), 400, "",
                   "number overflow parsing '1e999'"));
  t.push_back(post("NegativeLiteralOverflowsDouble",
                   splice(scene_body([](json& s) { s["integrator"]["t_end"] = "@T@"; }), "\"@T@\"", "-1e999"), 400, "",
                   "number overflow parsing '-1e999'"));
  t.push_back(
      post("StepIsTheStringNaN", scene_body([](json& s) { s["integrator"]["h"] = "nan"; }), 400, "/integrator/h", "unknown name 'nan'"));
  t.push_back(post("StepIsZeroOverZero", scene_body([](json& s) { s["integrator"]["h"] = "0/0"; }), 400, "/integrator/h",
                   "evaluates to a non-finite value"));
  t.push_back(post("ExpressionLiteralOverflows", scene_body([](json& s) { s["integrator"]["t_end"] = "1e999"; }), 400, "/integrator/t_end",
                   "number out of range '1e999'"));
  t.push_back(post("ParameterLogOfMinusOne", scene_body([](json& s) {
                     s["parameters"] = {{"a", "log(-1)"}};
                     s["initial"]["v"] = {"a"};
                   }),
                   400, "/parameters/a", "evaluates to a non-finite value"));
  t.push_back(post("UnusedParameterNonFinite", scene_body([](json& s) {
                     s["parameters"] = {{"spare", "1/0"}};
                   }),
                   400, "/parameters/spare", "evaluates to a non-finite value"));
  t.push_back(post("MassInfiniteAtStart", scene_body([](json& s) { s["system"]["mass"] = {{"1/q1"}}; }), 400, "/system/mass/0/0",
                   "is not finite at the initial state"));
  t.push_back(post("ForceInfiniteAtStart", scene_body([](json& s) { s["system"]["force"] = {"1/q1"}; }), 400, "/system/force/0",
                   "not finite at the initial state"));
  t.push_back(post("PotentialNaNAtStart", scene_body([](json& s) { s["system"]["potential"] = "q1^2/2 + log(q1 - 1)"; }), 400,
                   "/system/potential", "V(q) is not finite at the initial state"));
  t.push_back(
      post("KineticEnergyOverflows", scene_body([](json& s) { s["initial"]["v"] = {1e308}; }), 400, "/initial/v", "kinetic energy"));
  t.push_back(post("LureStorageOverflows", lure_body([](json& s) {
                     s["system"]["feedback"][0] = {{"type", "relay"}, {"gain", 1}};
                     s["initial"]["x"] = {1e308};
                   }),
                   400, "/initial/x", "storage function"));
  t.push_back(post("LureGraphVertexNaN", lure_body([](json& s) {
                     s["system"]["feedback"][0]["vertices"] = {{0, "0/0"}, {1, 1}};
                   }),
                   400, "/system/feedback/0/vertices/0/1", "evaluates to a non-finite value"));

  // Step and horizon.
  t.push_back(post("StepZero", scene_body([](json& s) { s["integrator"]["h"] = 0; }), 400, "/integrator/h", "must be > 0, got 0"));
  t.push_back(
      post("StepNegative", scene_body([](json& s) { s["integrator"]["h"] = -1e-3; }), 400, "/integrator/h", "must be > 0, got -0.001"));
  t.push_back(post("EndEqualsStart", scene_body([](json& s) { s["integrator"]["t_end"] = 0; }), 400, "/integrator/t_end",
                   "must be > t0 (0), got 0"));
  t.push_back(
      post("EndBeforeStart", scene_body([](json& s) { s["integrator"]["t0"] = 5; }), 400, "/integrator/t_end", "must be > t0 (5), got 2"));
  t.push_back(post("EndLostInRoundOff", scene_body([](json& s) {
                     s["integrator"]["t0"] = 1e300;
                     s["integrator"]["t_end"] = "1e300 + 1";
                   }),
                   400, "/integrator/t_end", "must be > t0"));
  t.push_back(post("TooManyStepsForAnyScene", scene_body([](json& s) { s["integrator"]["h"] = 1e-12; }), 400, "/integrator/h",
                   "more than the limit of 2000000000"));
  t.push_back(post("TooManyStepsForThisServer", scene_body([](json& s) { s["integrator"]["h"] = 1e-6; }), 400, "/integrator/h",
                   "this server runs at most 100000 steps per job"));
  t.push_back(post("TooManyStepsForThisServerAdaptive", scene_body([](json& s) {
                     s["integrator"]["h"] = 1e-6;
                     s["integrator"]["step_rule"] = "theorem-4.1";
                   }),
                   400, "/integrator/h", "needs at least 2000000 steps; this server runs at most 100000 steps per job"));
  t.push_back(post("TooManyTrajectoryRows", scene_body([](json& s) {
                     s["integrator"]["h"] = 1e-4;
                     s["integrator"]["t_end"] = 5;
                   }),
                   400, "/output/every", "set /output/every to at least 3"));
  t.push_back(post("OutputEveryHuge", scene_body([](json& s) {
                     s["output"] = {{"every", 1e18}};
                   }),
                   400, "/output/every", "must be a whole number >= 1"));

  // Absurd sizes.
  t.push_back(post("FiftyThousandCoordinates", scene_body([](json& s) {
                     json names = json::array();
                     for (int i = 0; i < 50000; ++i) names.push_back(std::string(1, 'x').append(std::to_string(i)));
                     s["system"]["coordinates"] = names;
                   }),
                   400, "/system/coordinates", "more than 10000 degrees of freedom (got 50000)"));
  // At scale the abl scheme takes quadratic and abs terms (the large ABL path); the norm term is not separable.
  t.push_back(post("HundredCoordinatesWithANormController", scene_body([](json& s) {
                     s["system"]["mass"] = {{"diagonal", std::vector<int>(100, 1)}};
                     s["system"]["controller"] = json::array({{{"type", "norm"}, {"gain", 1}}});
                   }),
                   400, "/system/controller/0", "the norm term (not separable) is not taken"));
  t.push_back(post("MassSixtyFiveSquare", scene_body([](json& s) {
                     s["system"]["mass"] = json::array();
                     for (int i = 0; i < 65; ++i) s["system"]["mass"].push_back(std::vector<int>(65, 0));
                   }),
                   400, "/system/mass", "more than 64 degrees of freedom"));
  t.push_back(post("InitialQTwoHundredThousand", scene_body([](json& s) { s["initial"]["q"] = std::vector<int>(200000, 0); }), 400,
                   "/initial/q", "got 200000"));
  t.push_back(post("LureGraphTwoThousandVertices", lure_body([](json& s) {
                     s["system"]["feedback"][0]["vertices"] = std::vector<std::vector<int>>(2000, {0, 0});
                   }),
                   400, "/system/feedback/0/vertices", "more than 1024 vertices"));

  // Expressions: nesting, length, and a message that quotes the text without cutting a UTF-8 character.
  t.push_back(post("EightThousandNestedParentheses",
                   scene_body([](json& s) { s["system"]["potential"] = std::string(8000, '(') + "q1" + std::string(8000, ')'); }), 400,
                   "/system/potential", "nesting deeper than 128"));
  t.push_back(post("TenThousandUnaryMinus", scene_body([](json& s) { s["system"]["potential"] = std::string(10000, '-') + "q1"; }), 400,
                   "/system/potential", "nesting deeper than 128"));
  t.push_back(post("TenThousandNestedParentheses",
                   scene_body([](json& s) { s["system"]["potential"] = std::string(10000, '(') + "q1" + std::string(10000, ')'); }), 400,
                   "/system/potential", "expression longer than 16384 characters"));
  t.push_back(post("ExpressionLongerThanLimit", scene_body([](json& s) { s["system"]["potential"] = repeat("q1+", 6000) + "q1"; }), 400,
                   "/system/potential", "expression longer than 16384 characters"));
  t.push_back(post("ExpressionQuotedAcrossUtf8", scene_body([](json& s) {
                     s["system"]["potential"] = "q1 + " + repeat("\xc3\xa9", 150);  // U+00E9 straddles byte 200
                   }),
                   400, "/system/potential", "unexpected byte 0xC3 at character 5"));

  // Invalid UTF-8 and other malformed JSON.
  t.push_back(post("InvalidUtf8InString", splice(valid, "\"tiny\"", "\"ti\xff\xfeny\""), 400, "", "ill-formed UTF-8 byte"));
  t.push_back(post("InvalidUtf8InKey", splice(valid, "\"name\"", "\"na\xc3me\""), 400, "", "ill-formed UTF-8 byte"));
  t.push_back(post("OverlongUtf8InString", splice(valid, "\"tiny\"", "\"ti\xc0\xafny\""), 400, "", "ill-formed UTF-8 byte"));
  t.push_back(post("LoneSurrogateEscape", splice(valid, "\"tiny\"", "\"ti\\ud800ny\""), 400, "",
                   "surrogate U+D800..U+DBFF must be followed by U+DC00..U+DFFF"));
  t.push_back(post("TruncatedJson", valid.substr(0, valid.size() / 2), 400, "", "unexpected end of input"));
  t.push_back(post("EmptyBody", "", 400, "", "unexpected end of input"));
  t.push_back(post("BodyIsArray", "[1, 2, 3]", 400, "", "the body must be an object"));
  t.push_back(post("BodyIsNumber", "42", 400, "", "the body must be an object"));
  t.push_back(post("BodyIsNull", "null", 400, "", "the body must be an object"));
  t.push_back(post("TrailingGarbage", valid + " {}", 400, "", "expected end of input"));
  t.push_back(post("JsonWithComment", "/* scene */ " + valid, 400, "", "invalid literal"));
  t.push_back(post("JsonNestedTooDeep", "{\"scene\": {\"name\": " + std::string(100, '[') + std::string(100, ']') + "}}", 400, "",
                   "nested deeper than 64 levels"));

  // Content types.
  t.push_back({"TextPlain", "POST", "/v1/jobs", "text/plain", valid, 415, "", "takes application/json, got 'text/plain'"});
  t.push_back({"NoContentType", "POST", "/v1/jobs", std::nullopt, valid, 415, "", "takes application/json, got ''"});
  t.push_back({"MultipartFormData", "POST", "/v1/jobs", "multipart/form-data; boundary=xyz",
               "--xyz\r\nContent-Disposition: form-data; name=\"scene\"\r\n\r\nmanipulator\r\n--xyz--\r\n", 415, "",
               "got 'multipart/form-data; boundary=xyz'"});
  t.push_back({"FormUrlencoded", "POST", "/v1/jobs", "application/x-www-form-urlencoded", "scene=manipulator", 415, "",
               "unsupported content type"});
  t.push_back({"JsonPatchContentType", "POST", "/v1/jobs", "application/json-patch+json", valid, 415, "", "takes application/json"});
  t.push_back({"ContentTypeInvalidUtf8", "POST", "/v1/jobs", "text/\xff\xfe", valid, 415, "", "takes application/json"});

  // Too large.
  t.push_back(post("BodyOverTheLimit", "{\"scene\": \"" + std::string(kMaxBody + 1024, 'x') + "\"}", 413, "", "at most 1048576 bytes"));

  // The request's own fields.
  t.push_back(post("UnknownRequestField", request_body([](json& r) { r["colour"] = "blue"; }), 400, "/colour",
                   "unknown field (expected scene, overrides, stream, strict)"));
  t.push_back(post("MissingScene", R"({"overrides": []})", 400, "/scene", "missing required field 'scene'"));
  t.push_back(post("SceneIsANumber", R"({"scene": 5})", 400, "/scene", "expected a scene object or the name"));
  t.push_back(post("UnknownShippedScene", R"({"scene": "no-such-scene"})", 400, "/scene", "no shipped scene by that name"));
  t.push_back(post("ShippedScenePathTraversal", R"({"scene": "../../etc/passwd"})", 400, "/scene", "no shipped scene by that name"));

  // Overrides.
  t.push_back(
      post("OverrideNotAString", request_body([](json& r) { r["overrides"] = {5}; }), 400, "/overrides/0", "expected a string PATH=VALUE"));
  t.push_back(post("OverridesNotAList", request_body([](json& r) { r["overrides"] = 5; }), 400, "/overrides",
                   "expected an array of \"PATH=VALUE\" or an object"));
  t.push_back(post("OverrideWithoutEquals", request_body([](json& r) { r["overrides"] = {"integrator.h"}; }), 400, "/overrides/0",
                   "is not of the form PATH=VALUE"));
  t.push_back(post("OverridePathThroughANumber", request_body([](json& r) { r["overrides"] = {"integrator.h.x=1"}; }), 400,
                   "/integrator/h/x", "override path goes through a number"));
  t.push_back(post("OverrideIndexOutOfRange", request_body([](json& r) { r["overrides"] = {"initial.q.5=1"}; }), 400, "/initial/q/5",
                   "index 5 is out of range (size 1)"));
  t.push_back(post("OverrideBadPointerEscape", request_body([](json& r) { r["overrides"] = {"/integrator/~2=1"}; }), 400, "/integrator/~2",
                   "not a valid JSON pointer"));
  t.push_back(post("OverrideValueNotJson", request_body([](json& r) { r["overrides"] = {"integrator.h={bad"}; }), 400, "/integrator/h",
                   "unexpected character '{'"));
  t.push_back(post("OverrideObjectUnknownField", request_body([](json& r) {
                     r["overrides"] = {{"integrator.nope", 1}};
                   }),
                   400, "/integrator/nope", "unknown field 'nope'"));
  t.push_back(post("OverrideObjectNull", request_body([](json& r) {
                     r["overrides"] = {{"integrator.h", nullptr}};
                   }),
                   400, "/integrator/h", "got null"));

  // Streaming settings.
  t.push_back(post("StreamIsANumber", request_body([](json& r) { r["stream"] = 5; }), 400, "/stream", "expected true or an object"));
  t.push_back(post("StreamPeriodZero", request_body([](json& r) {
                     r["stream"] = {{"period", 0}};
                   }),
                   400, "/stream/period", "expected a positive number"));
  t.push_back(post("StreamPeriodString", request_body([](json& r) {
                     r["stream"] = {{"period", "1"}};
                   }),
                   400, "/stream/period", "expected a positive number"));
  t.push_back(post("StreamChannelLowercase", request_body([](json& r) {
                     r["stream"] = {{"channel", "moreau"}};
                   }),
                   400, "/stream/channel", "UPPER_SNAKE"));
  t.push_back(post("StreamRealtimeString", request_body([](json& r) {
                     r["stream"] = {{"realtime", "yes"}};
                   }),
                   400, "/stream/realtime", "expected true or false"));
  t.push_back(post("StreamUnknownField", request_body([](json& r) {
                     r["stream"] = {{"rate", 1}};
                   }),
                   400, "/stream/rate", "unknown field (expected channel, period, realtime)"));

  // Query parameters (on a finished job).
  t.push_back(get("UnknownQueryParameter", "/v1/jobs?sort=age", 400, "unknown query parameter 'sort'"));
  t.push_back(get("QueryParameterOfAnotherEndpoint", "/v1/jobs/{id}?limit=3", 400, "unknown query parameter 'limit'"));
  t.push_back(get("FigureFormatUnknown", "/v1/jobs/{id}/figure?format=gif", 400, "'format' must be png or svg"));
  t.push_back(get("WaitNotANumber", "/v1/jobs/{id}?wait=abc", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitOneBillion", "/v1/jobs/{id}?wait=1e9", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitNegative", "/v1/jobs/{id}?wait=-1", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitNaN", "/v1/jobs/{id}?wait=nan", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitEmpty", "/v1/jobs/{id}?wait=", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("LimitNegative", "/v1/jobs?limit=-1", 400, "'limit' must be a number in [1, 1000000000]"));
  t.push_back(get("StateUnknown", "/v1/jobs?state=bogus", 400, "state must be queued, running, cancelling, done, failed or cancelled"));
  t.push_back(get("FigureKindUnknown", "/v1/jobs/{id}/figure?kind=pie", 400, "kind must be state, energy, step, phase or tracking"));
  t.push_back(get("FigureWidthOneBillion", "/v1/jobs/{id}/figure?width=1e9", 400, "'width' must be a number in [64, 4096]"));
  t.push_back(get("FigureHeightTiny", "/v1/jobs/{id}/figure?height=10", 400, "'height' must be a number in [64, 4096]"));
  // A number is the whole value, spelt as JSON spells it: strtod once read "600\0abc" as 600, a lone NUL
  // as 0, and hexadecimal.
  t.push_back(get("FigureWidthWithANulInside", "/v1/jobs/{id}/figure?width=600%00abc", 400, "'width' must be a number in [64, 4096]"));
  t.push_back(get("WaitALoneNul", "/v1/jobs/{id}?wait=%00", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitHexadecimal", "/v1/jobs/{id}?wait=0x10", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("WaitLeadingSpace", "/v1/jobs/{id}?wait=%201", 400, "'wait' must be a number in [0, 60]"));
  t.push_back(get("FigureRobustYNotABoolean", "/v1/jobs/{id}/figure?robust_y=1", 400, "'robust_y' must be true or false"));
  // Given twice, the second value would be ignored unseen.
  t.push_back(
      get("FigureKindTwice", "/v1/jobs/{id}/figure?kind=state&kind=energy", 400, "query parameter 'kind' is given 2 times; give it once"));
  t.push_back(get("TrajectoryFormatXml", "/v1/jobs/{id}/trajectory?format=xml", 400, "format must be json, csv or npy"));

  // Job ids: unknown, malformed, path traversal (plain and percent-encoded), and scene names.
  t.push_back(
      get("UnknownJobId", "/v1/jobs/0123456789abcdef0123456789abcdef", 404, "no job 0123456789abcdef0123456789abcdef on this server"));
  t.push_back(get("UppercaseJobId", "/v1/jobs/0123456789ABCDEF0123456789ABCDEF/report", 404,
                  "'0123456789ABCDEF0123456789ABCDEF' is not a job id: job ids are 32 lowercase hex digits"));
  t.push_back(get("JobIdTooLong", "/v1/jobs/{id}0/trajectory", 404, "no such job"));
  t.push_back(get("JobIdWithEncodedNul", "/v1/jobs/{id}%00", 404, "no such job"));
  t.push_back(get("JobIdPathTraversal", "/v1/jobs/../../etc/passwd", 404, "not found"));
  t.push_back(get("JobIdEncodedTraversal", "/v1/jobs/..%2F..%2Fetc%2Fpasswd", 404, "not found"));
  t.push_back(get("JobIdEncodedDotDot", "/v1/jobs/%2e%2e/report", 404, "no such job"));
  t.push_back(get("UnknownStudyId", "/v1/studies/0123456789abcdef0123456789abcdef/table", 404,
                  "no study 0123456789abcdef0123456789abcdef on this server"));
  t.push_back({"DeleteUnknownJob", "DELETE", "/v1/jobs/0123456789abcdef0123456789abcdef", std::nullopt, "", 404, "", "no such job"});
  t.push_back(get("EventsOfDotDot", "/v1/jobs/../events", 404, "no such job"));
  t.push_back(get("SceneEncodedTraversal", "/v1/scenes/..%2F..%2Fetc%2Fpasswd", 404, "not found"));
  t.push_back(get("UnknownSceneName", "/v1/scenes/no-such-scene", 404, "no shipped scene 'no-such-scene'"));

  // Unknown endpoints and wrong methods.
  t.push_back(get("UnknownEndpoint", "/v1/nothing", 404, "no endpoint GET /v1/nothing"));
  t.push_back(get("UnknownTopLevelFile", "/index.html", 404, "not found"));  // "/" is the web page
  t.push_back({"PutJobs", "PUT", "/v1/jobs", kJson, valid, 405, "", "method not allowed"});
  t.push_back({"PatchJob", "PATCH", "/v1/jobs/{id}", kJson, "{}", 405, "", "method not allowed"});
  t.push_back({"PostHealthz", "POST", "/healthz", kJson, "{}", 405, "", "method not allowed"});
  t.push_back({"PostJobReport", "POST", "/v1/jobs/{id}/report", kJson, "{}", 405, "", "method not allowed"});
  t.push_back({"DeleteScenes", "DELETE", "/v1/scenes", std::nullopt, "", 405, "", "method not allowed"});
  t.push_back({"PutUnknownEndpoint", "PUT", "/v1/nothing", kJson, "{}", 404, "", "no endpoint PUT /v1/nothing"});
  t.push_back({"OptionsUnknownEndpoint", "OPTIONS", "/v1/nothing", std::nullopt, "", 404, "", "no endpoint OPTIONS /v1/nothing"});
  t.push_back({"UnknownMethod", "BREW", "/v1/jobs", std::nullopt, "", 400, "", "bad request"});
  return t;
}

// ---- The server, shared by the cases of one run (one process per case under CTest).

class BadInput : public ::testing::TestWithParam<Case> {
 public:
  static void SetUpTestSuite() {
    ServerConfig cfg;
    cfg.workers = 1;
    cfg.max_body_bytes = kMaxBody;
    cfg.max_steps = 100'000;
    cfg.max_samples = 20'000;
    // The data directory on tmpfs when there is one: this test is about answers, not durability, and
    // under CTest every case starts its own server and runs its own jobs.
    std::error_code ec;
    if (std::filesystem::is_directory("/dev/shm", ec)) {
      std::string pattern = "/dev/shm/moreau-bad-input-XXXXXX";
      if (mkdtemp(pattern.data()) != nullptr) data_ = pattern;
    }
    server_ = new TestServer(cfg, data_);
  }

  // After the table (or, under CTest, after each case): the server answers, and a valid scene still
  // runs to "done" with a finite report and trajectory.
  static void TearDownTestSuite() {
    if (server_ != nullptr) {
      check_still_healthy();
      delete server_;
      server_ = nullptr;
    }
    if (!data_.empty()) {
      std::error_code ec;
      std::filesystem::remove_all(data_, ec);
      data_.clear();
    }
  }

  // A finished job, for the cases about query parameters (made on first use).
  static const std::string& finished_job() {
    if (job_id_.empty()) {
      auto c = server_->client();
      c->set_read_timeout(kReadTimeoutSeconds, 0);
      auto r = moreau::server::testing::submit(*c, {{"scene", tiny_scene()}});
      if (r && r->status == 202) {
        const std::string id = json::parse(r->body)["id"];
        if (moreau::server::testing::wait_final(*c, id, 10)["state"] == "done") job_id_ = id;
      }
    }
    return job_id_;
  }

 protected:
  static void check_still_healthy() {
    const Reply health = exchange(server_->port(), http_request("GET", "/healthz", std::nullopt, ""));
    EXPECT_TRUE(health.ok) << health.error;
    EXPECT_EQ(health.status, 200) << health.body;

    const Reply sub = exchange(server_->port(), http_request("POST", "/v1/jobs", kJson, json({{"scene", tiny_scene()}}).dump()));
    ASSERT_TRUE(sub.ok) << sub.error;
    ASSERT_EQ(sub.status, 202) << sub.body;
    const std::string id = json::parse(sub.body)["id"];
    auto c = server_->client();
    c->set_read_timeout(kReadTimeoutSeconds, 0);
    const json job = moreau::server::testing::wait_final(*c, id, 10);
    ASSERT_EQ(job["state"], "done") << job.dump(2);
    const json& report = job["report"];
    EXPECT_EQ(report["status"], "completed");
    EXPECT_EQ(report["steps"], 200);
    for (const char* part : {"q", "v"}) {
      ASSERT_EQ(report["final"][part].size(), 1u);
      ASSERT_TRUE(report["final"][part][0].is_number()) << report.dump();
      EXPECT_TRUE(std::isfinite(report["final"][part][0].get<double>()));
    }
    // The relay stops the unit mass at t = 1, q = 1/2, exactly at rest.
    EXPECT_NEAR(report["final"]["q"][0].get<double>(), 0.5, 1e-2);
    EXPECT_EQ(report["final"]["v"][0].get<double>(), 0.0);
    for (const char* e : {"initial", "final"}) EXPECT_TRUE(report["energy"][e].is_number()) << report.dump();
    // NaN and Inf are written as null: this report has no null anywhere.
    std::vector<std::string> nulls;
    std::function<void(const json&, const std::string&)> walk = [&](const json& j, const std::string& at) {
      if (j.is_null()) nulls.push_back(at);
      if (j.is_number_float() && !std::isfinite(j.get<double>())) nulls.push_back(at);
      if (j.is_object())
        for (const auto& [k, v] : j.items()) walk(v, at + "/" + k);
      if (j.is_array())
        for (std::size_t i = 0; i < j.size(); ++i) walk(j[i], at + "/" + std::to_string(i));
    };
    walk(report, "");
    EXPECT_THAT(nulls, ::testing::IsEmpty()) << report.dump();
    // Every number of the trajectory is finite.
    auto csv = c->Get("/v1/jobs/" + id + "/trajectory?format=csv");
    ASSERT_TRUE(csv);
    ASSERT_EQ(csv->status, 200);
    std::istringstream lines(csv->body);
    std::string line;
    std::getline(lines, line);  // header
    int rows = 0;
    while (std::getline(lines, line)) {
      ++rows;
      std::istringstream cells(line);
      std::string cell;
      while (std::getline(cells, cell, ',')) EXPECT_TRUE(std::isfinite(std::strtod(cell.c_str(), nullptr))) << line;
    }
    EXPECT_EQ(rows, 201);
  }

  static TestServer* server_;
  static std::filesystem::path data_;
  static std::string job_id_;
};

TestServer* BadInput::server_ = nullptr;
std::filesystem::path BadInput::data_;
std::string BadInput::job_id_;

TEST_P(BadInput, GetsAClearErrorAndLeavesTheServerHealthy) {
  const Case& c = GetParam();
  ASSERT_NE(server_, nullptr);
  std::string path = c.path;
  if (const auto at = path.find("{id}"); at != std::string::npos) {
    ASSERT_FALSE(finished_job().empty()) << "the job these cases query did not run";
    path.replace(at, 4, finished_job());
  }

  const auto t0 = Clock::now();
  const Reply r = exchange(server_->port(), http_request(c.method, path, c.content_type, c.body));
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  ASSERT_TRUE(r.ok) << "no answer: " << r.error;
  EXPECT_LT(seconds, kMaxCaseSeconds) << "the answer took " << seconds << " s";
  EXPECT_EQ(r.status, c.status) << r.body;
  EXPECT_THAT(r.content_type, ::testing::StartsWith("application/json"));
  const json body = json::parse(r.body, nullptr, /*allow_exceptions=*/false);
  ASSERT_FALSE(body.is_discarded()) << "not JSON: " << r.body;
  ASSERT_TRUE(body.is_object()) << r.body;
  ASSERT_TRUE(body.contains("error") && body["error"].is_string()) << r.body;
  if (c.pointer.empty()) {
    EXPECT_FALSE(body.contains("pointer")) << r.body;
  } else {
    ASSERT_TRUE(body.contains("pointer")) << r.body;
    EXPECT_EQ(body["pointer"], c.pointer) << r.body;
    ASSERT_TRUE(body.contains("where")) << r.body;
    EXPECT_THAT(body["where"].get<std::string>(), ::testing::AnyOf("scene", "request")) << r.body;
  }
  const std::string reason = body.contains("reason") && body["reason"].is_string() ? body["reason"].get<std::string>() : "";
  EXPECT_THAT(body["error"].get<std::string>() + "\n" + reason, ::testing::HasSubstr(c.message)) << r.body;

  // Still answering, on a new connection.
  const Reply health = exchange(server_->port(), http_request("GET", "/healthz", std::nullopt, ""));
  ASSERT_TRUE(health.ok) << "the server stopped answering: " << health.error;
  EXPECT_EQ(health.status, 200);
  EXPECT_EQ(json::parse(health.body, nullptr, false), json({{"status", "ok"}}));
}

INSTANTIATE_TEST_SUITE_P(Http, BadInput, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& info) { return info.param.name; });

// The table must stay large enough to mean something.
TEST(BadInputTable, HasAtLeastFortyFiveCasesWithUniqueNames) {
  const auto all = cases();
  EXPECT_GE(all.size(), 45u);
  std::set<std::string> names;
  for (const auto& c : all) EXPECT_TRUE(names.insert(c.name).second) << "duplicate case " << c.name;
}

}  // namespace
