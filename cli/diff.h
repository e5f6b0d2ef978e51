// `shadowcull diff OLD NEW`: a regression report between two bakes. Each side is a results
// JSON file (`bake --results`) or a baked space directory (then only the <shadow> masks of
// its chunk files are known, no evidence). Compares per chunk, object (uuid, else element
// index), group and light, and reports changed bits with the evidence on each side,
// verdict-only changes (same bit, other verdict or stage), objects and lights added,
// removed or renamed.
#pragma once

#include <iosfwd>
#include <string>

namespace shadowcull::cli {

struct DiffOptions {
    std::string oldPath, newPath;  // results JSON file or baked space directory
    std::string htmlPath;          // empty: no HTML report
    std::string jsonPath;          // empty: no machine-readable report
};

// Exit codes of runDiff (a CI gate): nothing changed, something changed. Bad input is
// kExitBadInput (3) and a report that cannot be written kExitIo (4), as for `bake`.
constexpr int kDiffSame = 0;
constexpr int kDiffChanged = 1;

// Reads both sides, prints the text summary to `out` (errors to `err`), writes the HTML
// and JSON reports when asked. Output is deterministic: paths are printed as given.
int runDiff(const DiffOptions& options, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
