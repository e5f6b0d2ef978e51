// tinyxml2's own error text ("Error=XML_ERROR_PARSING_ELEMENT ErrorID=6 (0x6) Line
// number=11: XMLElement name=fi") names the parser's enum, not the user's mistake: every
// reader turns a parse failure into one plain sentence with this.
#pragma once

#include <string>

namespace tinyxml2 {
class XMLDocument;
}

namespace shadowcull {

// What is wrong with the XML `doc` failed to parse, in a user's words, e.g. "not
// well-formed XML: the element <fi> is cut off or not closed (a missing '>' or end tag?)".
// The line is the document's ErrorLineNum() (0 for an empty file); the caller names it.
std::string xmlParseProblem(const tinyxml2::XMLDocument& doc);

}  // namespace shadowcull
