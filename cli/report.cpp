#include "cli/report.h"

#include <cstdio>

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

namespace {

std::string fmt(const char* f, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, f, v);
    return buf;
}

std::string pct(uint64_t a, uint64_t b) { return b ? fmt("%.1f%%", 100.0 * double(a) / double(b)) : "-"; }

}  // namespace

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
    s += "time: load " + fmt("%.2f s", r.loadSeconds);
    for (const StageTiming& st : r.stages) {
        s += ", " + st.name + " " + fmt("%.2f s", st.stats.seconds);
        if (st.stats.raysCast) s += " (" + std::to_string(st.stats.raysCast) + " rays)";
        if (st.stats.exactTests) s += " (" + std::to_string(st.stats.exactTests) + " exact tests)";
        if (st.stats.gpuPasses) s += " (" + std::to_string(st.stats.gpuPasses) + " passes)";
    }
    s += ", write " + fmt("%.2f s", r.writeSeconds) + ", total " + fmt("%.2f s", r.totalSeconds) + "\n";
    return s;
}

namespace {

nlohmann::json vec(const glm::dvec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

}  // namespace

nlohmann::json resultsJson(const BakeResult& r) {
    using nlohmann::json;
    json j;
    j["format"] = "shadowcull-results";
    j["version"] = 1;
    j["space"] = r.settings.spaceDir;
    json lights = json::array();
    for (size_t l = 0; l < r.settings.lights.size(); ++l) {
        const Light& L = r.settings.lights[l];
        lights.push_back({{"index", l + 1}, {"bit", l}, {"name", L.name}, {"type", lightTypeName(L.type)}});
    }
    j["lights"] = lights;
    json chunks = json::array();
    for (const ChunkVerdicts& cv : r.chunks) {
        json jc;
        jc["chunk"] = chunkFileName(cv.coord);
        jc["simulated"] = cv.simulated;
        json objects = json::array();
        for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
            const ObjectVerdicts& ov = cv.objects[oi];
            json jo;
            jo["element"] = ov.elementIndex;
            jo["kind"] = ov.terrain ? "terrain" : "model";
            if (!ov.uuid.empty()) jo["uuid"] = ov.uuid;
            if (ov.windowObject < 0) {
                jo["skipped"] = true;
                objects.push_back(jo);
                continue;
            }
            uint32_t mask = 0;
            json groups = json::array();
            for (int g = 0; g < ov.groupCount; ++g) {
                const uint32_t gm = cv.groupMask(oi, g);
                mask |= gm;
                json bits = json::array();
                for (int l = 0; l < cv.lightCount; ++l) {
                    const Decision& d = cv.at(oi, g, l);
                    json jb;
                    jb["light"] = l + 1;
                    jb["bit"] = d.verdict == Verdict::Culled ? 0 : 1;
                    jb["verdict"] = verdictName(d.verdict);
                    if (!d.stage.empty()) jb["stage"] = std::string(d.stage);
                    if (!d.reason().empty()) jb["reason"] = std::string(d.reason());
                    if (const Witness* wp = d.witness()) {
                        const Witness& w = *wp;
                        jb["witness"] = {{"origin", vec(w.wsOrigin)}, {"direction", vec(w.wsDirection)},
                                         {"p", vec(w.wsP)}, {"q", vec(w.wsQ)}, {"receiver", w.receiver}};
                    }
                    bits.push_back(jb);
                }
                groups.push_back({{"group", g}, {"mask", gm}, {"lights", bits}});
            }
            jo["mask"] = mask;
            jo["groups"] = groups;
            objects.push_back(jo);
        }
        jc["objects"] = objects;
        chunks.push_back(jc);
    }
    j["chunks"] = chunks;
    const BitCounts c = countBits(r);
    j["summary"] = {{"chunks", r.chunks.size()}, {"groups", c.groups},   {"bits", c.bits},
                    {"kept", c.kept},            {"culled", c.culled},   {"provedKept", c.provedKept},
                    {"undecided", c.undecided},  {"culledBy", c.culledBy}};
    json warnings = json::array();
    for (const Diagnostic& d : r.diagnostics) warnings.push_back(d.what());
    j["warnings"] = warnings;
    return j;
}

}  // namespace shadowcull::cli
