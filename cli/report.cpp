#include "cli/report.h"

#include "cli/savings_report.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace shadowcull::cli {

BitCounts countBits(const BakeResult& r) { return r.totals.bits; }

savings::Tally tallyBake(const BakeResult& r) {
    savings::Tally t(r.settings.lights.size());
    for (const ChunkVerdicts& cv : r.chunks) {
        t.beginChunk();
        tallyVerdicts(t, cv);
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

std::string formatSimulated(const BakeTotals& totals) {
    // Effects of the whole window first, then each light's, in light order.
    std::vector<std::pair<std::string, size_t>> effects = totals.simulated;
    auto lightOf = [](const std::string& e) { return e.rfind("light ", 0) == 0 ? std::atoi(e.c_str() + 6) : 0; };
    std::stable_sort(effects.begin(), effects.end(), [&](const auto& a, const auto& b) { return lightOf(a.first) < lightOf(b.first); });
    if (!totals.chunks) return {};
    if (effects.empty()) return "simulated: nothing beyond the plain definition (no alpha test, terrain, bias or local light)\n";
    std::string s = "simulated:\n";
    for (const auto& [effect, n] : effects)
        s += "  " + effect + (n == totals.chunks ? "" : " (" + std::to_string(n) + " of " + std::to_string(totals.chunks) + " chunks)") + "\n";
    return s;
}

std::string formatReach(const ReachTotals& reach, const SpaceSettings& settings) {
    if (!reach.windows) return {};
    const double windows = double(reach.windows);
    std::string s = "windows: " + fmt("%.1f", double(reach.chunks) / windows) +
                    " chunks each on average (every chunk the shadows and occluders reach), " +
                    (reach.chunksBeyond ? fmt("%.1f", double(reach.chunksBeyond) / windows) : std::string("none")) +
                    " past the neighbours rectangle\n";
    for (size_t i = 0; i < reach.lights.size() && i < settings.lights.size(); ++i) {
        const LightReach& L = reach.lights[i];
        if (!L.chunksBeyond) continue;
        s += "  " + settings.lights[i].name + ": up to " + std::to_string(L.ringsBeyond) + " chunk ring" +
             (L.ringsBeyond == 1 ? "" : "s") + " (" + fmt("%.0f m", L.ringsBeyond * settings.chunkSize) +
             ") past the rectangle, " + std::to_string(L.chunksBeyond) + " chunk load" + (L.chunksBeyond == 1 ? "" : "s") +
             " for it in " + std::to_string(reach.windowsBeyond[i]) + " of " + std::to_string(reach.windows) + " windows\n";
    }
    return s;
}

std::string formatWindow(const WindowPlan& plan, const SpaceSettings& settings) {
    std::string s = "window: " + std::to_string(plan.chunks.size()) + " chunk" + (plan.chunks.size() == 1 ? "" : "s") +
                    " (this one and every chunk its shadows and occluders reach), " +
                    (plan.chunksBeyond ? std::to_string(plan.chunksBeyond) : std::string("none")) +
                    " past the neighbours rectangle\n";
    for (size_t i = 0; i < plan.lights.size() && i < settings.lights.size(); ++i) {
        const LightReach& L = plan.lights[i];
        if (L.beyond.empty()) continue;
        s += "  " + settings.lights[i].name + ": " + std::to_string(L.beyond.size()) + " chunk" +
             (L.beyond.size() == 1 ? "" : "s") + ", up to " + std::to_string(L.ringsBeyond) + " ring" +
             (L.ringsBeyond == 1 ? "" : "s") + " (" + fmt("%.0f m", L.ringsBeyond * settings.chunkSize) + ") past it:";
        for (ChunkCoord c : L.beyond) s += " " + chunkFileName(c).substr(0, 9);
        s += "\n";
    }
    return s;
}

std::string formatSummary(const BakeResult& r, bool wrote) {
    const BitCounts c = countBits(r);
    std::string s;
    s += "chunks " + std::to_string(r.totals.chunks);
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
    s += formatSavingsTable(r.totals.savings.world(), lightNames);
    s += formatSimulated(r.totals);
    s += formatReach(r.reach, r.settings);
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

results::LightRecord lightRecord(const Light& L, size_t l) {
    results::LightRecord r;
    r.index = int(l) + 1, r.bit = int(l), r.name = L.name, r.type = lightTypeName(L.type);
    if (L.type != LightType::Directional) r.position = L.position, r.range = L.range;
    if (L.type != LightType::Point) r.direction = L.direction;
    if (L.type == LightType::Spot) r.coneAngle = L.coneHalfAngleDeg;
    r.bias = L.bias, r.slopeBias = L.slopeBias, r.filterRadius = L.filterRadius, r.normalBias = L.normalBias;
    return r;
}

ResultsBuilder::ResultsBuilder(const SpaceSettings& settings) : tally_(settings.lights.size()) {
    file_.space = settings.spaceDir;
    for (size_t l = 0; l < settings.lights.size(); ++l) file_.lights.push_back(lightRecord(settings.lights[l], l));
}

ResultsBuilder::ResultsBuilder(std::vector<results::LightRecord> lights) : tally_(lights.size()) {
    file_.lights = std::move(lights);
}

results::Summary ResultsBuilder::summary() const {
    results::Summary s = file_.summary;
    s.savings = tally_.world();
    return s;
}

void ResultsBuilder::add(results::ChunkRecord& chunk) {
    beginChunk();
    for (const results::ObjectRecord& o : chunk.objects) addObject(o);
    endChunk(chunk);
}

// What the masks remove, per chunk and for the world: tallied from the records (the resumed
// chunks' too), as `merge` and `report` tally a file.
void ResultsBuilder::beginChunk() { tally_.beginChunk(); }

void ResultsBuilder::addObject(const results::ObjectRecord& object) {
    tally_.addObject(object);
    file_.summary.countObject(object);
}

void ResultsBuilder::endChunk(results::ChunkRecord& chunk) {
    chunk.savings = tally_.takeLastChunk();
    ++file_.summary.chunks;
}

results::ResultsFile ResultsBuilder::tail(const std::vector<Diagnostic>& diagnostics,
                                          const std::optional<results::ShardRecord>& shard) const {
    results::ResultsFile f = file_;
    f.summary = summary();
    for (const Diagnostic& d : diagnostics) f.warnings.push_back(d.what());
    f.shard = shard;
    return f;
}

results::ResultsFile resultsFile(const BakeResult& r) {
    // The baked chunks and those --resume skipped (as recorded when they were baked), in
    // grid order, as a bake of all of them lists them.
    std::vector<results::ChunkRecord> chunks;
    for (const ChunkVerdicts& cv : r.chunks) chunks.push_back(chunkRecord(cv));
    chunks.insert(chunks.end(), r.resumedRecords.begin(), r.resumedRecords.end());
    std::stable_sort(chunks.begin(), chunks.end(), [](const results::ChunkRecord& a, const results::ChunkRecord& b) {
        return parseChunkName(a.chunk).value_or(ChunkCoord{}) < parseChunkName(b.chunk).value_or(ChunkCoord{});
    });
    ResultsBuilder builder(r.settings);
    for (results::ChunkRecord& c : chunks) builder.add(c);
    results::ResultsFile f = builder.tail(r.diagnostics, r.shard);
    f.chunks = std::move(chunks);
    return f;
}

}  // namespace shadowcull::cli
