// bake --shard K/N and merge (issue 16), as plain processes: a generated world baked once
// whole and once in shards must give the same chunk files and, after merge, the same
// results file, byte for byte; merge refuses shards that do not make up one bake.

#include <set>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bench/world_gen.h"
#include "cli/shard.h"
#include "core/scene.h"
#include "io/results_file.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// 4 x 3 chunks of the benchmark forest, thinned so that a bake takes seconds: terrain,
// trees (alpha-tested canopies), rocks, buildings, three suns and four local lights.
bench::WorldSpec smallWorld() {
    bench::WorldSpec w;
    w.name = "shard-test";
    w.chunksX = 4, w.chunksZ = 3;
    w.seed = 16;
    w.objectsPerChunk = 24;
    w.terrainSamples = 9;
    w.localLights = 4;
    return w;
}

// The world, written once per test run into `dir`/space.
std::string writeSmallWorld(const fs::path& dir) {
    const fs::path space = dir / "space";
    bench::writeWorld(smallWorld(), space.string());
    return space.string();
}

const char* const kStages = " --quiet --stages raycast,geometry --samples 8";

int bake(const std::string& args, const fs::path& dir, const std::string& tag) {
    return runCli("bake " + args + kStages, dir / (tag + ".out"), dir / (tag + ".err"));
}

int merge(const std::string& args, const fs::path& dir, const std::string& tag) {
    return runCli("merge " + args, dir / (tag + ".out"), dir / (tag + ".err"));
}

}  // namespace

TEST(Shards, PartitionIsDeterministicDisjointAndBalancedByWork) {
    const fs::path dir = freshTestDir();
    const std::string spaceDir = writeSmallWorld(dir);
    Expected<SpaceSource> space = SpaceSource::scan(spaceDir, "");
    ASSERT_TRUE(space) << space.error().what();
    ASSERT_EQ(space->chunks().size(), 12u);
    double biggest = 0;
    for (const auto& [c, e] : space->chunks()) biggest = std::max(biggest, cli::chunkWork(*space, c));
    for (int n = 1; n <= 5; ++n) {
        const auto parts = cli::partitionChunks(*space, n);
        ASSERT_EQ(parts.size(), size_t(n));
        EXPECT_EQ(parts, cli::partitionChunks(*space, n)) << "the same space must give the same partition";
        std::set<std::pair<int, int>> seen;
        double least = 1e300, most = 0;
        for (const auto& part : parts) {
            EXPECT_TRUE(std::is_sorted(part.begin(), part.end())) << "each shard in grid order";
            if (!part.empty()) {
                // A consecutive run of the grid order.
                const auto first = space->chunks().find(part.front());
                EXPECT_EQ(size_t(std::distance(first, space->chunks().find(part.back()))) + 1, part.size());
            }
            double load = 0;
            for (ChunkCoord c : part) {
                EXPECT_TRUE(seen.insert({c.x, c.z}).second) << chunkFileName(c) << " in two shards";
                load += cli::chunkWork(*space, c);
            }
            least = std::min(least, load), most = std::max(most, load);
        }
        EXPECT_EQ(seen.size(), space->chunks().size()) << "every chunk in a shard";
        // Runs cut at the work's quantiles: each shard is within one chunk's work of its share
        // at each end, so no two differ by more than two chunks' work.
        EXPECT_LE(most - least, 2 * biggest + 1e-9) << n << " shards";
    }
    // The estimate sees the objects: an emptied chunk weighs less than the others.
    const ChunkCoord first = space->chunks().begin()->first;
    const double full = cli::chunkWork(*space, first);
    writeText(space->chunks().begin()->second.path, "<chunk>\n</chunk>\n");
    Expected<SpaceSource> emptied = SpaceSource::scan(spaceDir, "");
    ASSERT_TRUE(emptied) << emptied.error().what();
    EXPECT_LT(cli::chunkWork(*emptied, first), full);
    EXPECT_FALSE(cli::parseShard("0/3"));
    EXPECT_FALSE(cli::parseShard("4/3"));
    EXPECT_FALSE(cli::parseShard("1/"));
    EXPECT_FALSE(cli::parseShard("-1/3"));
    ASSERT_TRUE(cli::parseShard("3/3"));
    EXPECT_EQ(cli::parseShard("2/7")->index, 2);
    EXPECT_EQ(cli::parseShard("2/7")->count, 7);
}

// The estimate weighs an object's triangles too (cli/shard.h): of two chunks with one object
// each, the one whose mesh has 20,000 triangles weighs about 20 objects' worth more (before:
// the same, and a shard of dense chunks took 1.59x the mean time on world R with D's rocks).
TEST(Shards, TheWorkEstimateWeighsTriangles) {
    const fs::path dir = freshTestDir();
    SpaceBuilder b;
    b.addMesh("crate", MeshSpec::box({0, 0, 0}, {2, 2, 2}));
    b.addMesh("scan", MeshSpec::jaggedSheet(100, 0.2, 0.05));
    b.addLight(LightSpec::directional("sun", {0.3, -1, 0.2}).withBias(0.01));
    b.addModel("crate", Affine::translation({50, 0, 50}), fixedUuid(1));
    b.addModel("scan", Affine::translation({150, 0, 50}), fixedUuid(2));
    b.write((dir / "space").string());
    Expected<SpaceSource> space = SpaceSource::scan((dir / "space").string(), "");
    ASSERT_TRUE(space) << space.error().what();
    const double crate = cli::chunkWork(*space, {0, 0}), scan = cli::chunkWork(*space, {1, 0});
    EXPECT_EQ(space->chunks().at({1, 0}).triangles, 20000u);
    EXPECT_NEAR(scan - crate, (20000.0 - 12.0) / cli::kTrianglesPerObject, 1e-9);
}

TEST(Shards, ThreeShardsMergedEqualOneBakeByteForByteAndResumeAlone) {
    const fs::path dir = freshTestDir();
    const std::string space = writeSmallWorld(dir);
    const fs::path whole = dir / "whole", sharded = dir / "sharded";
    ASSERT_EQ(bake("'" + space + "' --out '" + whole.string() + "' --results '" + (dir / "whole.json").string() + "'", dir, "whole"), 0)
        << readText(dir / "whole.err");
    std::string shardFiles;
    for (int k = 1; k <= 3; ++k) {
        const fs::path results = dir / ("shard-" + std::to_string(k) + ".json");
        ASSERT_EQ(bake("'" + space + "' --out '" + sharded.string() + "' --results '" + results.string() + "' --resume --shard " +
                           std::to_string(k) + "/3",
                       dir, "shard" + std::to_string(k)),
                  0)
            << readText(dir / ("shard" + std::to_string(k) + ".err"));
        // Each shard wrote only its own chunks so far.
        Expected<results::ResultsFile> r = results::readResultsFile(results.string());
        ASSERT_TRUE(r) << r.error().what();
        ASSERT_TRUE(r->shard);
        EXPECT_EQ(r->shard->index, k);
        EXPECT_EQ(r->shard->count, 3);
        EXPECT_FALSE(r->shard->assigned.empty());
        std::set<std::string> mine(r->shard->assigned.begin(), r->shard->assigned.end());
        for (const results::ChunkRecord& c : r->chunks) EXPECT_TRUE(mine.count(c.chunk)) << c.chunk;
        EXPECT_TRUE(fs::exists(sharded / (".shadowcull-bake-state.shard-" + std::to_string(k) + "-of-3.json")));
        shardFiles += " '" + results.string() + "'";
    }
    EXPECT_FALSE(fs::exists(sharded / ".shadowcull-bake-state.json")) << "shards keep their own resume state";
    const fs::path merged = dir / "merged.json";
    ASSERT_EQ(merge("'" + merged.string() + "'" + shardFiles, dir, "merge"), 0) << readText(dir / "merge.err");
    const std::string wholeText = readText(dir / "whole.json");
    ASSERT_FALSE(wholeText.empty());
    EXPECT_EQ(readText(merged), wholeText) << "merged results differ from the single bake's";
    const auto wholeChunks = chunkTexts(whole), shardedChunks = chunkTexts(sharded);
    ASSERT_EQ(wholeChunks.size(), 12u);
    EXPECT_EQ(shardedChunks, wholeChunks) << "chunk files differ";
    // The single bake's chunks differ from the input (something was baked at all).
    EXPECT_NE(chunkTexts(space), wholeChunks);

    // A shard rerun alone with --resume: nothing to bake, the same results file (the
    // chunks' parts come from its resume state), and the merge is still the single bake's.
    const fs::path again = dir / "shard-2-again.json";
    ASSERT_EQ(bake("'" + space + "' --out '" + sharded.string() + "' --results '" + again.string() + "' --resume --shard 2/3", dir,
                   "again"),
              0)
        << readText(dir / "again.err");
    EXPECT_EQ(readText(again), readText(dir / "shard-2.json"));
    // Its chunk files were not rewritten: a second run must not bake (its state is complete).
    Expected<results::ResultsFile> r2 = results::readResultsFile(again.string());
    ASSERT_TRUE(r2);
    EXPECT_EQ(r2->chunks.size(), r2->shard->assigned.size());
    EXPECT_EQ(chunkTexts(sharded), wholeChunks);
    fs::remove(merged);
    ASSERT_EQ(merge("'" + merged.string() + "' '" + (dir / "shard-1.json").string() + "' '" + again.string() + "' '" +
                        (dir / "shard-3.json").string() + "'",
                    dir, "merge2"),
              0)
        << readText(dir / "merge2.err");
    EXPECT_EQ(readText(merged), wholeText);
}

TEST(Shards, MergeRefusesShardsThatAreNotOneBake) {
    const fs::path dir = freshTestDir();
    const std::string space = writeSmallWorld(dir);
    auto shard = [&](int k, int n, const std::string& extra, const std::string& name) {
        const fs::path out = dir / ("out-" + name);
        const int rc = bake("'" + space + "' --out '" + out.string() + "' --results '" + (dir / (name + ".json")).string() +
                                "' --shard " + std::to_string(k) + "/" + std::to_string(n) + extra,
                            dir, name);
        EXPECT_EQ(rc, 0) << readText(dir / (name + ".err"));
        return "'" + (dir / (name + ".json")).string() + "'";
    };
    const std::string a = shard(1, 2, "", "a"), b = shard(2, 2, "", "b");
    const std::string bOther = shard(2, 2, " --gpu-terrain", "b-other");  // another option, in the inputs' hash
    const std::string c3 = shard(3, 3, "", "c3");
    const fs::path out = dir / "merged.json";
    const std::string o = "'" + out.string() + "' ";
    auto refusal = [&](const std::string& args, int code, const std::string& words) {
        const int rc = merge(o + args, dir, "refused");
        const std::string err = readText(dir / "refused.err");
        EXPECT_EQ(rc, code) << args << "\n" << err;
        EXPECT_NE(err.find(words), std::string::npos) << err;
        EXPECT_FALSE(fs::exists(out)) << "a refused merge writes nothing";
    };
    refusal(a, 8, "shard(s) 2 of 2 missing");
    refusal(a + " " + a, 8, "given twice");
    refusal(a + " " + bOther, 7, "inputs");
    refusal(a + " " + c3, 7, "shard counts");
    // A single bake's results are not a shard's.
    ASSERT_EQ(bake("'" + space + "' --dry-run --results '" + (dir / "whole.json").string() + "'", dir, "whole"), 0);
    refusal(a + " '" + (dir / "whole.json").string() + "'", 3, "not a shard's results");
    // A shard whose results lost a chunk (cut by hand).
    Expected<results::ResultsFile> cut = results::readResultsFile((dir / "b.json").string());
    ASSERT_TRUE(cut);
    ASSERT_FALSE(cut->chunks.empty());
    cut->chunks.pop_back();
    writeText(dir / "b-cut.json", results::writeResults(*cut));
    refusal(a + " '" + (dir / "b-cut.json").string() + "'", 8, "no results for its chunk");
    // The output must not be one of the inputs.
    EXPECT_EQ(merge(a + " " + a + " " + b, dir, "self"), 3) << readText(dir / "self.err");
    // And the two good shards do merge.
    EXPECT_EQ(merge(o + a + " " + b, dir, "good"), 0) << readText(dir / "good.err");
    Expected<results::ResultsFile> m = results::readResultsFile(out.string());
    ASSERT_TRUE(m) << m.error().what();
    EXPECT_FALSE(m->shard) << "the merged file is a whole bake's";
    EXPECT_EQ(m->chunks.size(), 12u);
}

// Shards baked in place one after another (a busy cluster starting an array's tasks at
// different times, a dead shard rerun later): each later shard reads chunk files into which
// the earlier ones wrote masks. The masks are the bake's output, not its input, so the
// shards are still one bake: the merge equals the single bake, and a shard rerun with
// --resume finds its chunks up to date although its neighbours' files changed since.
TEST(Shards, InPlaceShardsBakedOneAfterAnotherMergeToTheSingleBake) {
    const fs::path dir = freshTestDir();
    const std::string space = writeSmallWorld(dir);
    // The reference reads the same space directory (the results name it) before any shard.
    ASSERT_EQ(bake("'" + space + "' --out '" + (dir / "whole").string() + "' --results '" + (dir / "whole.json").string() + "'",
                   dir, "whole"),
              0)
        << readText(dir / "whole.err");
    const auto original = chunkTexts(space);
    std::string shardFiles;
    for (int k = 1; k <= 3; ++k) {
        const std::string name = "shard-" + std::to_string(k);
        ASSERT_EQ(bake("'" + space + "' --results '" + (dir / (name + ".json")).string() + "' --resume --shard " +
                           std::to_string(k) + "/3",
                       dir, name),
                  0)
            << readText(dir / (name + ".err"));
        shardFiles += " '" + (dir / (name + ".json")).string() + "'";
    }
    ASSERT_NE(chunkTexts(space), original) << "the shards wrote masks in place";
    const fs::path merged = dir / "merged.json";
    ASSERT_EQ(merge("'" + merged.string() + "'" + shardFiles, dir, "merge"), 0) << readText(dir / "merge.err");
    EXPECT_EQ(readText(merged), readText(dir / "whole.json")) << "merged results differ from the single bake's";
    EXPECT_EQ(chunkTexts(space), chunkTexts(dir / "whole")) << "chunk files differ from the single bake's";

    // Shard 1 again: the masks shards 2 and 3 wrote after it are no edit of its inputs.
    const fs::path state = fs::path(space) / ".shadowcull-bake-state.shard-1-of-3.json";
    const std::string stateBefore = readText(state);
    ASSERT_FALSE(stateBefore.empty());
    ASSERT_EQ(bake("'" + space + "' --results '" + (dir / "again.json").string() + "' --resume --shard 1/3", dir, "again"), 0)
        << readText(dir / "again.err");
    EXPECT_EQ(readText(state), stateBefore) << "the rerun baked chunks again";
    EXPECT_EQ(readText(dir / "again.json"), readText(dir / "shard-1.json"));
}

// merge streams the shards' files chunk by chunk when they are laid out as the bake writes
// them; a file laid out otherwise (pretty-printed again by hand or by a tool) is read whole,
// and the merge is the same bytes either way.
TEST(Shards, MergeOfAReformattedShardFileIsTheSameBytes) {
    const fs::path dir = freshTestDir();
    const std::string space = writeSmallWorld(dir);
    ASSERT_EQ(bake("'" + space + "' --dry-run --results '" + (dir / "whole.json").string() + "'", dir, "whole"), 0)
        << readText(dir / "whole.err");
    std::string shardFiles;
    for (int k = 1; k <= 2; ++k) {
        const std::string name = "shard-" + std::to_string(k);
        ASSERT_EQ(bake("'" + space + "' --dry-run --results '" + (dir / (name + ".json")).string() + "' --shard " +
                           std::to_string(k) + "/2",
                       dir, name),
                  0)
            << readText(dir / (name + ".err"));
        shardFiles += " '" + (dir / (name + ".json")).string() + "'";
    }
    const fs::path streamed = dir / "streamed.json";
    ASSERT_EQ(merge("'" + streamed.string() + "'" + shardFiles, dir, "streamed"), 0) << readText(dir / "streamed.err");
    EXPECT_EQ(readText(streamed), readText(dir / "whole.json"));

    // Shard 2 pretty-printed with another indent: read whole, merged to the same bytes.
    const std::string original = readText(dir / "shard-2.json");
    const std::string reformatted = nlohmann::json::parse(original).dump(4) + "\n";
    ASSERT_NE(reformatted, original);
    writeText(dir / "shard-2.json", reformatted);
    const fs::path whole = dir / "read-whole.json";
    ASSERT_EQ(merge("'" + whole.string() + "'" + shardFiles, dir, "read-whole"), 0) << readText(dir / "read-whole.err");
    EXPECT_EQ(readText(whole), readText(dir / "whole.json"));

    // A malformed chunk in a streamed file is refused with the whole-file reader's words.
    std::string cut = original;
    const size_t at = cut.find("\"chunk\": \"");
    ASSERT_NE(at, std::string::npos);
    cut.replace(at, 10, "\"chunk\": 3, \"was\": \"");
    writeText(dir / "shard-2.json", cut);
    EXPECT_EQ(merge("'" + (dir / "bad.json").string() + "'" + shardFiles, dir, "bad"), 3);
    EXPECT_NE(readText(dir / "bad.err").find("malformed results at chunks[0]"), std::string::npos) << readText(dir / "bad.err");
    EXPECT_FALSE(fs::exists(dir / "bad.json"));
}
