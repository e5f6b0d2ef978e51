// Fuzz target: a sharded bake's plan as `bake --shard K/N --plan DIR` reads it
// (io/shard_plan.h: readShardPlan, readPlanInputs), then what the bake makes of a plan it
// accepts: SpaceSource::planned over data/sample and the windows of the shard's chunks.
// Input, split by kFuzzSeparator (fuzz_support.h): the --shard argument ("K/N", as the
// command line takes it), plan.json, shard-K-of-N.json, inputs.json.
//
// Stand-ins, replaced before the files are written: "$SAMPLE" by data/sample's path and
// "$SETTINGS" by the hash of its space.xml and resource root (both depend on where the
// checkout is); then, in the shard and inputs files, "$PLAN" by the hash of plan.json as
// written (what `plan` writes there). Without the last, any change to plan.json would make
// its shard file stale and the shard reader would only ever see the seeds' plan.json; a
// mutated "$PLAN" still reaches the stale-plan checks.
//
// An accepted plan must hold what the bake relies on: the shard asked for, a plan of that
// many shards, its chunks in grid order and each once (the order of its results file),
// every assigned chunk summarised, and every chunk of its windows too
// (SpaceSource::load looks each one up). Errors must be BadInput, StalePlan or
// MissingResource; the source built from an accepted plan must be one (or a BadInput or
// StalePlan error) that holds the plan's chunks and outline.

#include <cstdio>
#include <filesystem>
#include <optional>

#include "cli/shard.h"
#include "core/window_plan.h"
#include "fuzz/fuzz_support.h"
#include "io/scene_reader.h"
#include "io/shard_plan.h"
#include "io/space_source.h"
#include "util/hash.h"

namespace {

using namespace shadowcull;

const std::string kSample = SHADOWCULL_SOURCE_DIR "/data/sample";

// The sample's settings and outline as a full scan sees them, read once per process.
const SpaceSource& sample() {
    static const SpaceSource source = [] {
        Expected<SpaceSource> s = SpaceSource::scan(kSample, "");
        if (!s) brokenPromise("data/sample scans");
        return std::move(*s);
    }();
    return source;
}

std::string replaced(std::string text, const std::string& token, const std::string& value) {
    for (size_t at = text.find(token); at != std::string::npos; at = text.find(token, at + value.size()))
        text.replace(at, token.size(), value);
    return text;
}

void expectKind(const Error& e, std::initializer_list<ErrorKind> kinds, const char* what) {
    for (ErrorKind k : kinds)
        if (e.kind == k) return;
    brokenPromise(what);
}

// What the shard's bake does with the plan next: plan its windows (analytic, over the plan's
// bounds, as cli/pipeline.cpp does), which must hold only chunks the plan summarises.
void checkWindows(const LoadedShardPlan& plan) {
    const WindowPlanner planner(sample().settings(), plan.shard.chunks, true, plan.head.outline.bounds);
    for (ChunkCoord c : plan.shard.assigned)
        for (ChunkCoord w : planner.plan(c).chunks)
            if (!plan.shard.chunks.count(w)) brokenPromise("a window holds a chunk the plan does not summarise");
}

void checkAccepted(const LoadedShardPlan& plan, const cli::ShardSpec& asked) {
    if (plan.shard.index != asked.index || plan.shard.count != asked.count) brokenPromise("the shard read is the one asked for");
    if (plan.head.shards != asked.count) brokenPromise("a plan of as many shards as asked for");
    if (plan.head.shardChunks.size() != size_t(plan.head.shards)) brokenPromise("shardChunks lists every shard");
    for (size_t k = 0; k < plan.shard.assigned.size(); ++k) {
        if (!plan.shard.chunks.count(plan.shard.assigned[k])) brokenPromise("every assigned chunk has a summary");
        if (k > 0 && !(plan.shard.assigned[k - 1] < plan.shard.assigned[k])) brokenPromise("assigned chunks in grid order, each once");
    }
}

// SpaceSource::planned over the sample (the bake's openSpace), and the rest of its inputs.
void checkPlannedSource(LoadedShardPlan plan) {
    const SpaceOutline outline = plan.head.outline;
    const size_t chunks = plan.shard.chunks.size();
    Expected<SpaceSource> src = SpaceSource::planned(kSample, "", plannedSpaceOf(scratchDir(), std::move(plan)));
    if (!src) return expectKind(src.error(), {ErrorKind::BadInput, ErrorKind::StalePlan}, "a plan refused as bad or stale");
    if (!src->isPlanned() || src->chunks().size() != chunks || !(src->outline().bounds == outline.bounds) ||
        src->outline().chunks != outline.chunks)
        brokenPromise("the planned source holds the plan's chunks and outline");
    if (Status s = src->readOtherInputs(); !s)
        expectKind(s.error(), {ErrorKind::BadInput, ErrorKind::StalePlan, ErrorKind::MissingResource},
                   "inputs refused as bad, stale or missing");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<std::string> parts = splitInput(data, size, 4);
    const std::optional<cli::ShardSpec> asked = cli::parseShard(parts[0]);
    if (!asked) return 0;  // the command line refuses it before any plan is read
    parts.erase(parts.begin());
    for (std::string& part : parts)
        part = replaced(replaced(part, "$SAMPLE", kSample), "$SETTINGS", hexHash(sample().outline().settingsHash));
    const uint64_t planId = Hasher().str(parts.empty() ? "" : parts[0]).value();
    for (size_t k = 1; k < parts.size(); ++k) parts[k] = replaced(parts[k], "$PLAN", hexHash(planId));
    // The shard file's name follows K/N: the previous input's goes first, so that files of
    // other names neither pile up nor stand in for a missing part.
    static std::string lastShard;
    if (!lastShard.empty()) std::remove(lastShard.c_str());
    lastShard = ShardPlanFiles::shardPath(scratchDir(), asked->index, asked->count);
    writeFiles(parts, {"plan.json", std::filesystem::path(lastShard).filename().string(), "inputs.json"});

    const std::initializer_list<ErrorKind> refusals{ErrorKind::BadInput, ErrorKind::StalePlan, ErrorKind::MissingResource};
    if (Expected<std::vector<std::string>> inputs = readPlanInputs(scratchDir(), planId); !inputs)
        expectKind(inputs.error(), refusals, "inputs refused as bad, stale or missing");
    Expected<LoadedShardPlan> plan = readShardPlan(scratchDir(), asked->index, asked->count);
    if (!plan) {
        expectKind(plan.error(), refusals, "a plan refused as bad, stale or missing");
        return 0;
    }
    if (plan->head.id != planId) brokenPromise("the plan's id is the hash of plan.json");
    checkAccepted(*plan, *asked);
    checkWindows(*plan);
    checkPlannedSource(std::move(*plan));
    return 0;
}
