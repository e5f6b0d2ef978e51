// Fuzz target: results JSON files as `shadowcull diff` reads them. The reader is internal
// to cli/diff.cpp, so the whole command runs (runDiff), with the HTML and JSON reports
// written too (they format what was read). Input: old.json, then new.json, split by
// kFuzzSeparator (fuzz_support.h); without a second part both sides are the same file.

#include <sstream>

#include "cli/diff.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 2);
    if (parts.size() == 1) parts.push_back(parts[0]);
    const std::vector<std::string> paths = writeFiles(parts, {"old.json", "new.json"});
    std::ostringstream out, err;
    (void)shadowcull::cli::runDiff({paths[0], paths[1], scratchDir() + "/report.html", scratchDir() + "/report.json"},
                                   out, err);
    return 0;
}
