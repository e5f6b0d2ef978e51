// A sharded bake's plan (shadowcull plan, docs/cluster.md): the space scanned once, its
// chunks partitioned among N shards, and for each shard what its bake needs to know without
// reading the rest of the world. A directory of JSON files:
//
//   plan.json             the space's outline (chunk count, content, listing and settings
//                         hashes, bounds for planning windows), its warnings, the chunks
//                         per shard
//   shard-K-of-N.json     shard K's chunks, and the summaries of every chunk its windows
//                         hold (analytic windows and the `neighbours` rectangles both)
//   inputs.json           every input besides space.xml and the chunk files (resources
//                         and the files behind them): read by a shard only when one of its
//                         outputs already exists, since only then can it be an input
//
// A shard reads plan.json and its own file: its start-up follows its windows, not the world
// (but for the warnings of reading the space, and the names of the chunk files it lists).
// Each shard and inputs file names plan.json's hash, so files of two plans are never mixed. Doubles
// are written in the shortest form that reads back to the same bits (nlohmann/json).
#pragma once

#include <string>
#include <vector>

#include "core/scene.h"
#include "io/space_source.h"
#include "util/status.h"

namespace shadowcull {

struct ShardPlanFiles {
    static std::string planPath(const std::string& dir);
    static std::string shardPath(const std::string& dir, int index, int count);
    static std::string inputsPath(const std::string& dir);
};

// plan.json.
struct PlanHead {
    std::string spaceDir;                     // as given to `plan` (named in messages)
    int shards = 0;
    SpaceOutline outline;
    std::vector<Diagnostic> diagnostics;      // every warning of reading the space
    std::vector<size_t> shardChunks;          // how many chunks each shard bakes
    uint64_t id = 0;                          // hash of plan.json's bytes (set by readShardPlan)
};

// shard-K-of-N.json.
struct PlanShard {
    int index = 0, count = 0;                 // K of N
    std::vector<ChunkCoord> assigned;         // the chunks it bakes, in grid order
    std::map<ChunkCoord, ChunkEntry> chunks;  // every chunk its windows hold (contentHash unset)
};

// Writes the plan into `dir` (created if missing): the shard files first, plan.json last,
// each atomically. Io errors name the file.
// `resourceFiles`: every input besides space.xml and the chunk files (inputs.json).
Status writeShardPlan(const std::string& dir, const PlanHead& head, const std::vector<PlanShard>& shards,
                      const std::vector<std::string>& resourceFiles);

// Reads plan.json and shard K of N. BadInput for a file that is not a plan's (file named),
// StalePlan when the shard file belongs to another plan.json, MissingResource when a file
// is missing; a plan for another shard count is BadInput with both counts named.
struct LoadedShardPlan {
    PlanHead head;
    PlanShard shard;
};
Expected<LoadedShardPlan> readShardPlan(const std::string& dir, int index, int count);

// inputs.json of the plan in `dir` whose plan.json has hash `planId`; StalePlan when it
// belongs to another plan.
Expected<std::vector<std::string>> readPlanInputs(const std::string& dir, uint64_t planId);

// What a shard's SpaceSource takes from its plan in `dir` (SpaceSource::planned).
PlannedSpace plannedSpaceOf(const std::string& dir, LoadedShardPlan&& plan);

}  // namespace shadowcull
