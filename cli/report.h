// What a bake reports: the terminal summary and the results JSON (--results).
#pragma once

#include <string>


#include "cli/pipeline.h"
#include "core/results_file.h"
#include "core/savings.h"

namespace shadowcull::cli {

struct BitCounts {
    uint64_t groups = 0, bits = 0;
    uint64_t kept = 0, culled = 0;         // bits written 1 / 0
    uint64_t provedKept = 0;               // 1 with a witness
    uint64_t undecided = 0;                // 1 because nobody could decide
    std::map<std::string, uint64_t> culledBy;  // stage -> bits proved 0
    std::map<std::string, uint64_t> keptBy;    // stage -> bits kept with evidence
};

BitCounts countBits(const BakeResult& r);

// The shadow-pass savings of a bake (core/savings.h), per light, for the world and per
// chunk (in r.chunks order), from the groups' placed triangles.
savings::Tally tallyBake(const BakeResult& r);

// The effects the bake simulated (semantics.md: "the bake says which it simulated"): each
// effect of the chunks' `simulated` lists once, with how many chunks it applied to when not
// all. One line per effect after "simulated:".
std::string formatSimulated(const std::vector<ChunkVerdicts>& chunks);

// The summary printed at the end of a bake (plain text, deterministic but for the times).
std::string formatSummary(const BakeResult& r, bool wrote);

// The results file (--results) of a bake: per chunk, object, group and light, the bit, the
// deciding stage and its evidence; written by results::writeResults. Deterministic for the
// same input: chunks in grid order, objects in document order (the writer prints doubles in
// shortest round-trip form).
results::ResultsFile resultsFile(const BakeResult& r);

// One baked chunk as the results file lists it (what --resume keeps for a later bake).
results::ChunkRecord chunkRecord(const ChunkVerdicts& cv);


}  // namespace shadowcull::cli
