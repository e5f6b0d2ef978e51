// bake_bench's reports (Markdown on stdout): the worlds, each bake's stage table, the
// original GPU method beside the analytic bake, the bare-Embree comparison and the
// targets of issues 6, 13 and 16, all from the figures the bake children wrote.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench/machine.h"
#include "bench/world_gen.h"

namespace shadowcull::bench {

// Targets of issue 6.
inline constexpr double kTargetRaysRatio = 0.5;       // pipeline rays/s >= half of bare Embree occlusion
inline constexpr double kTargetLinearity = 0.10;      // L per chunk within 10% of M per chunk
inline constexpr double kTargetMemoryGiB = 4.0;       // peak memory of L
inline constexpr double kTargetGpuSpeedup = 10.0;     // analytic bake vs GPU method at 2048, world M
inline constexpr double kTargetDenseRatio = 2.0;      // issue 13: whole bake of D within 2x of D2k
inline constexpr double kTargetWindowMemory = 1.5;    // issue 16: peak RSS of XL within 1.5x of M's

std::string fmt(const char* f, double v);
std::string count(uint64_t v);
std::string seconds(double s);
std::string rate(double perSecond);
std::string mib(double kib);

struct WorldRun {
    WorldSpec spec;
    std::filesystem::path dir;
    nlohmann::json stats, bake, baseline;
    bool baked = false, baselined = false;
    long bakePeakKiB = 0;
    double bakeJobWall = 0, bakeJobCpu = 0;
    std::string loadBefore, loadAfter;
    long baselinePeakKiB = 0;
    // The original GPU method on the same chunks (--gpu-baseline).
    bool gpuRun = false, gpuBaked = false;
    std::string gpuFailure;
    nlohmann::json gpuBake;
    long gpuPeakKiB = 0;
    uint64_t gpuCulls = 0, gpuFalseCulls = 0, analyticCullsGpuKeeps = 0, comparedBits = 0;
    // The same analytic bake with the `neighbours` rectangle as its windows (--window-only);
    // `windowDiff`: how its bits differ from the whole-space bake's (compareWindowOnly).
    bool windowRun = false, windowBaked = false;
    nlohmann::json windowBake, windowDiff;
    long windowPeakKiB = 0;
    // M baked again right after L (with both), so that the two bakes the linearity target
    // compares bracket L in time: the mean of M's two bakes against L corrects a drift of
    // the machine's speed over the run, and their difference shows its noise.
    nlohmann::json again;
    // --rounds N: every round's bake of this world, in the order run ({round, position in
    // the round, totalSeconds, cpuSeconds, peakRssKiB}); `bake` is the median one's.
    nlohmann::json rounds = nlohmann::json::array();

    bool partial() const { return baked && bake["chunksBaked"].get<uint64_t>() < bake["chunksTotal"].get<uint64_t>(); }
    double perChunk() const { return bake["totalSeconds"].get<double>() / bake["chunksBaked"].get<double>(); }
    double cpuPerChunk() const { return bake["cpuSeconds"].get<double>() / bake["chunksBaked"].get<double>(); }
    // The second bake's figures (valid when `again` is set), and the mean of both bakes.
    double againPerChunk() const { return again["totalSeconds"].get<double>() / again["chunksBaked"].get<double>(); }
    double againCpuPerChunk() const { return again["cpuSeconds"].get<double>() / again["chunksBaked"].get<double>(); }
    double meanPerChunk() const { return again.is_null() ? perChunk() : (perChunk() + againPerChunk()) / 2; }
    double meanCpuPerChunk() const { return again.is_null() ? cpuPerChunk() : (cpuPerChunk() + againCpuPerChunk()) / 2; }
    double projectedTotal() const { return perChunk() * bake["chunksTotal"].get<double>(); }
    // Seconds per chunk of a bake of the whole world: the scan of every chunk file once per
    // world chunk, the rest per chunk baked (a partial bake of XL scans all of it).
    double wholeBakePerChunk() const {
        const double load = bake["loadSeconds"].get<double>();
        return (bake["totalSeconds"].get<double>() - load) / bake["chunksBaked"].get<double>() +
               load / bake["chunksTotal"].get<double>();
    }
    // The same in CPU time (every thread; robust to other processes taking the cores).
    double wholeBakeCpuPerChunk() const {
        const double load = bake.value("loadCpuSeconds", 0.0);
        return (bake["cpuSeconds"].get<double>() - load) / bake["chunksBaked"].get<double>() + load / bake["chunksTotal"].get<double>();
    }
    const nlohmann::json* stage(const std::string& name) const {
        for (const nlohmann::json& s : bake["stages"])
            if (s["name"] == name) return &s;
        return nullptr;
    }
    double pipelineRaysPerSecond() const {
        const nlohmann::json* s = stage("raycast");
        if (!s || (*s)["seconds"].get<double>() <= 0) return 0;
        return (*s)["raysCast"].get<double>() / (*s)["seconds"].get<double>();
    }
    // Peak RSS of a bake of the whole world. The bake keeps no verdicts and holds the
    // chunks its sliding window still needs (about two columns of the grid), so a partial
    // bake that ran through two columns or more (--contiguous) held what a whole bake
    // holds; spread chunks hold less, and their peak is only a lower bound.
    double projectedPeakKiB() const { return double(bakePeakKiB); }
    bool contiguous = false;  // a partial bake of consecutive chunks (--contiguous)
};

// Bits past the reach stage per chunk baked: the work a chunk asks for (compare per-chunk
// times of worlds only where this matches).
double examinedPerChunk(const WorldRun& w);
void printWorlds(const std::vector<WorldRun>& runs);
void printBake(const WorldRun& w);
// Counts the GPU method's culls, false culls and the analytic bake's extra culls from the
// two bakes' verdict codes.
void compareWithGpu(WorldRun& w, const std::filesystem::path& analyticBits, const std::filesystem::path& gpuBits);
void printGpuBaseline(const std::vector<WorldRun>& runs);
// Counts how the window-only bake's bits differ from the whole-space bake's, by what each
// bake says ("window culled, whole kept": a false cull of the window-only bake, its shadow
// witnessed beyond the rectangle).
void compareWindowOnly(WorldRun& w, const std::filesystem::path& wholeBits, const std::filesystem::path& windowBits);
void printWindowOnly(const std::vector<WorldRun>& runs);
// The bare-Embree comparison, the targets of issues 6, 13 and 16, and a caution when other
// processes loaded the machine.
void printComparisons(const std::vector<WorldRun>& runs);

}  // namespace shadowcull::bench
