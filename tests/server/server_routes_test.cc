// The server's route table (server/src/routes.h) against the OpenAPI document it serves
// (server/openapi.json, compiled in byte for byte): the same operations in the same order, each with its
// operationId, its query parameters and whether it needs the token; the figure kinds and formats the
// document lists are the names of figure_kind.h; and the matchers derived from the table (the router's
// regular expressions, the segment matcher behind Allow and the query check) agree with each other and
// with the Allow header the document implies.
#include <cctype>
#include <ostream>
#include <regex>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "embedded_files.h"
#include "moreau/analysis/figure_kind.h"
#include "routes.h"

namespace {

using moreau::server::allowed_methods;
using moreau::server::api_routes;
using moreau::server::method_name;
using moreau::server::path_matches;
using moreau::server::Route;
using moreau::server::route_regex;
using ordered_json = nlohmann::ordered_json;

// One operation as the document and the table both describe it.
struct Operation {
  std::string method, path, operation_id;
  std::vector<std::string> query;
  bool open = false;
  bool operator==(const Operation& o) const {
    return std::tie(method, path, operation_id, query, open) == std::tie(o.method, o.path, o.operation_id, o.query, o.open);
  }
  bool operator<(const Operation& o) const { return std::tie(path, method) < std::tie(o.path, o.method); }
};

std::ostream& operator<<(std::ostream& os, const Operation& o) {
  os << o.method << " " << o.path << " (" << o.operation_id << "; query:";
  for (const auto& q : o.query) os << " " << q;
  return os << (o.open ? "; open)" : "; token)");
}

ordered_json document() { return ordered_json::parse(moreau::server::openapi_document()); }

// The document's operations in its order: paths as listed, methods in the order each path lists them.
std::vector<Operation> documented() {
  std::vector<Operation> out;
  const ordered_json doc = document();
  for (const auto& [path, item] : doc["paths"].items()) {
    for (const auto& [method, op] : item.items()) {
      if (method != "get" && method != "post" && method != "delete" && method != "put" && method != "patch") continue;
      Operation o;
      o.method = method;
      for (char& c : o.method) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
      o.path = path;
      o.operation_id = op.at("operationId").get<std::string>();
      for (const auto& p : op.value("parameters", ordered_json::array()))
        if (p.at("in") == "query") o.query.push_back(p.at("name").get<std::string>());
      // The document's default is the token; an operation open without it says `security: []`.
      o.open = op.contains("security") && op["security"].empty();
      out.push_back(o);
    }
  }
  return out;
}

std::vector<Operation> tabled() {
  std::vector<Operation> out;
  for (const Route& r : api_routes()) {
    Operation o{method_name(r.method), std::string(r.path), std::string(r.operation_id), {}, r.access == moreau::server::Access::kOpen};
    for (const auto q : r.query) o.query.emplace_back(q);
    out.push_back(o);
  }
  return out;
}

// A path the route serves: each "{...}" segment replaced by a value.
std::string concrete(std::string_view pattern, const std::string& value) {
  std::string out;
  while (!pattern.empty()) {
    if (pattern[0] == '{') {
      out += value;
      pattern.remove_prefix(pattern.find('}') + 1);
    } else {
      out += pattern[0];
      pattern.remove_prefix(1);
    }
  }
  return out;
}

TEST(ServerRoutes, TableIsTheOpenApiDocument) {
  const std::vector<Operation> doc = documented(), table = tabled();
  ASSERT_FALSE(doc.empty());
  // Both ways: what one has and the other lacks, by method and path, then the details of each.
  const std::set<Operation> doc_set(doc.begin(), doc.end()), table_set(table.begin(), table.end());
  for (const Operation& o : doc)
    EXPECT_TRUE(table_set.count(o)) << "the document describes " << o.method << " " << o.path << ", which the route table lacks";
  for (const Operation& o : table)
    EXPECT_TRUE(doc_set.count(o)) << "the route table has " << o.method << " " << o.path << ", which the document does not describe";
  for (const Operation& o : doc) {
    const auto it = table_set.find(o);
    if (it != table_set.end()) {
      EXPECT_EQ(*it, o) << "the table's operation differs from the document's";
    }
  }
  // And in the same order, so that reading one beside the other is easy.
  auto order = [](const std::vector<Operation>& ops) {
    std::vector<std::string> out;
    for (const Operation& o : ops) out.push_back(o.method + " " + o.path);
    return out;
  };
  EXPECT_EQ(order(table), order(doc));
  // No path is listed twice under one method (httplib would take the first).
  EXPECT_EQ(table_set.size(), table.size());
  // Each route has the one handler its method calls: a body handler for POST, a plain one otherwise.
  for (const Route& r : api_routes()) {
    const bool post = r.method == moreau::server::Method::kPost;
    EXPECT_EQ(r.handler == nullptr, post) << r.path;
    EXPECT_EQ(r.body_handler == nullptr, !post) << r.path;
  }
}

TEST(ServerRoutes, FigureKindsAndFormatsAreTheDocumentsNames) {
  using moreau::scene::CampaignFigure;
  using moreau::scene::FigureFormat;
  using moreau::scene::StudyFigure;
  using moreau::scene::TrajectoryFigure;
  const ordered_json doc = document();
  auto query_schema = [&](const char* path, const char* name) {
    for (const auto& p : doc["paths"][path]["get"]["parameters"])
      if (p["in"] == "query" && p["name"] == name) return p["schema"];
    ADD_FAILURE() << path << " documents no query parameter " << name;
    return ordered_json();
  };
  auto names = [](const ordered_json& schema) { return schema.value("enum", std::vector<std::string>{}); };
  struct Case {
    const char* path;
    std::vector<std::string> kinds;
    std::string default_kind;
  };
  for (const Case& c : {Case{"/v1/jobs/{id}/figure", moreau::scene::figure_names<TrajectoryFigure>(),
                             moreau::scene::figure_name(moreau::scene::default_figure<TrajectoryFigure>())},
                        Case{"/v1/studies/{id}/figure", moreau::scene::figure_names<StudyFigure>(),
                             moreau::scene::figure_name(moreau::scene::default_figure<StudyFigure>())},
                        Case{"/v1/campaigns/{id}/figure", moreau::scene::figure_names<CampaignFigure>(),
                             moreau::scene::figure_name(moreau::scene::default_figure<CampaignFigure>())}}) {
    SCOPED_TRACE(c.path);
    const ordered_json kind = query_schema(c.path, "kind"), format = query_schema(c.path, "format");
    EXPECT_EQ(names(kind), c.kinds);
    EXPECT_EQ(kind.value("default", ""), c.default_kind);
    EXPECT_EQ(names(format), moreau::scene::figure_names<FigureFormat>());
    EXPECT_EQ(format.value("default", ""), moreau::scene::figure_name(moreau::scene::default_figure<FigureFormat>()));
  }
}

TEST(ServerRoutes, RouterAndAllowMatchTheSamePaths) {
  const std::vector<Operation> doc = documented();
  const std::vector<std::string> values = {"0123456789abcdef0123456789abcdef", "manipulator", "x.y"};
  for (const Route& r : api_routes()) {
    const std::regex router(route_regex(r.path));
    for (const std::string& v : values) {
      const std::string path = concrete(r.path, v);
      SCOPED_TRACE(path);
      EXPECT_TRUE(path_matches(path, r.path));
      EXPECT_TRUE(std::regex_match(path, router));
      // The Allow header: the methods the document gives the path, HEAD wherever GET is, and OPTIONS.
      std::set<std::string> methods;
      for (const Operation& o : doc)
        if (o.path == r.path) methods.insert(o.method);
      std::string allow = methods.count("GET") ? "GET, HEAD, " : "";
      if (methods.count("POST")) allow += "POST, ";
      if (methods.count("DELETE")) allow += "DELETE, ";
      EXPECT_EQ(allowed_methods(path), allow + "OPTIONS");
    }
    // Near misses: neither matcher takes them, for any route.
    for (const std::string& miss :
         {concrete(r.path, "") + "/", concrete(r.path, "a") + "/extra/more/deeper", "/x" + concrete(r.path, "a")}) {
      SCOPED_TRACE(miss);
      for (const Route& other : api_routes()) {
        EXPECT_FALSE(path_matches(miss, other.path)) << other.path;
        EXPECT_FALSE(std::regex_match(miss, std::regex(route_regex(other.path)))) << other.path;
      }
      EXPECT_EQ(allowed_methods(miss), "");
    }
  }
  // A dot in a path is a dot, not any character; an empty segment is no id.
  for (const char* miss : {"/v1/openapiXjson", "/ui/appXjs", "/v1/jobs//events", "/v1/jobs/", ""}) {
    SCOPED_TRACE(miss);
    for (const Route& r : api_routes()) {
      EXPECT_FALSE(path_matches(miss, r.path)) << r.path;
      EXPECT_FALSE(std::regex_match(std::string(miss), std::regex(route_regex(r.path)))) << r.path;
    }
  }
}

}  // namespace
