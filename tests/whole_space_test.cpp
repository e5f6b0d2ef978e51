// Receivers are every surface of the space (issue 33, ../shared/spec/semantics.md): on a
// generated world under a sun 10 degrees up, whose shadows run chunks past a neighbours-1
// window, the bake gives the same bits whatever `neighbours` says, and no bit it culls has
// a witness anywhere in the world, found by a dense ray search over a window that holds
// every chunk of the space.

#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bench/world_gen.h"
#include "cli/pipeline.h"
#include "core/stage.h"
#include "core/window.h"
#include "io/scene_reader.h"
#include "raycast/raycast_stage.h"
#include "tests/test_files.h"

using namespace shadowcull;
using shadowcull::testing::freshTestDir;
namespace fs = std::filesystem;

namespace {

// 6 x 2 chunks of the benchmark forest, thinned: terrain, trees, rocks, buildings, a few
// floating objects, lights that include `sun_low`, 10 degrees above the horizon.
std::string writeLowSunWorld(const fs::path& dir, int neighbours) {
    bench::WorldSpec w;
    w.name = "whole-space-test";
    w.chunksX = 6, w.chunksZ = 2;
    w.seed = 3303;
    w.objectsPerChunk = 14;
    w.terrainSamples = 9;
    w.localLights = 2;
    w.neighbours = neighbours;
    const fs::path space = dir / ("space-n" + std::to_string(neighbours));
    bench::writeWorld(w, space.string());
    return space.string();
}

// `neighbourWindows`: windows of the neighbours rectangle, as before issue 33 (the
// benchmarks' window-only bake).
cli::BakeResult bakeAll(const std::string& space, bool neighbourWindows = false) {
    cli::BakeOptions opt;
    opt.spaceDir = space;
    opt.write = false;
    opt.gpuResolution = 256;
    opt.neighbourWindows = neighbourWindows;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

// "verdict:stage" of every bit, chunk by chunk.
std::map<ChunkCoord, std::vector<std::string>> codes(const cli::BakeResult& r) {
    std::map<ChunkCoord, std::vector<std::string>> out;
    for (const ChunkVerdicts& cv : r.chunks)
        for (const ObjectVerdicts& ov : cv.objects)
            for (const Decision& d : ov.decisions)
                out[cv.coord].push_back(verdictName(d.verdict) + std::string(":") + std::string(d.stage));
    return out;
}

// Marks every bit the bake did not cull as decided, so that the dense search below looks
// only at the 0s, less those the input settles by definition (castsShadow false, no area:
// the engine draws no shadow for them). Returns how many bits are left to search.
size_t keepOnlyTheCulled(const ChunkVerdicts& baked, ChunkVerdicts& search) {
    size_t left = 0;
    for (size_t oi = 0; oi < search.objects.size(); ++oi)
        for (size_t k = 0; k < search.objects[oi].decisions.size(); ++k) {
            Decision& d = search.objects[oi].decisions[k];
            if (d.verdict != Verdict::Undecided) continue;
            const Decision& b = baked.objects[oi].decisions[k];
            if (b.verdict == Verdict::Culled && b.stage != std::string_view("input")) ++left;
            else decide(d, Verdict::Kept, "test", "not a 0 of the bake: not searched");
        }
    return left;
}

struct DenseSearch {
    size_t searched = 0;                // bits culled by the bake and searched
    std::vector<std::string> witnessed;  // of those, the ones a witness ray proves 1
};

// Searches a witness for every bit `baked` culled, densely, in windows that hold every
// chunk of the space: a shadow anywhere in the world is a receiver here.
DenseSearch searchTheWholeWorld(const std::string& space, const cli::BakeResult& baked) {
    DenseSearch out;
    Expected<Space> world = loadSpace(space, "");
    EXPECT_TRUE(world) << (world ? "" : world.error().what());
    if (!world) return out;
    std::vector<ChunkCoord> every;
    for (const auto& [c, cf] : world->chunks) every.push_back(c);
    // Far denser than the bake's own search (256 area samples), every caster also through
    // the receivers in its shadow.
    raycast::RaycastOptions dense;
    dense.areaSamples = 2048;
    dense.maxFeatureSamples = 4096;
    dense.receiverSamples = 8192;
    dense.maxHitsPerRay = 256;
    dense.largeCasterSpacing = 0.0;
    raycast::RaycastStage stage(dense);
    TerrainMeshes terrain;
    for (const ChunkVerdicts& cv : baked.chunks) {
        const BakeWindow window = buildWindow(*world, cv.coord, every, terrain);
        ChunkVerdicts search = makeChunkVerdicts(*world, window);
        EXPECT_EQ(search.objects.size(), cv.objects.size()) << chunkFileName(cv.coord);
        if (search.objects.size() != cv.objects.size()) continue;
        out.searched += keepOnlyTheCulled(cv, search);
        StageStats stats;
        EXPECT_TRUE(stage.run(window, search, stats));
        for (size_t oi = 0; oi < search.objects.size(); ++oi)
            for (size_t k = 0; k < search.objects[oi].decisions.size(); ++k) {
                const Decision& d = search.objects[oi].decisions[k];
                if (d.verdict != Verdict::Kept || d.stage != std::string_view("raycast")) continue;
                const Decision& b = cv.objects[oi].decisions[k];
                out.witnessed.push_back(chunkFileName(cv.coord) + " " + search.objects[oi].uuid + " group " +
                                        std::to_string(k / size_t(cv.lightCount)) + " light " +
                                        std::to_string(k % size_t(cv.lightCount) + 1) + ": culled by " +
                                        std::string(b.stage) + " (" + std::string(b.reason()) + "), but a witness lands on " +
                                        (d.witness() ? d.witness()->receiver : "?"));
            }
    }
    return out;
}

}  // namespace

TEST(WholeSpace, LowSunBitsDoNotDependOnNeighbours) {
    const fs::path dir = freshTestDir();
    const cli::BakeResult one = bakeAll(writeLowSunWorld(dir, 1));
    const cli::BakeResult wide = bakeAll(writeLowSunWorld(dir, 6));
    ASSERT_EQ(one.chunks.size(), 12u);
    // The world must exercise what the test is about: windows reaching past the rectangle.
    EXPECT_GT(one.reach.chunksBeyond, 0u) << "no shadow left a neighbours-1 window";
    const auto a = codes(one), b = codes(wide);
    ASSERT_EQ(a.size(), b.size());
    for (const auto& [c, bits] : a) EXPECT_EQ(bits, b.at(c)) << chunkFileName(c);
}

// The search finds what it is for: the same world baked with windows of the neighbours
// rectangle (as before issue 33) has a 0 whose shadow lands beyond the rectangle.
TEST(WholeSpace, NoCulledBitHasAWitnessAnywhereInTheWorld) {
    const fs::path dir = freshTestDir();
    const std::string space = writeLowSunWorld(dir, 1);
    const cli::BakeResult baked = bakeAll(space);
    ASSERT_EQ(baked.chunks.size(), 12u);
    const DenseSearch whole = searchTheWholeWorld(space, baked);
    EXPECT_GT(whole.searched, 200u) << "the world must give the bake 0s to check";
    for (const std::string& w : whole.witnessed) ADD_FAILURE() << w;

    const DenseSearch windowOnly = searchTheWholeWorld(space, bakeAll(space, true));
    EXPECT_FALSE(windowOnly.witnessed.empty()) << "the window-only bake's false cull must be found";
}

// Every scene x the two proofs that must never meet: on generated worlds (a corner of the
// forest, and the whole real-map-like world R: 400 chunks of half-buried rocks under a low
// and a high sun), the geometry stage also examines every bit the witness rays kept, and
// the bake fails if it would prove one of them 0 (GeometryOptions::crossCheckWitnesses). A
// meeting is a wrong witness (a false keep, as the float depth on a rock face seen nearly
// edge-on made on R's chunk fffe0007o; raycast/hit_depth.h) or a wrong proof (a false
// cull): either is a bug. (R takes 15-25 s here, most of the test.)
TEST(CrossCheck, NoWitnessMeetsAProofOfZeroOnGeneratedWorlds) {
    bench::WorldSpec forest = bench::worldS();
    forest.name = "cross-check-forest";
    forest.objectsPerChunk = 60;
    forest.localLights = 4;
    forest.seed = 3811;
    const bench::WorldSpec rocks = bench::worldR();
    for (const bench::WorldSpec& w : {forest, rocks}) {
        SCOPED_TRACE(w.name);
        const fs::path space = freshTestDir("-" + w.name) / "space";
        bench::writeWorld(w, space.string());
        cli::BakeOptions opt;
        opt.spaceDir = space.string();
        opt.write = false;
        opt.useGpu = false;
        opt.geometry.crossCheckWitnesses = true;
        Expected<cli::BakeResult> r = cli::runBake(opt);
        ASSERT_TRUE(r) << r.error().what();
        uint64_t kept = 0, examined = 0;
        for (const cli::StageTiming& t : r->stages) {
            if (t.name == "raycast") kept = t.stats.provedKept;
            if (t.name == "geometry") examined = t.stats.bitsExamined;
        }
        EXPECT_GT(kept, 1000u) << "the world must give the cross-check witnesses";
        EXPECT_GE(examined, kept);  // every kept bit went to the exact test too
    }
}
