// io/results_file.h: the one model, reader and writer of the results JSON. The writer
// must give the bytes `bake --results` writes (merge and export will rewrite what they
// read, and the determinism tests compare files byte for byte); the reader must refuse what
// is not a results file with the file, line or JSON path, as `shadowcull diff` always did.

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "io/results_file.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

const fs::path kSample = fs::path(SHADOWCULL_SOURCE_DIR) / "data" / "sample";

// Bakes `space` into dir/out (the space is not touched) with --results dir/r.json and
// returns the results file's text. `exitCode`: what the bake must return.
std::string bakeResults(const fs::path& space, const fs::path& dir, int exitCode = 0) {
    const int rc = runCli("bake '" + space.string() + "' --quiet --out '" + (dir / "out").string() + "' --results '" +
                              (dir / "r.json").string() + "'",
                          dir / "stdout", dir / "stderr");
    EXPECT_EQ(rc, exitCode) << readText(dir / "stderr");
    return readText(dir / "r.json");
}

results::ResultsFile parseOk(const std::string& text) {
    Expected<results::ResultsFile> f = results::parseResults("r.json", text);
    EXPECT_TRUE(f) << (f ? "" : f.error().what());
    return f ? std::move(*f) : results::ResultsFile{};
}

// The error parseResults gives for `text` (the test fails when it parses).
Error parseError(const std::string& text) {
    Expected<results::ResultsFile> f = results::parseResults("bad.json", text);
    EXPECT_FALSE(f) << "parsed: " << text.substr(0, 200);
    return f ? Error{} : f.error();
}

// The sample's results with one edit made on the JSON value.
template <class Edit>
std::string editedSample(const std::string& text, Edit edit) {
    nlohmann::json j = nlohmann::json::parse(text);
    edit(j);
    return j.dump(1);
}

// What nlohmann prints for the same value: the layout the bake wrote before the model
// existed (a json value dumped with indent 1, keys sorted), whatever pieces writeResults
// assembles it from.
std::string canonical(const std::string& text) { return nlohmann::json::parse(text).dump(1) + "\n"; }

// A file made by hand with every case of omission: no chunk, a chunk without objects, a
// skipped object with and without uuid, an undecided bit (no stage, no reason), a witness.
results::ResultsFile handMade(bool withChunks) {
    results::ResultsFile f;
    f.space = "space";
    auto light = [](int index, const char* name, const char* type) {
        results::LightRecord L;
        L.index = index;
        L.bit = index - 1;
        L.name = name;
        L.type = type;
        return L;
    };
    f.lights = {light(1, "sun", "directional"), light(2, "lamp", "point")};
    if (withChunks) {
        results::ChunkRecord empty;
        empty.chunk = "00000000o.chunk";
        results::ChunkRecord c;
        c.chunk = "00000001o.chunk";
        c.simulated = {"terrain rule"};
        results::ObjectRecord skipped;
        skipped.element = 0;
        skipped.kind = "model";
        skipped.uuid = "U-1";
        skipped.skipped = true;
        results::ObjectRecord skippedNoUuid = skipped;
        skippedNoUuid.element = 1;
        skippedNoUuid.uuid.clear();
        results::ObjectRecord o;
        o.element = 2;
        o.kind = "terrain";
        o.mask = 1;
        results::GroupRecord g;
        g.group = 0;
        g.mask = 1;
        results::BitRecord kept;
        kept.light = 1;
        kept.bit = 1;
        kept.verdict = "kept";
        kept.stage = "raycast";
        kept.reason = "witness ray";
        kept.witness = results::WitnessRecord{{0.1, 2.0, -3.5}, {0.0, -1.0, 0.0}, {1e-300, 5.0, 6.0}, {7.0, 8.0, 9.0},
                                              "00000001o.chunk terrain #2 group 0", std::nullopt};
        results::BitRecord undecided;
        undecided.light = 2;
        undecided.bit = 1;
        undecided.verdict = "undecided";
        g.lights = {kept, undecided};
        o.groups = {g};
        c.objects = {skipped, skippedNoUuid, o};
        f.chunks = {empty, c};
    }
    f.summary = results::summarize(f.chunks);
    f.warnings = {"a.chunk:3: something skipped"};
    return f;
}

}  // namespace

// The golden check: what the bake wrote is exactly what the writer makes of the parsed file,
// and writing, parsing and writing again changes nothing.
TEST(ResultsFile, SampleBakeRoundTripsByteForByte) {
    const fs::path dir = freshTestDir();
    const std::string baked = bakeResults(kSample, dir);
    ASSERT_FALSE(baked.empty());
    const results::ResultsFile f = parseOk(baked);
    EXPECT_EQ(results::writeResults(f), baked);
    const std::string again = results::writeResults(parseOk(results::writeResults(f)));
    EXPECT_EQ(again, baked);

    // What was read is the sample's bake, not an empty shell that happens to print alike.
    EXPECT_EQ(f.version, 1);
    EXPECT_EQ(f.lights.size(), 3u);
    EXPECT_EQ(f.chunks.size(), 9u);
    EXPECT_EQ(f.summary.chunks, 9u);
    size_t witnesses = 0;
    for (const results::ChunkRecord& c : f.chunks)
        for (const results::ObjectRecord& o : c.objects)
            for (const results::GroupRecord& g : o.groups)
                for (const results::BitRecord& b : g.lights) witnesses += b.witness.has_value();
    EXPECT_GT(witnesses, 0u);
    // The summary the bake wrote is the one the records give.
    const results::Summary s = results::summarize(f.chunks);
    EXPECT_EQ(s.bits, f.summary.bits);
    EXPECT_EQ(s.groups, f.summary.groups);
    EXPECT_EQ(s.kept, f.summary.kept);
    EXPECT_EQ(s.culled, f.summary.culled);
    EXPECT_EQ(s.provedKept, f.summary.provedKept);
    EXPECT_EQ(s.undecided, f.summary.undecided);
    EXPECT_EQ(s.culledBy, f.summary.culledBy);
    EXPECT_GT(f.summary.bits, 0u);

    // readResultsFile reads the same.
    Expected<results::ResultsFile> fromFile = results::readResultsFile((dir / "r.json").string());
    ASSERT_TRUE(fromFile) << fromFile.error().what();
    EXPECT_EQ(results::writeResults(*fromFile), baked);
}

// A damaged copy of the sample: skipped objects (no mask, no groups), an object without
// uuid, and warnings, all as the bake writes them.
TEST(ResultsFile, SkippedObjectsAndWarningsRoundTrip) {
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    fs::copy(kSample, space, fs::copy_options::recursive);
    std::string chunk = readText(space / "00000000o.chunk");
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"models/house.obj", "models/missing.obj"},
                                   {"<uuid> 5A3B1E00-00000000-00000000-000000C1 </uuid>", ""}}) {
        const size_t at = chunk.find(from);
        ASSERT_NE(at, std::string::npos) << from;
        chunk.replace(at, from.size(), to);
    }
    writeText(space / "00000000o.chunk", chunk);
    const std::string baked = bakeResults(space, dir, 1);
    const results::ResultsFile f = parseOk(baked);
    EXPECT_EQ(results::writeResults(f), baked);
    EXPECT_EQ(f.warnings.size(), 2u);
    int skipped = 0, withoutUuid = 0;
    for (const results::ChunkRecord& c : f.chunks)
        for (const results::ObjectRecord& o : c.objects) {
            skipped += o.skipped;
            withoutUuid += o.kind == "model" && o.uuid.empty();
            if (o.skipped) {
                EXPECT_TRUE(o.groups.empty());
            }
        }
    EXPECT_EQ(skipped, 1);
    EXPECT_EQ(withoutUuid, 1);
}

// writeResults assembles the file from pieces (chunkJson, head, tail) for a later streaming
// writer: the bytes must still be nlohmann's dump of the whole value, with and without
// chunks.
TEST(ResultsFile, WriterGivesTheLayoutOfOneDump) {
    for (bool withChunks : {false, true}) {
        SCOPED_TRACE(withChunks ? "chunks" : "no chunk");
        const results::ResultsFile f = handMade(withChunks);
        const std::string text = results::writeResults(f);
        EXPECT_EQ(text, canonical(text));
        EXPECT_EQ(results::writeResults(parseOk(text)), text);
        const nlohmann::json j = nlohmann::json::parse(text);
        EXPECT_EQ(j.at("format"), "shadowcull-results");
        EXPECT_EQ(j.at("version"), 1);
        EXPECT_EQ(j.at("lights").size(), 2u);
        if (!withChunks) {
            EXPECT_NE(text.find("\"chunks\": [],\n"), std::string::npos) << text;
            continue;
        }
        // Fields left out when empty, as the bake writes them.
        const nlohmann::json& objects = j.at("chunks").at(1).at("objects");
        EXPECT_EQ(objects.at(0), nlohmann::json::parse(R"({"element": 0, "kind": "model", "uuid": "U-1", "skipped": true})"));
        EXPECT_EQ(objects.at(1), nlohmann::json::parse(R"({"element": 1, "kind": "model", "skipped": true})"));
        const nlohmann::json& undecided = objects.at(2).at("groups").at(0).at("lights").at(1);
        EXPECT_EQ(undecided, nlohmann::json::parse(R"({"light": 2, "bit": 1, "verdict": "undecided"})"));
        const nlohmann::json& witness = objects.at(2).at("groups").at(0).at("lights").at(0).at("witness");
        EXPECT_EQ(witness.at("p").at(0).get<double>(), 1e-300);
        EXPECT_EQ(j.at("chunks").at(0).at("objects"), nlohmann::json::array());
        // A chunk's piece is the text of that chunk inside the file, an object's of that object.
        EXPECT_NE(text.find(results::chunkJson(f.chunks[1])), std::string::npos);
        for (const results::ObjectRecord& o : f.chunks[1].objects) {
            const std::string piece = results::chunkObjectJson(o);
            EXPECT_NE(text.find(piece), std::string::npos);
            Expected<results::ObjectRecord> back = results::parseObjectJson("o.json", piece);
            ASSERT_TRUE(back) << back.error().what();
            EXPECT_EQ(results::chunkObjectJson(*back), piece);
        }
        EXPECT_EQ(j.at("summary").at("bits"), 2);
        EXPECT_EQ(j.at("summary").at("provedKept"), 1);
        EXPECT_EQ(j.at("summary").at("undecided"), 1);
    }
}

// Fields a reader can do without are optional; the summary of a file without one is
// computed from its chunks.
TEST(ResultsFile, OptionalFields) {
    const std::string text = results::writeResults(handMade(true));
    const results::ResultsFile full = parseOk(text);
    const results::ResultsFile bare = parseOk(editedSample(text, [](nlohmann::json& j) {
        j.erase("space");
        j.erase("summary");
        j.erase("warnings");
        for (nlohmann::json& L : j["lights"]) {
            L.erase("index");
            L.erase("bit");
        }
        j["chunks"][1].erase("simulated");
    }));
    EXPECT_EQ(bare.space, "");
    EXPECT_TRUE(bare.warnings.empty());
    EXPECT_TRUE(bare.chunks[1].simulated.empty());
    ASSERT_EQ(bare.lights.size(), 2u);
    EXPECT_EQ(bare.lights[1].index, 2);
    EXPECT_EQ(bare.lights[1].bit, 1);
    EXPECT_EQ(bare.summary.bits, full.summary.bits);
    EXPECT_EQ(bare.summary.provedKept, 1u);
    EXPECT_EQ(bare.summary.undecided, 1u);
    EXPECT_EQ(bare.summary.chunks, 2u);
}

TEST(ResultsFile, MalformedJsonNamesFileAndLine) {
    const Error e = parseError("{\n \"format\": \"shadowcull-results\",\n \"version\": 1,\n oops\n}\n");
    EXPECT_EQ(e.kind, ErrorKind::BadInput);
    EXPECT_EQ(e.file, "bad.json");
    EXPECT_EQ(e.line, 4);
    EXPECT_EQ(e.what().rfind("bad.json:4: malformed JSON: ", 0), 0u) << e.what();

    // Beyond a double: not a parse error for nlohmann, still malformed JSON here.
    const Error big = parseError("{\"format\": \"shadowcull-results\", \"version\": 1e400}");
    EXPECT_EQ(big.what().rfind("bad.json: malformed JSON: ", 0), 0u) << big.what();
}

TEST(ResultsFile, NotAResultsFile) {
    for (const char* text : {"{\"format\": \"something else\"}", "[1, 2]", "{}", "{\"format\": 1}"}) {
        const Error e = parseError(text);
        EXPECT_EQ(e.what(), "bad.json: not a shadowcull results file (expected \"format\": \"shadowcull-results\")")
            << text;
    }
    const Error v = parseError("{\"format\": \"shadowcull-results\", \"version\": 2}");
    EXPECT_EQ(v.what(), "bad.json: malformed results at top level: unsupported version 2 (this tool reads version 1)");
}

// Bad content: the message names the JSON path of the part being read.
TEST(ResultsFile, BadContentNamesTheJsonPath) {
    const fs::path dir = freshTestDir();
    const std::string sample = bakeResults(kSample, dir);
    struct Case {
        std::function<void(nlohmann::json&)> edit;
        std::string message;
    };
    const std::vector<Case> cases = {
        {[](nlohmann::json& j) { j["chunks"][1]["objects"][2]["groups"][0]["lights"][1].erase("verdict"); },
         "bad.json: malformed results at chunks[1].objects[2].groups[0].lights[1]: key 'verdict' not found"},
        {[](nlohmann::json& j) { j["chunks"][0]["objects"][1].erase("element"); },
         "bad.json: malformed results at chunks[0].objects[1]: key 'element' not found"},
        {[](nlohmann::json& j) { j["chunks"][2]["objects"][0]["mask"] = 4294967296ull; },
         "bad.json: malformed results at chunks[2].objects[0]: 'mask' 4294967296 is out of range"},
        {[](nlohmann::json& j) { j["chunks"][2]["objects"][0]["groups"][0]["mask"] = -1; },
         "bad.json: malformed results at chunks[2].objects[0].groups[0]: 'mask' -1 is out of range"},
        {[](nlohmann::json& j) { j["chunks"][0]["objects"][0]["element"] = 2.5; },
         "bad.json: malformed results at chunks[0].objects[0]: 'element' must be an integer, not 2.5"},
        {[](nlohmann::json& j) { j["version"] = 1e308; },
         "bad.json: malformed results at top level: 'version' must be an integer, not 1e+308"},
        {[](nlohmann::json& j) { j["chunks"].push_back(j["chunks"][0]); },
         "bad.json: malformed results at chunks[9]: chunk ffffffffo.chunk appears twice"},
        {[](nlohmann::json& j) { j["chunks"][0]["objects"][0]["groups"][0]["group"] = 1; },
         "bad.json: malformed results at chunks[0].objects[0].groups[0]: groups out of order"},
        {[](nlohmann::json& j) { j["chunks"][0]["objects"][0]["groups"][0]["lights"][2]["light"] = 2; },
         "bad.json: malformed results at chunks[0].objects[0].groups[0].lights[2]: lights out of order"},
        {[](nlohmann::json& j) { j["chunks"][0]["objects"][0]["groups"][0]["lights"][0]["witness"]["p"] = {1, 2}; },
         "bad.json: malformed results at chunks[0].objects[0].groups[0].lights[0]: expected [x, y, z]"},
        {[](nlohmann::json& j) { j["lights"][1].erase("type"); },
         "bad.json: malformed results at lights[1]: key 'type' not found"},
        {[](nlohmann::json& j) { j["summary"]["culled"] = "many"; },
         "bad.json: malformed results at summary: 'culled' must be an integer, not \"many\""},
        {[](nlohmann::json& j) { j["warnings"] = 3; },
         "bad.json: malformed results at top level: type must be array, but is number"},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.message);
        const Error e = parseError(editedSample(sample, c.edit));
        EXPECT_EQ(e.kind, ErrorKind::BadInput);
        EXPECT_EQ(e.what(), c.message);
    }
}

TEST(ResultsFile, ReadResultsFileReadsRegularFilesOnly) {
    const fs::path dir = freshTestDir();
    Expected<results::ResultsFile> missing = results::readResultsFile((dir / "missing.json").string());
    ASSERT_FALSE(missing);
    EXPECT_EQ(missing.error().kind, ErrorKind::MissingResource);
    EXPECT_NE(missing.error().what().find("missing.json: cannot open results file"), std::string::npos)
        << missing.error().what();
    Expected<results::ResultsFile> directory = results::readResultsFile(dir.string());
    ASSERT_FALSE(directory);
    EXPECT_EQ(directory.error().kind, ErrorKind::BadInput) << directory.error().what();
}

// A space path (or a warning) that is not valid UTF-8 is written with U+FFFD in its place:
// before, nlohmann threw from dump() and the bake died at its very end (exit 134).
TEST(ResultsFile, InvalidUtf8IsReplacedNotFatal) {
    shadowcull::results::ResultsFile f;
    f.space = "caf\xe9/space";
    f.warnings.push_back("m\xff.obj: skipped");
    std::string text;
    ASSERT_NO_THROW(text = shadowcull::results::writeResults(f));
    shadowcull::Expected<shadowcull::results::ResultsFile> back = shadowcull::results::parseResults("r.json", text);
    ASSERT_TRUE(back) << back.error().what();
    EXPECT_EQ(back->space, "caf\xef\xbf\xbd/space");
    ASSERT_EQ(back->warnings.size(), 1u);
    EXPECT_EQ(back->warnings[0], "m\xef\xbf\xbd.obj: skipped");
}
