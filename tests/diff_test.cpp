// `shadowcull diff`: golden reports for bakes that differ in known bits, exit codes (CI
// gate), baked space directories, and the self-contained HTML report.

#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/diff.h"
#include "cli/pipeline.h"
#include "cli/report.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

cli::BakeResult bake(const fs::path& space, bool useGeometry = true, bool write = false) {
    cli::BakeOptions opt;
    opt.spaceDir = space.string();
    opt.useGeometry = useGeometry;
    opt.write = write;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

// Writes the scene as DIR/NAME-space, bakes it dry and writes DIR/NAME.json.
fs::path bakeToJson(const SpaceBuilder& b, const fs::path& dir, const std::string& name, bool useGeometry = true) {
    const fs::path space = dir / (name + "-space");
    b.write(space.string());
    const fs::path json = dir / (name + ".json");
    writeText(json, results::writeResults(cli::resultsFile(bake(space, useGeometry))));
    return json;
}

struct DiffRun {
    int code = -1;
    std::string out, err;
};

DiffRun diff(const fs::path& a, const fs::path& b, const fs::path& html = {}, const fs::path& json = {}) {
    std::ostringstream out, err;
    DiffRun r;
    r.code = cli::runDiff({a.string(), b.string(), html.string(), json.string()}, out, err);
    r.out = out.str();
    r.err = err.str();
    return r;
}

// The output with the test's scratch directory replaced by "DIR": paths are printed as
// given, and the scratch root differs per run and machine.
std::string portable(std::string text, const fs::path& dir) {
    const std::string d = dir.string();
    for (size_t k; (k = text.find(d)) != std::string::npos;) text.replace(k, d.size(), "DIR");
    return text;
}

// Floating cubes (nothing below them, so every bit is truly 0) plus a lamp above them.
// With range 5 the reach stage proves the lamp's bits 0; with range 30 it cannot, and the
// shadow volumes prove them. No witness ray anywhere: the reports hold no float hit
// positions from Embree, so the golden text is the same on every CPU.
SpaceBuilder floatingCubesUnderLamp(double range) {
    SpaceBuilder b = twoFloatingCubes();
    b.addLight(LightSpec::point("lamp", {45, 25, 50.5}, range));
    return b;
}

}  // namespace

// Raycast-only leaves the floating cubes undecided (written 1); the shadow volumes prove 0.
TEST(Diff, GoldenGeometryStage) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(twoFloatingCubes(), dir, "raycast-only", false);
    const fs::path b = bakeToJson(twoFloatingCubes(), dir, "full", true);
    const DiffRun r = diff(a, b, {}, dir / "diff.json");
    EXPECT_EQ(r.code, cli::kDiffChanged) << r.err;
    EXPECT_EQ(r.err, "");
    expectGolden("diff_geometry.txt", portable(r.out, dir));
    expectGolden("diff_geometry.json", portable(readText(dir / "diff.json"), dir));
}

// A light's range changed: the bits stay 0, the proof moves from reach to geometry. Exit 1:
// a regression of the analytic pipeline counts even when no bit changed.
TEST(Diff, GoldenLightRangeVerdictOnly) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(floatingCubesUnderLamp(5), dir, "range5");
    const fs::path b = bakeToJson(floatingCubesUnderLamp(30), dir, "range30");
    const DiffRun r = diff(a, b);
    EXPECT_EQ(r.code, cli::kDiffChanged) << r.err;
    expectGolden("diff_range.txt", portable(r.out, dir));
}

TEST(Diff, IdenticalBakesExitZero) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(cubeOnTerrain(), dir, "a");
    const fs::path b = bakeToJson(cubeOnTerrain(), dir, "b");  // baked again: deterministic
    const DiffRun r = diff(a, b);
    EXPECT_EQ(r.code, cli::kDiffSame) << r.out << r.err;
    EXPECT_NE(r.out.find("result: no changes"), std::string::npos) << r.out;
    EXPECT_EQ(diff(a, a).code, cli::kDiffSame);
}

// A witness lost and a proof gained, shown with the evidence on each side; the HTML report
// is self-contained and holds the changed row and a plot of the old witness.
TEST(Diff, LostWitnessAndHtmlReport) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(cubeBesideLamp(10), dir, "range10");
    const fs::path b = bakeToJson(cubeBesideLamp(5), dir, "range5");
    const DiffRun r = diff(a, b, dir / "report.html", dir / "report.json");
    EXPECT_EQ(r.code, cli::kDiffChanged) << r.err;
    EXPECT_NE(r.out.find(fixedUuid(1) + " (model #0)  group 0  light 1 'lamp': 1 -> 0"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("old: kept by raycast: witness ray p ("), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("new: culled by reach: the group lies beyond the light's range (5 m)"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("evidence: lost witness, new proof (reach)"), std::string::npos) << r.out;

    const std::string html = readText(dir / "report.html");
    EXPECT_EQ(html.find("http://"), std::string::npos);
    EXPECT_EQ(html.find("https://"), std::string::npos);
    EXPECT_EQ(html.find("src="), std::string::npos);
    EXPECT_EQ(html.find("<link"), std::string::npos);
    EXPECT_NE(html.find("<style>"), std::string::npos);
    EXPECT_NE(html.find("<td>" + fixedUuid(1) + " (model #0)</td>"), std::string::npos);
    EXPECT_NE(html.find("lost witness, new proof (reach)"), std::string::npos);
    EXPECT_NE(html.find("<svg"), std::string::npos);
    EXPECT_NE(html.find("<circle class=\"old p\""), std::string::npos) << "the old witness's p is plotted";

    const std::string json = readText(dir / "report.json");
    EXPECT_NE(json.find("\"changedBits\""), std::string::npos);
    EXPECT_NE(json.find("\"witness\""), std::string::npos);

    // Two runs give byte-identical reports.
    const DiffRun again = diff(a, b, dir / "again.html", dir / "again.json");
    EXPECT_EQ(again.out, r.out);
    EXPECT_EQ(readText(dir / "again.html"), html);
    EXPECT_EQ(readText(dir / "again.json"), json);
}

TEST(Diff, HtmlPlaceholderWithoutWitness) {
    const fs::path dir = freshTestDir();
    const fs::path a = bakeToJson(twoFloatingCubes(), dir, "a", false);
    const fs::path b = bakeToJson(twoFloatingCubes(), dir, "b", true);
    diff(a, b, dir / "report.html");
    const std::string html = readText(dir / "report.html");
    EXPECT_NE(html.find("no witness ray on either side"), std::string::npos);
    EXPECT_EQ(html.find("http://"), std::string::npos);
}

TEST(Diff, LightListsDifferProminently) {
    const fs::path dir = freshTestDir();
    SpaceBuilder renamed;
    renamed.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    renamed.addChunk(0, 0);
    renamed.addLight(LightSpec::point("lantern", {45, 25, 50.5}, 5));  // light 1 was the sun
    renamed.addLight(LightSpec::directional("sun", {0.05, -1.0, 0.02}));
    renamed.addModel("cube", Affine::translation({40, 20, 50}), fixedUuid(1));
    renamed.addModel("cube", Affine::translation({50, 20, 50}), fixedUuid(2));
    const fs::path a = bakeToJson(twoFloatingCubes(), dir, "a");
    const fs::path b = bakeToJson(renamed, dir, "b");
    const DiffRun r = diff(a, b);
    EXPECT_EQ(r.code, cli::kDiffChanged);
    EXPECT_NE(r.out.find("*** LIGHT LISTS DIFFER"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("light 1: 'sun' (directional) -> 'lantern' (point): renamed, type changed"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("light 2: - -> 'sun' (directional): added"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("'sun' was light 1, is light 2"), std::string::npos) << r.out;
}

TEST(Diff, ObjectsAddedAndRemoved) {
    const fs::path dir = freshTestDir();
    SpaceBuilder other;
    other.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    other.addChunk(0, 0);
    other.addLight(LightSpec::directional("sun", {0.05, -1.0, 0.02}));
    other.addModel("cube", Affine::translation({40, 20, 50}), fixedUuid(1));
    other.addModel("cube", Affine::translation({60, 20, 50}), fixedUuid(7));
    const DiffRun r = diff(bakeToJson(twoFloatingCubes(), dir, "a"), bakeToJson(other, dir, "b"));
    EXPECT_EQ(r.code, cli::kDiffChanged);
    EXPECT_NE(r.out.find("00000000o.chunk  " + fixedUuid(7) + " (model #1): added"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("00000000o.chunk  " + fixedUuid(2) + " (model #1): removed"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("changed bits (0)"), std::string::npos) << r.out;
}

TEST(Diff, BadInputExitsThree) {
    const fs::path dir = freshTestDir();
    const fs::path good = bakeToJson(cubeOnTerrain(), dir, "good");
    writeText(dir / "broken.json", "{\n \"format\": \"shadowcull-results\",\n \"version\": 1,\n oops\n}\n");
    DiffRun r = diff(good, dir / "broken.json");
    EXPECT_EQ(r.code, cli::kExitBadInput);
    EXPECT_NE(r.err.find((dir / "broken.json").string() + ":4: malformed JSON"), std::string::npos) << r.err;
    EXPECT_EQ(r.out, "");

    writeText(dir / "other.json", "{\"format\": \"something else\"}\n");
    r = diff(dir / "other.json", good);
    EXPECT_EQ(r.code, cli::kExitBadInput);
    EXPECT_NE(r.err.find("other.json: not a shadowcull results file"), std::string::npos) << r.err;

    writeText(dir / "partial.json",
              "{\"format\": \"shadowcull-results\", \"version\": 1, \"lights\": [],"
              " \"chunks\": [{\"chunk\": \"00000000o.chunk\", \"objects\": ["
              "{\"element\": 0, \"kind\": \"model\", \"skipped\": true}, {\"kind\": \"model\"}]}]}");
    r = diff(good, dir / "partial.json");
    EXPECT_EQ(r.code, cli::kExitBadInput);
    EXPECT_NE(r.err.find("partial.json: malformed results at chunks[0].objects[1]: key 'element' not found"),
              std::string::npos)
        << r.err;

    // Found by fuzzing: numbers where integers belong were converted with undefined
    // behaviour, and a number beyond a double escaped as an uncaught exception.
    for (const auto& [text, words] : std::vector<std::pair<std::string, std::string>>{
             {"{\"format\": \"shadowcull-results\", \"version\": 1e308}", "'version' must be an integer, not 1e+308"},
             {"{\"format\": \"shadowcull-results\", \"version\": 1, \"lights\": [], \"chunks\": [{\"chunk\": \"c\", "
              "\"objects\": [{\"element\": 0, \"kind\": \"model\", \"mask\": 4294967296, \"groups\": []}]}]}",
              "'mask' 4294967296 is out of range"},
             {"{\"format\": \"shadowcull-results\", \"version\": 1e400}", "malformed JSON"}}) {
        writeText(dir / "numbers.json", text);
        r = diff(good, dir / "numbers.json");
        EXPECT_EQ(r.code, cli::kExitBadInput) << text;
        EXPECT_NE(r.err.find(words), std::string::npos) << r.err;
    }

    r = diff(dir / "missing.json", good);
    EXPECT_EQ(r.code, cli::kExitBadInput);
    EXPECT_NE(r.err.find("missing.json: cannot open results file"), std::string::npos) << r.err;
}

// Baked spaces: only the <shadow> masks are compared; evidence is unavailable and said so.
TEST(Diff, BakedSpaceDirectories) {
    const fs::path dir = freshTestDir();
    const fs::path a = dir / "raycast-only", b = dir / "full";
    twoFloatingCubes().write(a.string());
    twoFloatingCubes().write(b.string());
    bake(a, false, true);
    bake(b, true, true);
    const DiffRun r = diff(a, b);
    EXPECT_EQ(r.code, cli::kDiffChanged) << r.err;
    EXPECT_NE(r.out.find("note: old (" + a.string() + ") is a baked space: masks only"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("lights: 1 'sun' (directional)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("changed bits (2)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(fixedUuid(2) + " (model #1)  group 0  light 1 'sun': 1 -> 0"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("old: bit 1 (mask only, no evidence)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("evidence: evidence unavailable (both are baked spaces)"), std::string::npos) << r.out;

    // Evidence on one side only: still unavailable for the comparison, and said which.
    writeText(dir / "raycast-only.json", results::writeResults(cli::resultsFile(bake(a, false))));
    const DiffRun half = diff(dir / "raycast-only.json", b);
    EXPECT_EQ(half.code, cli::kDiffChanged);
    EXPECT_NE(half.out.find("old: undecided, kept as 1\n      new: bit 0 (mask only, no evidence)\n"
                            "      evidence: evidence unavailable (new is a baked space)"),
              std::string::npos)
        << half.out;

    EXPECT_EQ(diff(b, b).code, cli::kDiffSame);
    // A results file against the space it describes: same bits.
    writeText(dir / "full.json", results::writeResults(cli::resultsFile(bake(b))));
    const DiffRun mixed = diff(dir / "full.json", b);
    EXPECT_EQ(mixed.code, cli::kDiffSame) << mixed.out;

    // An unbaked copy has no <shadow> elements.
    twoFloatingCubes().write((dir / "unbaked").string());
    const DiffRun unbaked = diff(dir / "unbaked", b);
    EXPECT_EQ(unbaked.code, cli::kDiffChanged);
    EXPECT_NE(unbaked.out.find("no <shadow> in old"), std::string::npos) << unbaked.out;

    // A malformed chunk file is bad input naming the file.
    writeText(a / "00000000o.chunk", "<chunk>\n  <model>\n</chunk>\n");
    const DiffRun bad = diff(a, b);
    EXPECT_EQ(bad.code, cli::kExitBadInput);
    EXPECT_NE(bad.err.find((a / "00000000o.chunk").string()), std::string::npos) << bad.err;
}
