// Fuzz target: results JSON files as `shadowcull diff` reads them. The reader is
// io/results_file.h (parseResults), the one reader of the format; the whole command runs
// (runDiff), with the HTML and JSON reports written too (they format what was read). Each
// file that parses must also survive the writer: written, parsed again and written again,
// it gives the same bytes (merge and export will rewrite what they read). Input: old.json,
// then new.json, split by kFuzzSeparator (fuzz_support.h); without a second part both
// sides are the same file. The streamed reader merge uses (streamResultsFile) must agree
// with the whole-file reader on every file it accepts: the same chunks and the same rest.

#include <cstdlib>
#include <sstream>

#include "cli/diff.h"
#include "fuzz/fuzz_support.h"
#include "io/results_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 2);
    if (parts.size() == 1) parts.push_back(parts[0]);
    for (const std::string& part : parts) {
        const shadowcull::Expected<shadowcull::results::ResultsFile> file =
            shadowcull::results::parseResults("fuzz.json", part);
        if (!file) continue;
        const std::string once = shadowcull::results::writeResults(*file);
        const shadowcull::Expected<shadowcull::results::ResultsFile> again =
            shadowcull::results::parseResults("written.json", once);
        if (!again || shadowcull::results::writeResults(*again) != once) std::abort();  // the writer lost something
    }
    const std::vector<std::string> paths = writeFiles(parts, {"old.json", "new.json"});
    for (const std::string& path : paths) {
        namespace results = shadowcull::results;
        std::vector<results::ChunkRecord> chunks;
        const auto streamed = results::streamResultsFile(path, [&](results::ChunkRecord& c) {
            chunks.push_back(c);
            return shadowcull::Status::ok();
        });
        if (!streamed || !*streamed) continue;
        const auto whole = results::readResultsFile(path);
        if (!whole) std::abort();  // streamed what the whole-file reader refuses
        results::ResultsFile fromStream = **streamed;
        fromStream.chunks = std::move(chunks);
        // Without a "summary" the whole-file reader counts the chunks, the stream none.
        fromStream.summary = whole->summary;
        if (results::writeResults(fromStream) != results::writeResults(*whole)) std::abort();  // they disagree
    }
    std::ostringstream out, err;
    (void)shadowcull::cli::runDiff({paths[0], paths[1], scratchDir() + "/report.html", scratchDir() + "/report.json"},
                                   out, err);
    return 0;
}
