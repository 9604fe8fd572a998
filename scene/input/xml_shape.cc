// check_xml_shape (xml_shape.h): one pass of Expat, a non-recursive parser, with depth and element
// counters in its callbacks.
#include "xml_shape.h"

#include <expat.h>

#include <climits>
#include <memory>

namespace moreau::scene::detail {
namespace {

struct State {
  XML_Parser parser;
  int max_depth;
  std::size_t max_elements;
  int depth = 0;
  XmlShape shape;
  std::string refusal;  // set when a callback stopped the parser
};

std::string at_line(XML_Parser p) { return "line " + std::to_string(XML_GetCurrentLineNumber(p)); }

void stop(State& s, std::string why) {
  s.refusal = std::move(why);
  XML_StopParser(s.parser, XML_FALSE);
}

void XMLCALL on_start(void* data, const XML_Char*, const XML_Char**) {
  State& s = *static_cast<State*>(data);
  if (!s.refusal.empty()) return;
  ++s.depth;
  ++s.shape.elements;
  if (s.depth > s.shape.depth) s.shape.depth = s.depth;
  if (s.depth > s.max_depth)
    return stop(s, "elements nested deeper than " + std::to_string(s.max_depth) + " levels (" + at_line(s.parser) +
                       "): a URDF nests about 5 deep, and deeper nesting is refused before any parser recurses over it");
  if (s.shape.elements > s.max_elements)
    stop(s, "more than " + std::to_string(s.max_elements) + " XML elements (the next is at " + at_line(s.parser) + ")");
}

void XMLCALL on_end(void* data, const XML_Char*) { --static_cast<State*>(data)->depth; }

// TinyXML reads a processing instruction <?target ...?> (any but the XML declaration) as an unknown node
// that ends at the first '>', where Expat reads on to "?>": elements inside one are markup to TinyXML and
// invisible here, so a PI could hide any nesting from this check (the URDF fuzzer found it). A URDF has
// no use for one: refused.
void XMLCALL on_processing_instruction(void* data, const XML_Char* target, const XML_Char*) {
  State& s = *static_cast<State*>(data);
  stop(s, "a processing instruction <?" + std::string(target).substr(0, 40) + " ...?> (" + at_line(s.parser) +
              "): processing instructions are not accepted in a URDF");
}

void XMLCALL on_doctype(void* data, const XML_Char*, const XML_Char*, const XML_Char*, int) {
  State& s = *static_cast<State*>(data);
  stop(s, "a DOCTYPE declaration (" + at_line(s.parser) + "): DOCTYPE and entity declarations are not accepted in a URDF");
}

}  // namespace

XmlShape check_xml_shape(std::string_view text, int max_depth, std::size_t max_elements) {
  if (text.size() > static_cast<std::size_t>(INT_MAX)) throw XmlShapeError("the XML text is larger than 2 GiB");
  // The encoding is fixed to UTF-8, whatever the text declares: the parsers after this one read it so.
  std::unique_ptr<XML_ParserStruct, void (*)(XML_Parser)> parser(XML_ParserCreate("UTF-8"), XML_ParserFree);
  if (!parser) throw XmlShapeError("out of memory while reading the XML text");
  State s{parser.get(), max_depth, max_elements, 0, XmlShape{}, std::string()};
  XML_SetUserData(s.parser, &s);
  XML_SetElementHandler(s.parser, on_start, on_end);
  XML_SetStartDoctypeDeclHandler(s.parser, on_doctype);
  XML_SetProcessingInstructionHandler(s.parser, on_processing_instruction);
  // No external entity is ever read (Expat reads none unless a handler is set; none is).
  const XML_Status status = XML_Parse(s.parser, text.data(), static_cast<int>(text.size()), XML_TRUE);
  if (!s.refusal.empty()) throw XmlShapeError(s.refusal);
  if (status != XML_STATUS_OK)
    throw XmlShapeError("malformed XML at line " + std::to_string(XML_GetCurrentLineNumber(s.parser)) + ", column " +
                        std::to_string(XML_GetCurrentColumnNumber(s.parser) + 1) + ": " + XML_ErrorString(XML_GetErrorCode(s.parser)));
  return s.shape;
}

}  // namespace moreau::scene::detail
