// Fuzz target: results JSON files as `shadowcull diff` reads them. The reader is
// io/results_file.h (parseResults), the one reader of the format; the whole command runs
// (runDiff), with the HTML and JSON reports written too (they format what was read). Each
// file that parses must also survive the writer: written, parsed again and written again,
// it gives the same bytes (merge and export will rewrite what they read). Input: old.json,
// then new.json, split by kFuzzSeparator (fuzz_support.h); without a second part both
// sides are the same file. The streamed reader merge uses (streamResultsFile, one object at
// a time) must agree with the whole-file reader on every file it accepts: the same chunks
// and the same rest; and it must accept the writer's own text of every file with chunks.

#include <cstdlib>
#include <sstream>

#include "cli/diff.h"
#include "fuzz/fuzz_support.h"
#include "io/results_file.h"
#include "io/results_stream.h"

namespace {

namespace results = shadowcull::results;

// The streamed reader (one chunk, one object at a time: what merge reads through) agrees
// with the whole-file reader on the file at `path`, or leaves it to it; `mustStream`: the
// file is the writer's own text with chunks, which it must read.
void checkStreamed(const std::string& path, bool mustStream) {
    std::vector<results::ChunkRecord> chunks;
    const auto streamed = results::streamResultsFile(path, [&](results::ChunkRecord& c) {
        chunks.push_back(c);
        return shadowcull::Status::ok();
    });
    if (!streamed) std::abort();  // no part refuses: an error can only be a part's
    if (!*streamed) {
        if (mustStream) brokenPromise("the streamed reader left the writer's own text to the whole-file reader");
        return;
    }
    const auto whole = results::readResultsFile(path);
    if (!whole) std::abort();  // streamed what the whole-file reader refuses
    results::ResultsFile fromStream = **streamed;
    fromStream.chunks = std::move(chunks);
    // Without a "summary" the whole-file reader counts the chunks, the stream none.
    fromStream.summary = whole->summary;
    if (results::writeResults(fromStream) != results::writeResults(*whole)) std::abort();  // they disagree
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 2);
    if (parts.size() == 1) parts.push_back(parts[0]);
    std::vector<std::string> written;  // what the writer made of each part that parses
    for (const std::string& part : parts) {
        const shadowcull::Expected<results::ResultsFile> file = results::parseResults("fuzz.json", part);
        if (!file) continue;
        const std::string once = results::writeResults(*file);
        const shadowcull::Expected<results::ResultsFile> again = results::parseResults("written.json", once);
        if (!again || results::writeResults(*again) != once) std::abort();  // the writer lost something
        if (!file->chunks.empty()) written.push_back(once);
    }
    const std::vector<std::string> paths = writeFiles(parts, {"old.json", "new.json"});
    for (const std::string& path : paths) checkStreamed(path, false);
    const std::vector<std::string> writtenPaths = writeFiles(written, {"written-old.json", "written-new.json"});
    for (size_t k = 0; k < written.size(); ++k) checkStreamed(writtenPaths[k], true);
    std::ostringstream out, err;
    (void)shadowcull::cli::runDiff({paths[0], paths[1], scratchDir() + "/report.html", scratchDir() + "/report.json"},
                                   out, err);
    return 0;
}
