// What a bake's masks remove from each light's shadow pass, in the engine's units: casters
// (primitive groups, one draw each) and their placed triangles, split by why:
//   (a) engineCulls: what the engine's own run-time culling already skips (castsShadow
//       false, the group beyond a point or spot light's range, outside a spot's cone: the
//       reach stage, core/reach_stage.cpp with core/light_reach.h, decides exactly these);
//   (b) bakeCulls: what only this bake removes (proved hidden, proved to fall on nothing,
//       a group without a triangle that has area), to be read against the work left after (a);
//   undecided: written 1 without a proof, the savings still left on the table.
// One tally serves the bake (its summary and results JSON, cli/report.cpp) and `shadowcull
// report` (a results file with the triangles counted in the space, cli/savings_report.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/verdict.h"
#include "io/results_file.h"

namespace shadowcull::results {
// Work added and taken away (found by argument-dependent lookup wherever records are used).
WorkRecord operator-(const WorkRecord& a, const WorkRecord& b);
WorkRecord& operator+=(WorkRecord& a, const WorkRecord& b);
}  // namespace shadowcull::results

namespace shadowcull::savings {

using results::LightSavingsRecord;
using results::ResultsFile;
using results::WorkRecord;

// The reach stage's reason for a caster the engine never draws into a shadow map
// (core/verdict.h), which the classification below counts as the engine's cull.
using reasons::kCastsShadowFalse;

enum class Why : uint8_t {
    EngineCulls,  // (a)
    BakeCulls,    // (b)
    ProvedKept,   // 1 with a witness
    Undecided,    // 1 without a proof
};

// A bit's class from its verdict ("culled", "kept", "undecided"), deciding stage and reason
// (as the results file and core/verdict.h name them). Culled by the reach stage, or by the
// input check for castsShadow false: (a); culled by anything else (the input check for a
// group without a triangle of area, raycast, geometry, gpu, the original GPU method): (b).
Why classify(std::string_view verdict, std::string_view stage, std::string_view reason);

// Left in the pass after the engine's culling (all - (a)); after the bake too (- (b)).
inline WorkRecord afterEngine(const LightSavingsRecord& s) { return s.all - s.engineCulls; }
inline WorkRecord afterBake(const LightSavingsRecord& s) { return s.all - s.engineCulls - s.bakeCulls; }

// Adds up the bits of a bake, chunk by chunk; every chunk's figures add to the world's.
class Tally {
public:
    explicit Tally(size_t lights);
    // Starts the figures of one more chunk (the bits added next are its).
    void beginChunk();
    // One (group, light) bit: `light` from 0; `triangles` the group's placed triangles.
    void add(size_t light, Why why, std::string_view stage, uint64_t triangles);
    // One chunk of a results file, from its groups' `triangles` (as tallyResults counts it).
    void addChunk(const results::ChunkRecord& chunk);
    // One object of the chunk last begun (addChunk, an object at a time).
    void addObject(const results::ObjectRecord& object);
    // The figures of the last chunk begun, removed from chunks() (a bake that streams its
    // results file keeps only the world's figures).
    std::vector<LightSavingsRecord> takeLastChunk();
    const std::vector<LightSavingsRecord>& world() const { return world_; }
    // Per chunk, in the order begun.
    const std::vector<std::vector<LightSavingsRecord>>& chunks() const { return chunks_; }

private:
    std::vector<LightSavingsRecord> world_;
    std::vector<std::vector<LightSavingsRecord>> chunks_;
};

// The tally of a results file from its groups' `triangles` (a group without them counts 0
// triangles; `shadowcull report` fills them in from the space first). Skipped objects have
// no verdicts and count nowhere.
Tally tallyResults(const ResultsFile& file);

}  // namespace shadowcull::savings
