// shadowcull plan and bake --shard K/N --plan DIR, as plain processes: shards that read a
// plan bake what shards that scan the whole space bake (the same results, byte for byte,
// and the same merge); a shard reads only the chunks its windows hold; a plan that no longer
// matches the space is refused with exit 9 before anything is written.

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bench/world_gen.h"
#include "io/shard_plan.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

const char* const kStages = " --quiet --stages raycast,geometry --samples 8";

int cli(const std::string& args, const fs::path& dir, const std::string& tag) {
    return runCli(args, dir / (tag + ".out"), dir / (tag + ".err"));
}

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

// 4 x 3 chunks of the benchmark forest (three suns, one of them low, and local lights):
// the windows reach across the world.
std::string writeForest(const fs::path& dir) {
    bench::WorldSpec w;
    w.name = "plan-test";
    w.chunksX = 4, w.chunksZ = 3;
    w.seed = 37;
    w.objectsPerChunk = 20;
    w.terrainSamples = 9;
    w.localLights = 3;
    const fs::path space = dir / "space";
    bench::writeWorld(w, space.string());
    return space.string();
}

// A row of 8 chunks, each a flat terrain with a crate on it, under a sun straight down: a
// window holds its chunk and the two beside it (their boxes touch its box's column).
std::string writeRow(const fs::path& dir) {
    SpaceBuilder b;
    b.addMesh("crate", MeshSpec::box({-2, 0, -2}, {2, 4, 2}));
    b.addLight(LightSpec::directional("noon", {0, -1, 0}).withBias(0.01));
    for (int gx = 0; gx < 8; ++gx) {
        b.addFlatTerrain(gx, 0, 0.0);
        b.addModel("crate", Affine::translation({gx * 100.0 + 50, 0, 50}), fixedUuid(uint32_t(gx + 1)));
    }
    const fs::path space = dir / "row";
    b.write(space.string());
    return space.string();
}

std::string shardArgs(const std::string& space, int k, int n) {
    return "bake " + q(space) + " --shard " + std::to_string(k) + "/" + std::to_string(n);
}

}  // namespace

TEST(Plan, ShardsWithAPlanBakeWhatScanningShardsBakeAndMergeToTheSingleBake) {
    const fs::path dir = freshTestDir();
    const std::string space = writeForest(dir);
    ASSERT_EQ(cli("bake " + q(space) + " --out " + q(dir / "whole") + " --results " + q(dir / "whole.json") + kStages, dir, "whole"), 0)
        << readText(dir / "whole.err");
    ASSERT_EQ(cli("plan " + q(space) + " --shards 3 --plan " + q(dir / "plan"), dir, "plan"), 0) << readText(dir / "plan.err");
    EXPECT_NE(readText(dir / "plan.out").find("12 chunks in 3 shards"), std::string::npos) << readText(dir / "plan.out");
    // Into another directory: each shard with and without the plan gives the same bytes.
    for (int k = 1; k <= 3; ++k) {
        const std::string n = std::to_string(k);
        ASSERT_EQ(cli(shardArgs(space, k, 3) + " --out " + q(dir / "scanned") + " --results " + q(dir / ("scanned-" + n + ".json")) + kStages,
                      dir, "scanned-" + n),
                  0);
        ASSERT_EQ(cli(shardArgs(space, k, 3) + " --plan " + q(dir / "plan") + " --out " + q(dir / "planned") + " --results " +
                          q(dir / ("planned-" + n + ".json")) + kStages,
                      dir, "planned-" + n),
                  0)
            << readText(dir / ("planned-" + n + ".err"));
        EXPECT_EQ(readText(dir / ("planned-" + n + ".json")), readText(dir / ("scanned-" + n + ".json"))) << "shard " << k;
    }
    EXPECT_EQ(chunkTexts(dir / "planned"), chunkTexts(dir / "whole"));

    // In place, one shard after another (each reads masks the earlier ones wrote), with
    // --resume as the Slurm array runs them; then merged.
    std::string shardFiles;
    for (int k = 1; k <= 3; ++k) {
        const std::string n = std::to_string(k);
        ASSERT_EQ(cli(shardArgs(space, k, 3) + " --plan " + q(dir / "plan") + " --resume --results " + q(dir / ("inplace-" + n + ".json")) + kStages,
                      dir, "inplace-" + n),
                  0)
            << readText(dir / ("inplace-" + n + ".err"));
        shardFiles += " " + q(dir / ("inplace-" + n + ".json"));
    }
    ASSERT_EQ(cli("merge " + q(dir / "merged.json") + shardFiles, dir, "merge"), 0) << readText(dir / "merge.err");
    EXPECT_EQ(readText(dir / "merged.json"), readText(dir / "whole.json"));
    EXPECT_EQ(chunkTexts(space), chunkTexts(dir / "whole"));

    // A rerun of shard 1 with its plan, after its neighbours wrote masks: nothing to bake again.
    const fs::path state = fs::path(space) / ".shadowcull-bake-state.shard-1-of-3.json";
    const std::string stateBefore = readText(state);
    ASSERT_EQ(cli(shardArgs(space, 1, 3) + " --plan " + q(dir / "plan") + " --resume --results " + q(dir / "again.json") + kStages, dir, "again"), 0)
        << readText(dir / "again.err");
    EXPECT_EQ(readText(state), stateBefore) << "the rerun baked chunks again";
    EXPECT_EQ(readText(dir / "again.json"), readText(dir / "inplace-1.json"));
}

TEST(Plan, AShardReadsOnlyTheChunksItsWindowsHold) {
    const fs::path dir = freshTestDir();
    const std::string space = writeRow(dir);
    ASSERT_EQ(cli("plan " + q(space) + " --shards 4 --plan " + q(dir / "plan"), dir, "plan"), 0) << readText(dir / "plan.err");
    Expected<LoadedShardPlan> plan = readShardPlan((dir / "plan").string(), 1, 4);
    ASSERT_TRUE(plan) << plan.error().what();
    ASSERT_EQ(plan->shard.assigned.size(), 2u);
    EXPECT_EQ(plan->shard.chunks.size(), 3u) << "shard 1 bakes chunks 0 and 1; its windows hold 0, 1 and 2";
    EXPECT_EQ(plan->head.outline.chunks, 8u);

    // The far chunks are not read: garbage there does not stop shard 1 ...
    ASSERT_EQ(cli(shardArgs(space, 1, 4) + " --out " + q(dir / "clean") + " --results " + q(dir / "clean.json") + kStages, dir, "clean"), 0);
    const fs::path far = fs::path(space) / chunkFileName({6, 0});
    writeText(far, "<chunk> not xml");
    ASSERT_EQ(cli(shardArgs(space, 1, 4) + " --plan " + q(dir / "plan") + " --out " + q(dir / "out") + " --results " + q(dir / "out.json") + kStages,
                  dir, "planned"),
              0)
        << readText(dir / "planned.err");
    EXPECT_EQ(readText(dir / "out.json"), readText(dir / "clean.json"));
    // ... while a shard that scans the space reads every chunk file and stops at it.
    EXPECT_EQ(cli(shardArgs(space, 1, 4) + " --out " + q(dir / "scan") + kStages, dir, "scan"), 3);
    EXPECT_NE(readText(dir / "scan.err").find(chunkFileName({6, 0})), std::string::npos) << readText(dir / "scan.err");
    // An output that is one of the space's inputs is refused, though the shard reads neither
    // (the plan's list of every input, read because the output exists).
    for (const fs::path& input : {fs::path(space) / chunkFileName({5, 0}), fs::path(space) / "models" / "crate.obj"}) {
        ASSERT_TRUE(fs::exists(input)) << input;
        const std::string before = readText(input);
        EXPECT_EQ(cli(shardArgs(space, 1, 4) + " --plan " + q(dir / "plan") + " --out " + q(dir / "out-x") + " --results " + q(input) + kStages,
                      dir, "results-input"),
                  3)
            << input;
        EXPECT_NE(readText(dir / "results-input.err").find("--results"), std::string::npos) << readText(dir / "results-input.err");
        EXPECT_EQ(readText(input), before);
    }
    // The shards whose windows hold it read it: a malformed chunk file is bad input, named.
    EXPECT_EQ(cli(shardArgs(space, 4, 4) + " --plan " + q(dir / "plan") + " --out " + q(dir / "out4") + kStages, dir, "far"), 3)
        << readText(dir / "far.err");
    EXPECT_NE(readText(dir / "far.err").find(chunkFileName({6, 0})), std::string::npos) << readText(dir / "far.err");
}

TEST(Plan, APlanThatNoLongerMatchesTheSpaceIsRefusedBeforeAnythingIsWritten) {
    const fs::path dir = freshTestDir();
    const std::string space = writeRow(dir);
    const std::string planDir = (dir / "plan").string();
    ASSERT_EQ(cli("plan " + q(space) + " --shards 4 --plan " + q(planDir), dir, "plan"), 0) << readText(dir / "plan.err");
    const std::string withPlan = " --plan " + q(planDir) + kStages;
    auto refused = [&](int k, const std::string& tag, const std::string& fragment) {
        const fs::path out = dir / ("out-" + tag);
        EXPECT_EQ(cli(shardArgs(space, k, 4) + " --out " + q(out) + withPlan, dir, tag), 9) << tag << ": " << readText(dir / (tag + ".err"));
        EXPECT_NE(readText(dir / (tag + ".err")).find(fragment), std::string::npos) << readText(dir / (tag + ".err"));
        EXPECT_TRUE(!fs::exists(out) || chunkTexts(out).empty()) << tag << ": a chunk file was written";
    };

    // A comment in chunk 2: shards 1 and 2 hold it in their windows, shard 4 does not.
    const fs::path chunk2 = fs::path(space) / chunkFileName({2, 0});
    const std::string original = readText(chunk2);
    writeText(chunk2, "<!-- moved a crate -->\n" + original);
    refused(1, "edited-1", "changed since the plan was made");
    refused(2, "edited-2", chunkFileName({2, 0}));
    EXPECT_EQ(cli(shardArgs(space, 4, 4) + " --out " + q(dir / "out-4") + withPlan, dir, "edited-4"), 0) << readText(dir / "edited-4.err");
    writeText(chunk2, original);
    EXPECT_EQ(cli(shardArgs(space, 1, 4) + " --out " + q(dir / "out-back") + withPlan, dir, "back"), 0) << "the edit undone: " << readText(dir / "back.err");

    // Masks are the bake's output, not an edit: a chunk baked in place still matches.
    ASSERT_EQ(cli(shardArgs(space, 2, 4) + withPlan, dir, "inplace-2"), 0) << readText(dir / "inplace-2.err");
    ASSERT_NE(readText(chunk2), original) << "shard 2 wrote chunk 2's masks";
    EXPECT_EQ(cli(shardArgs(space, 1, 4) + " --out " + q(dir / "out-masked") + withPlan, dir, "masked"), 0) << readText(dir / "masked.err");

    // A chunk file added, space.xml edited: every shard refuses.
    const fs::path added = fs::path(space) / chunkFileName({8, 0});
    fs::copy_file(fs::path(space) / chunkFileName({7, 0}), added);
    refused(4, "added", "added, removed or renamed");
    fs::remove(added);
    const std::string xml = readText(fs::path(space) / "space.xml");
    writeText(fs::path(space) / "space.xml", xml + "\n<!-- -->\n");
    refused(3, "space-xml", "space.xml");
    writeText(fs::path(space) / "space.xml", xml);

    // A summary that is not the chunk's (a plan edited by hand: a box lowered, which could
    // leave a receiver out of the windows) is refused when the chunk is loaded.
    {
        const fs::path shardFile = fs::path(planDir) / "shard-1-of-4.json";
        const std::string before = readText(shardFile);
        nlohmann::json j = nlohmann::json::parse(before);
        j["chunks"][0]["bounds"][1][1] = j["chunks"][0]["bounds"][1][1].get<double>() - 1.0;
        writeText(shardFile, j.dump() + "\n");
        refused(1, "edited-box", "the plan's summary of it is not its own");
        writeText(shardFile, before);
    }

    // The plan of another shard count is bad input; a shard file of another plan is stale.
    EXPECT_EQ(cli(shardArgs(space, 1, 2) + " --out " + q(dir / "out-n") + withPlan, dir, "other-n"), 3);
    EXPECT_NE(readText(dir / "other-n.err").find("a plan for 4 shards, not 2"), std::string::npos) << readText(dir / "other-n.err");
    ASSERT_EQ(cli("plan " + q(space) + " --shards 4 --plan " + q(dir / "plan-b"), dir, "plan-b"), 0);
    writeText(dir / "plan-b" / "plan.json", readText(dir / "plan-b" / "plan.json") + " ");
    ASSERT_EQ(cli(shardArgs(space, 3, 4) + " --out " + q(dir / "out-mixed") + " --plan " + q(dir / "plan-b") + kStages, dir, "mixed"), 9)
        << readText(dir / "mixed.err");
    EXPECT_NE(readText(dir / "mixed.err").find("belongs to another plan"), std::string::npos) << readText(dir / "mixed.err");
    EXPECT_EQ(cli("bake " + q(space) + " --plan " + q(planDir) + kStages, dir, "no-shard"), 2);
}
