// shadowcull plan SPACE --shards N --plan DIR: the space scanned once for a sharded bake
// (docs/cluster.md). Each shard then reads the plan and only the chunks its windows hold
// (bake --shard K/N --plan DIR), so its start-up no longer grows with the world.
#pragma once

#include <string>
#include <vector>

#include "io/space_source.h"
#include "util/status.h"

namespace shadowcull::cli {

struct PlanOptions {
    std::string spaceDir;
    std::string resourceRoot;  // --res
    std::string planDir;       // where plan.json and shard-K-of-N.json go
    int shards = 0;
    int threads = 0;           // 0: all cores (the scan loads a chunk's resources in parallel)
    ScanProgress onScanned;
};

// What `plan` made, for its summary line.
struct PlanSummary {
    size_t chunks = 0;
    std::vector<Diagnostic> diagnostics;  // every warning of reading the space (the shards carry them too)
    size_t largestShardChunks = 0;   // chunks the busiest shard bakes
    size_t largestWindowChunks = 0;  // chunks the largest shard file summarises
    double seconds = 0;
};

// Scans the space, partitions it (cli/shard.h) and writes the plan. Errors: the scan's
// (BadInput...), an output that is one of the inputs (BadInput), Io.
Expected<PlanSummary> makePlan(const PlanOptions& opt);

}  // namespace shadowcull::cli
