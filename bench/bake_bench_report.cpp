// bake_bench's reports: see bake_bench_report.h.

#include "bench/bake_bench_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>

using nlohmann::json;
namespace fs = std::filesystem;

namespace shadowcull::bench {


std::string fmt(const char* f, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, f, v);
    return buf;
}

// 1234567 -> "1,234,567"
std::string count(uint64_t v) {
    std::string s = std::to_string(v), out;
    for (size_t k = 0; k < s.size(); ++k) {
        if (k > 0 && (s.size() - k) % 3 == 0) out += ',';
        out += s[k];
    }
    return out;
}

std::string seconds(double s) {
    if (s < 0.01) return fmt("%.4f", s);
    if (s < 10) return fmt("%.3f", s);
    return fmt("%.1f", s);
}

std::string rate(double perSecond) {
    if (perSecond >= 1e6) return fmt("%.2f M", perSecond / 1e6);
    if (perSecond >= 1e3) return fmt("%.1f k", perSecond / 1e3);
    return fmt("%.0f", perSecond);
}

std::string mib(double kib) {
    if (kib >= 1024.0 * 1024.0) return fmt("%.2f GiB", kib / (1024.0 * 1024.0));
    return fmt("%.0f MiB", kib / 1024.0);
}


// Bits past the reach stage per chunk baked: the work a chunk asks for (compare per-chunk
// times of worlds only where this matches).
double examinedPerChunk(const WorldRun& w) {
    const json* s = w.stage("raycast");
    return s ? (*s)["bitsExamined"].get<double>() / w.bake["chunksBaked"].get<double>() : 0.0;
}

void printWorlds(const std::vector<WorldRun>& runs) {
    std::printf("\n## Worlds\n\n");
    std::printf("| world | chunks | models | trees | rocks | buildings (+ interior props) | props | grass (castsShadow false) | "
                "floating / hidden | unique meshes (triangles) | placed triangles | lights (dir / point / spot) | "
                "on disk | files | generated in | generation peak RSS |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const WorldRun& w : runs) {
        const json& s = w.stats;
        auto kind = [&](const char* k) { return s["byKind"].contains(k) ? s["byKind"][k].get<uint64_t>() : 0; };
        const std::string gen = s.contains("generationWallSeconds")
                                    ? seconds(s["generationWallSeconds"].get<double>()) + " s (build " +
                                          seconds(s["buildSeconds"].get<double>()) + " + write " +
                                          seconds(s["writeSeconds"].get<double>()) + ")"
                                    : "?";
        std::printf("| %s (%dx%d) | %d | %s | %s | %s | %s (+ %s) | %s | %s | %s / %s | %d (%s) | %s | %d / %d / %d | %.1f MB | %s | %s%s | %s |\n",
                    w.spec.name.c_str(), w.spec.chunksX, w.spec.chunksZ, s["chunks"].get<int>(),
                    count(s["models"].get<uint64_t>()).c_str(), count(kind("tree")).c_str(),
                    (count(kind("rock")) + (kind("sheet") ? " + " + count(kind("sheet")) + " sheets" : std::string())).c_str(),
                    count(kind("building")).c_str(), count(kind("interior")).c_str(), count(kind("prop")).c_str(),
                    count(kind("grass")).c_str(), count(kind("floating")).c_str(), count(kind("hidden")).c_str(),
                    s["uniqueMeshes"].get<int>(), count(s["uniqueMeshTriangles"].get<uint64_t>()).c_str(),
                    count(s["placedTriangles"].get<uint64_t>()).c_str(), s["directionalLights"].get<int>(),
                    s["pointLights"].get<int>(), s["spotLights"].get<int>(), s["bytesOnDisk"].get<double>() / 1e6,
                    count(s["files"].get<uint64_t>()).c_str(), gen.c_str(),
                    s.value("cached", false) ? " (cached)" : "",
                    s.contains("generationPeakRssKiB") ? mib(s["generationPeakRssKiB"].get<double>()).c_str() : "?");
    }
}

// "1,234 (GPU 2.10 s)": a stage's GPU passes and, where the driver has timer queries,
// their GL_TIME_ELAPSED sum.
static std::string gpuCell(const json& stage) {
    std::string c = count(stage.value("gpuPasses", uint64_t(0)));
    if (stage.value("gpuTimed", false)) c += " (GPU " + seconds(stage["gpuSeconds"].get<double>()) + " s)";
    return c;
}

void printBake(const WorldRun& w) {
    const json& b = w.bake;
    const double chunks = b["chunksBaked"].get<double>();
    bool hasGpuStage = false;
    for (const json& s : b["stages"]) hasGpuStage = hasGpuStage || s["name"] == "gpu";
    std::printf("\n## World %s: bake (%s of %s chunks%s, %d threads%s)\n\n", w.spec.name.c_str(),
                count(b["chunksBaked"].get<uint64_t>()).c_str(), count(b["chunksTotal"].get<uint64_t>()).c_str(),
                w.partial() ? (w.contiguous ? ", consecutive in grid order from the middle; totals below are for these chunks"
                                            : ", evenly spread; totals below are for these chunks")
                            : "",
                b["threads"].get<int>(),
                hasGpuStage ? fmt(", GPU confirmation at %.0f px", b.value("gpuResolution", 0.0)).c_str() : "");
    std::printf("| stage | seconds | s per chunk | rays cast | rays/s | exact (CGAL) tests | GPU passes | bits examined | "
                "proved 0 | proved 1 |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    const double load = b["loadSeconds"].get<double>();
    std::printf("| load (read + meshes) | %s | %s | | | | | | | |\n", seconds(load).c_str(), seconds(load / chunks).c_str());
    double staged = 0;
    for (const json& s : b["stages"]) {
        const double sec = s["seconds"].get<double>();
        staged += sec;
        const uint64_t rays = s["raysCast"].get<uint64_t>();
        std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", s["name"].get<std::string>().c_str(),
                    seconds(sec).c_str(), seconds(sec / chunks).c_str(), rays ? count(rays).c_str() : "0",
                    rays && sec > 0 ? rate(double(rays) / sec).c_str() : "", count(s["exactTests"].get<uint64_t>()).c_str(),
                    gpuCell(s).c_str(), count(s["bitsExamined"].get<uint64_t>()).c_str(), count(s["provedCulled"].get<uint64_t>()).c_str(),
                    count(s["provedKept"].get<uint64_t>()).c_str());
    }
    // --write: the chunk files staged and committed.
    const double write = b.contains("writeSeconds") ? b["writeSeconds"].get<double>() : 0.0;
    if (b.contains("writeSeconds"))
        std::printf("| write (chunk files staged, then committed) | %s | %s | | | | | | | |\n", seconds(write).c_str(),
                    seconds(write / chunks).c_str());
    // The original GPU method runs as its own bake (printGpuBaseline).
    const double total = b["totalSeconds"].get<double>();
    const double other = std::max(0.0, total - load - staged - write);
    std::printf("| other (windows, verdict tables) | %s | %s | | | | | | | |\n", seconds(other).c_str(),
                seconds(other / chunks).c_str());
    const json& bits = b["bits"];
    std::printf("| **total** | **%s** | **%s** | | | | | %s bits | %s | %s |\n", seconds(total).c_str(),
                seconds(total / chunks).c_str(), count(bits["bits"].get<uint64_t>()).c_str(),
                count(bits["culled"].get<uint64_t>()).c_str(), count(bits["provedKept"].get<uint64_t>()).c_str());
    std::printf("\nBits: %s groups x lights = %s; proved 0: %s", count(bits["groups"].get<uint64_t>()).c_str(),
                count(bits["bits"].get<uint64_t>()).c_str(), count(bits["culled"].get<uint64_t>()).c_str());
    std::string by;
    for (auto it = bits["culledBy"].begin(); it != bits["culledBy"].end(); ++it)
        by += (by.empty() ? "" : ", ") + it.key() + " " + count(it.value().get<uint64_t>());
    std::printf(" (%s); proved 1: %s; kept undecided (written 1): %s.\n", by.c_str(),
                count(bits["provedKept"].get<uint64_t>()).c_str(), count(bits["undecided"].get<uint64_t>()).c_str());
    std::printf("Peak RSS of the bake process: %s (after load + first chunk: %s)%s. Process: wall %s s, CPU %s s "
                "(%.2f cores busy); load average before / after: %s / %s.",
                mib(double(w.bakePeakKiB)).c_str(), mib(b["rssAfterFirstChunkKiB"].get<double>()).c_str(),
                w.partial() && !w.contiguous ? " (spread chunks: a lower bound of a whole bake's)" : "",
                seconds(w.bakeJobWall).c_str(), seconds(w.bakeJobCpu).c_str(),
                w.bakeJobWall > 0 ? w.bakeJobCpu / w.bakeJobWall : 0.0, w.loadBefore.c_str(), w.loadAfter.c_str());
    if (!w.again.is_null())
        std::printf(" Baked again after L (the linearity target's bracket): %s s, CPU %s s, same verdicts: %s.",
                    seconds(w.again["totalSeconds"].get<double>()).c_str(), seconds(w.again["cpuSeconds"].get<double>()).c_str(),
                    w.again["bits"] == b["bits"] ? "yes" : "NO");
    if (w.partial())
        std::printf(" Projected full bake: %s s (%s s per chunk x %s chunks).", seconds(w.projectedTotal()).c_str(),
                    seconds(w.perChunk()).c_str(), count(b["chunksTotal"].get<uint64_t>()).c_str());
    if (!b.value("gl", std::string()).empty()) std::printf(" OpenGL: %s.", b["gl"].get<std::string>().c_str());
    for (const json& n : b.value("notes", json::array())) std::printf(" Note: %s.", n.get<std::string>().c_str());
    if (b["warnings"].get<uint64_t>() > 0) {
        std::printf(" **%s input warnings**, first:", count(b["warnings"].get<uint64_t>()).c_str());
        for (const json& m : b["firstWarnings"]) std::printf(" `%s`", m.get<std::string>().c_str());
    }
    std::printf("\n\n| light | type | proved 1 | proved 0 (by stage) | undecided | terrain bits proved 0 / 1 / undecided | "
                "undecided share of caster triangles |\n|---|---|---:|---|---:|---:|---:|\n");
    for (const json& l : b["lights"]) {
        const json& c = l["counts"];
        std::string culled;
        for (auto it = c.begin(); it != c.end(); ++it)
            if (it.key().rfind("culled:", 0) == 0)
                culled += (culled.empty() ? "" : ", ") + it.key().substr(7) + " " + count(it.value().get<uint64_t>());
        const uint64_t tris = c.value("triangles", uint64_t(0)), undecidedTris = c.value("undecidedTriangles", uint64_t(0));
        std::printf("| %s | %s | %s | %s | %s | %s / %s / %s | %s |\n", l["name"].get<std::string>().c_str(),
                    l["type"].get<std::string>().c_str(), count(c.value("kept", uint64_t(0))).c_str(), culled.c_str(),
                    count(c.value("undecided", uint64_t(0))).c_str(), count(c.value("terrain:culled", uint64_t(0))).c_str(),
                    count(c.value("terrain:kept", uint64_t(0))).c_str(), count(c.value("terrain:undecided", uint64_t(0))).c_str(),
                    tris ? fmt("%.2f %%", 100.0 * double(undecidedTris) / double(tris)).c_str() : "");
    }
}

// Compares the verdict codes of the analytic bake and the GPU method's (same chunks).
void compareWithGpu(WorldRun& w, const fs::path& analyticBits, const fs::path& gpuBits) {
    std::ifstream a(analyticBits, std::ios::binary), g(gpuBits, std::ios::binary);
    const std::string ca((std::istreambuf_iterator<char>(a)), {}), cg((std::istreambuf_iterator<char>(g)), {});
    if (ca.size() != cg.size()) {
        w.gpuFailure = "its verdict table does not match the analytic bake's";
        w.gpuBaked = false;
        return;
    }
    w.comparedBits = ca.size();
    for (size_t k = 0; k < ca.size(); ++k) {
        w.gpuCulls += cg[k] == 'c';
        w.gpuFalseCulls += cg[k] == 'c' && ca[k] == 'k';        // culled, but a witness ray exists
        w.analyticCullsGpuKeeps += ca[k] == 'c' && cg[k] != 'c';  // proved 0 where the GPU method keeps
    }
}

void compareWindowOnly(WorldRun& w, const fs::path& wholeBits, const fs::path& windowBits) {
    std::ifstream a(wholeBits, std::ios::binary), b(windowBits, std::ios::binary);
    const std::string whole((std::istreambuf_iterator<char>(a)), {}), window((std::istreambuf_iterator<char>(b)), {});
    if (whole.size() != window.size()) {
        w.windowBaked = false;
        return;
    }
    auto name = [](char c) { return c == 'k' ? "kept" : c == 'c' ? "culled" : "undecided"; };
    json diff = json::object();
    for (size_t k = 0; k < whole.size(); ++k)
        if (whole[k] != window[k]) diff[std::string("window ") + name(window[k]) + ", whole " + name(whole[k])] =
                                       diff.value(std::string("window ") + name(window[k]) + ", whole " + name(whole[k]), uint64_t(0)) + 1;
    w.windowDiff = diff;
}

void printWindowOnly(const std::vector<WorldRun>& runs) {
    bool any = false;
    for (const WorldRun& w : runs) any = any || w.windowRun;
    if (!any) return;
    std::printf("\n## Receivers from the whole space vs the neighbours rectangle (--window-only)\n\n");
    std::printf("The same analytic bake, once with windows that hold every chunk a shadow reaches (the default) and once "
                "with the `neighbours` rectangle as before issue 33, one child process each. \"window culled, whole kept\": "
                "a false cull of the window-only bake (its shadow has a witness on a receiver beyond the rectangle).\n\n");
    std::printf("| world | whole s | window s | whole / window (CPU time) | chunks per window (past the rectangle) | peak loaded chunks "
                "(whole / window) | peak RSS (whole / window) | culled (whole / window) | undecided (whole / window) | "
                "bits that differ |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n");
    for (const WorldRun& w : runs) {
        if (!w.windowRun) continue;
        if (!w.windowBaked) {
            std::printf("| %s | | n/a (failed) | | | | | | | |\n", w.spec.name.c_str());
            continue;
        }
        const json &a = w.bake, &b = w.windowBake;
        const double ta = a["totalSeconds"].get<double>(), tb = b["totalSeconds"].get<double>();
        const double cpuRatio = a["cpuSeconds"].get<double>() / std::max(1e-9, b["cpuSeconds"].get<double>());
        const double windows = std::max(1.0, a["reach"]["windows"].get<double>());
        std::string diff;
        for (auto it = w.windowDiff.begin(); it != w.windowDiff.end(); ++it)
            diff += (diff.empty() ? "" : "; ") + it.key() + ": " + count(it.value().get<uint64_t>());
        std::printf("| %s | %s | %s | %.2fx (%.2fx) | %.1f (%.1f) | %s / %s | %s / %s | %s / %s | %s / %s | %s |\n", w.spec.name.c_str(),
                    seconds(ta).c_str(), seconds(tb).c_str(), ta / tb, cpuRatio, a["reach"]["chunks"].get<double>() / windows,
                    a["reach"]["chunksBeyond"].get<double>() / windows, count(a["peakLoadedChunks"].get<uint64_t>()).c_str(),
                    count(b["peakLoadedChunks"].get<uint64_t>()).c_str(), mib(double(w.bakePeakKiB)).c_str(),
                    mib(double(w.windowPeakKiB)).c_str(), count(a["bits"]["culled"].get<uint64_t>()).c_str(),
                    count(b["bits"]["culled"].get<uint64_t>()).c_str(), count(a["bits"]["undecided"].get<uint64_t>()).c_str(),
                    count(b["bits"]["undecided"].get<uint64_t>()).c_str(), diff.empty() ? "none" : diff.c_str());
    }
    std::printf("\n| world | light | culled (whole / window) | kept by a witness (whole / window) | undecided (whole / "
                "window) |\n|---|---|---:|---:|---:|\n");
    auto culled = [](const json& counts) {
        uint64_t n = 0;
        for (auto it = counts.begin(); it != counts.end(); ++it)
            if (it.key().rfind("culled:", 0) == 0) n += it.value().get<uint64_t>();
        return n;
    };
    for (const WorldRun& w : runs) {
        if (!w.windowRun || !w.windowBaked) continue;
        for (size_t l = 0; l < w.bake["lights"].size() && l < w.windowBake["lights"].size(); ++l) {
            const json &a = w.bake["lights"][l]["counts"], &b = w.windowBake["lights"][l]["counts"];
            std::printf("| %s | %s | %s / %s | %s / %s | %s / %s |\n", w.spec.name.c_str(),
                        w.bake["lights"][l]["name"].get<std::string>().c_str(), count(culled(a)).c_str(), count(culled(b)).c_str(),
                        count(a.value("kept", uint64_t(0))).c_str(), count(b.value("kept", uint64_t(0))).c_str(),
                        count(a.value("undecided", uint64_t(0))).c_str(), count(b.value("undecided", uint64_t(0))).c_str());
        }
    }
}

void printGpuBaseline(const std::vector<WorldRun>& runs) {
    bool any = false;
    for (const WorldRun& w : runs) any = any || w.gpuRun;
    if (!any) return;
    std::printf("\n## The original GPU method (BakeOptions::gpuBaseline) vs the analytic bake\n\n");
    std::printf("Same chunks, one child process each. False culls of the GPU method: bits it culls for which the "
                "analytic bake has a witness ray (the shadow provably matters).\n\n");
    std::printf("| world | resolution | gpu baseline s | s per chunk | analytic bake s | GPU / analytic | GPU culls | GPU false "
                "culls | analytic culls the GPU keeps | GPU passes | peak RSS |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const WorldRun& w : runs) {
        if (!w.gpuRun) continue;
        const double analytic = w.bake["totalSeconds"].get<double>();
        if (!w.gpuBaked) {
            std::printf("| %s | %d | n/a (failed: %s) | | %s | | | | | | |\n", w.spec.name.c_str(),
                        w.gpuBake.value("gpuResolution", 0), w.gpuFailure.c_str(), seconds(analytic).c_str());
            continue;
        }
        const double gpu = w.gpuBake["totalSeconds"].get<double>();
        uint64_t passes = 0;
        for (const json& st : w.gpuBake["stages"]) passes += st.value("gpuPasses", uint64_t(0));
        std::printf("| %s | %d | %s | %s | %s | %.2fx | %s | %s | %s | %s | %s |\n", w.spec.name.c_str(),
                    w.gpuBake["gpuResolution"].get<int>(), seconds(gpu).c_str(),
                    seconds(gpu / w.gpuBake["chunksBaked"].get<double>()).c_str(), seconds(analytic).c_str(), gpu / analytic,
                    count(w.gpuCulls).c_str(), count(w.gpuFalseCulls).c_str(), count(w.analyticCullsGpuKeeps).c_str(),
                    count(passes).c_str(), mib(double(w.gpuPeakKiB)).c_str());
    }
}



// The raycast stage against the bare Embree loops, per world.
void printEmbreeComparison(const std::vector<WorldRun>& runs) {
    std::printf("\n## Raycast stage vs a bare Embree loop over the same scene\n\n");
    std::printf("Scene: the window of chunk (0,0) (it and its 8 neighbours), built as the stage builds it. Rays: from "
                "each light through the sample points of every centre group it reaches, each light's share weighted by the "
                "bits the stage examined for it; the occlusion loops trace the segment light -> sample point (the shadow "
                "ray of \"is p lit\"), the closest-hit and all-hit loops the stage's whole ray. Each loop traces as many "
                "rays as the stage made Embree calls (capped), median of 3. The stage's rays/s is its Embree calls "
                "(occlusion-packet rays, p rays, q steps) over its whole time, scene builds and sampling included.\n\n");
    std::printf("| world | window objects / triangles | rays per loop | bare rtcOccluded1 rays/s (occluded) | "
                "bare rtcOccluded16 rays/s | bare closest-hit rtcIntersect1 + alpha filter rays/s | "
                "bare all-hit rtcIntersect1 rays/s (hits per ray) | pipeline raycast stage rays/s | pipeline / occluded1 | "
                "pipeline / occluded16 | pipeline / closest-hit |\n");
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const WorldRun& w : runs) {
        if (!w.baked) continue;
        const double pipe = w.pipelineRaysPerSecond();
        if (!w.baselined) {
            std::printf("| %s | | | n/a | n/a | n/a | n/a | %s | n/a | n/a | n/a |\n", w.spec.name.c_str(), rate(pipe).c_str());
            continue;
        }
        const json& b = w.baseline;
        const double o1 = b["occluded1"]["raysPerSecond"].get<double>(), o16 = b["occluded16"]["raysPerSecond"].get<double>();
        const double ch = b["closest1"]["raysPerSecond"].get<double>();
        const double ah = b["allhits1"]["raysPerSecond"].get<double>();
        std::printf("| %s | %s / %s | %s | %s (%.0f%%) | %s | %s | %s (%.1f) | %s | **%.3f** | **%.3f** | %.3f |\n",
                    w.spec.name.c_str(), count(b["window"]["objects"].get<uint64_t>()).c_str(),
                    count(b["window"]["triangles"].get<uint64_t>()).c_str(), count(b["rays"].get<uint64_t>()).c_str(),
                    rate(o1).c_str(), 100 * b["occluded1"]["metric"].get<double>(), rate(o16).c_str(), rate(ch).c_str(),
                    rate(ah).c_str(), b["allhits1"]["metric"].get<double>(), rate(pipe).c_str(), pipe / o1, pipe / o16,
                    pipe / ch);
    }
}

// The baked world named `name`, if any.
const WorldRun* bakedWorld(const std::vector<WorldRun>& runs, const char* name) {
    const WorldRun* found = nullptr;
    for (const WorldRun& w : runs)
        if (w.spec.name == name && w.baked) found = &w;
    return found;
}

// The targets on S, M, L: against the GPU method, the bare Embree loop, linear time and
// L's memory.
void printForestTargets(const std::vector<WorldRun>& runs, const WorldRun* M, const WorldRun* L) {
    std::printf("\n## Targets (issue 6), measured side by side in this run\n\n| target | measured | status |\n|---|---|---|\n");
    {
        const char* what = "analytic bake >= %.0fx faster than the GPU method at 2048 on M, zero false culls";
        std::printf("| ");
        std::printf(what, kTargetGpuSpeedup);
        if (M && M->gpuBaked) {
            const double speedup = M->gpuBake["totalSeconds"].get<double>() / M->bake["totalSeconds"].get<double>();
            const int res = M->gpuBake["gpuResolution"].get<int>();
            std::printf(" | %.2fx (GPU method at %d px: %s s, analytic: %s s%s); the analytic bake culls only with a proof "
                        "(false culls are not measured against an independent reference here: `shadowcull sweep`); the "
                        "GPU method culls %s bits that have a witness | %s |\n",
                        speedup, res, seconds(M->gpuBake["totalSeconds"].get<double>()).c_str(),
                        seconds(M->bake["totalSeconds"].get<double>()).c_str(), M->partial() ? ", partial bake" : "",
                        count(M->gpuFalseCulls).c_str(),
                        res != 2048 ? "not measured (resolution is not 2048)" : speedup >= kTargetGpuSpeedup ? "met" : "NOT met");
        } else if (M && M->gpuRun) {
            std::printf(" | gpu baseline s: n/a (the GPU method failed: %s) | not measured |\n", M->gpuFailure.c_str());
        } else {
            std::printf(" | gpu baseline s: n/a (not run: needs M and --gpu-baseline M) | not measured |\n");
        }
    }
    {
        const WorldRun* w = M;
        if (!w || !w->baselined)
            for (const WorldRun& r : runs)
                if (r.baselined) w = &r;
        if (w && w->baselined) {
            const double ratio = w->pipelineRaysPerSecond() / w->baseline["occluded1"]["raysPerSecond"].get<double>();
            std::printf("| raycast stage rays/s >= %.1f x bare Embree occlusion loop (rtcOccluded1), same scene | %.3f (world %s) | %s |\n",
                        kTargetRaysRatio, ratio, w->spec.name.c_str(), ratio >= kTargetRaysRatio ? "met" : "NOT met");
        } else {
            std::printf("| raycast stage rays/s >= %.1f x bare Embree occlusion loop | n/a (baseline not run) | not measured |\n",
                        kTargetRaysRatio);
        }
    }
    if (M && L) {
        const double ratio = L->perChunk() / M->meanPerChunk();
        const double cpuRatio = L->cpuPerChunk() / M->meanCpuPerChunk();
        const bool projected = L->partial() || M->partial();
        const std::string mTimes =
            M->again.is_null()
                ? seconds(M->perChunk()) + " s/chunk"
                : seconds(M->meanPerChunk()) + " s/chunk, the mean of its bakes before and after L: " + seconds(M->perChunk()) +
                      " and " + seconds(M->againPerChunk());
        std::printf("| L time per chunk within %.0f%% of M's (L total ~ 9x M) | %.3f (L %s s/chunk, M %s; bits past "
                    "the reach stage per chunk: L %.0f, M %.0f)%s | %s |\n",
                    kTargetLinearity * 100, ratio, seconds(L->perChunk()).c_str(), mTimes.c_str(),
                    examinedPerChunk(*L), examinedPerChunk(*M),
                    (fmt("; CPU time per chunk L / M: %.3f", cpuRatio) + (projected ? ", from a partial bake" : "")).c_str(),
                    [&] {
                        // Wall time is the target's measure; CPU time tells apart a pipeline that
                        // does not scale from a machine whose other load changed between the bakes.
                        const bool wallMet = std::abs(ratio - 1) <= kTargetLinearity;
                        const bool cpuMet = std::abs(cpuRatio - 1) <= kTargetLinearity;
                        std::string st = wallMet ? "met" : "NOT met";
                        if (wallMet != cpuMet) st += cpuMet ? " on wall time (met on CPU time)" : " on wall time (NOT met on CPU time)";
                        return st + (projected ? " (projected)" : "");
                    }()
                        .c_str());
    } else {
        std::printf("| L time per chunk within %.0f%% of M's | n/a (needs M and L in one run: --sizes M,L) | not measured |\n",
                    kTargetLinearity * 100);
    }
    if (L) {
        const double gib = L->projectedPeakKiB() / (1024.0 * 1024.0);
        std::printf("| peak memory of L < %.0f GiB | %.2f GiB%s | %s |\n", kTargetMemoryGiB, gib,
                    L->partial() ? (L->contiguous ? " (consecutive chunks: what a whole bake holds)" : " (spread chunks: a lower bound)") : "",
                    gib < kTargetMemoryGiB ? (L->partial() ? "met (projected)" : "met")
                                           : (L->partial() ? "NOT met (projected)" : "NOT met"));
    } else {
        std::printf("| peak memory of L < %.0f GiB | n/a (L not baked) | not measured |\n", kTargetMemoryGiB);
    }
}

// The whole bake of the dense world against the same placements of 2k-triangle meshes
// (D2k), both baked in this run.
void printDenseTargets(const std::vector<WorldRun>& runs) {
    const WorldRun* D = bakedWorld(runs, "D");
    const WorldRun* D2k = bakedWorld(runs, "D2k");
    if (D || D2k) {
        std::printf("\n## Targets (issue 13), measured side by side in this run\n\n| target | measured | status |\n|---|---|---|\n");
        if (D && D2k && D->bake["chunksBaked"] == D2k->bake["chunksBaked"]) {
            const double ratio = D->bake["totalSeconds"].get<double>() / D2k->bake["totalSeconds"].get<double>();
            const double cpuRatio = D->bake["cpuSeconds"].get<double>() / D2k->bake["cpuSeconds"].get<double>();
            // With --rounds: each world's median round, and the ratio of every round's pair.
            std::string perRound;
            const size_t n = std::min(D->rounds.size(), D2k->rounds.size());
            if (n > 1) {
                std::vector<double> r(n);
                for (size_t k = 0; k < n; ++k)
                    r[k] = D->rounds[k]["totalSeconds"].get<double>() / D2k->rounds[k]["totalSeconds"].get<double>();
                const auto [lo, hi] = std::minmax_element(r.begin(), r.end());
                perRound = fmt(", medians of %.0f rounds in alternating order; ", double(n)) + fmt("rounds %.2fx", *lo) +
                           fmt(" to %.2fx", *hi);
            }
            std::printf("| whole bake of D within %.0fx of D2k (same placements, 2k-triangle meshes) | %.2fx (D %s s, D2k %s s; "
                        "CPU time %.2fx%s)%s | %s |\n",
                        kTargetDenseRatio, ratio, seconds(D->bake["totalSeconds"].get<double>()).c_str(),
                        seconds(D2k->bake["totalSeconds"].get<double>()).c_str(), cpuRatio, perRound.c_str(),
                        D->partial() ? fmt(", %.0f chunks of each", D->bake["chunksBaked"].get<double>()).c_str() : "",
                        ratio <= kTargetDenseRatio ? "met" : "NOT met");
        } else {
            std::printf("| whole bake of D within %.0fx of D2k | n/a (needs D and D2k on the same chunks: --sizes D,D2k) | not "
                        "measured |\n",
                        kTargetDenseRatio);
        }
        std::printf("| geometry stage >= 10x faster on D, >= 3x on R than before commit 82a0666, same verdicts | not measured "
                    "by this program (needs the old code): see docs/performance.md, issue 13 | not measured |\n");
    }
}

// Memory follows the window, so a world 100x the size of M needs about M's memory and the
// same time per chunk.
void printWindowTargets(const std::vector<WorldRun>& runs, const WorldRun* M) {
    const WorldRun* XL = bakedWorld(runs, "XL");
    if (XL) {
        std::printf("\n## Targets (issue 16), measured side by side in this run\n\n| target | measured | status |\n|---|---|---|\n");
        if (M) {
            const double mem = double(XL->bakePeakKiB) / double(M->bakePeakKiB);
            std::printf("| peak RSS of XL (%s chunks read whole, %s baked) within %.1fx of M's | %.2fx (XL %s, M %s; chunks held "
                        "at once: XL %s, M %s) | %s |\n",
                        count(XL->bake["chunksTotal"].get<uint64_t>()).c_str(), count(XL->bake["chunksBaked"].get<uint64_t>()).c_str(),
                        kTargetWindowMemory, mem, mib(double(XL->bakePeakKiB)).c_str(), mib(double(M->bakePeakKiB)).c_str(),
                        count(XL->bake.value("peakLoadedChunks", uint64_t(0))).c_str(),
                        count(M->bake.value("peakLoadedChunks", uint64_t(0))).c_str(), mem <= kTargetWindowMemory ? "met" : "NOT met");
            const double t = XL->wholeBakePerChunk() / M->wholeBakePerChunk();
            const double cpu = XL->wholeBakeCpuPerChunk() / M->wholeBakeCpuPerChunk();
            // One-sided: a world 100 times M's must not make a chunk slower (XL's chunks may
            // ask for less work than M's: fewer local lights reach its middle).
            const bool wallMet = t <= 1 + kTargetLinearity, cpuMet = cpu <= 1 + kTargetLinearity;
            std::printf("| XL time per chunk at most %.0f%% above M's | %.3f (XL %s s, M %s s per chunk; the scan of XL's %s chunk "
                        "files %s s, counted per world chunk); CPU time per chunk the same way: %.3f (XL %s s, M %s s; bits "
                        "past the reach stage per chunk: XL %.0f, M %.0f) | %s |\n",
                        kTargetLinearity * 100, t, seconds(XL->wholeBakePerChunk()).c_str(), seconds(M->wholeBakePerChunk()).c_str(),
                        count(XL->bake["chunksTotal"].get<uint64_t>()).c_str(), seconds(XL->bake["loadSeconds"].get<double>()).c_str(),
                        cpu, seconds(XL->wholeBakeCpuPerChunk()).c_str(), seconds(M->wholeBakeCpuPerChunk()).c_str(),
                        examinedPerChunk(*XL), examinedPerChunk(*M),
                        wallMet ? (cpuMet ? "met" : "met on wall time (NOT met on CPU time)")
                                : (cpuMet ? "NOT met on wall time (met on CPU time)" : "NOT met"));
        } else {
            std::printf("| peak RSS of XL within %.1fx of M's | n/a (needs M and XL in one run: --sizes M,XL) | not measured |\n",
                        kTargetWindowMemory);
        }
    }
}

// Other processes on the machine skew wall times (and so every ratio above).
void printLoadCaution(const std::vector<WorldRun>& runs) {
    double worstLoad = 0;
    for (const WorldRun& w : runs)
        for (const std::string& l : {w.loadBefore, w.loadAfter}) worstLoad = std::max(worstLoad, std::atof(l.c_str()));
    if (worstLoad > double(std::thread::hardware_concurrency()))
        std::printf("\n**Caution:** the 1-minute load average reached %.2f on %u hardware threads during this run: "
                    "other processes took CPU time, so wall times and the ratios above are skewed (see \"cores busy\" and "
                    "the CPU-time ratio). Rerun on an idle machine for figures to quote.\n",
                    worstLoad, std::thread::hardware_concurrency());
}

// The exact stage at the cost of the rays (issue 38): per world its tests per bit it
// decided, and on R its time against the raycast stage's; on S the raycast stage against
// the bare occlusion loop.
void printExactStageTargets(const std::vector<WorldRun>& runs) {
    const WorldRun* R = bakedWorld(runs, "R");
    const WorldRun* S = bakedWorld(runs, "S");
    if (!R && !S) return;
    std::printf("\n## Targets (issue 38), measured side by side in this run\n\n| target | measured | status |\n|---|---|---|\n");
    if (R && R->stage("geometry") && R->stage("raycast")) {
        const double g = (*R->stage("geometry"))["seconds"].get<double>(), r = (*R->stage("raycast"))["seconds"].get<double>();
        std::printf("| geometry stage at most the raycast stage's time on R | %.2fx (geometry %s s, raycast %s s) | %s |\n",
                    r > 0 ? g / r : 0.0, seconds(g).c_str(), seconds(r).c_str(), g <= r ? "met" : "NOT met");
    }
    if (S && S->baselined) {
        const double ratio = S->pipelineRaysPerSecond() / S->baseline["occluded1"]["raysPerSecond"].get<double>();
        std::printf("| raycast stage at least 0.8 of the bare rtcOccluded1 loop on S | %.3f | %s |\n", ratio,
                    ratio >= 0.8 ? "met" : "NOT met");
    }
    if (R && R->bake.contains("writeSeconds")) {
        const double w = R->bake["writeSeconds"].get<double>(), t = R->bake["totalSeconds"].get<double>();
        std::printf("| write at most 5 %% of the bake on R | %.1f %% (write %s s of %s s, %s chunk files) | %s |\n",
                    t > 0 ? 100 * w / t : 0.0, seconds(w).c_str(), seconds(t).c_str(),
                    count(R->bake["chunksBaked"].get<uint64_t>()).c_str(), w <= 0.05 * t ? "met" : "NOT met");
    } else if (R) {
        std::printf("| write at most 5 %% of the bake on R | not measured: these bakes write nothing (--write) | not measured |\n");
    }
    std::printf("\nExact tests per bit the geometry stage proved 0:");
    for (const WorldRun& w : runs) {
        const json* g = w.stage("geometry");
        if (!g) continue;
        const double tests = (*g)["exactTests"].get<double>(), proved = (*g)["provedCulled"].get<double>();
        const double examined = (*g)["bitsExamined"].get<double>();
        std::printf(" %s %s (%s tests, %s bits proved of %s examined: %s per bit examined);", w.spec.name.c_str(),
                    proved > 0 ? fmt("%.1f", tests / proved).c_str() : "n/a", count(uint64_t(tests)).c_str(),
                    count(uint64_t(proved)).c_str(), count(uint64_t(examined)).c_str(),
                    examined > 0 ? fmt("%.1f", tests / examined).c_str() : "n/a");
    }
    std::printf("\n");
}

void printComparisons(const std::vector<WorldRun>& runs) {
    printEmbreeComparison(runs);
    printExactStageTargets(runs);
    const WorldRun* M = bakedWorld(runs, "M");
    printForestTargets(runs, M, bakedWorld(runs, "L"));
    printDenseTargets(runs);
    printWindowTargets(runs, M);
    printLoadCaution(runs);
}

}  // namespace shadowcull::bench
