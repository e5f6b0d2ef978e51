#include "cli/report.h"

#include "cli/savings_report.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace shadowcull::cli {

BitCounts countBits(const BakeResult& r) {
    BitCounts c;
    for (const ChunkVerdicts& cv : r.chunks)
        for (const ObjectVerdicts& ov : cv.objects) {
            c.groups += uint64_t(ov.groupCount);
            for (const Decision& d : ov.decisions) {
                ++c.bits;
                switch (d.verdict) {
                    case Verdict::Culled: ++c.culled; ++c.culledBy[std::string(d.stage)]; break;
                    case Verdict::Kept: ++c.kept; ++c.provedKept; ++c.keptBy[std::string(d.stage)]; break;
                    case Verdict::Undecided: ++c.kept; ++c.undecided; break;
                }
            }
        }
    return c;
}

savings::Tally tallyBake(const BakeResult& r) {
    savings::Tally t(r.settings.lights.size());
    for (const ChunkVerdicts& cv : r.chunks) {
        t.beginChunk();
        for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
            const ObjectVerdicts& ov = cv.objects[oi];
            for (int g = 0; g < ov.groupCount; ++g) {
                const uint64_t tris = size_t(g) < ov.groupTriangles.size() ? ov.groupTriangles[size_t(g)] : 0;
                for (int l = 0; l < cv.lightCount; ++l) {
                    const Decision& d = cv.at(oi, g, l);
                    t.add(size_t(l), savings::classify(verdictName(d.verdict), d.stage, d.reason()), d.stage, tris);
                }
            }
        }
    }
    return t;
}

namespace {

std::string fmt(const char* f, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, f, v);
    return buf;
}

std::string pct(uint64_t a, uint64_t b) { return b ? fmt("%.1f%%", 100.0 * double(a) / double(b)) : "-"; }

}  // namespace

std::string formatSimulated(const std::vector<ChunkVerdicts>& chunks) {
    // Each effect once, in the order first met, with the chunks that simulated it.
    std::vector<std::pair<std::string, size_t>> effects;
    for (const ChunkVerdicts& cv : chunks)
        for (const std::string& e : cv.simulated) {
            auto it = std::find_if(effects.begin(), effects.end(), [&](const auto& p) { return p.first == e; });
            if (it == effects.end()) effects.emplace_back(e, 1);
            else ++it->second;
        }
    // Effects of the whole window first, then each light's, in light order.
    auto lightOf = [](const std::string& e) { return e.rfind("light ", 0) == 0 ? std::atoi(e.c_str() + 6) : 0; };
    std::stable_sort(effects.begin(), effects.end(), [&](const auto& a, const auto& b) { return lightOf(a.first) < lightOf(b.first); });
    if (chunks.empty()) return {};
    if (effects.empty()) return "simulated: nothing beyond the plain definition (no alpha test, terrain, bias or local light)\n";
    std::string s = "simulated:\n";
    for (const auto& [effect, n] : effects)
        s += "  " + effect + (n == chunks.size() ? "" : " (" + std::to_string(n) + " of " + std::to_string(chunks.size()) + " chunks)") + "\n";
    return s;
}

std::string formatSummary(const BakeResult& r, bool wrote) {
    const BitCounts c = countBits(r);
    std::string s;
    s += "chunks " + std::to_string(r.chunks.size());
    if (wrote) s += " (" + std::to_string(r.chunksWritten) + " written)";
    if (r.chunksResumed) s += ", " + std::to_string(r.chunksResumed) + " unchanged since the last bake (skipped)";
    s += ", groups " + std::to_string(c.groups) + ", lights " + std::to_string(r.settings.lights.size()) + "\n";
    s += "bits " + std::to_string(c.bits) + ": kept " + std::to_string(c.kept) + ", culled " + std::to_string(c.culled) +
         " (" + pct(c.culled, c.bits) + ")\n";
    auto byStage = [](const std::map<std::string, uint64_t>& m) {
        std::string t;
        for (const auto& [stage, n] : m) t += (t.empty() ? " (" : ", ") + stage + " " + std::to_string(n);
        return t.empty() ? t : t + ")";
    };
    const bool baselineOnly = c.keptBy.size() + c.culledBy.size() > 0 && c.keptBy.count("gpu-baseline") + c.culledBy.count("gpu-baseline") > 0;
    s += std::string(baselineOnly ? "  kept by samples passed    " : "  proved 1 by witness ray   ") + std::to_string(c.provedKept) +
         byStage(c.keptBy) + "\n";
    s += std::string(baselineOnly ? "  culled, 0 samples passed  " : "  proved 0                  ") + std::to_string(c.culled) +
         byStage(c.culledBy);
    s += "\n  undecided, kept as 1      " + std::to_string(c.undecided) + "\n";
    std::vector<std::string> lightNames;
    for (const Light& L : r.settings.lights) lightNames.push_back(L.name);
    s += formatSavingsTable(tallyBake(r).world(), lightNames);
    s += formatSimulated(r.chunks);
    s += "time: load " + fmt("%.2f s", r.loadSeconds);
    for (const StageTiming& st : r.stages) {
        s += ", " + st.name + " " + fmt("%.2f s", st.stats.seconds);
        if (st.stats.raysCast) s += " (" + std::to_string(st.stats.raysCast) + " rays)";
        if (st.stats.exactTests) s += " (" + std::to_string(st.stats.exactTests) + " exact tests)";
        if (st.stats.gpuPasses) s += " (" + std::to_string(st.stats.gpuPasses) + " passes)";
        if (st.stats.gpuTimed) s += " (GPU time " + fmt("%.2f s", st.stats.gpuSeconds) + ")";
    }
    s += ", write " + fmt("%.2f s", r.writeSeconds) + ", total " + fmt("%.2f s", r.totalSeconds) + "\n";
    if (!r.gl.empty()) s += "OpenGL: " + r.gl + "\n";
    return s;
}

results::ChunkRecord chunkRecord(const ChunkVerdicts& cv) {
    results::ChunkRecord c;
    c.chunk = chunkFileName(cv.coord);
    c.simulated = cv.simulated;
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        const ObjectVerdicts& ov = cv.objects[oi];
        results::ObjectRecord& o = c.objects.emplace_back();
        o.element = ov.elementIndex;
        o.kind = ov.terrain ? "terrain" : "model";
        o.uuid = ov.uuid;
        o.skipped = ov.windowObject < 0;
        if (o.skipped) continue;
        for (int g = 0; g < ov.groupCount; ++g) {
            results::GroupRecord& gr = o.groups.emplace_back();
            gr.group = g;
            gr.mask = cv.groupMask(oi, g);
            if (size_t(g) < ov.groupTriangles.size()) gr.triangles = ov.groupTriangles[size_t(g)];
            if (size_t(g) < ov.wsGroupBounds.size() && ov.wsGroupBounds[size_t(g)][0].x <= ov.wsGroupBounds[size_t(g)][1].x)
                gr.bounds = ov.wsGroupBounds[size_t(g)];
            o.mask |= gr.mask;
            for (int l = 0; l < cv.lightCount; ++l) {
                const Decision& d = cv.at(oi, g, l);
                results::BitRecord& b = gr.lights.emplace_back();
                b.light = l + 1;
                b.bit = d.verdict == Verdict::Culled ? 0 : 1;
                b.verdict = verdictName(d.verdict);
                b.stage = std::string(d.stage);
                b.reason = std::string(d.reason());
                for (const StageNote& n : d.notes()) b.notes.emplace_back(std::string(n.stage), n.text);
                if (const Witness* w = d.witness())
                {
                    b.witness = results::WitnessRecord{w->wsOrigin, w->wsDirection, w->wsP, w->wsQ, w->receiver, std::nullopt};
                    if (w->wsReceiverMin.x <= w->wsReceiverMax.x)
                        b.witness->receiverBounds = results::BoxRecord{w->wsReceiverMin, w->wsReceiverMax};
                }
            }
        }
    }
    return c;
}

results::ResultsFile resultsFile(const BakeResult& r) {
    results::ResultsFile f;
    f.space = r.settings.spaceDir;
    for (size_t l = 0; l < r.settings.lights.size(); ++l) {
        const Light& L = r.settings.lights[l];
        results::LightRecord& r = f.lights.emplace_back();
        r.index = int(l) + 1, r.bit = int(l), r.name = L.name, r.type = lightTypeName(L.type);
        if (L.type != LightType::Directional) r.position = L.position, r.range = L.range;
        if (L.type != LightType::Point) r.direction = L.direction;
        if (L.type == LightType::Spot) r.coneAngle = L.coneHalfAngleDeg;
        r.bias = L.bias, r.slopeBias = L.slopeBias, r.filterRadius = L.filterRadius;
    }
    for (const ChunkVerdicts& cv : r.chunks) f.chunks.push_back(chunkRecord(cv));
    // The counts the summary line prints (countBits), not recounted from the records.
    const BitCounts n = countBits(r);
    f.summary.chunks = r.chunks.size();
    f.summary.groups = n.groups;
    f.summary.bits = n.bits;
    f.summary.kept = n.kept;
    f.summary.culled = n.culled;
    f.summary.provedKept = n.provedKept;
    f.summary.undecided = n.undecided;
    f.summary.culledBy = n.culledBy;
    if (!r.resumedRecords.empty()) {
        // Chunks --resume skipped, as recorded when they were baked: the file lists every
        // chunk of the bake, in grid order, as a bake of all of them would.
        const results::Summary more = results::summarize(r.resumedRecords);
        f.summary.chunks += more.chunks, f.summary.groups += more.groups, f.summary.bits += more.bits;
        f.summary.kept += more.kept, f.summary.culled += more.culled;
        f.summary.provedKept += more.provedKept, f.summary.undecided += more.undecided;
        for (const auto& [stage, k] : more.culledBy) f.summary.culledBy[stage] += k;
        f.chunks.insert(f.chunks.end(), r.resumedRecords.begin(), r.resumedRecords.end());
        std::stable_sort(f.chunks.begin(), f.chunks.end(), [](const results::ChunkRecord& a, const results::ChunkRecord& b) {
            return parseChunkName(a.chunk).value_or(ChunkCoord{}) < parseChunkName(b.chunk).value_or(ChunkCoord{});
        });
    }
    // What the masks remove, per chunk and for the world: tallied from the records (the
    // resumed chunks' too), as `merge` and `report` tally a file.
    const savings::Tally t = savings::tallyResults(f);
    f.summary.savings = t.world();
    for (size_t k = 0; k < f.chunks.size() && k < t.chunks().size(); ++k) f.chunks[k].savings = t.chunks()[k];
    for (const Diagnostic& d : r.diagnostics) f.warnings.push_back(d.what());
    f.shard = r.shard;
    return f;
}


}  // namespace shadowcull::cli
