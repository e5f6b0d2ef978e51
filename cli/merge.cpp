#include "cli/merge.h"

#include <algorithm>
#include <map>
#include <set>

#include "cli/output_guard.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "core/scene.h"
#include "io/chunk_writer.h"
#include "io/results_stream.h"
#include "util/stop_request.h"

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

namespace {

using Shard = std::pair<std::string, results::ResultsFile>;  // {path, file}, as mergeShards takes them

// One shard's file for the checks: streamed, keeping its chunks' names only (the records are
// read again when the merged file is written), or, when it is not in the writer's layout,
// read whole (then `whole` is set).
Expected<Shard> readShard(const std::string& path, bool& whole) {
    std::vector<results::ChunkRecord> names;
    results::ChunkParts parts;  // each object is read and checked, and dropped
    parts.begin = [&](const std::string& chunk) {
        names.emplace_back().chunk = chunk;
        return Status::ok();
    };
    Expected<std::optional<results::ResultsFile>> streamed = results::streamResultsFile(path, parts);
    whole = !(streamed && *streamed);
    if (!whole) {
        (*streamed)->chunks = std::move(names);
        return Shard{path, std::move(**streamed)};
    }
    Expected<results::ResultsFile> f = results::readResultsFile(path);
    if (!f) return f.error();
    return Shard{path, std::move(*f)};
}

// The shards in the order their chunks go into the merged file, when each holds one run of
// the grid order and the runs do not interleave (as `bake --shard` partitions a space):
// then the merged chunks are the shards' chunks one shard after another. Empty otherwise.
std::vector<const Shard*> runOrder(const std::vector<Shard>& shards) {
    std::vector<const Shard*> order;
    for (const Shard& s : shards)
        if (!s.second.chunks.empty()) order.push_back(&s);
    std::sort(order.begin(), order.end(), [](const Shard* a, const Shard* b) {
        return coordOf(a->second.chunks.front().chunk) < coordOf(b->second.chunks.front().chunk);
    });
    std::optional<ChunkCoord> last;
    for (const Shard* s : order)
        for (const results::ChunkRecord& c : s->second.chunks) {
            const ChunkCoord at = coordOf(c.chunk);
            if (last && !(*last < at)) return {};
            last = at;
        }
    return order;
}

// The merged file written as the shards' files are read, one object in memory at a time:
// each chunk's opening, its objects and its close as they come, counted into the summary.
class StreamedMerge {
public:
    StreamedMerge(StagedFile& out, const std::vector<results::LightRecord>& lights) : out_(out), builder_(lights) {}

    // Appends the chunks of the shard's file at `path`; `names`: its chunks as the checks
    // read them (anything else is a file changed since).
    Status appendShard(const std::string& path, const std::vector<results::ChunkRecord>& names) {
        size_t inShard = 0;
        auto changed = [&] { return Status(makeError(ErrorKind::BadInput, path, 0, "changed while it was being merged")); };
        results::ChunkParts parts;
        parts.begin = [&](const std::string& chunk) {
            if (inShard >= names.size() || chunk != names[inShard].chunk) return changed();
            ++inShard;
            objects_ = 0;
            builder_.beginChunk();
            return out_.append((chunks_++ == 0 ? "\n" : ",\n") + results::chunkOpenJson(chunk));
        };
        parts.object = [&](results::ObjectRecord& object) {
            builder_.addObject(object);
            return out_.append((objects_++ == 0 ? "\n" : ",\n") + results::chunkObjectJson(object));
        };
        parts.end = [&](results::ChunkRecord& rest) {
            builder_.endChunk(rest);  // its savings, from its objects
            return out_.append(results::chunkCloseJson(rest, objects_ > 0));
        };
        Expected<std::optional<results::ResultsFile>> again = results::streamResultsFile(path, parts);
        if (!again) return again.error();
        return *again && inShard == names.size() ? Status::ok() : changed();
    }

    size_t chunks() const { return chunks_; }
    results::Summary summary() const { return builder_.summary(); }

private:
    StagedFile& out_;
    ResultsBuilder builder_;
    size_t chunks_ = 0;   // written, from every shard
    size_t objects_ = 0;  // of the chunk being written
};

// Writes the merged file chunk by chunk from the shards' files in `order`; `checked` is
// mergeShards' outcome on the names (warnings, lights). The same bytes as writeResults of
// the merge in memory.
Status writeStreamed(const std::string& outPath, const std::vector<const Shard*>& order, const MergeOutcome& checked,
                     size_t& chunks, uint64_t& bits) {
    Expected<StagedFile> outFile = StagedFile::open(outPath);
    if (!outFile) return outFile.error();
    const std::string temp = tempPathFor(outPath);
    const bool held = holdTemporary(temp.c_str());
    StreamedMerge merge(*outFile, checked.merged.lights);
    Status s = outFile->append(results::resultsHead());
    for (const Shard* shard : order)
        if (s) s = merge.appendShard(shard->first, shard->second.chunks);
    results::ResultsFile tail;
    tail.version = checked.merged.version;
    tail.space = checked.merged.space;
    tail.lights = checked.merged.lights;
    tail.warnings = checked.merged.warnings;
    tail.summary = merge.summary();
    chunks = merge.chunks();
    bits = tail.summary.bits;
    if (s) s = outFile->append(results::resultsTail(tail, chunks > 0));
    if (s) s = outFile->sync();
    if (s) s = outFile->commit();
    if (held) releaseTemporary();
    return s;
}

}  // namespace

int runMerge(const MergeOptions& opt, std::ostream& out, std::ostream& err) {
    if (Status s = refuseInputAsOutput(opt.outPath, opt.shardPaths, "OUT"); !s) {
        err << "shadowcull: error: " << s.error().what() << "\n";
        return kExitBadInput;
    }
    // 1. The shards' files without their chunks' contents: every check needs only names.
    std::vector<Shard> shards;
    std::vector<bool> readWhole;
    for (const std::string& path : opt.shardPaths) {
        bool whole = false;
        Expected<Shard> shard = readShard(path, whole);
        if (!shard) {
            err << "shadowcull: error: " << shard.error().what() << "\n";
            return exitCodeFor(shard.error().kind);
        }
        shards.push_back(std::move(*shard));
        readWhole.push_back(whole);
    }
    const MergeOutcome checked = mergeShards(shards);
    if (checked.exitCode != 0) {
        err << "shadowcull: error: " << checked.message << "; nothing written\n";
        return checked.exitCode;
    }
    // 2. Streamed when every shard was streamed and their chunks are runs of the grid order
    // (memory independent of the world); otherwise in memory, as the model says.
    size_t chunks = 0;
    uint64_t bits = 0;
    const bool streamable = std::none_of(readWhole.begin(), readWhole.end(), [](bool whole) { return whole; });
    const std::vector<const Shard*> order = streamable ? runOrder(shards) : std::vector<const Shard*>{};
    Status written;
    if (streamable && (!order.empty() || checked.merged.chunks.empty())) {
        written = writeStreamed(opt.outPath, order, checked, chunks, bits);
    } else {
        for (size_t k = 0; k < shards.size(); ++k) {
            if (readWhole[k]) continue;
            Expected<results::ResultsFile> f = results::readResultsFile(shards[k].first);
            if (!f) {
                err << "shadowcull: error: " << f.error().what() << "\n";
                return exitCodeFor(f.error().kind);
            }
            shards[k].second = std::move(*f);
        }
        const MergeOutcome o = mergeShards(shards);
        if (o.exitCode != 0) {
            err << "shadowcull: error: " << o.message << "; nothing written\n";
            return o.exitCode;
        }
        written = writeFileAtomic(opt.outPath, results::writeResults(o.merged));
        chunks = o.merged.chunks.size();
        bits = o.merged.summary.bits;
    }
    if (!written) {
        err << "shadowcull: error: " << written.error().what() << "\n";
        return written.error().kind == ErrorKind::BadInput ? kExitBadInput : kExitIo;
    }
    out << "merged " << opt.shardPaths.size() << " shard(s): " << chunks << " chunk(s), " << bits << " bits, into " << opt.outPath
        << "\n";
    return kExitOk;
}

}  // namespace shadowcull::cli
