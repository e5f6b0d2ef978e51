// The files of one bake (docs/cli.md): the output directory's locks, each chunk's new text
// staged in a temporary file beside its target and renamed only once every chunk is baked
// (with --resume: renamed at once and recorded in the resume state), and the results file,
// streamed one chunk at a time and committed after the chunk files. Every chunk file ends
// either as it was or complete.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli/pipeline.h"
#include "io/results_file.h"
#include "io/space_source.h"

namespace shadowcull::cli {

// "; no chunk file was changed" or "; N chunk file(s) were updated before it, each
// completely: a b", for the end of an error's message.
std::string writtenNote(const std::vector<std::string>& committed);

class BakeFiles {
public:
    // `result` receives the warnings and notes about the files, and their counts;
    // `committed` each chunk file renamed, whatever happens after.
    BakeFiles(const BakeOptions& options, BakeResult& result, std::vector<std::string>& committed);
    // Removes the staged chunk files not committed (a stopped bake), before the locks go.
    ~BakeFiles();
    BakeFiles(const BakeFiles&) = delete;
    BakeFiles& operator=(const BakeFiles&) = delete;

    // Before any work: makes --out, refuses an input as --results, takes the output
    // directory's locks (clearing what a killed bake left), and leaves out of `targets` the
    // chunks whose output may not be written (writing nothing: an output that is a symbolic
    // link or an input stops the bake).
    Status prepare(const SpaceSource& source, std::vector<ChunkCoord>& targets);
    // Opens the resume state (--resume) and starts the results file (--results).
    Status open();

    bool resuming() const;       // --resume, writing
    bool wantResults() const;    // --results
    // Where a chunk's bytes go: in place (through a symlink, to its target), or a copy under
    // --out, by name.
    std::string targetOf(const std::string& chunkPath) const;
    // --resume: whether the chunk's file still holds what the last bake wrote for the same
    // inputs (and, with --results, its recorded part of the results, then added).
    Expected<bool> unchanged(const std::string& chunkName, const std::string& target, uint64_t inputHash);
    // The chunk's new text (its <shadow> elements from `verdicts`, every other byte kept),
    // staged; with --resume, committed and recorded at once. A chunk file edited since the
    // scan is not written (a warning).
    Status write(const ChunkFile& chunk, const std::string& chunkName, const std::string& target, uint64_t inputHash,
                 const ChunkVerdicts& verdicts, const std::optional<results::ChunkRecord>& record);
    // Appends the chunk's part to the results file.
    Status addResults(results::ChunkRecord& record);
    // Ends the results file (its tail lists the warnings so far) and syncs it: before any
    // chunk file is renamed.
    Status finishResults();
    // One rename per staged chunk file (each atomic), then the results file's. Not
    // interrupted once begun.
    Status commit();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace shadowcull::cli
