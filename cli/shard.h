// bake --shard K/N: a deterministic partition of a space's chunks into N parts of about
// equal work, so that N processes (a Slurm job array, docs/cluster.md) bake one space
// together, each writing only its own chunk files, and `shadowcull merge` joins their
// results files into the one a single bake would write.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/scene.h"
#include "io/space_source.h"

namespace shadowcull::cli {

struct ShardSpec {
    int index = 0, count = 0;  // K of N, K from 1
};

// "K/N" with 1 <= K <= N <= kMaxShards, plain decimal; nothing for anything else.
inline constexpr int kMaxShards = 100000;
std::optional<ShardSpec> parseShard(const std::string& text);

// Estimated work of baking chunk `c`: its objects (models and terrain that are not
// skipped), each weighing one plus its triangles per kTrianglesPerObject, times the lights
// that may reach its column (conservative reach: a point or spot light counts unless its
// range sphere or cone surely misses the column), plus one so that an empty chunk still
// costs its read and write. Unitless; only ratios matter.
//
// kTrianglesPerObject: calibrated on world R with D's 6 x 6 chunks of scanned rocks (51k-180k
// triangles) in its middle, baked in 4 shards: their CPU times fit 0.44 ms per object plus
// 0.46-0.55 us per triangle, an object weighing about as much as 1,000 triangles. Counting
// objects alone gave the shards holding the rocks 1.59x the mean CPU time (the real map's
// dense chunks: 3.4x).
inline constexpr double kTrianglesPerObject = 1000.0;
double chunkWork(const SpaceSource& space, ChunkCoord c);

// The chunks of each of `count` shards: consecutive runs of the grid order of about equal
// work (a shard's work is within one chunk's of its share at each end), so that a shard's
// windows overlap and it loads each chunk about once. Depends only on the space, so every
// shard computes the same partition.
std::vector<std::vector<ChunkCoord>> partitionChunks(const SpaceSource& space, int count);

}  // namespace shadowcull::cli
