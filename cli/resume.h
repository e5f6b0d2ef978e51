// bake --resume: which chunks a previous bake already wrote for the same inputs.
//
// A chunk is up to date when (1) the hash of everything its bake reads is the one recorded:
// the settings and lights, the bake options that change verdicts, and every object of its
// window (placement, flags, and the content of its mesh or heightfield); and (2) its file
// still holds exactly the bytes that bake wrote. The record lives beside the chunk files in
// `.shadowcull-bake-state.json`, rewritten atomically.
#pragma once

#include <map>
#include <string>
#include <unordered_map>

#include "core/scene.h"
#include "io/space_source.h"
#include "util/status.h"

namespace shadowcull::cli {

struct BakeOptions;

// Hash of everything the bake of chunk `centre` reads, as the scan of the space found it
// (no chunk needs to be loaded for it).
uint64_t windowInputHash(const SpaceSource& space, ChunkCoord centre, const std::vector<ChunkCoord>& window,
                         const BakeOptions& options);

// Hash of everything a bake of the whole space reads (the settings and lights, the options
// that change verdicts, the space directory as given, every chunk's objects, mesh content
// and file bytes): the shards of one bake must agree on it (bake --shard, merge).
uint64_t spaceInputHash(const SpaceSource& space, const BakeOptions& options);

// The record of what a --resume bake wrote: a journal, one JSON object per line after a
// header line, appended and synced as each chunk is committed, so that a killed bake loses
// nothing it committed and the bake keeps in memory only an index (a chunk's results are
// read back from the file when a later bake skips the chunk).
class ResumeState {
public:
    ResumeState() = default;
    ~ResumeState();
    ResumeState(const ResumeState&) = delete;
    ResumeState& operator=(const ResumeState&) = delete;

    // The state's file in `dir`; a shard (bake --shard K/N) has its own, named after K and N.
    static std::string nameFor(int shardIndex = 0, int shardCount = 0);
    static std::string pathIn(const std::string& dir, int shardIndex = 0, int shardCount = 0);
    // Reads the journal at `path` and opens it for appending. A missing or unreadable
    // journal, or its torn last line (a bake killed while appending), means those chunks are
    // not up to date (the worst case is baking them again). A journal holding older records
    // of a chunk, a torn line or another format is first rewritten with the latest record
    // of each chunk only (atomically). Errors: the journal cannot be written (Io).
    Status open(const std::string& path);
    // `needResults`: the bake writes a results file, so the chunk's part of it must have
    // been recorded too (a chunk baked without --results is baked again).
    bool upToDate(const std::string& chunk, uint64_t inputHash, const std::string& currentBytes,
                  bool needResults = false) const;
    // The chunk's part of the results file as recorded (results::chunkJson), or empty.
    std::string results(const std::string& chunk) const;
    // Appends the chunk's record and syncs it.
    Status record(const std::string& chunk, uint64_t inputHash, const std::string& writtenBytes,
                  const std::string& resultsJson = {});
    size_t size() const { return entries_.size(); }

private:
    struct Entry {
        uint64_t input = 0, output = 0;
        bool hasResults = false;          // baked with --results
        uint64_t offset = 0, length = 0;  // its line in the journal
    };
    std::map<std::string, Entry> entries_;
    std::string path_;
    int fd_ = -1;
    uint64_t size_ = 0;
};

}  // namespace shadowcull::cli
