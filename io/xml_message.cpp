#include "io/xml_message.h"

#include <tinyxml2.h>

namespace shadowcull {

namespace {

// The element tinyxml2 names after "XMLElement name=" in its error text, or "".
std::string elementNamed(const tinyxml2::XMLDocument& doc) {
    const char* s = doc.ErrorStr();
    const std::string text = s ? s : "";
    const std::string key = "XMLElement name=";
    const size_t at = text.find(key);
    if (at == std::string::npos) return {};
    std::string name = text.substr(at + key.size());
    // An element name has no blanks; anything after one is not part of it.
    if (const size_t end = name.find_first_of(" \t\r\n"); end != std::string::npos) name.resize(end);
    return name;
}

}  // namespace

std::string xmlParseProblem(const tinyxml2::XMLDocument& doc) {
    const std::string name = elementNamed(doc);
    const std::string element = name.empty() ? "an element" : "the element <" + name + ">";
    std::string what;
    switch (doc.ErrorID()) {
        case tinyxml2::XML_ERROR_PARSING_ELEMENT:
            what = element + " is cut off or not closed (a missing '>' or end tag?)";
            break;
        case tinyxml2::XML_ERROR_PARSING_ATTRIBUTE:
            what = "an attribute of " + element + " is malformed (write name=\"value\", each name once)";
            break;
        case tinyxml2::XML_ERROR_PARSING_TEXT: what = "text that is not XML (a stray '<' or '&'?)"; break;
        case tinyxml2::XML_ERROR_PARSING_CDATA: what = "a <![CDATA[ section is not closed with ]]>"; break;
        case tinyxml2::XML_ERROR_PARSING_COMMENT: what = "a comment <!-- is not closed with -->"; break;
        case tinyxml2::XML_ERROR_PARSING_DECLARATION: what = "the <?xml ... ?> declaration is not closed with ?>"; break;
        case tinyxml2::XML_ERROR_PARSING_UNKNOWN: what = "a <! ... > construct is not closed"; break;
        case tinyxml2::XML_ERROR_EMPTY_DOCUMENT: return "the file is empty: no XML element in it";
        case tinyxml2::XML_ERROR_MISMATCHED_ELEMENT:
            what = element + " that starts here is closed by an end tag of another name";
            break;
        case tinyxml2::XML_ELEMENT_DEPTH_EXCEEDED:
            what = "elements nested more than " + std::to_string(TINYXML2_MAX_ELEMENT_DEPTH) + " deep";
            break;
        default: what = "an element left open at the end of the file, or a tag that is not XML"; break;
    }
    return "not well-formed XML: " + what;
}

}  // namespace shadowcull
