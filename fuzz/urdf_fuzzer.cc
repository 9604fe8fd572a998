// Fuzzes URDF text: any bytes must be read as a robot or refused with a UrdfError, never crash, hang or
// recurse without bound. And a differential check of the guard in front of the recursive parsers: when
// check_xml_shape (Expat, xml_shape.h) accepts a text, the tree TinyXML builds from it (TinyXML recurses
// once per level, and urdfdom parses with it) is measured here without recursion and must be no deeper,
// and have no more elements, than the guard allows.
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <tinyxml.h>

#include "moreau/scene/urdf.h"
#include "xml_shape.h"

namespace {

// Depth and element count of TinyXML's tree, by an explicit stack.
std::pair<int, std::size_t> tinyxml_shape(const TiXmlNode& root) {
  int depth = 0;
  std::size_t elements = 0;
  std::vector<std::pair<const TiXmlNode*, int>> stack{{&root, 0}};
  while (!stack.empty()) {
    const auto [node, level] = stack.back();
    stack.pop_back();
    const int here = level + (node->ToElement() ? 1 : 0);
    if (node->ToElement()) ++elements;
    if (here > depth) depth = here;
    for (const TiXmlNode* c = node->FirstChild(); c; c = c->NextSibling()) stack.emplace_back(c, here);
  }
  return {depth, elements};
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace moreau::scene;
  const std::string text(reinterpret_cast<const char*>(data), size);
  bool accepted = true;
  try {
    (void)detail::check_xml_shape(text);
  } catch (const detail::XmlShapeError&) {
    accepted = false;
  }
  if (accepted) {
    TiXmlDocument doc;
    doc.Parse(text.c_str(), nullptr, TIXML_ENCODING_UTF8);
    const auto [depth, elements] = tinyxml_shape(doc);
    if (depth > detail::kMaxXmlDepth || elements > detail::kMaxXmlElements) __builtin_trap();
  }
  try {
    (void)read_urdf(text);
  } catch (const UrdfError&) {
  }
  return 0;
}
