// io/results_stream.h, the results file read one chunk and one object at a time, and the
// merge that reads its shards through it: what a streamed reading gives must be what the
// whole-file reader gives (or the file is left to that reader), and a merge of shards with a
// very large chunk must give the same bytes as the merge in memory without holding the chunk.

#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "cli/merge.h"
#include "cli/report.h"
#include "io/results_file.h"
#include "io/results_stream.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

results::LightRecord light(int index, const std::string& name, const std::string& type) {
    results::LightRecord L;
    L.index = index, L.bit = index - 1, L.name = name, L.type = type;
    return L;
}

const std::vector<results::LightRecord> kLights = {light(1, "sun", "directional"), light(2, "lamp", "point")};

// An object of two groups, every bit of it a kind the bake writes: a kept bit with a witness
// (most of a real file's bytes), a culled one, an undecided one with notes.
results::ObjectRecord object(int element) {
    results::ObjectRecord o;
    o.element = element;
    o.kind = element % 5 == 0 ? "terrain" : "model";
    o.uuid = element % 7 == 0 ? "" : "U-" + std::to_string(element);
    for (int g = 0; g < 2; ++g) {
        results::GroupRecord group;
        group.group = g;
        const double at = element * 0.37 + g / 3.0;
        group.bounds = results::BoxRecord{glm::dvec3(at, -1.0 / 7.0, 2.5), glm::dvec3(at + 1.1, 3.0, 4.0e-7)};
        group.triangles = uint64_t(12 + element % 9);
        for (int light = 1; light <= int(kLights.size()); ++light) {
            results::BitRecord b;
            b.light = light;
            switch ((element + g + light) % 3) {
                case 0:
                    b.verdict = "kept", b.stage = "raycast", b.reason = "witness ray";
                    b.witness = results::WitnessRecord{{at, 300.0 + at, -at}, {0.6, -0.8, 0.0}, {at, 1.0 / 3.0, 2.0},
                                                       {at, 0.1, 2.0}, "00000000o.chunk terrain #280 group 0",
                                                       results::BoxRecord{glm::dvec3(-500.0), glm::dvec3(-400.0)}};
                    break;
                case 1:
                    b.bit = 0, b.verdict = "culled", b.stage = "geometry", b.reason = "shadow falls on nothing";
                    break;
                default:
                    b.verdict = "undecided";
                    b.notes = {{"raycast", "no witness in 64 samples"}, {"geometry", "occluders overlap"}};
            }
            group.mask |= uint32_t(b.bit) << (light - 1);
            group.lights.push_back(std::move(b));
        }
        o.mask |= group.mask;
        o.groups.push_back(std::move(group));
    }
    return o;
}

results::ChunkRecord chunk(const std::string& name, int objects) {
    results::ChunkRecord c;
    c.chunk = name;
    c.simulated = {"terrain rule"};
    for (int k = 0; k < objects; ++k) c.objects.push_back(object(k));
    if (objects > 3) c.objects[3].skipped = true, c.objects[3].groups.clear(), c.objects[3].mask = 0;
    return c;
}

// Shard K of N holding `chunks` ({name, objects}), as `bake --shard` writes it (savings and
// summary counted by the bake's builder).
results::ResultsFile shard(int index, int count, const std::vector<std::pair<std::string, int>>& chunks, uint64_t spaceChunks) {
    results::ResultsFile f;
    f.space = "space";
    cli::ResultsBuilder builder(kLights);
    for (const auto& [name, objects] : chunks) {
        f.chunks.push_back(chunk(name, objects));
        builder.add(f.chunks.back());
    }
    f.lights = kLights;
    f.summary = builder.summary();
    results::ShardRecord s;
    s.index = index, s.count = count, s.inputs = "0123456789abcdef", s.spaceChunks = spaceChunks;
    for (const auto& c : chunks) s.assigned.push_back(c.first);
    f.shard = s;
    return f;
}

// What streaming `path` gives: the file with its chunks assembled from their parts, or
// std::nullopt (left to the whole-file reader). `events`: "begin NAME", "object ELEMENT",
// "end NAME", in order.
std::optional<results::ResultsFile> streamed(const fs::path& path, std::vector<std::string>* events = nullptr) {
    std::vector<results::ChunkRecord> chunks;
    results::ChunkParts parts;
    parts.begin = [&](const std::string& name) {
        if (events) events->push_back("begin " + name);
        chunks.emplace_back().chunk = name;
        return Status::ok();
    };
    parts.object = [&](results::ObjectRecord& o) {
        if (events) events->push_back("object " + std::to_string(o.element));
        chunks.back().objects.push_back(std::move(o));
        return Status::ok();
    };
    parts.end = [&](results::ChunkRecord& rest) {
        if (events) events->push_back("end " + rest.chunk);
        chunks.back().simulated = rest.simulated;
        chunks.back().savings = rest.savings;
        return Status::ok();
    };
    Expected<std::optional<results::ResultsFile>> f = results::streamResultsFile(path.string(), parts);
    EXPECT_TRUE(f) << f.error().what();
    if (!f || !*f) return std::nullopt;
    (*f)->chunks = std::move(chunks);
    return **f;
}

// A streamed reading of `text` agrees with the whole-file reader, or leaves it to it.
void expectStreamAgrees(const fs::path& dir, const std::string& text, bool leftToWholeReader) {
    const fs::path path = dir / "r.json";
    writeText(path, text);
    const std::optional<results::ResultsFile> stream = streamed(path);
    EXPECT_EQ(stream.has_value(), !leftToWholeReader);
    if (!stream) return;
    Expected<results::ResultsFile> whole = results::readResultsFile(path.string());
    ASSERT_TRUE(whole) << "streamed what the whole-file reader refuses: " << whole.error().what();
    EXPECT_EQ(results::writeResults(*stream), results::writeResults(*whole));
}

// `text` with `from` (which must be there) replaced by `to`, the first time only.
std::string replaced(std::string text, const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos) text.replace(at, from.size(), to);
    return text;
}

// Runs the shadowcull executable with `args` (no shell, output to /dev/null); its exit code
// and peak RSS in KiB (ru_maxrss from wait4: this child alone).
std::pair<int, long> runMeasured(std::vector<std::string> args) {
    args.insert(args.begin(), SHADOWCULL_BIN);
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const pid_t pid = ::fork();
    if (pid == 0) {
        const int null = ::open("/dev/null", O_WRONLY);
        ::dup2(null, 1), ::dup2(null, 2);
        ::execv(argv[0], argv.data());
        ::_exit(127);
    }
    int status = 0;
    struct rusage ru {};
    while (::wait4(pid, &status, 0, &ru) < 0 && errno == EINTR) {
    }
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ru.ru_maxrss};
}

}  // namespace

// A file in the writer's layout is handed over chunk by chunk and, within a chunk, object by
// object, and the parts make up what the whole-file reader reads.
TEST(ResultsFileStream, ChunksComeInPartsThatMakeUpTheWholeFile) {
    const fs::path dir = freshTestDir();
    const results::ResultsFile f = shard(1, 1, {{"00000000o.chunk", 0}, {"00000001o.chunk", 5}, {"00010000o.chunk", 1}}, 3);
    const std::string text = results::writeResults(f);
    writeText(dir / "r.json", text);
    std::vector<std::string> events;
    const std::optional<results::ResultsFile> stream = streamed(dir / "r.json", &events);
    ASSERT_TRUE(stream) << "not read as the writer's layout";
    EXPECT_EQ(results::writeResults(*stream), text);
    const std::vector<std::string> expected = {"begin 00000000o.chunk", "end 00000000o.chunk", "begin 00000001o.chunk",
                                               "object 0", "object 1", "object 2", "object 3", "object 4",
                                               "end 00000001o.chunk", "begin 00010000o.chunk", "object 0",
                                               "end 00010000o.chunk"};
    EXPECT_EQ(events, expected);

    // The whole chunks of the other overload are the same.
    std::vector<results::ChunkRecord> chunks;
    const results::ChunkVisitor visitor = [&](results::ChunkRecord& c) {
        chunks.push_back(c);
        return Status::ok();
    };
    Expected<std::optional<results::ResultsFile>> again = results::streamResultsFile((dir / "r.json").string(), visitor);
    ASSERT_TRUE(again && *again);
    (*again)->chunks = chunks;
    EXPECT_EQ(results::writeResults(**again), text);

    // An error of a part ends the reading and is what it returns.
    results::ChunkParts refusing;
    int objects = 0;
    refusing.object = [&](results::ObjectRecord&) {
        return ++objects < 3 ? Status::ok() : Status(makeError(ErrorKind::Io, "here", 0, "stop"));
    };
    Expected<std::optional<results::ResultsFile>> stopped = results::streamResultsFile((dir / "r.json").string(), refusing);
    ASSERT_FALSE(stopped);
    EXPECT_EQ(stopped.error().kind, ErrorKind::Io);
    EXPECT_EQ(objects, 3);
}

// The whole-file reader keeps the last of two equal keys. A file in the writer's layout but
// for a key given again, or a part that closes what holds it, must not be read apart as if
// the key were not there: such a file is left to the whole-file reader. (Before: a second
// "chunks" after the chunks, or one opened inside a chunk's text, gave the streamed reader
// chunks that the whole-file reader does not read.)
TEST(ResultsFileStream, AKeyGivenTwiceIsLeftToTheWholeFileReader) {
    const fs::path dir = freshTestDir();
    const results::ResultsFile f = shard(1, 1, {{"00000000o.chunk", 2}, {"00000001o.chunk", 2}, {"00000002o.chunk", 2}}, 3);
    const std::string text = results::writeResults(f);
    expectStreamAgrees(dir, text, false);
    // "chunks" again after the chunks: the whole-file reader reads none.
    expectStreamAgrees(dir, replaced(text, "\n ],\n", "\n ],\n \"chunks\": [],\n"), true);
    // A chunk's text that closes the array and opens another "chunks": the whole-file reader
    // reads the chunks from there on only.
    const std::string simulated = "   \"simulated\": [\n    \"terrain rule\"\n   ]\n  },\n  {\n   \"chunk\": \"00000002o.chunk\"";
    expectStreamAgrees(dir, replaced(text, simulated,
                                     "   \"simulated\": []}], \"chunks\": [{\"chunk\": \"b\", \"objects\": []\n  },\n  {\n"
                                     "   \"chunk\": \"00000002o.chunk\""),
                       true);
    // "objects" again after a chunk's objects: the whole-file reader reads that one.
    expectStreamAgrees(dir, replaced(text, "\n   ],\n   \"savings\"", "\n   ],\n   \"objects\": [],\n   \"savings\""), true);
    // An object's text that closes its object and adds one: read whole, it is two objects.
    const std::string twoObjects = "\n     \"element\": 1, \"kind\": \"model\", \"skipped\": true}, {\n     \"element\": 7,";
    expectStreamAgrees(dir, replaced(text, "\n     \"element\": 1,", twoObjects), true);
}

// A shard with a chunk far larger than any other (tens of thousands of witnesses, 10 MB of
// text) merges to the bytes of the merge in memory, and the merge's peak memory does not
// follow that chunk: against the same merge with small chunks, it grows by less than half
// the chunk's text (the whole chunk as a JSON value took ten times its text).
TEST(Merge, AVeryLargeChunkMergesToTheSameBytesWithoutBeingHeld) {
    const fs::path dir = freshTestDir();
    // The shards' files and the merge in memory's bytes, written, and every copy freed
    // before a merge is measured: a forked child's peak counts the parent's pages it
    // started with (its maxrss is kept across exec), so this process must be small then.
    auto prepare = [&](int objects, const std::string& tag) {
        const std::vector<std::pair<std::string, results::ResultsFile>> shards = {
            {(dir / (tag + "-1.json")).string(), shard(1, 2, {{"00000000o.chunk", objects}, {"00000001o.chunk", 3}}, 3)},
            {(dir / (tag + "-2.json")).string(), shard(2, 2, {{"00010000o.chunk", 2}}, 3)}};
        for (const auto& [path, f] : shards) writeText(path, results::writeResults(f));
        const cli::MergeOutcome inMemory = cli::mergeShards(shards);
        EXPECT_EQ(inMemory.exitCode, 0) << inMemory.message;
        writeText(dir / (tag + "-expected.json"), results::writeResults(inMemory.merged));
        return results::chunkJson(shards[0].second.chunks[0]).size();
    };
    auto merged = [&](const std::string& tag) {
        const fs::path out = dir / (tag + ".json");
        const auto [rc, peakKiB] = runMeasured(
            {"merge", out.string(), (dir / (tag + "-2.json")).string(), (dir / (tag + "-1.json")).string()});
        EXPECT_EQ(rc, 0);
        return peakKiB;
    };
    const size_t largeText = prepare(5000, "large");
    prepare(4, "small");
    ::malloc_trim(0);
    const long small = merged("small"), large = merged("large");
    for (const std::string tag : {"small", "large"})
        EXPECT_TRUE(readText(dir / (tag + ".json")) == readText(dir / (tag + "-expected.json"))) << tag;
    ASSERT_GT(largeText, size_t(8) << 20);
    EXPECT_LT(double(large - small) * 1024, 0.5 * double(largeText))
        << "peak " << large << " KiB with a chunk of " << largeText << " bytes, " << small << " KiB without";
}

// A shard's file in the writer's layout but for a second "chunks" after the chunks: merge
// reads it as the whole-file reader does (no chunks: shard 1's are missing, exit 8), not
// as the chunks its lines show (before: merged them, exit 0).
TEST(Merge, AShardFileWithChunksTwiceIsReadAsTheWholeFileReaderReadsIt) {
    const fs::path dir = freshTestDir();
    const std::string one = (dir / "shard-1.json").string(), two = (dir / "shard-2.json").string();
    const std::string text = results::writeResults(shard(1, 2, {{"00000000o.chunk", 2}}, 2));
    writeText(one, replaced(text, "\n ],\n", "\n ],\n \"chunks\": [],\n"));
    writeText(two, results::writeResults(shard(2, 2, {{"00010000o.chunk", 2}}, 2)));
    Expected<results::ResultsFile> whole = results::readResultsFile(one);
    ASSERT_TRUE(whole) << whole.error().what();
    EXPECT_TRUE(whole->chunks.empty());
    EXPECT_EQ(runCli("merge '" + (dir / "out.json").string() + "' '" + one + "' '" + two + "'", dir / "out", dir / "err"),
              cli::kExitShardsIncomplete)
        << readText(dir / "err");
    const std::string err = readText(dir / "err");
    EXPECT_NE(err.find("has no results for its chunk 00000000o.chunk"), std::string::npos) << err;
    EXPECT_FALSE(fs::exists(dir / "out.json"));
}
