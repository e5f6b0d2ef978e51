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
#include "core/status.h"

namespace shadowcull::cli {

struct BakeOptions;

// Hash of everything the bake of chunk `centre` reads. `meshHashes` caches per mesh and
// heightfield across chunks.
uint64_t windowInputHash(const Space& space, ChunkCoord centre, const BakeOptions& options,
                         std::unordered_map<const void*, uint64_t>& meshHashes);

// Hash of everything a bake of the whole space reads (the settings and lights, the options
// that change verdicts, the space directory as given, every chunk's objects, mesh content
// and file bytes): the shards of one bake must agree on it (bake --shard, merge).
uint64_t spaceInputHash(const Space& space, const BakeOptions& options,
                        std::unordered_map<const void*, uint64_t>& meshHashes);

class ResumeState {
public:
    // The state's file in `dir`; a shard (bake --shard K/N) has its own, named after K and N.
    static std::string nameFor(int shardIndex = 0, int shardCount = 0);
    static std::string pathIn(const std::string& dir, int shardIndex = 0, int shardCount = 0);
    // A missing or unreadable state means "nothing is up to date" (never an error: the
    // worst case is baking again).
    void load(const std::string& path);
    // `needResults`: the bake writes a results file, so the chunk's part of it must have
    // been recorded too (a chunk baked without --results is baked again).
    bool upToDate(const std::string& chunk, uint64_t inputHash, const std::string& currentBytes,
                  bool needResults = false) const;
    // The chunk's part of the results file as recorded (results::chunkJson), or empty.
    const std::string& results(const std::string& chunk) const;
    void record(const std::string& chunk, uint64_t inputHash, const std::string& writtenBytes,
                std::string resultsJson = {});
    Status save(const std::string& path) const;

private:
    struct Entry {
        uint64_t input = 0, output = 0;
        std::string results;  // results::chunkJson of the chunk; empty: baked without --results
    };
    std::map<std::string, Entry> entries_;
};

}  // namespace shadowcull::cli
