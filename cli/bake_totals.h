// What a bake counts as it goes (the summary's figures): a bake that keeps no chunk's
// verdicts (BakeOptions::keepVerdicts false: memory follows the window) still prints
// every count, the savings table and the effects it simulated.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cli/savings.h"
#include "core/verdict.h"

namespace shadowcull::cli {

struct BitCounts {
    uint64_t groups = 0, bits = 0;
    uint64_t kept = 0, culled = 0;         // bits written 1 / 0
    uint64_t provedKept = 0;               // 1 with a witness
    uint64_t undecided = 0;                // 1 because nobody could decide
    std::map<std::string, uint64_t> culledBy;  // stage -> bits proved 0
    std::map<std::string, uint64_t> keptBy;    // stage -> bits kept with evidence
};

// The figures of the chunks baked so far (not those --resume skipped).
struct BakeTotals {
    BakeTotals() : savings(0) {}
    explicit BakeTotals(size_t lights) : savings(lights) {}
    size_t chunks = 0;
    BitCounts bits;
    savings::Tally savings;  // the world's figures only (no per-chunk list)
    // Each effect the chunks simulated, with how many chunks it applied to, in the order
    // first met.
    std::vector<std::pair<std::string, size_t>> simulated;

    // Counts one more baked chunk.
    void add(const ChunkVerdicts& chunk);
};

// Adds every bit of a baked chunk to `tally` (its groups' placed triangles, classified by
// verdict, stage and reason): what the summary's savings table counts.
void tallyVerdicts(savings::Tally& tally, const ChunkVerdicts& chunk);

}  // namespace shadowcull::cli
