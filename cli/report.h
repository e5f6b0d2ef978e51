// What a bake reports: the terminal summary and the results JSON (--results).
#pragma once

#include <string>


#include "cli/pipeline.h"
#include "cli/savings.h"
#include "io/results_file.h"

namespace shadowcull::cli {

// The bits of the chunks baked (BakeResult::totals; not those --resume skipped).
BitCounts countBits(const BakeResult& r);

// The shadow-pass savings of a bake (cli/savings.h), per light, for the world and per
// chunk (in r.chunks order: the bake must have kept its verdicts), from the groups' placed
// triangles.
savings::Tally tallyBake(const BakeResult& r);

// The effects the bake simulated (semantics.md: "the bake says which it simulated"): each
// effect of the chunks' `simulated` lists once, with how many chunks it applied to when not
// all. One line per effect after "simulated:".
std::string formatSimulated(const BakeTotals& totals);
// How far the analytic bake's windows reached past the `neighbours` rectangle, per light
// ("" for a bake that planned no windows: the original method).
std::string formatReach(const ReachTotals& reach, const SpaceSettings& settings);
// One window (explain): how many chunks it held, and per light the chunks past the
// `neighbours` rectangle that its shadows and occluders took it to.
std::string formatWindow(const WindowPlan& plan, const SpaceSettings& settings);

// The summary printed at the end of a bake (plain text, deterministic but for the times).
std::string formatSummary(const BakeResult& r, bool wrote);

// The results file (--results) of a bake: per chunk, object, group and light, the bit, the
// deciding stage and its evidence; written by results::writeResults. Deterministic for the
// same input: chunks in grid order, objects in document order (the writer prints doubles in
// shortest round-trip form). From the verdicts the bake kept (BakeOptions::keepVerdicts)
// and the records of the chunks --resume skipped; the bake itself streams the same bytes
// through a ResultsBuilder.
results::ResultsFile resultsFile(const BakeResult& r);

// A results file built one chunk at a time, in grid order: each chunk gets its savings and
// is counted into the summary as it is added, so that the bake can write it and let it go.
class ResultsBuilder {
public:
    explicit ResultsBuilder(const SpaceSettings& settings);
    // The lights as a results file lists them already (merge).
    explicit ResultsBuilder(std::vector<results::LightRecord> lights);
    // Fills `chunk.savings` and counts it.
    void add(results::ChunkRecord& chunk);
    // add() an object at a time, for a writer that holds one (merge): beginChunk(), then
    // addObject() for each object of the chunk, then endChunk(chunk) with the chunk without
    // its objects, which fills its savings and counts the chunk.
    void beginChunk();
    void addObject(const results::ObjectRecord& object);
    void endChunk(results::ChunkRecord& chunk);
    // The counts and savings of the chunks added so far.
    results::Summary summary() const;
    // The file without its chunks (lights, summary, warnings, shard): what follows them.
    results::ResultsFile tail(const std::vector<Diagnostic>& diagnostics, const std::optional<results::ShardRecord>& shard) const;

private:
    results::ResultsFile file_;
    savings::Tally tally_;
};

// Light `l` (from 0) of a space as the results file records it: what `report` compares a
// results file's lights with.
results::LightRecord lightRecord(const Light& L, size_t l);

// One baked chunk as the results file lists it (what --resume keeps for a later bake).
results::ChunkRecord chunkRecord(const ChunkVerdicts& cv);


}  // namespace shadowcull::cli
