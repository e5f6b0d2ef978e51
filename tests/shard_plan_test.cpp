// io/shard_plan.h's reader on plan files that were edited or broken: each fault is a
// BadInput error naming the file, never an exception out of the reader, undefined behaviour
// (a float out of an integer's range) or a count wrapped around (fuzz/fuzz_plan.cpp found
// them; its reproducers are in fuzz/regressions/plan/).

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "io/shard_plan.h"
#include "tests/test_files.h"
#include "util/hash.h"

using namespace shadowcull;
using namespace shadowcull::testing;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

// Two shards of a row of three chunks, one warning: as `shadowcull plan` writes them.
fs::path writePlan() {
    const fs::path dir = freshTestDir();
    PlanHead head;
    head.spaceDir = "space";
    head.shards = 2;
    head.outline.chunks = 3;
    head.outline.bounds.wsSpace = Aabb{{0, 0, 0}, {300, 10, 100}};
    head.diagnostics.push_back({"space/00000000o.chunk", 12, "resource m.obj could not be loaded; object skipped"});
    head.shardChunks = {2, 1};
    std::vector<PlanShard> shards(2);
    for (int k = 0; k < 2; ++k) {
        shards[size_t(k)].index = k + 1, shards[size_t(k)].count = 2;
        for (int x = 0; x < 3; ++x) {
            ChunkEntry e;
            e.path = "space/" + chunkFileName({x, 0});
            e.usableObjects = 1;
            e.wsBounds = Aabb{{x * 100.0, 0, 0}, {x * 100.0 + 100, 10, 100}};
            shards[size_t(k)].chunks.emplace(ChunkCoord{x, 0}, e);
        }
    }
    shards[0].assigned = {{0, 0}, {1, 0}};
    shards[1].assigned = {{2, 0}};
    EXPECT_TRUE(writeShardPlan(dir.string(), head, shards, {"space/m.obj"}));
    return dir;
}

// Sets `pointer` of the JSON file at `path` to `value`; an edit of plan.json is carried into
// the shard files' and inputs.json's "plan" (the hash they name), so that what is refused is
// the edit and not a stale plan.
void edit(const fs::path& dir, const std::string& file, const std::string& pointer, const json& value) {
    json j = json::parse(readText(dir / file));
    j[json::json_pointer(pointer)] = value;
    writeText(dir / file, j.dump() + "\n");
    if (file != "plan.json") return;
    const std::string planId = hexHash(Hasher().str(readText(dir / "plan.json")).value());
    for (const char* other : {"shard-1-of-2.json", "shard-2-of-2.json", "inputs.json"}) {
        json o = json::parse(readText(dir / other));
        o["plan"] = planId;
        writeText(dir / other, o.dump() + "\n");
    }
}

struct Fault {
    const char* file;
    const char* pointer;
    json value;
    const char* says;
};

}  // namespace

TEST(ShardPlan, APlanAsWrittenReadsBack) {
    const fs::path dir = writePlan();
    Expected<LoadedShardPlan> plan = readShardPlan(dir.string(), 1, 2);
    ASSERT_TRUE(plan) << plan.error().what();
    EXPECT_EQ(plan->head.shards, 2);
    EXPECT_EQ(plan->head.outline.chunks, 3u);
    EXPECT_EQ(plan->head.shardChunks, (std::vector<size_t>{2, 1}));
    ASSERT_EQ(plan->head.diagnostics.size(), 1u);
    EXPECT_EQ(plan->head.diagnostics[0].line, 12);
    EXPECT_EQ(plan->shard.assigned, (std::vector<ChunkCoord>{{0, 0}, {1, 0}}));
    EXPECT_EQ(plan->shard.chunks.size(), 3u);
    Expected<std::vector<std::string>> inputs = readPlanInputs(dir.string(), plan->head.id);
    ASSERT_TRUE(inputs) << inputs.error().what();
    EXPECT_EQ(*inputs, std::vector<std::string>{"space/m.obj"});
}

// Before, the first two were exceptions out of the reader (terminate), the floats out of
// int's range undefined behaviour, and the rest were taken: -1 as a count of 1.8e19,
// 4294967298 shards as 2, 1.5 as 1, a chunk assigned twice baked twice.
TEST(ShardPlan, AFieldOfTheWrongTypeOrRangeIsBadInputNamingTheFile) {
    const Fault faults[] = {
        {"plan.json", "/format", 5, "not a shadowcull-plan file"},
        {"plan.json", "/version", "1", "another version"},
        {"plan.json", "/version", 1.5, "another version"},
        {"plan.json", "/shards", 1e20, "shards must be an integer from 1"},
        {"plan.json", "/shards", 4294967298u, "shards must be an integer from 1"},
        {"plan.json", "/shards", 0, "shards must be an integer from 1"},
        {"plan.json", "/chunks", -1, "chunks must be an integer from 0"},
        {"plan.json", "/shardChunks/1", -1, "shardChunks must be an integer from 0"},
        {"plan.json", "/shardChunks", "2", "shardChunks must be a list"},
        {"plan.json", "/warnings/0/line", 1e20, "line must be an integer from 0"},
        {"plan.json", "/warnings/0/line", -3, "line must be an integer from 0"},
        {"plan.json", "/content", "-1", "not a hex hash"},
        {"plan.json", "/listing", " 1f", "not a hex hash"},
        {"shard-1-of-2.json", "/format", nullptr, "not a shadowcull-plan-shard file"},
        {"shard-1-of-2.json", "/version", json::array({1}), "another version"},
        {"shard-1-of-2.json", "/shard", 1.5, "shard must be an integer from 1"},
        {"shard-1-of-2.json", "/of", -2, "of must be an integer from 1"},
        {"shard-1-of-2.json", "/chunks/0/usable", -1, "usable must be an integer from 0"},
        {"shard-1-of-2.json", "/chunks/0/usable", 2.5, "usable must be an integer from 0"},
        {"shard-1-of-2.json", "/assigned", json::array({"00000000o.chunk", "00000000o.chunk"}), "grid order, each once"},
        {"shard-1-of-2.json", "/assigned", json::array({"00010000o.chunk", "00000000o.chunk"}), "grid order, each once"},
        {"shard-1-of-2.json", "/assigned", "00000000o.chunk", "assigned must be a list"},
    };
    for (const Fault& f : faults) {
        const fs::path dir = writePlan();
        edit(dir, f.file, f.pointer, f.value);
        const std::string label = std::string(f.file) + f.pointer + " = " + f.value.dump();
        Expected<LoadedShardPlan> plan = readShardPlan(dir.string(), 1, 2);
        ASSERT_FALSE(plan) << label << ": read";
        EXPECT_EQ(plan.error().kind, ErrorKind::BadInput) << label << ": " << plan.error().what();
        EXPECT_EQ(plan.error().file, (dir / f.file).string()) << label;
        EXPECT_NE(plan.error().message.find(f.says), std::string::npos) << label << ": " << plan.error().what();
    }
}

TEST(ShardPlan, AnInputsFileOfTheWrongShapeIsBadInputNamingTheFile) {
    const fs::path dir = writePlan();
    Expected<LoadedShardPlan> plan = readShardPlan(dir.string(), 2, 2);
    ASSERT_TRUE(plan) << plan.error().what();
    const Fault faults[] = {
        {"inputs.json", "/format", 7, "not a shadowcull-plan-inputs file"},
        {"inputs.json", "/version", "x", "another version"},
        {"inputs.json", "/files", json::array({1}), "malformed plan"},
    };
    for (const Fault& f : faults) {
        const std::string before = readText(dir / "inputs.json");
        edit(dir, f.file, f.pointer, f.value);
        Expected<std::vector<std::string>> inputs = readPlanInputs(dir.string(), plan->head.id);
        ASSERT_FALSE(inputs) << f.pointer;
        EXPECT_EQ(inputs.error().kind, ErrorKind::BadInput) << inputs.error().what();
        EXPECT_EQ(inputs.error().file, (dir / "inputs.json").string());
        EXPECT_NE(inputs.error().message.find(f.says), std::string::npos) << inputs.error().what();
        writeText(dir / "inputs.json", before);
    }
}
