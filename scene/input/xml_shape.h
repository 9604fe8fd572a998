// The shape of an XML text, checked before any parser that recurses over it sees it.
//
// TinyXML (which the URDF module uses to name lines) and urdfdom's parser build their trees by recursion,
// one stack frame per level of element nesting: a URDF string of 40,000 nested elements overflowed the
// stack of the thread that read it and killed the process. JSON's nesting limit never sees it, because the
// nesting is inside a string. So every URDF text first goes through Expat, a parser that keeps its own
// stack on the heap, with callbacks that stop it at the first element deeper than kMaxXmlDepth or beyond
// kMaxXmlElements, and at any DOCTYPE or processing instruction (TinyXML ends a PI at its first '>', Expat
// at "?>", so elements inside one would be seen by one parser and not the other). A text that passes is well-formed XML 1.0 with at most
// those numbers, so the recursive parsers after it nest at most kMaxXmlDepth frames deep (a few kilobytes), on any thread, whatever its
// stack size.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <string_view>

namespace moreau::scene::detail {

// A URDF nests 5 deep (robot, link, visual, geometry, mesh); extensions such as <gazebo><plugin> add a
// few. 64 leaves room, and 64 recursive frames fit on any thread's stack.
inline constexpr int kMaxXmlDepth = 64;
// A 1024-link robot with visuals, collisions and inertials has about 20,000 elements. TinyXML spends about
// 200 bytes per element, so the bound also keeps its memory under about 20 MB.
inline constexpr std::size_t kMaxXmlElements = 100'000;

class XmlShapeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct XmlShape {
  int depth = 0;             // deepest element nesting (the document element is depth 1)
  std::size_t elements = 0;  // elements in the whole document
};

// Parses `text` (UTF-8) as XML 1.0 and returns its shape, or throws XmlShapeError naming the line:
// malformed XML, nesting deeper than max_depth, more than max_elements elements, a DOCTYPE (a document
// type declaration, and with it every entity declaration, is not accepted), or a processing instruction
// (the XML declaration <?xml version="1.0"?> is not one, and is accepted).
XmlShape check_xml_shape(std::string_view text, int max_depth = kMaxXmlDepth, std::size_t max_elements = kMaxXmlElements);

}  // namespace moreau::scene::detail
