// glTF scenes in and out, as a user runs them: `shadowcull import` a generated scene with
// known answers, bake it, `shadowcull export` the masks, and read them back from the
// exported file's extras.shadowcull. The same scenes moved 100 km and turned, and passed
// through `gltfpack -c` (quantized + meshopt-compressed), must give the same masks.

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <limits>

#include <cmath>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "gltf/gltf_import.h"
#include "io/results_file.h"
#include "tests/support/gltf_scenes.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

uint32_t u32(const std::string& s, size_t at) {
    uint32_t v = 0;
    for (size_t k = 0; k < 4; ++k) v |= uint32_t(uint8_t(s[at + k])) << (8 * k);
    return v;
}

// The JSON of a .gltf or .glb file, and a .glb's BIN chunk.
struct GltfParts {
    json doc;
    std::string bin;
};

GltfParts readGltf(const fs::path& path) {
    const std::string bytes = readText(path);
    GltfParts parts;
    if (bytes.compare(0, 4, "glTF") != 0) {
        parts.doc = json::parse(bytes);
        return parts;
    }
    const size_t jsonLength = u32(bytes, 12);
    parts.doc = json::parse(bytes.substr(20, jsonLength));
    const size_t binAt = 20 + jsonLength;
    if (binAt + 8 <= bytes.size()) parts.bin = bytes.substr(binAt + 8, u32(bytes, binAt));
    return parts;
}

// Node name -> group masks, from the exported file's extras.shadowcull. An unnamed node
// counts under its nearest named ancestor (gltfpack -kn moves meshes of named nodes to
// unnamed children).
std::map<std::string, std::vector<uint32_t>> exportedMasks(const json& doc) {
    std::map<size_t, size_t> parent;
    for (size_t n = 0; n < doc["nodes"].size(); ++n)
        for (const json& c : doc["nodes"][n].value("children", json::array())) parent[c.get<size_t>()] = n;
    std::map<std::string, std::vector<uint32_t>> masks;
    for (size_t i = 0; i < doc["nodes"].size(); ++i) {
        const json& n = doc["nodes"][i];
        if (!n.contains("extras") || !n["extras"].contains("shadowcull")) continue;
        size_t named = i;
        while (!doc["nodes"][named].contains("name") && parent.count(named)) named = parent[named];
        masks[doc["nodes"][named].value("name", std::string())] = n["extras"]["shadowcull"]["groups"].get<std::vector<uint32_t>>();
    }
    return masks;
}

struct CliRun {
    int code = -1;
    std::string out, err;
};

CliRun cli(const fs::path& dir, const std::string& args) {
    CliRun r;
    r.code = runCli(args, dir / "stdout.txt", dir / "stderr.txt");
    r.out = readText(dir / "stdout.txt");
    r.err = readText(dir / "stderr.txt");
    return r;
}

std::string q(const fs::path& p) { return "'" + p.string() + "'"; }

// import -> bake -> export; returns the exported document.
json importBakeExport(const fs::path& dir, const fs::path& scene, const std::string& importArgs = "") {
    const fs::path space = dir / "space", results = dir / "results.json", out = dir / ("exported" + scene.extension().string());
    CliRun r = cli(dir, "import " + q(scene) + " " + q(space) + " " + importArgs);
    EXPECT_EQ(r.code, 0) << r.err;
    r = cli(dir, "bake " + q(space) + " --quiet --results " + q(results));
    EXPECT_EQ(r.code, 0) << r.err;
    r = cli(dir, "export " + q(space) + " " + q(results) + " --gltf " + q(scene) + " --out " + q(out));
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("wrote"), std::string::npos) << r.out;
    return fs::exists(out) ? readGltf(out).doc : json();
}

void expectKnownMasks(const KnownGltfScene& k, const json& exported, bool anyPrimitiveOrder = false) {
    const auto masks = exportedMasks(exported);
    for (const auto& [name, want] : k.expected) {
        auto it = masks.find(name);
        ASSERT_NE(it, masks.end()) << k.name << ": node " << name << " has no extras.shadowcull";
        std::vector<uint32_t> got = it->second, expected = want;
        if (anyPrimitiveOrder) {
            std::sort(got.begin(), got.end());
            std::sort(expected.begin(), expected.end());
        }
        EXPECT_EQ(got, expected) << k.name << ": node " << name;
    }
    ASSERT_TRUE(exported["extras"]["shadowcull"]["lights"].is_array());
    const json& lights = exported["extras"]["shadowcull"]["lights"];
    ASSERT_EQ(lights.size(), k.lightNames.size());
    // A light without a name takes its node's (gltfpack drops light names: "Sun").
    auto lower = [](std::string s) {
        for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
        return s;
    };
    for (size_t l = 0; l < lights.size(); ++l) EXPECT_EQ(lower(lights[l]["name"].get<std::string>()), k.lightNames[l]);
}

TEST(GltfImport, KnownScenesImportBakeAndExportTheirMasks) {
    for (bool moved : {false, true}) {
        const KnownGltfScene k = courtyardScene(moved);
        const fs::path dir = freshTestDir(moved ? "-moved" : "");
        // Both containers: .glb, and .gltf with its buffer in a data: URI.
        const fs::path scene = dir / (moved ? "scene.gltf" : "scene.glb");
        writeText(scene, moved ? k.scene.gltf() : k.scene.glb());
        const json exported = importBakeExport(dir, scene);
        expectKnownMasks(k, exported);
        // Lights: one per light node, in depth-first order, with the node's extras.
        const std::string space = readText(dir / "space" / "space.xml");
        EXPECT_NE(space.find("<bias>0.02</bias>"), std::string::npos) << space;
        EXPECT_EQ(exported["extras"]["shadowcull"]["lights"][1]["node"], 2);  // World, Sun, Lamp
    }
}

// Nodes that cast no shadow block no light and still receive, through glTF as through a
// space (semantics.md condition 1), at the origin and 100 km away, turned.
TEST(GltfImport, NodesThatCastNoShadowHideNothingAndStillReceive) {
    for (bool moved : {false, true}) {
        const KnownGltfScene k = nonCasterScene(moved);
        const fs::path dir = freshTestDir(moved ? "-moved" : "");
        const fs::path scene = dir / "scene.glb";
        writeText(scene, k.scene.glb());
        expectKnownMasks(k, importBakeExport(dir, scene));
    }
}

TEST(GltfImport, InstancedMeshesAreWrittenOnce) {
    const KnownGltfScene k = courtyardScene();
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.gltf", k.scene.gltf());
    CliRun r = cli(dir, "import " + q(dir / "scene.gltf") + " " + q(dir / "space"));
    ASSERT_EQ(r.code, 0) << r.err;
    size_t resources = 0;
    for (const auto& e : fs::directory_iterator(dir / "space" / "models")) resources += e.path().extension() == ".glb";
    EXPECT_EQ(resources, 4u);  // Cube, Ground, Shelf, Bush: 11 models
    EXPECT_NE(r.out.find("11 models"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("every window holds the whole scene"), std::string::npos) << r.out;
    // Every model records its node.
    std::string chunks;
    for (const auto& [name, text] : chunkTexts(dir / "space")) chunks += text;
    EXPECT_NE(chunks.find("name=\"ShelfCaster\""), std::string::npos);
    EXPECT_NE(chunks.find("<castsShadow>false</castsShadow>"), std::string::npos);
}

// Export changes nothing but extras.shadowcull: the JSON minus those members is the
// original's, the binary chunk is the same bytes; exporting onto the export again works.
TEST(GltfImport, ExportKeepsEverythingElse) {
    const KnownGltfScene k = courtyardScene();
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.glb", k.scene.glb());
    importBakeExport(dir, dir / "scene.glb");
    const GltfParts before = readGltf(dir / "scene.glb"), after = readGltf(dir / "exported.glb");
    EXPECT_EQ(before.bin, after.bin);
    json stripped = after.doc;
    stripped.erase("extras");
    for (json& n : stripped["nodes"])
        if (n.contains("extras")) {
            n["extras"].erase("shadowcull");
            if (n["extras"].empty()) n.erase("extras");
        }
    EXPECT_EQ(stripped, before.doc);
    // Re-exporting onto the exported file (an earlier export of the same scene) is allowed
    // and gives the same masks.
    CliRun r = cli(dir, "export " + q(dir / "space") + " " + q(dir / "results.json") + " --gltf " + q(dir / "exported.glb") +
                         " --out " + q(dir / "again.glb"));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(exportedMasks(readGltf(dir / "again.glb").doc), exportedMasks(after.doc));
    // Never over an input.
    r = cli(dir, "export " + q(dir / "space") + " " + q(dir / "results.json") + " --gltf " + q(dir / "scene.glb") + " --out " +
                     q(dir / "scene.glb"));
    EXPECT_NE(r.code, 0);
    EXPECT_EQ(readGltf(dir / "scene.glb").doc, before.doc);
    // A copy that cannot be written says why (it said only "could not write").
    r = cli(dir, "export " + q(dir / "space") + " " + q(dir / "results.json") + " --gltf " + q(dir / "scene.glb") + " --out " +
                     q(dir / "no" / "such" / "x.glb"));
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("x.glb: cannot create temporary file"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("No such file or directory (nothing written)"), std::string::npos) << r.err;
}

TEST(GltfImport, ExportRefusesAnotherScene) {
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.glb", courtyardScene().scene.glb());
    writeText(dir / "other.glb", courtyardScene(true).scene.glb());
    importBakeExport(dir, dir / "scene.glb");
    CliRun r = cli(dir, "export " + q(dir / "space") + " " + q(dir / "results.json") + " --gltf " + q(dir / "other.glb") +
                         " --out " + q(dir / "x.glb"));
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_NE(r.err.find("is not the scene"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.glb"));
}

TEST(GltfImport, ExportRefusesResultsOfAnotherScene) {
    const fs::path dir = freshTestDir();
    KnownGltfScene other = courtyardScene();
    other.scene.doc()["nodes"][5]["name"] = "Box";  // same structure, one node renamed
    writeText(dir / "other" / "scene.glb", other.scene.glb());
    importBakeExport(dir / "other", dir / "other" / "scene.glb");
    writeText(dir / "scene.glb", courtyardScene().scene.glb());
    CliRun r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "space"));
    ASSERT_EQ(r.code, 0) << r.err;
    r = cli(dir, "export " + q(dir / "space") + " " + q(dir / "other" / "results.json") + " --gltf " + q(dir / "scene.glb") +
                     " --out " + q(dir / "x.glb"));
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_NE(r.err.find("does not match nodes[5] 'Crate'"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir / "x.glb"));
}

// --scene picks another scene of the file; the default is `scene`.
TEST(GltfImport, SceneOptionPicksTheScene) {
    KnownGltfScene k = courtyardScene();
    json& doc = k.scene.doc();
    // Scene 1: a new root with two cubes and no light (--sun gives one).
    const size_t root = doc["nodes"].size();
    doc["nodes"].push_back({{"name", "Second"}, {"children", json::array({root + 1, root + 2})}});
    doc["nodes"].push_back({{"name", "A"}, {"mesh", 0}, {"translation", {0.0, 0.55, 0.0}}});
    doc["nodes"].push_back({{"name", "B"}, {"mesh", 0}, {"translation", {3.0, 0.55, 0.0}}});
    doc["scenes"].push_back({{"nodes", json::array({root})}});
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.glb", k.scene.glb());
    CliRun r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "one") + " --scene 1 --sun 0,45");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("2 models"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("1 light (0 from the scene, 1 from --sun)"), std::string::npos) << r.out;
    r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "zero"));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("11 models"), std::string::npos) << r.out;
    r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "two") + " --scene 2");
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_NE(r.err.find("scenes[2] does not exist (2 defined)"), std::string::npos) << r.err;
}

// gltfpack -c: quantized positions (with the dequantization in the node transforms) and
// meshopt-compressed buffers. -kn keeps the named nodes, -km the materials, -ke extras.
TEST(GltfImport, GltfpackCompressedScenesGiveTheSameMasks) {
    if (std::system("command -v gltfpack > /dev/null 2>&1") != 0) GTEST_SKIP() << "gltfpack is not installed (scripts/install-deps.sh installs it)";
    for (bool moved : {false, true}) {
        const KnownGltfScene k = courtyardScene(moved);
        const fs::path dir = freshTestDir(moved ? "-moved" : "");
        writeText(dir / "scene.glb", k.scene.glb());
        const std::string cmd = "gltfpack -i " + q(dir / "scene.glb") + " -o " + q(dir / "packed.glb") + " -c -kn -km -ke > " +
                                q(dir / "gltfpack.txt") + " 2>&1";
        ASSERT_EQ(std::system(cmd.c_str()), 0) << readText(dir / "gltfpack.txt");
        const json packed = readGltf(dir / "packed.glb").doc;
        ASSERT_TRUE(packed.contains("extensionsUsed"));
        EXPECT_NE(packed["extensionsUsed"].dump().find("EXT_meshopt_compression"), std::string::npos) << packed["extensionsUsed"];
        const json exported = importBakeExport(dir, dir / "packed.glb");
        expectKnownMasks(k, exported, true);
    }
}

struct BadScene {
    std::string name, expect;
    std::function<void(GltfSceneBuilder&)> edit;
    std::string args = "";  // extra import options
};

TEST(GltfImport, BadScenesAreRefusedWithTheirJsonPathAndNothingIsWritten) {
    const std::vector<BadScene> cases = {
        {"cycle", "is its own ancestor", [](GltfSceneBuilder& b) { b.doc()["nodes"][1]["children"] = json::array({0}); }},
        {"no scene", "defines no scene", [](GltfSceneBuilder& b) { b.doc().erase("scenes"); b.doc().erase("scene"); }},
        {"missing default scene", "scenes[4] does not exist", [](GltfSceneBuilder& b) { b.doc()["scene"] = 4; }},
        {"singular", "nodes[5]: the composed node transform is singular",
         [](GltfSceneBuilder& b) { b.doc()["nodes"][5]["scale"] = {1.0, 0.0, 1.0}; }},
        {"non-finite", "nodes[5].translation", [](GltfSceneBuilder& b) { b.doc()["nodes"][5]["translation"] = {1.0, std::numeric_limits<double>::infinity(), 1.0}; }},
        {"unknown light type", "extensions.KHR_lights_punctual.lights[1].type: unknown light type 'area'",
         [](GltfSceneBuilder& b) { b.doc()["extensions"]["KHR_lights_punctual"]["lights"][1]["type"] = "area"; }},
        {"no lights", "--sun", [](GltfSceneBuilder& b) {
             for (json& n : b.doc()["nodes"]) n.erase("extensions");
         }},
        {"33 lights", "at most 32 lights", [](GltfSceneBuilder& b) {
             for (int i = 0; i < 30; ++i) b.setLight(b.node("extra", -1), {{"type", "directional"}});
         }},
        {"bad extras", "nodes[2].extras.shadowcull_bias", [](GltfSceneBuilder& b) { b.setExtras(2, {{"shadowcull_bias", "a lot"}}); }},
        // Issue 35: what import would have read as something else, or doubled, or taken
        // only to fail at export after the bake.
        {"unknown required extension", "extensionsRequired[0]: 'KHR_frobnicate' is required",
         [](GltfSceneBuilder& b) { b.doc()["extensionsRequired"] = {"KHR_frobnicate"}; }},
        {"matrix with a projective last row", "nodes[5].matrix: elements 3, 7, 11 and 15 (the last row) are 0 0 0.25 1",
         [](GltfSceneBuilder& b) {
             b.doc()["nodes"][5].erase("translation");
             b.doc()["nodes"][5]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.25, 0, 0.55, 0, 1};
         }},
        {"matrix and TRS", "nodes[5]: both matrix and translation",
         [](GltfSceneBuilder& b) { b.doc()["nodes"][5]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; }},
        {"root listed twice", "scenes[0].nodes: nodes[0] is listed twice",
         [](GltfSceneBuilder& b) { b.doc()["scenes"][0]["nodes"] = {0, 0}; }},
        {"scale 1e300", "nodes[5]: the composed node transform scales by 1e+300, beyond the accepted 10000",
         [](GltfSceneBuilder& b) { b.doc()["nodes"][5]["scale"] = {1e300, 1e300, 1e300}; }},
        {"mesh node extras not an object", "nodes[5].extras: an object expected (export writes the masks into it), got \"crate\"",
         [](GltfSceneBuilder& b) { b.setExtras(5, "crate"); }},
        {"root extras not an object", "extras: an object expected (export writes the lights into it), got [1]",
         [](GltfSceneBuilder& b) { b.doc()["extras"] = {1}; }},
    };
    for (const BadScene& c : cases) {
        SCOPED_TRACE(c.name);
        KnownGltfScene k = courtyardScene();
        c.edit(k.scene);
        const fs::path dir = freshTestDir("-" + std::to_string(&c - cases.data()));
        writeText(dir / "scene.gltf", k.scene.gltf());
        CliRun r = cli(dir, "import " + q(dir / "scene.gltf") + " " + q(dir / "space") + " " + c.args);
        EXPECT_EQ(r.code, 3) << r.err;
        EXPECT_NE(r.err.find(c.expect), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("scene.gltf"), std::string::npos) << r.err;
        EXPECT_FALSE(fs::exists(dir / "space"));
        for (const auto& e : fs::directory_iterator(dir)) EXPECT_EQ(e.path().filename().string().find("space.import"), std::string::npos);
    }
}

TEST(GltfImport, SunOptionAndDerivedRangesAreStated) {
    KnownGltfScene k = courtyardScene();
    k.scene.doc()["extensions"]["KHR_lights_punctual"]["lights"][1].erase("range");  // the lamp: 50 cd
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.glb", k.scene.glb());
    CliRun r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "space") + " --sun 90,30");
    ASSERT_EQ(r.code, 0) << r.err;
    // sqrt(50 cd / 0.01 lux) = 70.7 m, with a warning naming the node.
    EXPECT_NE(r.err.find("nodes[2]: light 'lamp' has no range: using 70.7107 m"), std::string::npos) << r.err;
    const std::string space = readText(dir / "space" / "space.xml");
    EXPECT_NE(space.find("<range>70.71067811865476</range>"), std::string::npos) << space;
    // --sun comes after the scene's lights: from the east (+X), 30 degrees up.
    EXPECT_NE(space.find("<name>sun</name>\n        <type>directional</type>\n        <direction>-0.8660254037844387 -0.49999999999999994"),
              std::string::npos)
        << space;
    EXPECT_NE(r.out.find("4 lights (3 from the scene, 1 from --sun)"), std::string::npos) << r.out;
}

TEST(GltfImport, OutputMustBeNewOrEmpty) {
    const fs::path dir = freshTestDir();
    writeText(dir / "scene.glb", courtyardScene().scene.glb());
    writeText(dir / "space" / "notes.txt", "mine");
    CliRun r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "space"));
    EXPECT_EQ(r.code, 4) << r.err;
    EXPECT_NE(r.err.find("not empty"), std::string::npos) << r.err;
    EXPECT_EQ(readText(dir / "space" / "notes.txt"), "mine");
    fs::remove(dir / "space" / "notes.txt");
    r = cli(dir, "import " + q(dir / "scene.glb") + " " + q(dir / "space"));
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "space" / "space.xml"));
}

TEST(GltfImport, NodeUuidsMapBack) {
    EXPECT_EQ(gltf::nodeFromUuid(gltf::nodeUuid(12, "Rock.003")), std::optional<size_t>(12));
    EXPECT_EQ(gltf::nodeFromUuid(gltf::nodeUuid(0xABCDEF, "")), std::optional<size_t>(0xABCDEF));
    EXPECT_FALSE(gltf::nodeFromUuid("6055E290-4CC63BB3-1E14A3AE-0DFBE9A0"));
    EXPECT_FALSE(gltf::nodeFromUuid("474C5446-0000000G-00000000-00000000"));
}

}  // namespace

// `shadowcull export`'s root extras.shadowcull.lights: each light's entry carries the
// parameters the masks were baked for (bias, slopeBias, filterRadius, normalBias, range and
// coneAngle where they apply, and the direction of a light without a node), so that an
// engine (examples/threejs) draws its shadows with them; a space whose lights changed
// since the bake is refused rather than exported with parameters the masks do not hold for.
namespace {

// The courtyard (sun, lamp, torch on nodes) with a normal bias on the lamp's node,
// imported with shared settings and a --sun after the scene's lights, then baked.
struct Baked {
    fs::path dir, scene, space, results;
};

Baked importAndBake() {
    Baked b;
    b.dir = freshTestDir();
    KnownGltfScene k = courtyardScene();
    for (json& node : k.scene.doc()["nodes"])
        if (node.value("name", "") == "Lamp") node["extras"]["shadowcull_normal_bias"] = 0.04;
    b.scene = b.dir / "scene.glb", b.space = b.dir / "space", b.results = b.dir / "results.json";
    writeText(b.scene, k.scene.glb());
    CliRun r = cli(b.dir, "import " + q(b.scene) + " " + q(b.space) +
                           " --sun 90,30 --bias 0.05 --slope-bias 0.01 --filter-radius 0.02");
    EXPECT_EQ(r.code, 0) << r.err;
    r = cli(b.dir, "bake " + q(b.space) + " --quiet --results " + q(b.results));
    EXPECT_EQ(r.code, 0) << r.err;
    return b;
}

}  // namespace

TEST(GltfExportLights, EachLightCarriesTheParametersItWasBakedWith) {
    const Baked b = importAndBake();
    const fs::path out = b.dir / "exported.glb";
    const CliRun r = cli(b.dir, "export " + q(b.space) + " " + q(b.results) + " --gltf " + q(b.scene) + " --out " + q(out));
    ASSERT_EQ(r.code, 0) << r.err;
    const json lights = readGltf(out).doc["extras"]["shadowcull"]["lights"];
    ASSERT_EQ(lights.size(), 4u) << lights.dump();

    // Bit 0: the sun on node 1: the shared settings; placed by its node, so no direction.
    const json& sun = lights[0];
    EXPECT_EQ(sun["node"], 1);
    EXPECT_EQ(sun["type"], "directional");
    EXPECT_EQ(sun["bias"], 0.05);
    EXPECT_EQ(sun["slopeBias"], 0.01);
    EXPECT_EQ(sun["filterRadius"], 0.02);
    EXPECT_EQ(sun["normalBias"], 0.0);
    for (const char* absent : {"range", "coneAngle", "direction"}) EXPECT_FALSE(sun.contains(absent)) << absent;

    // Bit 1: the lamp (point): its node's own bias and normal bias, and its range.
    const json& lamp = lights[1];
    EXPECT_EQ(lamp["node"], 2);
    EXPECT_EQ(lamp["type"], "point");
    EXPECT_EQ(lamp["bias"], 0.02);
    EXPECT_EQ(lamp["normalBias"], 0.04);
    EXPECT_EQ(lamp["range"], 6.0);
    EXPECT_FALSE(lamp.contains("coneAngle"));
    EXPECT_FALSE(lamp.contains("direction"));

    // Bit 2: the torch (spot): range and cone half-angle in degrees (outerConeAngle 0.5 rad).
    const json& torch = lights[2];
    EXPECT_EQ(torch["type"], "spot");
    EXPECT_EQ(torch["range"], 20.0);
    EXPECT_NEAR(torch["coneAngle"].get<double>(), 0.5 * 180.0 / M_PI, 1e-9);

    // Bit 3: --sun 90,30 has no node: the way its light travels, from +X, 30 degrees up.
    const json& extra = lights[3];
    EXPECT_TRUE(extra["node"].is_null());
    EXPECT_EQ(extra["name"], "sun");
    ASSERT_TRUE(extra["direction"].is_array());
    const double pi = M_PI;
    EXPECT_NEAR(extra["direction"][0].get<double>(), -std::cos(pi / 6), 1e-12);
    EXPECT_NEAR(extra["direction"][1].get<double>(), -std::sin(pi / 6), 1e-12);
    EXPECT_NEAR(extra["direction"][2].get<double>(), 0.0, 1e-12);
    EXPECT_EQ(extra["bias"], 0.05);
}

TEST(GltfExportLights, ASpaceWhoseLightsChangedSinceTheBakeIsRefused) {
    const Baked b = importAndBake();
    const fs::path xml = b.space / "space.xml";
    std::string text = readText(xml);
    const std::string was = "<bias>0.02</bias>";  // the lamp's, from its node's extras
    ASSERT_NE(text.find(was), std::string::npos) << text;
    text.replace(text.find(was), was.size(), "<bias>0.5</bias>");
    writeText(xml, text);
    const fs::path out = b.dir / "exported.glb";
    const CliRun r = cli(b.dir, "export " + q(b.space) + " " + q(b.results) + " --gltf " + q(b.scene) + " --out " + q(out));
    EXPECT_EQ(r.code, 3) << r.err;
    EXPECT_NE(r.err.find("light 2 'lamp' was baked with bias 0.02 but"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("bake again"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
}
