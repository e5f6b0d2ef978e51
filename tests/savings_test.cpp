// Issue 14: what a bake removes from each light's shadow pass, split into (a) what the
// engine's own culling removes and (b) what only the bake removes, in casters and placed
// triangles: the bake summary, the results JSON and `shadowcull report` (text, HTML, errors).

#include <regex>
#include <sstream>

#include <gtest/gtest.h>

#include "cli/pipeline.h"
#include "cli/report.h"
#include "cli/savings.h"
#include "cli/savings_report.h"
#include "io/results_file.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

using results::LightSavingsRecord;
using results::WorkRecord;

// Flat terrain (2 triangles) over chunk (0, 0), an empty chunk (1, 0). Lights: 1 "sun"
// (0.05, -1, 0.02), 2 "lamp" point at (20, 5, 20) range 10, 3 "torch" spot at (20, 8, 20)
// straight down, range 20, cone 30 degrees (the lights of rangeAndCone()). Closed 1 m cubes
// (12 triangles):
//   A (22, 0, 20): its shadow lands on the terrain for every light (rangeAndCone).
//   B (80, 0, 80): sun kept; beyond the lamp's and the torch's range: (a).
//   C (26, 0, 20): sun and lamp kept; outside the torch's cone: (a).
//   G (60, 0, 60) with castsShadow false: (a) for every light.
// F, two groups floating 20 m up over the terrain-less chunk (1, 0): group 0 a cube at
// (150, 20, 50) (12 triangles), group 1 an upward quad at (160..161, 20, 50..51) (2
// triangles). Under the sun nothing lies below them: (b); beyond both local lights: (a).
// The terrain: flat, one-sided, nothing under it: its shadow falls on nothing for every
// light: (b) (the lamp and the torch reach it).
// The lights, terrain and chunks of savingsScene(), and its cube mesh.
void addGround(SpaceBuilder& b) {
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addLight(LightSpec::directional("sun", {0.05, -1.0, 0.02}));
    b.addLight(LightSpec::point("lamp", {20, 5, 20}, 10));
    b.addLight(LightSpec::spot("torch", {20, 8, 20}, {0, -1, 0}, 20, 30));
    b.addFlatTerrain(0, 0, 0.0);
    b.addChunk(1, 0);
}

SpaceBuilder savingsScene() {
    SpaceBuilder b;
    addGround(b);
    MeshSpec two = MeshSpec::box({0, 0, 0}, {1, 1, 1}, GroupSpec::named("stone"));
    two.append(MeshSpec::quad({10, 0, 0}, {10, 0, 1}, {11, 0, 1}, {11, 0, 0}, GroupSpec::named("leaf")));
    b.addMesh("two", two);
    b.addModel("cube", Affine::translation({22, 0, 20}), fixedUuid(1));
    b.addModel("cube", Affine::translation({80, 0, 80}), fixedUuid(2));
    b.addModel("cube", Affine::translation({26, 0, 20}), fixedUuid(3));
    b.addModel("cube", Affine::translation({60, 0, 60}), fixedUuid(4), false);
    b.addModel("two", Affine::translation({150, 20, 50}), fixedUuid(5));
    return b;
}

struct Want {
    WorkRecord all, engine, bake, undecided;
};

void expectWork(const WorkRecord& got, const WorkRecord& want, const std::string& what) {
    EXPECT_EQ(got.casters, want.casters) << what << ": casters";
    EXPECT_EQ(got.triangles, want.triangles) << what << ": triangles";
}

void expectLight(const LightSavingsRecord& s, const Want& e, const std::string& what) {
    expectWork(s.all, e.all, what + " all");
    expectWork(s.engineCulls, e.engine, what + " (a)");
    expectWork(s.bakeCulls, e.bake, what + " (b)");
    expectWork(s.undecided, e.undecided, what + " undecided");
}

// Every caster: 4 cubes (48), F's two groups (14), the terrain (2).
const WorkRecord kAll{7, 64};

cli::BakeResult bake(const fs::path& space, bool allStages, const fs::path& resultsPath = {}) {
    cli::BakeOptions o;
    o.spaceDir = space.string();
    o.write = false;
    o.useGeometry = o.useGpu = allStages;
    o.resultsPath = resultsPath.string();
    Expected<cli::BakeResult> r = cli::runBake(o);
    if (!r) ADD_FAILURE() << r.error().what();
    return r ? std::move(*r) : cli::BakeResult{};
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

// The stages decide what the scene's comment says; the tally adds it up exactly.
TEST(Savings, KnownSceneSplitsEngineAndBakeCulls) {
    const fs::path dir = freshTestDir();
    savingsScene().write((dir / "space").string());
    const cli::BakeResult r = bake(dir / "space", true, dir / "results.json");
    ASSERT_EQ(r.chunks.size(), 2u);
    const savings::Tally t = cli::tallyBake(r);
    ASSERT_EQ(t.world().size(), 3u);
    // sun: (a) G; (b) F's two groups and the terrain; A, B, C kept.
    expectLight(t.world()[0], {kAll, {1, 12}, {3, 16}, {0, 0}}, "sun");
    // lamp: (a) B, G, F0, F1; (b) the terrain; A, C kept.
    expectLight(t.world()[1], {kAll, {4, 38}, {1, 2}, {0, 0}}, "lamp");
    // torch: (a) B, C, G, F0, F1; (b) the terrain; A kept.
    expectLight(t.world()[2], {kAll, {5, 50}, {1, 2}, {0, 0}}, "torch");
    // (a) by the reach stage's two reasons; (b) by the stages after it.
    EXPECT_EQ(savings::afterEngine(t.world()[2]).triangles, 14u);
    EXPECT_EQ(savings::afterBake(t.world()[0]).triangles, 36u);
    EXPECT_EQ(t.world()[0].bakeCullsBy.count("reach"), 0u);

    // Per chunk: chunk (0, 0) holds A, B, C, G and the terrain; (1, 0) holds F.
    ASSERT_EQ(t.chunks().size(), 2u);
    expectLight(t.chunks()[0][0], {{5, 50}, {1, 12}, {1, 2}, {0, 0}}, "sun 00000000o");
    expectLight(t.chunks()[1][0], {{2, 14}, {0, 0}, {2, 14}, {0, 0}}, "sun 00010000o");
    expectLight(t.chunks()[1][1], {{2, 14}, {2, 14}, {0, 0}, {0, 0}}, "lamp 00010000o");

    // The results JSON carries the groups' triangles and the same figures, and reads back.
    Expected<results::ResultsFile> f = results::readResultsFile((dir / "results.json").string());
    ASSERT_TRUE(f) << f.error().what();
    ASSERT_EQ(f->summary.savings.size(), 3u);
    expectLight(f->summary.savings[1], {kAll, {4, 38}, {1, 2}, {0, 0}}, "lamp in the JSON");
    ASSERT_EQ(f->chunks.size(), 2u);
    ASSERT_EQ(f->chunks[1].savings.size(), 3u);
    expectLight(f->chunks[1].savings[0], {{2, 14}, {0, 0}, {2, 14}, {0, 0}}, "sun 00010000o in the JSON");
    ASSERT_EQ(f->chunks[1].objects.at(0).groups.size(), 2u);
    EXPECT_EQ(f->chunks[1].objects[0].groups[0].triangles, std::optional<uint64_t>(12));
    EXPECT_EQ(f->chunks[1].objects[0].groups[1].triangles, std::optional<uint64_t>(2));
    // Tallied from the file alone, the figures are the bake's.
    const savings::Tally fromFile = savings::tallyResults(*f);
    for (size_t l = 0; l < 3; ++l)
        expectLight(fromFile.world()[l],
                    {t.world()[l].all, t.world()[l].engineCulls, t.world()[l].bakeCulls, t.world()[l].undecided},
                    "light " + std::to_string(l + 1) + " from the file");
    // Written again, the model gives the same bytes (one reader and writer).
    EXPECT_EQ(results::writeResults(*f), readText(dir / "results.json"));
}

// With witness rays alone nothing proves the floating model and the terrain 0: what was
// (b) becomes undecided (the savings left on the table), and (a) does not change.
TEST(Savings, UndecidedBitsAreCountedApart) {
    const fs::path dir = freshTestDir();
    savingsScene().write((dir / "space").string());
    const cli::BakeResult r = bake(dir / "space", false);
    const savings::Tally t = cli::tallyBake(r);
    ASSERT_EQ(t.world().size(), 3u);
    expectLight(t.world()[0], {kAll, {1, 12}, {0, 0}, {3, 16}}, "sun");
    expectLight(t.world()[1], {kAll, {4, 38}, {0, 0}, {1, 2}}, "lamp");
    expectLight(t.world()[2], {kAll, {5, 50}, {0, 0}, {1, 2}}, "torch");
}

TEST(Savings, ClassifyNamesTheEnginesOwnCulling) {
    using savings::Why;
    EXPECT_EQ(savings::classify("culled", "reach", "the group lies outside the light's cone"), Why::EngineCulls);
    EXPECT_EQ(savings::classify("culled", "input", "castsShadow is false"), Why::EngineCulls);
    EXPECT_EQ(savings::classify("culled", "input", "the group has no triangle with three distinct vertices"), Why::BakeCulls);
    EXPECT_EQ(savings::classify("culled", "geometry", "no receiver in the shadow volume"), Why::BakeCulls);
    EXPECT_EQ(savings::classify("kept", "raycast", ""), Why::ProvedKept);
    EXPECT_EQ(savings::classify("undecided", "", ""), Why::Undecided);
}

// The summary's lines, and `shadowcull report` on the same bake: same figures, the
// biggest saving with its proof, and the HTML page with a row and a map per light.
TEST(Savings, SummaryReportAndHtml) {
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space";
    savingsScene().write(space.string());
    const cli::BakeResult r = bake(space, true, dir / "results.json");
    const std::string summary = cli::formatSummary(r, false);
    EXPECT_TRUE(has(summary, "shadow pass per light, casters | triangles: (a) the engine's own culling")) << summary;
    // light, all, (a), left after (a), (b), share of what (a) leaves, left after (b), undecided
    EXPECT_TRUE(std::regex_search(summary, std::regex(R"(\n  1 'sun'\s+7 \|\s+64\s+1 \|\s+12\s+6 \|\s+52\s+3 \|\s+16\s+30\.8 %\s+3 \|\s+36\s+0 \|\s+0\n)")))
        << summary;
    EXPECT_TRUE(std::regex_search(summary, std::regex(R"(\n  3 'torch'\s+7 \|\s+64\s+5 \|\s+50\s+2 \|\s+14\s+1 \|\s+2\s+14\.3 %\s+1 \|\s+12\s+0 \|\s+0\n)")))
        << summary;

    std::ostringstream out, err;
    cli::ReportOptions o;
    o.spaceDir = space.string();
    o.resultsPath = (dir / "results.json").string();
    o.htmlPath = (dir / "report.html").string();
    ASSERT_EQ(cli::runReport(o, out, err), cli::kExitOk) << err.str();
    const std::string text = out.str();
    EXPECT_TRUE(has(text, "2 chunks, 3 lights, 7 caster groups, 64 placed triangles")) << text;
    EXPECT_TRUE(std::regex_search(text, std::regex(R"(\n  2 'lamp'\s+7 \|\s+64\s+4 \|\s+38\s+3 \|\s+26\s+1 \|\s+2\s+7\.7 %\s+2 \|\s+24\s+0 \|\s+0\n)")))
        << text;
    // Per chunk, the lights added up: chunk (1, 0) has F's 14 triangles per light, (a) twice.
    EXPECT_TRUE(std::regex_search(text, std::regex(R"(\n  00010000o\.chunk\s+6 \|\s+42\s+4 \|\s+28\s+2 \|\s+14\s+2 \|\s+14\s+100\.0 %\s+0 \|\s+0\s+0 \|\s+0\n)")))
        << text;
    // Biggest: F under the sun, 14 triangles in two groups, each with its proof.
    EXPECT_TRUE(has(text, "  14 triangles (2 groups): 00010000o.chunk model #0 " + fixedUuid(5) +
                              ", light 1 'sun' (directional)\n    group 0 (12 triangles): culled, stage ")) << text;
    EXPECT_TRUE(has(text, "; proof: ")) << text;

    const std::string html = readText(dir / "report.html");
    ASSERT_FALSE(html.empty());
    EXPECT_EQ(html.rfind("<!DOCTYPE html>", 0), 0u);
    EXPECT_TRUE(has(html, "</html>\n"));
    EXPECT_EQ(std::count(html.begin(), html.end(), '<') - std::count(html.begin(), html.end(), '>'), 0) << "unbalanced tags";
    // Well-formed enough: every opened table, svg, tr and figure is closed.
    for (const char* tag : {"table", "svg", "tr", "figure", "details", "title"}) {
        const std::string open = std::string("<") + tag, close = std::string("</") + tag + ">";
        size_t opened = 0, closed = 0;
        for (size_t k = html.find(open); k != std::string::npos; k = html.find(open, k + 1))
            if (k + open.size() < html.size() && (html[k + open.size()] == '>' || html[k + open.size()] == ' ')) ++opened;
        for (size_t k = html.find(close); k != std::string::npos; k = html.find(close, k + 1)) ++closed;
        EXPECT_EQ(opened, closed) << tag;
    }
    for (const char* light : {"light 1 &#39;sun&#39; (directional)", "light 2 &#39;lamp&#39; (point)", "light 3 &#39;torch&#39; (spot)"}) {
        EXPECT_TRUE(has(html, std::string("<tr class=\"light\"><td>") + light + "</td>")) << light;
        EXPECT_TRUE(has(html, std::string("<figcaption><b>") + light + "</b>")) << light;
    }
    EXPECT_EQ(std::count(html.begin(), html.end(), '\n') > 10, true);
    // Two chunks per map, each named on hover.
    size_t chunkRects = 0;
    for (size_t k = html.find("<rect class=\"chunk\""); k != std::string::npos; k = html.find("<rect class=\"chunk\"", k + 1)) ++chunkRects;
    EXPECT_EQ(chunkRects, 6u);
    EXPECT_TRUE(has(html, "<title>00010000o.chunk (x 1, z 0), light 1 'sun'")) << "hover names the chunk";
    EXPECT_TRUE(has(html, "<tr class=\"big\"><td class=\"n\">1</td><td class=\"n\">14</td>"));
    EXPECT_FALSE(has(html, "http://") && has(html, "<link")) << "no external resources";
    EXPECT_FALSE(has(html, "<script"));
}

// Errors, through the executable: exit codes as the other commands.
TEST(Savings, ReportErrors) {
    const fs::path dir = freshTestDir();
    const fs::path space = dir / "space", other = dir / "other";
    savingsScene().write(space.string());
    bake(space, false, dir / "results.json");
    const fs::path out = dir / "out.txt", err = dir / "err.txt";
    const std::string s = "'" + space.string() + "'", results = "'" + (dir / "results.json").string() + "'";

    // A results file that does not exist, or a space that does not: usage errors.
    EXPECT_EQ(runCli("report " + s + " '" + (dir / "missing.json").string() + "'", out, err), 2) << readText(err);
    EXPECT_EQ(runCli("report '" + (dir / "nowhere").string() + "' " + results, out, err), 2) << readText(err);
    // Not a results file.
    writeText(dir / "not.json", "{\"format\": \"something else\"}\n");
    EXPECT_EQ(runCli("report " + s + " '" + (dir / "not.json").string() + "'", out, err), 3);
    EXPECT_TRUE(has(readText(err), "not a shadowcull results file")) << readText(err);

    // Results of another space: the same lights, other objects.
    SpaceBuilder b;
    addGround(b);
    b.addModel("cube", Affine::translation({22, 0, 20}), fixedUuid(9));
    b.write(other.string());
    EXPECT_EQ(runCli("report '" + other.string() + "' " + results, out, err), 3);
    EXPECT_TRUE(has(readText(err), "results of another space")) << readText(err);
    // Of a space with other lights.
    EXPECT_EQ(runCli("report '" + fs::path(SHADOWCULL_SOURCE_DIR "/data/sample").string() + "' " + results, out, err), 3);
    EXPECT_TRUE(has(readText(err), "results of another space")) << readText(err);

    // --html naming the results file: refused before anything is written.
    const std::string before = readText(dir / "results.json");
    EXPECT_EQ(runCli("report " + s + " " + results + " --html " + results, out, err), 3);
    EXPECT_EQ(readText(dir / "results.json"), before);
    // A page that cannot be written: its directory does not exist.
    EXPECT_EQ(runCli("report " + s + " " + results + " --html '" + (dir / "no/such/dir/r.html").string() + "'", out, err), 4)
        << readText(err);
    // And the good case through the executable.
    EXPECT_EQ(runCli("report " + s + " " + results + " --html '" + (dir / "r.html").string() + "'", out, err), 0) << readText(err);
    EXPECT_TRUE(has(readText(out), "wrote ")) << readText(out);
    EXPECT_TRUE(fs::exists(dir / "r.html"));
}

// Issue 35: results baked with other light settings are not the space's figures: each
// setting the results record is compared (the lamp's range 10 m baked, 25 m now).
TEST(Savings, ReportRefusesResultsBakedWithOtherLightSettings) {
    struct Change {
        const char* name;
        std::string from, to, message;
    };
    const std::vector<Change> changes = {
        {"range", "<range> 10 </range>", "<range> 25 </range>", "light 2 'lamp': range 10 m in the results, 25 m in "},
        {"position", "<position> 20 5 20 </position>", "<position> 20 6 20 </position>",
         "light 2 'lamp': position (20, 5, 20) in the results, (20, 6, 20) in "},
        {"cone", "<coneAngle> 30 </coneAngle>", "<coneAngle> 35 </coneAngle>",
         "light 3 'torch': cone angle 30 deg in the results, 35 deg in "},
        {"bias", "<bias> 0 </bias>", "<bias> 0.5 </bias>", "light 1 'sun': bias 0 m in the results, 0.5 m in "},
        {"filter radius", "<filterRadius> 0 </filterRadius>", "<filterRadius> 0.3 </filterRadius>",
         "light 1 'sun': filter radius 0 m in the results, 0.3 m in "},
        {"normal bias", "<filterRadius> 0 </filterRadius>", "<filterRadius> 0 </filterRadius> <normalBias> 0.1 </normalBias>",
         "light 1 'sun': normal bias 0 m in the results, 0.1 m in "},
    };
    const fs::path dir = freshTestDir();
    savingsScene().write((dir / "space").string());
    bake(dir / "space", false, dir / "results.json");
    const std::string space = readText(dir / "space" / "space.xml");
    cli::ReportOptions o;
    o.spaceDir = (dir / "space").string();
    o.resultsPath = (dir / "results.json").string();
    for (const Change& c : changes) {
        SCOPED_TRACE(c.name);
        std::string edited = space;
        ASSERT_NE(edited.find(c.from), std::string::npos) << edited;
        edited.replace(edited.find(c.from), c.from.size(), c.to);
        writeText(dir / "space" / "space.xml", edited);
        std::ostringstream out, err;
        EXPECT_EQ(cli::runReport(o, out, err), cli::kExitBadInput) << err.str();
        EXPECT_TRUE(has(err.str(), "results of another space, or of " + o.spaceDir + " before it changed")) << err.str();
        EXPECT_TRUE(has(err.str(), c.message)) << err.str();
        EXPECT_EQ(out.str(), "") << "nothing is reported";
    }
    // The space as baked reports.
    writeText(dir / "space" / "space.xml", space);
    std::ostringstream out, err;
    EXPECT_EQ(cli::runReport(o, out, err), cli::kExitOk) << err.str();
}

// Files written before the triangles were recorded still read, and report counts the
// triangles in the space.
TEST(Savings, OlderResultsWithoutTrianglesStillReport) {
    const fs::path dir = freshTestDir();
    savingsScene().write((dir / "space").string());
    bake(dir / "space", true, dir / "results.json");
    Expected<results::ResultsFile> f = results::readResultsFile((dir / "results.json").string());
    ASSERT_TRUE(f);
    f->summary.savings.clear();
    for (results::ChunkRecord& c : f->chunks) {
        c.savings.clear();
        for (results::ObjectRecord& o : c.objects)
            for (results::GroupRecord& g : o.groups) g.triangles.reset();
    }
    const std::string old = results::writeResults(*f);
    EXPECT_FALSE(has(old, "\"triangles\"")) << "the writer leaves out what the model lacks";
    EXPECT_FALSE(has(old, "\"savings\""));
    writeText(dir / "old.json", old);
    std::ostringstream out, err;
    cli::ReportOptions o;
    o.spaceDir = (dir / "space").string();
    o.resultsPath = (dir / "old.json").string();
    ASSERT_EQ(cli::runReport(o, out, err), cli::kExitOk) << err.str();
    EXPECT_TRUE(has(out.str(), "7 caster groups, 64 placed triangles")) << out.str();
    EXPECT_TRUE(std::regex_search(out.str(), std::regex(R"(\n  1 'sun'\s+7 \|\s+64\s+1 \|\s+12\s+6 \|\s+52\s+3 \|\s+16)"))) << out.str();
}
