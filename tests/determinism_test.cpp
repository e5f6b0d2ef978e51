// The results JSON is the same, byte for byte, for the same input, on any thread count and
// in every run (issue 11: a bit was kept by the dense witness search where the GPU stage saw
// samples pass in some runs and undecided in others, because the pixels handed over to it
// were the first ones llvmpipe's rasteriser threads happened to record).
//
// The scene (hillsAndRocks below) makes the whole pipeline work: hilly terrain with rocks
// half buried in it under a low sun, the terrain groups sent to the GPU confirmation
// (--gpu-terrain), and a plate lit by the noon sun only through a slit in a roof of slabs,
// which only the dense search finds, among far more passed pixels than the GPU stage hands
// over. The first test bakes in its own process per bake (llvmpipe's threads schedule
// differently every time) at --threads 1 and 2 with several llvmpipe thread counts and
// compares the JSON bytes and the summary's counts; the second bakes in this process and
// compares every stage's counters (rays cast, bits examined and decided, GPU passes),
// which move with the pixels handed over even where no verdict does.
// Both skip, saying why, where no offscreen OpenGL context can be made.

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli/pipeline.h"
#include "cli/report.h"
#include "tests/support/gl_available.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// An irregular rock: a box with its top corners moved, welded (closed, shared edges).
MeshSpec rock() {
    const glm::dvec3 c[8] = {{-1.0, 0, -0.8}, {1.1, 0, -0.9}, {1.0, 0, 1.0}, {-0.9, 0, 0.9},
                             {-0.6, 1.4, -0.5}, {0.7, 1.7, -0.6}, {0.8, 1.2, 0.6}, {-0.5, 1.5, 0.7}};
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named("stone"));
    const glm::dvec3 inside(0.0, 0.6, 0.0);
    const int faces[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    for (const auto& f : faces) {
        // Quads with moved corners are not planar: two triangles each, facing outwards.
        m.addFace({c[f[0]], c[f[1]], c[f[2]]}, g, inside);
        m.addFace({c[f[0]], c[f[2]], c[f[3]]}, g, inside);
    }
    return m.welded();
}

// One chunk of hills with rocks half buried in them under a low sun, and in the middle, on
// flat ground, a 20 m plate 2 m up under a roof of 1 m slabs laid edge to edge, with one
// 4 cm slit at x = 48.25 m. Under the noon sun (straight down), the plate is lit only along the
// slit: the area samples of the ray stage miss it, the shadow volumes cannot prove the
// plate 0 (the ground lies under it), and the GPU stage sees samples pass along the slit
// and along every seam between two slabs (separate objects: no one sheet covers a seam's
// pixels whole), ~8,000 fragments at 1024 px where it hands over 256 pixels. Which pixels
// those are decides whether the dense search finds the witness through the slit: before
// issue 11 it took the first ones recorded, so with llvmpipe rasterising tile after tile
// (LP_NUM_THREADS=1) the first tile of seams filled them and the plate stayed undecided,
// while with many rasteriser threads the slit's tile got its share and the plate was kept.
SpaceBuilder hillsAndRocks() {
    SpaceBuilder b;
    b.addMesh("rock", rock());
    b.addMesh("plate", MeshSpec::box({-10, 0, -10}, {10, 1, 10}, GroupSpec::named("plate")));
    b.addMesh("slab", MeshSpec::box({0, 0, -12}, {1, 0.02, 12}, GroupSpec::named("slab")));
    b.addMesh("lath", MeshSpec::box({0, 0, -12}, {0.25, 0.02, 12}, GroupSpec::named("lath")));
    b.addLight(LightSpec::directional("low sun", {0.95, -0.17, 0.28}).withBias(0.05));
    b.addLight(LightSpec::directional("noon", {0, -1, 0}).withBias(0.05));
    // Hills, flattened within 25 m of the centre.
    auto height = [](double x, double z) {
        const double r = std::hypot(x - 50, z - 50), flat = std::clamp((r - 25) / 10, 0.0, 1.0);
        return flat * (4.0 * std::sin(x * 0.09) * std::cos(z * 0.07) + 1.5 * std::sin(z * 0.21 + 0.5));
    };
    b.addTerrain(0, 0, 33, height, -7.0, 7.0);
    b.addModel("plate", Affine::translation({50, 2, 50}));
    // The roof over x 37..61.29, z 38..62, 6 m up: 25 cm laths up to x = 44.25, then 1 m
    // slabs, and the slit between 48.25 and 48.29, where none of the ray stage's samples on
    // the plate (top, bottom or sides) lies.
    for (int k = 0; k < 29; ++k) b.addModel("lath", Affine::translation({37.0 + 0.25 * k, 6, 50}));
    for (int k = 0; k < 17; ++k) b.addModel("slab", Affine::translation({44.25 + k + (k >= 4 ? 0.04 : 0.0), 6, 50}));
    DeterministicRng rng(0xD1CE);
    for (int placed = 0; placed < 60;) {
        const double x = rng.uniform(3, 97), z = rng.uniform(3, 97);
        if (std::hypot(x - 50, z - 50) < 30) continue;
        const double s = rng.uniform(0.6, 2.5), turn = rng.uniform(0, 360);
        const Affine place = Affine::scaling({s, s * rng.uniform(0.6, 1.2), s})
                                 .then(Affine::rotationY(turn))
                                 .then(Affine::translation({x, *b.terrainHeightAt(x, z) - s * rng.uniform(0.3, 0.6), z}));
        b.addModel("rock", place);
        ++placed;
    }
    return b;
}

// A bake's counters, stage by stage: what moves when the pixels handed over move.
std::string stageCounters(const cli::BakeResult& r) {
    std::string s;
    for (const cli::StageTiming& t : r.stages)
        s += t.name + ": examined " + std::to_string(t.stats.bitsExamined) + ", rays " + std::to_string(t.stats.raysCast) +
             ", exact tests " + std::to_string(t.stats.exactTests) + ", GPU passes " + std::to_string(t.stats.gpuPasses) +
             ", proved 1 " + std::to_string(t.stats.provedKept) + ", proved 0 " + std::to_string(t.stats.provedCulled) + "\n";
    return s;
}

// The summary a bake prints, its times masked: every count in it (bits, rays, GPU passes,
// exact tests) must be the same in every run.
std::string withoutTimes(const std::string& summary) {
    return std::regex_replace(summary, std::regex(R"([0-9]+(\.[0-9]+)? (s|ms|min)\b)"), "T");
}

}  // namespace

// The CLI, one process per bake: the results JSON bytes and the summary of eight bakes, at
// --threads 1 and 2, with llvmpipe rasterising on 1 thread, on 16, on 4, and as it likes
// (LP_NUM_THREADS unset). Before issue 11's fix, the pixels handed to the dense search were
// the first ones llvmpipe's threads recorded: the dense pass's ray count moved with
// LP_NUM_THREADS (and on real maps with the scheduling alone), and with it which bits a
// witness was found for.
TEST(Determinism, ResultsJsonIsTheSameInEveryRunWithTheGpuStageAndTheDensePass) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    hillsAndRocks().write((dir / "space").string());
    const char* saved = std::getenv("LP_NUM_THREADS");
    const std::string savedValue = saved ? saved : "";
    struct Bake {
        std::string label, json, summary;
    };
    std::vector<Bake> bakes;
    for (const char* lp : {"1", "16", "4", ""})
        for (int threads : {1, 2}) {
            if (*lp) setenv("LP_NUM_THREADS", lp, 1);
            else unsetenv("LP_NUM_THREADS");
            const std::string label = std::string("LP_NUM_THREADS=") + (*lp ? lp : "(unset)") + " --threads " + std::to_string(threads);
            const fs::path json = dir / ("r" + std::to_string(bakes.size()) + ".json");
            // Without the receiver-side search (issue 19), which finds this scene's terrain
            // witnesses before the GPU stage: the dense pass must still have work.
            const int rc = runCli("bake '" + (dir / "space").string() + "' --dry-run --gpu-terrain --receiver-samples 0 --threads " +
                                      std::to_string(threads) + " --results '" + json.string() + "'",
                                  dir / "o", dir / "e");
            EXPECT_EQ(rc, 0) << label << ": " << readText(dir / "e");
            bakes.push_back({label, readText(json), withoutTimes(readText(dir / "o"))});
        }
    if (saved) setenv("LP_NUM_THREADS", savedValue.c_str(), 1);
    else unsetenv("LP_NUM_THREADS");

    ASSERT_GT(bakes[0].json.size(), 1000u);
    // The dense search found a witness (else this scene would not exercise what it is for).
    EXPECT_NE(bakes[0].json.find("where the GPU stage saw samples pass"), std::string::npos)
        << "no bit was kept by the dense witness search: the scene no longer exercises it";
    EXPECT_NE(bakes[0].summary.find("raycast (gpu pixels)"), std::string::npos) << bakes[0].summary;
    for (size_t k = 1; k < bakes.size(); ++k) {
        EXPECT_TRUE(bakes[k].json == bakes[0].json) << "results JSON of " << bakes[k].label << " differs from " << bakes[0].label;
        EXPECT_EQ(bakes[k].summary, bakes[0].summary) << bakes[k].label << " against " << bakes[0].label;
    }
}

// In this process: every stage's counters and the results JSON, at --threads 1 and 2.
TEST(Determinism, EveryStageCountsTheSameInEveryRun) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir();
    hillsAndRocks().write((dir / "space").string());
    std::vector<std::string> counters, jsons;
    for (int run = 0; run < 2; ++run)
        for (int threads : {1, 2}) {
            cli::BakeOptions opt;
            opt.spaceDir = (dir / "space").string();
            opt.write = false;
            opt.threads = threads;
            opt.gpuTerrain = true;
            Expected<cli::BakeResult> r = cli::runBake(opt);
            ASSERT_TRUE(r) << r.error().what();
            counters.push_back(stageCounters(*r));
            jsons.push_back(results::writeResults(cli::resultsFile(*r)));
        }
    EXPECT_NE(counters[0].find("raycast (gpu pixels)"), std::string::npos) << counters[0];
    for (size_t k = 1; k < counters.size(); ++k) {
        EXPECT_EQ(counters[k], counters[0]) << "bake " << k << " (threads " << (k % 2 ? 2 : 1) << ")";
        EXPECT_TRUE(jsons[k] == jsons[0]) << "results JSON of bake " << k << " differs from the first bake's";
    }
}
