// shadowcull merge OUT.json SHARD_RESULTS...: the results files of the shards of one bake
// (bake --shard K/N --results) joined into the file a single bake of the whole space with
// the same options writes, byte for byte. Read and written by io/results_file.h (and
// io/results_stream.h, which reads a shard's file an object at a time) only.
#pragma once

#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "io/results_file.h"

namespace shadowcull::cli {

// Exit codes of merge besides 0 (merged), 2 (usage), 3 (a file unreadable, malformed, or
// not a shard's results) and 4 (OUT cannot be written); docs/cli.md.
enum MergeExitCode : int {
    kExitShardsDiffer = 7,      // the shards are of different bakes: inputs, options, space or N
    kExitShardsIncomplete = 8,  // a shard or chunk is missing, or given twice
};

struct MergeOptions {
    std::string outPath;
    std::vector<std::string> shardPaths;
};

// What merging found: the merged file, or the exit code and message of the refusal.
struct MergeOutcome {
    results::ResultsFile merged;
    int exitCode = 0;
    std::string message;  // empty when merged
};

// Joins shards already read ({path, file}; paths only for messages). Refused: a file that
// is not a shard's (exit 3), shards of different bakes (7), a shard missing or given twice,
// a chunk in two shards or in none, a chunk of a shard without results that no warning of
// that shard explains (8). Chunks in grid order, summary counted from them, the space's
// warnings once and then each shard's own warnings (ordered by the chunk they name).
MergeOutcome mergeShards(const std::vector<std::pair<std::string, results::ResultsFile>>& shards);

// The command: reads every shard, merges, writes OUT atomically (never one of the inputs).
int runMerge(const MergeOptions& options, std::ostream& out, std::ostream& err);

}  // namespace shadowcull::cli
