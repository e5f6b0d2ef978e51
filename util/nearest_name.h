// "Did you mean ...?": the known name nearest to a mistyped one, for messages about an
// unknown element (<filterRadious>) or an unknown command (frobnicate).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace shadowcull {

// Edits (insert, delete, replace, swap two neighbours) that turn `a` into `b`, ignoring
// case: "filterRadious" is 1 from "filterRadius", "ligth" 1 from "light".
size_t editDistance(std::string_view a, std::string_view b);

// The name of `known` nearest to `given` by editDistance (the first of equals).
std::string nearestName(std::string_view given, const std::vector<std::string>& known);

// Whether `given` is near enough to `known` to be its misspelling: at most 2 edits, and
// fewer than half its letters (so "lod" is not taken for "row0").
bool looksLikeMisspelling(std::string_view given, std::string_view known);

}  // namespace shadowcull
