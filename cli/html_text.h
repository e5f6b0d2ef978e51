// Text in the self-contained HTML pages the commands write (diff --html, report --html).
#pragma once

#include <string>

namespace shadowcull::cli {

// `s` with the five characters HTML treats specially replaced by entities: safe in text and
// in quoted attribute values.
inline std::string htmlEscape(const std::string& s) {
    std::string o;
    o.reserve(s.size());
    for (char ch : s) {
        switch (ch) {
            case '&': o += "&amp;"; break;
            case '<': o += "&lt;"; break;
            case '>': o += "&gt;"; break;
            case '"': o += "&quot;"; break;
            case '\'': o += "&#39;"; break;
            default: o += ch;
        }
    }
    return o;
}

}  // namespace shadowcull::cli
