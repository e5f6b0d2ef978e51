// shadowcull plan (cli/plan.h).

#include "cli/plan.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <set>

#include <tbb/global_control.h>

#include "cli/output_guard.h"
#include "cli/shard.h"
#include "core/window_plan.h"
#include "io/shard_plan.h"

namespace fs = std::filesystem;

namespace shadowcull::cli {

namespace {

// The windows a shard's bake may plan: the analytic bake's (what the shadows reach) and the
// `neighbours` rectangles of the original method, so that a shard plans either. Built once
// per plan: each walks every chunk's summary.
struct Planners {
    WindowPlanner analytic, rectangle;
    explicit Planners(const SpaceSource& space)
        : analytic(space.settings(), space.chunks(), true, space.outline().bounds),
          rectangle(space.settings(), space.chunks(), false, space.outline().bounds) {}
};

// The chunks every window of `targets` holds.
std::set<ChunkCoord> windowChunks(const Planners& planners, const std::vector<ChunkCoord>& targets) {
    std::set<ChunkCoord> held;
    for (ChunkCoord c : targets) {
        for (ChunkCoord w : planners.analytic.plan(c).chunks) held.insert(w);
        for (ChunkCoord w : planners.rectangle.plan(c).chunks) held.insert(w);
    }
    return held;
}

PlanShard shardPlan(const SpaceSource& space, const Planners& planners, int index, int count, std::vector<ChunkCoord> assigned) {
    PlanShard s;
    s.index = index, s.count = count;
    for (ChunkCoord c : windowChunks(planners, assigned)) {
        ChunkEntry e = space.chunks().at(c);
        e.contentHash = 0;  // the shard's first load stands for it (SpaceSource::load)
        s.chunks.emplace(c, std::move(e));
    }
    s.assigned = std::move(assigned);
    return s;
}

PlanHead planHead(const SpaceSource& space, const PlanOptions& opt, const std::vector<PlanShard>& shards) {
    PlanHead head;
    head.spaceDir = opt.spaceDir;
    head.shards = opt.shards;
    head.outline = space.outline();
    head.diagnostics = space.diagnostics();
    for (const PlanShard& s : shards) head.shardChunks.push_back(s.assigned.size());
    return head;
}

// The inputs a shard cannot list itself (space.xml and the chunk files it can): the
// resources and the files behind them.
std::vector<std::string> resourceFiles(const SpaceSource& space) {
    std::set<std::string> listable{(fs::path(space.settings().spaceDir) / "space.xml").string()};
    for (const auto& [c, e] : space.chunks()) listable.insert(e.path);
    std::vector<std::string> out;
    for (const std::string& f : space.inputFiles())
        if (!listable.count(f)) out.push_back(f);
    return out;
}

}  // namespace

Expected<PlanSummary> makePlan(const PlanOptions& opt) {
    const auto t0 = std::chrono::steady_clock::now();
    std::unique_ptr<tbb::global_control> threadLimit;
    if (opt.threads > 0)
        threadLimit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(opt.threads));
    Expected<SpaceSource> scanned = SpaceSource::scan(opt.spaceDir, opt.resourceRoot, nullptr, opt.onScanned);
    if (!scanned) return scanned.error();
    const SpaceSource& space = *scanned;
    // Never an input overwritten: every file the plan writes is checked first.
    const std::vector<std::string> inputs = space.inputFiles();
    for (const std::string& path : {ShardPlanFiles::planPath(opt.planDir), ShardPlanFiles::inputsPath(opt.planDir)})
        if (Status s = refuseInputAsOutput(path, inputs, "--plan"); !s) return s.error();
    for (int k = 1; k <= opt.shards; ++k)
        if (Status s = refuseInputAsOutput(ShardPlanFiles::shardPath(opt.planDir, k, opt.shards), inputs, "--plan"); !s)
            return s.error();

    std::vector<std::vector<ChunkCoord>> parts = partitionChunks(space, opt.shards);
    const Planners planners(space);
    std::vector<PlanShard> shards;
    PlanSummary summary;
    for (int k = 1; k <= opt.shards; ++k) {
        shards.push_back(shardPlan(space, planners, k, opt.shards, std::move(parts[size_t(k - 1)])));
        summary.largestShardChunks = std::max(summary.largestShardChunks, shards.back().assigned.size());
        summary.largestWindowChunks = std::max(summary.largestWindowChunks, shards.back().chunks.size());
    }
    if (Status s = writeShardPlan(opt.planDir, planHead(space, opt, shards), shards, resourceFiles(space)); !s) return s.error();
    summary.chunks = space.outline().chunks;
    summary.diagnostics = space.diagnostics();
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return summary;
}

}  // namespace shadowcull::cli
