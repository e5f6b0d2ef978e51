#include "cli/merge.h"

#include <algorithm>
#include <map>
#include <set>

#include "cli/output_guard.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "core/scene.h"
#include "io/chunk_writer.h"

namespace shadowcull::cli {

namespace {

ChunkCoord coordOf(const std::string& name) { return parseChunkName(name).value_or(ChunkCoord{}); }

MergeOutcome refused(int code, std::string message) {
    MergeOutcome o;
    o.exitCode = code;
    o.message = std::move(message);
    return o;
}

std::string shardName(const results::ShardRecord& s) { return std::to_string(s.index) + "/" + std::to_string(s.count); }

// The lights as the writer prints them: equal text, equal lights.
std::string lightsText(const results::ResultsFile& f) {
    results::ResultsFile only;
    only.lights = f.lights;
    return results::writeResults(only);
}

}  // namespace

MergeOutcome mergeShards(const std::vector<std::pair<std::string, results::ResultsFile>>& shards) {
    if (shards.empty()) return refused(kExitUsage, "no shard results given");
    for (const auto& [path, f] : shards)
        if (!f.shard)
            return refused(kExitBadInput, path + ": not a shard's results (no \"shard\" part: written by a bake without --shard)");

    // 1. One bake: the same inputs, options, space, lights and shard count.
    // (Plain references, not structured bindings: clang's C++17 refuses lambdas that
    // capture those, and the fuzz build is clang.)
    const std::string& firstPath = shards.front().first;
    const results::ResultsFile& first = shards.front().second;
    const results::ShardRecord& s0 = *first.shard;
    const std::vector<std::string> spaceWarnings(first.warnings.begin(), first.warnings.begin() + std::ptrdiff_t(s0.spaceWarnings));
    const std::string lights0 = lightsText(first);
    for (const auto& shard : shards) {
        const std::string& path = shard.first;
        const results::ResultsFile& f = shard.second;
        const results::ShardRecord& s = *f.shard;
        auto differ = [&](const std::string& what) {
            return refused(kExitShardsDiffer, path + " (shard " + shardName(s) + ") and " + firstPath + " (shard " + shardName(s0) +
                                                  ") are not shards of one bake: " + what + " differ; bake every shard with the same space and options");
        };
        if (s.count != s0.count) return differ("their shard counts (" + std::to_string(s.count) + " and " + std::to_string(s0.count) + ")");
        if (s.inputs != s0.inputs)
            return differ("their inputs (settings, lights, options that change verdicts, chunk files or meshes: hash " + s.inputs + " and " + s0.inputs + ")");
        if (f.space != first.space) return differ("their space directories ('" + f.space + "' and '" + first.space + "')");
        if (s.spaceChunks != s0.spaceChunks) return differ("their spaces' chunk counts");
        if (lightsText(f) != lights0) return differ("their lights");
        if (s.spaceWarnings != s0.spaceWarnings ||
            !std::equal(spaceWarnings.begin(), spaceWarnings.end(), f.warnings.begin()))
            return differ("the warnings of reading the space");
    }

    // 2. Every shard once, every chunk of the space in exactly one shard.
    std::map<int, std::string> byIndex;
    std::map<std::string, int> owner;  // chunk -> shard index
    for (const auto& [path, f] : shards) {
        const results::ShardRecord& s = *f.shard;
        if (auto [it, fresh] = byIndex.emplace(s.index, path); !fresh)
            return refused(kExitShardsIncomplete, "shard " + shardName(s) + " given twice: " + it->second + " and " + path);
        for (const std::string& c : s.assigned)
            if (auto [it, fresh] = owner.emplace(c, s.index); !fresh)
                return refused(kExitShardsIncomplete, "chunk " + c + " is in shard " + std::to_string(it->second) + " and in shard " +
                                                          shardName(s) + " (" + path + ")");
    }
    std::string missing;
    for (int k = 1; k <= s0.count; ++k)
        if (!byIndex.count(k)) missing += (missing.empty() ? "" : ", ") + std::to_string(k);
    if (!missing.empty())
        return refused(kExitShardsIncomplete, "shard(s) " + missing + " of " + std::to_string(s0.count) + " missing: give the results of every shard");
    if (owner.size() != s0.spaceChunks)
        return refused(kExitShardsIncomplete, std::to_string(s0.spaceChunks - std::min<uint64_t>(s0.spaceChunks, owner.size())) +
                                                  " chunk(s) of the space are in no shard (a shard file was edited?)");

    // 3. Each shard's results cover its chunks: a chunk it did not bake must be explained by
    // one of its own warnings (a read-only file, an edit during the bake), as in a single bake.
    MergeOutcome o;
    results::ResultsFile& m = o.merged;
    m.version = first.version;
    m.space = first.space;
    m.lights = first.lights;
    m.warnings = spaceWarnings;
    std::vector<std::pair<ChunkCoord, std::string>> ownWarnings;
    for (const auto& [path, f] : shards) {
        const results::ShardRecord& s = *f.shard;
        std::set<std::string> baked;
        for (const results::ChunkRecord& c : f.chunks) {
            if (owner.count(c.chunk) == 0 || owner.at(c.chunk) != s.index)
                return refused(kExitShardsIncomplete, path + " (shard " + shardName(s) + ") has results for chunk " + c.chunk +
                                                          ", which is not one of its chunks");
            baked.insert(c.chunk);
            m.chunks.push_back(c);
        }
        const std::vector<std::string> own(f.warnings.begin() + std::ptrdiff_t(s.spaceWarnings), f.warnings.end());
        for (const std::string& c : s.assigned) {
            if (baked.count(c)) continue;
            if (std::none_of(own.begin(), own.end(), [&](const std::string& w) { return w.find(c) != std::string::npos; }))
                return refused(kExitShardsIncomplete, path + " (shard " + shardName(s) + ") has no results for its chunk " + c +
                                                          " and no warning about it: bake that shard again");
        }
        for (const std::string& w : own) {
            // The first of the shard's chunks the warning names (a single bake lists them in
            // grid order too).
            ChunkCoord at{};
            for (const std::string& c : s.assigned)
                if (w.find(c) != std::string::npos) {
                    at = coordOf(c);
                    break;
                }
            ownWarnings.emplace_back(at, w);
        }
    }
    std::stable_sort(m.chunks.begin(), m.chunks.end(),
                     [](const results::ChunkRecord& a, const results::ChunkRecord& b) { return coordOf(a.chunk) < coordOf(b.chunk); });
    std::stable_sort(ownWarnings.begin(), ownWarnings.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (auto& [at, w] : ownWarnings) m.warnings.push_back(std::move(w));
    // Counted and tallied from the records by the builder the single bake streams through.
    ResultsBuilder builder(m.lights);
    for (results::ChunkRecord& c : m.chunks) builder.add(c);
    m.summary = builder.summary();
    return o;
}

int runMerge(const MergeOptions& opt, std::ostream& out, std::ostream& err) {
    if (Status s = refuseInputAsOutput(opt.outPath, opt.shardPaths, "OUT"); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return kExitBadInput;
    }
    std::vector<std::pair<std::string, results::ResultsFile>> shards;
    for (const std::string& path : opt.shardPaths) {
        Expected<results::ResultsFile> f = results::readResultsFile(path);
        if (!f) {
            err << "shadowcull: error: " << f.error().what() << "\n";
            return exitCodeFor(f.error().kind);
        }
        shards.emplace_back(path, std::move(*f));
    }
    const MergeOutcome o = mergeShards(shards);
    if (o.exitCode != 0) {
        err << "shadowcull: error: " << o.message << "; nothing written\n";
        return o.exitCode;
    }
    if (Status s = writeFileAtomic(opt.outPath, results::writeResults(o.merged)); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return kExitIo;
    }
    out << "merged " << shards.size() << " shard(s): " << o.merged.chunks.size() << " chunk(s), " << o.merged.summary.bits
        << " bits, into " << opt.outPath << "\n";
    return kExitOk;
}

}  // namespace shadowcull::cli
