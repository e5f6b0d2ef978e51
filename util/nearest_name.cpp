#include "util/nearest_name.h"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <vector>

namespace shadowcull {

namespace {

bool sameLetter(char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
}

}  // namespace

size_t editDistance(std::string_view a, std::string_view b) {
    // Optimal string alignment: Levenshtein plus the swap of two neighbours, the commonest
    // typing slip. Three rows of the table suffice.
    std::vector<size_t> before(b.size() + 1), previous(b.size() + 1), current(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j) previous[j] = j;
    for (size_t i = 1; i <= a.size(); ++i) {
        current[0] = i;
        for (size_t j = 1; j <= b.size(); ++j) {
            const size_t replace = previous[j - 1] + (sameLetter(a[i - 1], b[j - 1]) ? 0 : 1);
            current[j] = std::min({previous[j] + 1, current[j - 1] + 1, replace});
            if (i > 1 && j > 1 && sameLetter(a[i - 1], b[j - 2]) && sameLetter(a[i - 2], b[j - 1]))
                current[j] = std::min(current[j], before[j - 2] + 1);
        }
        std::swap(before, previous);
        std::swap(previous, current);
    }
    return previous[b.size()];
}

std::string nearestName(std::string_view given, const std::vector<std::string>& known) {
    std::string best;
    size_t bestDistance = SIZE_MAX;
    for (const std::string& name : known)
        if (const size_t d = editDistance(given, name); d < bestDistance) best = name, bestDistance = d;
    return best;
}

bool looksLikeMisspelling(std::string_view given, std::string_view known) {
    const size_t d = editDistance(given, known);
    return d <= 2 && 2 * d < std::max(given.size(), known.size());
}

}  // namespace shadowcull
