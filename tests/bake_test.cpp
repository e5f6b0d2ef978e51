// End-to-end: known-answer scenes (every scene x the pipeline), metamorphic copies (moved
// 100 km, lifted 5 km, turned a quarter), the CLI's outputs and exit codes on bad input,
// byte preservation, and a bake killed mid-run.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>
#include <tinyxml2.h>

#include "cli/pipeline.h"
#include "cli/report.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/sample_space.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"
#include "util/float_mode.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

cli::BakeResult bakeDry(const fs::path& dir, bool useGeometry = true) {
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.write = false;
    opt.useGeometry = useGeometry;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

// Every (key, group, light) of a baked builder space -> "verdict/stage".
std::map<std::string, std::string> verdictMap(const SpaceBuilder& b, const cli::BakeResult& r, const WorldTransform& wt) {
    std::map<std::string, std::string> out;
    for (const auto& [key, loc] : b.locateObjects(wt)) {
        for (int g = 0;; ++g) {
            const Decision* d0 = findDecision(r, loc, g, 0);
            if (!d0) break;
            for (int l = 0; l < int(r.settings.lights.size()); ++l) {
                const Decision* d = findDecision(r, loc, g, l);
                out[key + " g" + std::to_string(g) + " l" + std::to_string(l + 1)] =
                    std::string(verdictName(d->verdict)) + "/" + std::string(d->stage);
            }
        }
    }
    return out;
}

const std::vector<NamedScene>& scenesWithSample() {
    static const std::vector<NamedScene> s = [] {
        std::vector<NamedScene> all = knownAnswerScenes();
        all.push_back({"sampleSpace", sampleSpace});
        return all;
    }();
    return s;
}

}  // namespace

// Every known answer of every scene: a true 1 is never written 0 and here is always proved
// by a witness; a true 0 never gets a witness (that would be a witness bug) and is either
// proved 0 or left undecided.
TEST(KnownAnswers, EverySceneAgreesWithItsAnswers) {
    for (const NamedScene& scene : scenesWithSample()) {
        SCOPED_TRACE(scene.name);
        SpaceBuilder b = scene.make();
        fs::path dir = freshTestDir(std::string("-") + scene.name);
        b.write((dir / "space").string());
        cli::BakeResult r = bakeDry(dir / "space");
        auto where = b.locateObjects();
        ASSERT_FALSE(b.expectations().empty());
        for (const KnownAnswer& a : b.expectations()) {
            SCOPED_TRACE(a.key + " group " + std::to_string(a.group) + ": " + a.why);
            ASSERT_TRUE(where.count(a.key));
            for (int l = 0; l < int(r.settings.lights.size()); ++l) {
                const Decision* d = findDecision(r, where.at(a.key), a.group, l);
                ASSERT_NE(d, nullptr);
                if (a.mask & (1u << l)) {
                    EXPECT_EQ(d->verdict, Verdict::Kept) << "light " << l + 1 << ": a true 1 must be proved by a witness";
                    EXPECT_TRUE(d->witness() != nullptr);
                } else {
                    EXPECT_NE(d->verdict, Verdict::Kept) << "light " << l + 1 << ": witness for a true 0: "
                                                         << (d->witness() ? d->witness()->receiver : "");
                }
            }
        }
    }
}

// Every known-answer scene through each stage alone (the others off): a stage that proves
// 0s never culls a true 1 (the geometry stage with the witness cross-check off, so that
// its own rules, "p not lit" among them, are what is tested), and the ray stage never finds
// a witness for a true 0. A surface that casts no shadow must hide nothing in any of them
// (the cube under a non-casting roof), and a normal bias must reach the wall's foot.
TEST(KnownAnswers, EachStageAloneNeverCullsATrueOne) {
    struct StageOnly {
        const char* name;
        bool raycast, geometry, gpu;
    };
    const StageOnly stages[] = {{"raycast", true, false, false}, {"geometry", false, true, false}, {"gpu", false, false, true}};
    for (const NamedScene& scene : knownAnswerScenes()) {
        SCOPED_TRACE(scene.name);
        SpaceBuilder b = scene.make();
        fs::path dir = freshTestDir(std::string("-") + scene.name);
        b.write((dir / "space").string());
        const auto where = b.locateObjects();
        for (const StageOnly& st : stages) {
            SCOPED_TRACE(st.name);
            cli::BakeOptions opt;
            opt.spaceDir = (dir / "space").string();
            opt.write = false;
            opt.useRaycast = st.raycast, opt.useGeometry = st.geometry, opt.useGpu = st.gpu;
            Expected<cli::BakeResult> r = cli::runBake(opt);
            ASSERT_TRUE(r) << r.error().what();
            for (const KnownAnswer& a : b.expectations())
                for (int l = 0; l < int(r->settings.lights.size()); ++l) {
                    const Decision* d = findDecision(*r, where.at(a.key), a.group, l);
                    ASSERT_NE(d, nullptr);
                    if (a.mask & (1u << l))
                        EXPECT_NE(d->verdict, Verdict::Culled) << a.key << " light " << l + 1 << " (" << a.why
                                                               << "): culled by " << d->stage << ": " << d->reason();
                    else
                        EXPECT_NE(d->verdict, Verdict::Kept) << a.key << " light " << l + 1 << " (" << a.why
                                                             << "): a witness for a true 0 on "
                                                             << (d->witness() ? d->witness()->receiver : "");
                }
        }
    }
}

// The engine's frame decides what a surface that casts no shadow does (semantics.md,
// condition 1), and what a normal bias reaches (condition 5): each answer proved, not left
// undecided, at the origin, 100 km away and turned.
TEST(KnownAnswers, NonCastersHideNothingAndNormalBiasReachesAsTheEngineDraws) {
    struct Case {
        const char* name;
        SpaceBuilder b;
        int object;  // fixedUuid(object)
        Verdict want;
        const char* stage;  // the stage that must decide it, or "" for any
    };
    const std::vector<Case> cases = {
        {"cube under a casting roof", hiddenUnderRoof(Roof::Opaque), 1, Verdict::Culled, ""},
        {"cube under a roof that casts no shadow", hiddenUnderRoof(Roof::CastsNoShadow), 1, Verdict::Kept, "raycast"},
        {"the roof that casts no shadow", hiddenUnderRoof(Roof::CastsNoShadow), 2, Verdict::Culled, "input"},
        {"cube over a floor that casts no shadow", cubeOverNonCastingFloor(), 1, Verdict::Kept, "raycast"},
        {"the floor that casts no shadow", cubeOverNonCastingFloor(), 2, Verdict::Culled, "input"},
        {"cube beside a wall, no normal bias", cubeBesideWall(0.0), 1, Verdict::Culled, "geometry"},
        {"cube beside a wall, normal bias 0.1 m", cubeBesideWall(0.1), 1, Verdict::Kept, "raycast"},
    };
    const std::vector<std::pair<const char*, WorldTransform>> moves = {
        {"at the origin", WorldTransform::identity()},
        {"moved 100 km", WorldTransform::moved({100000, 0, -100000})},
        {"turned a quarter", WorldTransform::turned(1)},
    };
    for (size_t c = 0; c < cases.size(); ++c) {
        SCOPED_TRACE(cases[c].name);
        for (size_t m = 0; m < moves.size(); ++m) {
            SCOPED_TRACE(moves[m].first);
            const fs::path dir = freshTestDir("-" + std::to_string(c) + "-" + std::to_string(m));
            cases[c].b.write((dir / "space").string(), moves[m].second);
            const cli::BakeResult r = bakeDry(dir / "space");
            const Decision* d = findDecision(r, cases[c].b.locateObjects(moves[m].second).at(fixedUuid(cases[c].object)), 0, 0);
            ASSERT_NE(d, nullptr);
            EXPECT_EQ(d->verdict, cases[c].want) << d->stage << ": " << d->reason();
            if (*cases[c].stage) {
                EXPECT_EQ(d->stage, std::string(cases[c].stage)) << d->reason();
            }
        }
    }
}

// Floating cubes with nothing below: witness rays alone cannot decide them (undecided,
// written 1); the shadow-volume stage proves them 0.
TEST(KnownAnswers, FloatingCubesAreUndecidedByRaysAndProvedByVolumes) {
    SpaceBuilder b = twoFloatingCubes();
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    cli::BakeResult rays = bakeDry(dir / "space", /*useGeometry=*/false);
    cli::BitCounts c = cli::countBits(rays);
    EXPECT_EQ(c.bits, 2u);
    EXPECT_EQ(c.undecided, 2u);
    EXPECT_EQ(c.culled, 0u);
    for (const ChunkVerdicts& cv : rays.chunks)
        for (size_t oi = 0; oi < cv.objects.size(); ++oi) EXPECT_EQ(cv.groupMask(oi, 0), 1u);
    cli::BakeResult all = bakeDry(dir / "space");
    c = cli::countBits(all);
    EXPECT_EQ(c.culled, 2u);
    EXPECT_EQ(c.culledBy["geometry"], 2u);
}

TEST(KnownAnswers, RangeAndConeExcludeWhatLiesOutside) {
    SpaceBuilder b = rangeAndCone();
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    cli::BakeResult r = bakeDry(dir / "space");
    auto where = b.locateObjects();
    // Every true 0 of a model in this scene is decided by the lights' reach alone.
    for (const KnownAnswer& a : b.expectations()) {
        if (a.key.rfind("terrain:", 0) == 0) continue;
        for (int l = 0; l < 2; ++l) {
            const Decision* d = findDecision(r, where.at(a.key), a.group, l);
            ASSERT_NE(d, nullptr);
            if (!(a.mask & (1u << l))) {
                EXPECT_EQ(d->verdict, Verdict::Culled) << a.key << " light " << l + 1;
                EXPECT_EQ(d->stage, "reach");
            }
        }
    }
}

// The seed's mask values: group masks 2 and 3, the model's number 3, as written by the CLI.
TEST(KnownAnswers, TwoLightsWriteTheSeedsMasks) {
    SpaceBuilder b = twoLightsMasks();
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    fs::path out = dir / "out";
    int rc = runCli("bake '" + (dir / "space").string() + "' --out '" + out.string() + "' --quiet", dir / "stdout", dir / "stderr");
    ASSERT_EQ(rc, 0) << readText(dir / "stderr");
    auto where = b.locateObjects();
    const KnownAnswer& first = b.expectations().front();
    tinyxml2::XMLDocument doc;
    ASSERT_EQ(doc.LoadFile((out / where.at(first.key).chunkFile).string().c_str()), tinyxml2::XML_SUCCESS);
    const tinyxml2::XMLElement* model = doc.RootElement()->FirstChildElement("model");
    ASSERT_NE(model, nullptr);
    const tinyxml2::XMLElement* shadow = model->FirstChildElement("shadow");
    ASSERT_NE(shadow, nullptr);
    EXPECT_EQ(std::atoi(shadow->GetText()), 3);
    const tinyxml2::XMLElement* g = shadow->FirstChildElement("RenderSet")->FirstChildElement("Geometry")->FirstChildElement("PrimitiveGroup");
    ASSERT_NE(g, nullptr);
    EXPECT_EQ(std::atoi(g->GetText()), 2);
    g = g->NextSiblingElement("PrimitiveGroup");
    ASSERT_NE(g, nullptr);
    EXPECT_EQ(std::atoi(g->GetText()), 3);
    EXPECT_EQ(g->NextSiblingElement("PrimitiveGroup"), nullptr);
}

// Metamorphic: the same space moved by 100 km, lifted by 5 km, and turned a quarter about Y
// gives the same verdict and deciding stage for every bit (so the same masks).
TEST(Metamorphic, MovedLiftedAndTurnedSpacesBakeIdentically) {
    const double S = 100.0;
    const std::vector<std::pair<const char*, WorldTransform>> moves = {
        {"moved 100 km", WorldTransform::moved({1000 * S, 0, -1000 * S})},
        {"lifted 5 km", WorldTransform::moved({0, 5000, 0})},
        {"turned a quarter", WorldTransform::turned(1)},
        {"turned three quarters and moved", WorldTransform{3, glm::dvec3(-1000 * S, 5000, 1000 * S)}},
    };
    for (const NamedScene& scene : knownAnswerScenes()) {
        SCOPED_TRACE(scene.name);
        SpaceBuilder b = scene.make();
        fs::path dir = freshTestDir(std::string("-") + scene.name);
        b.write((dir / "base").string());
        const auto base = verdictMap(b, bakeDry(dir / "base"), WorldTransform::identity());
        ASSERT_FALSE(base.empty());
        for (size_t k = 0; k < moves.size(); ++k) {
            SCOPED_TRACE(moves[k].first);
            fs::path moved = dir / ("moved" + std::to_string(k));
            b.write(moved.string(), moves[k].second);
            EXPECT_EQ(verdictMap(b, bakeDry(moved), moves[k].second), base);
        }
    }
}

// The sample space (hilly terrain, trees, houses, three lights): moved 100 km, lifted 5 km
// and turned half about Y (a half turn keeps the terrain's diagonal split; a quarter turn
// does not), the same verdicts.
TEST(Metamorphic, SampleSpaceMovedLiftedAndTurnedHalfBakesIdentically) {
    SpaceBuilder b = sampleSpace();
    fs::path dir = freshTestDir();
    b.write((dir / "base").string());
    const auto base = verdictMap(b, bakeDry(dir / "base"), WorldTransform::identity());
    ASSERT_GT(base.size(), 200u);
    const std::vector<WorldTransform> moves = {WorldTransform::moved({100000, 0, 100000}),
                                               WorldTransform::moved({-100000, 5000, 0}), WorldTransform::turned(2)};
    for (size_t k = 0; k < moves.size(); ++k) {
        SCOPED_TRACE(k);
        fs::path moved = dir / ("moved" + std::to_string(k));
        b.write(moved.string(), moves[k]);
        EXPECT_EQ(verdictMap(b, bakeDry(moved), moves[k]), base);
    }
}

TEST(Cli, ResultsJsonCarriesWitnessesAndProofs) {
    SpaceBuilder b = rangeAndCone();
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const auto before = chunkTexts(dir / "space");
    int rc = runCli("bake '" + (dir / "space").string() + "' --dry-run --results '" + (dir / "r.json").string() + "'",
                    dir / "stdout", dir / "stderr");
    ASSERT_EQ(rc, 0) << readText(dir / "stderr");
    EXPECT_EQ(chunkTexts(dir / "space"), before) << "--dry-run writes no chunk file";
    nlohmann::json j = nlohmann::json::parse(readText(dir / "r.json"));
    int witnesses = 0, proofs = 0;
    for (const auto& c : j["chunks"])
        for (const auto& o : c["objects"])
            for (const auto& g : o["groups"])
                for (const auto& bit : g["lights"]) {
                    if (bit["verdict"] == "kept") {
                        ++witnesses;
                        ASSERT_TRUE(bit.contains("witness"));
                        for (const char* k : {"origin", "direction", "p", "q"}) EXPECT_EQ(bit["witness"][k].size(), 3u);
                        EXPECT_FALSE(bit["witness"]["receiver"].get<std::string>().empty());
                        EXPECT_EQ(bit["bit"], 1);
                    } else if (bit["verdict"] == "culled") {
                        ++proofs;
                        EXPECT_EQ(bit["bit"], 0);
                        EXPECT_FALSE(bit["reason"].get<std::string>().empty());
                    }
                }
    EXPECT_GE(witnesses, 3);
    EXPECT_GE(proofs, 3);
    EXPECT_EQ(j["summary"]["bits"].get<int>(), j["summary"]["kept"].get<int>() + j["summary"]["culled"].get<int>());
    const std::string summary = readText(dir / "stdout");
    EXPECT_NE(summary.find("proved 1 by witness ray"), std::string::npos) << summary;
    EXPECT_NE(summary.find("undecided, kept as 1"), std::string::npos) << summary;
}

// A bake in place keeps every byte outside <shadow>, and baking again changes nothing.
TEST(Cli, InPlaceBakeKeepsEverythingElseAndIsIdempotent) {
    SpaceBuilder b = cubeOnTerrain();
    b.addChunkXml(0, 0, "  <!-- keep me -->\n  <lod distance=\"40\"><x a='1'/></lod>\n");
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const auto before = chunkTexts(dir / "space");
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --quiet", dir / "o", dir / "e"), 0) << readText(dir / "e");
    const auto after = chunkTexts(dir / "space");
    ASSERT_EQ(after.size(), before.size());
    for (const auto& [name, text] : after) {
        // Removing the <shadow> elements gives back the original.
        std::string stripped = text;
        for (size_t at; (at = stripped.find("<shadow>")) != std::string::npos;) {
            size_t end = stripped.find("</shadow>", at) + 9;
            size_t lineStart = stripped.rfind('\n', at);
            stripped.erase(lineStart, end - lineStart);
        }
        EXPECT_EQ(stripped, before.at(name));
        EXPECT_NE(text.find("<!-- keep me -->"), std::string::npos);
    }
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --quiet", dir / "o", dir / "e"), 0);
    EXPECT_EQ(chunkTexts(dir / "space"), after);
    for (const auto& e : fs::directory_iterator(dir / "space"))
        EXPECT_EQ(e.path().filename().string().find("shadowcull-tmp"), std::string::npos) << e.path();
}

struct BadInputCase {
    const char* name;
    std::function<void(const fs::path&)> spoil;  // spoils a written cubeOnTerrain space
    int exitCode;
    const char* message;  // must appear in stderr (file and line)
};

// Each bad input: the right exit code, a message naming the file (and line), and for a
// stopped bake no chunk file changed; for a skipped object its element is left as it was.
TEST(Cli, BadInputIsReportedWithFileLineAndExitCode) {
    const std::vector<BadInputCase> cases = {
        {"malformed chunk", [](const fs::path& d) { writeText(d / "00000000o.chunk", "<chunk>\n<model>\n</chunk>\n"); }, 3,
         "00000000o.chunk:2: not well-formed XML: the element <model> that starts here is closed by an end tag of another name"},
        {"unknown light type",
         [](const fs::path& d) { writeText(d / "space.xml", "<space>\n<light>\n<type> area </type>\n</light>\n</space>\n"); }, 3,
         "space.xml:3: unknown light type 'area'"},
        {"missing space.xml", [](const fs::path& d) { fs::remove(d / "space.xml"); }, 3, "space.xml: cannot open"},
        {"missing mesh",
         [](const fs::path& d) {
             for (const auto& e : fs::directory_iterator(d / "models")) fs::remove(e.path());
         },
         1, "00000000o.chunk:"},
        {"NaN vertex",
         [](const fs::path& d) {
             for (const auto& e : fs::directory_iterator(d / "models"))
                 if (e.path().extension() == ".obj") writeText(e.path(), "v 0 0 0\nv nan 1 0\nv 0 0 1\nf 1 2 3\n");
         },
         1, ".obj:2:"},
        {"bad chunk name", [](const fs::path& d) { writeText(d / "zzzz0000o.chunk", "<chunk/>"); }, 1,
         "zzzz0000o.chunk: not a chunk name"},
        {"8-bit heightmap",
         [](const fs::path& d) {
             for (const auto& e : fs::directory_iterator(d / "terrain"))
                 if (e.path().extension() == ".png") {
                     // A valid 2x2 8-bit grey PNG.
                     static const unsigned char png8[] = {
                         0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52,
                         0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x02, 0x08, 0x00, 0x00, 0x00, 0x00, 0x57, 0xdd, 0x52,
                         0xf8, 0x00, 0x00, 0x00, 0x0e, 0x49, 0x44, 0x41, 0x54, 0x78, 0x9c, 0x63, 0x60, 0x60, 0x60, 0x60,
                         0x00, 0x00, 0x00, 0x05, 0x00, 0x01, 0xa5, 0xf6, 0x45, 0x40, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45,
                         0x4e, 0x44, 0xae, 0x42, 0x60, 0x82};
                     writeText(e.path(), std::string(reinterpret_cast<const char*>(png8), sizeof png8));
                 }
         },
         1, "16-bit grey"},
    };
    for (const BadInputCase& c : cases) {
        SCOPED_TRACE(c.name);
        fs::path dir = freshTestDir(std::string("-") + std::to_string(&c - cases.data()));
        cubeOnTerrain().write((dir / "space").string());
        c.spoil(dir / "space");
        const auto before = chunkTexts(dir / "space");
        int rc = runCli("bake '" + (dir / "space").string() + "'", dir / "stdout", dir / "stderr");
        const std::string err = readText(dir / "stderr");
        EXPECT_EQ(rc, c.exitCode) << err;
        EXPECT_NE(err.find(c.message), std::string::npos) << err;
        const auto after = chunkTexts(dir / "space");
        if (c.exitCode == 3) {
            EXPECT_EQ(after, before) << "a stopped bake writes nothing";
        } else {
            // The skipped object's element is untouched; the baked ones have a <shadow>.
            ASSERT_EQ(after.size(), before.size());
            size_t shadows = 0;
            for (const auto& [name, text] : after)
                for (size_t at = 0; (at = text.find("<shadow>", at)) != std::string::npos; ++at) ++shadows;
            EXPECT_GE(shadows, 1u);
        }
    }
}

// A bake killed at any moment leaves every chunk file either as it was or complete.
TEST(KillTest, EveryChunkIsOriginalOrCompleteAfterSigkill) {
    SpaceBuilder b = manyChunks(12);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const auto original = chunkTexts(dir / "space");
    ASSERT_EQ(original.size(), 144u);

    // The complete result, and how long a bake takes here.
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --out '" + (dir / "ref").string() + "' --quiet", dir / "o", dir / "e"), 0)
        << readText(dir / "e");
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto complete = chunkTexts(dir / "ref");
    ASSERT_EQ(complete.size(), original.size());
    for (const auto& [name, text] : complete) ASSERT_NE(text, original.at(name)) << name << " gets a <shadow>";

    int sawMixed = 0, sawOriginal = 0, sawComplete = 0;
    for (int k = 0; k < 12; ++k) {
        fs::path work = dir / ("run" + std::to_string(k));
        fs::copy(dir / "space", work, fs::copy_options::recursive);
        pid_t pid = fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            execl(SHADOWCULL_BIN, SHADOWCULL_BIN, "bake", work.c_str(), "--quiet", static_cast<char*>(nullptr));
            _exit(127);
        }
        // Spread the kills over the whole run, the commit at its end included.
        std::this_thread::sleep_for(std::chrono::duration<double>(seconds * (0.1 + 0.09 * k)));
        kill(pid, SIGKILL);
        int status = 0;
        waitpid(pid, &status, 0);
        int originals = 0, completes = 0;
        for (const auto& [name, text] : chunkTexts(work)) {
            const bool isOriginal = text == original.at(name), isComplete = text == complete.at(name);
            EXPECT_TRUE(isOriginal || isComplete) << name << " is half written after a kill at step " << k;
            originals += isOriginal;
            completes += isComplete;
        }
        EXPECT_EQ(originals + completes, 144);
        if (originals && completes) ++sawMixed;
        else if (originals) ++sawOriginal;
        else ++sawComplete;
        // The next bake clears the killed one's temporaries and completes every file.
        ASSERT_EQ(runCli("bake '" + work.string() + "' --quiet", dir / "o", dir / "e"), 0) << readText(dir / "e");
        EXPECT_EQ(chunkTexts(work), complete);
        for (const auto& e : fs::directory_iterator(work))
            EXPECT_EQ(e.path().filename().string().find("shadowcull-tmp"), std::string::npos);
        fs::remove_all(work);
    }
    // Informational: where the kills landed.
    std::printf("kills: %d before commit, %d during commit, %d after\n", sawOriginal, sawMixed, sawComplete);
    EXPECT_GT(sawOriginal + sawMixed + sawComplete, 0);
}

// --chunk bakes only the named chunk (its neighbours loaded, not written).
TEST(Cli, ChunkOptionBakesOnlyTheNamedChunk) {
    SpaceBuilder b = manyChunks(3);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const auto before = chunkTexts(dir / "space");
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --chunk 00010001o --quiet", dir / "o", dir / "e"), 0)
        << readText(dir / "e");
    const auto after = chunkTexts(dir / "space");
    for (const auto& [name, text] : after) {
        if (name == "00010001o.chunk") EXPECT_NE(text, before.at(name));
        else EXPECT_EQ(text, before.at(name)) << name;
    }
    EXPECT_EQ(runCli("bake '" + (dir / "space").string() + "' --chunk 0001000 --quiet", dir / "o", dir / "e"), 3);
    EXPECT_NE(readText(dir / "e").find("not a chunk name"), std::string::npos);
    EXPECT_EQ(runCli("bake '" + (dir / "space").string() + "' --chunk 00200020o --quiet", dir / "o", dir / "e"), 3);
    EXPECT_NE(readText(dir / "e").find("no such chunk"), std::string::npos);
    EXPECT_EQ(runCli("bake '" + (dir / "space").string() + "' --frobnicate", dir / "o", dir / "e"), 2);
}

// Progress: in a log (stderr not a terminal) one line at the end at least, with the
// chunks --resume skipped; the ETA counts only the chunks that were baked.
TEST(Cli, ProgressInALogAndEtaFromBakedChunks) {
    cli::BakeProgress p{10, 100, 5};
    EXPECT_DOUBLE_EQ(p.etaSeconds(50.0), 900.0);  // 5 baked in 50 s: 10 s each, 90 to go
    p.resumed = 10;
    EXPECT_LT(p.etaSeconds(50.0), 0.0);  // nothing baked yet: unknown
    p = {100, 100, 40};
    EXPECT_DOUBLE_EQ(p.etaSeconds(60.0), 0.0);

    SpaceBuilder b = manyChunks(3);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    const std::string bake = "bake '" + (dir / "space").string() + "' --out '" + (dir / "out").string() + "' --resume";
    ASSERT_EQ(runCli(bake, dir / "o", dir / "e"), 0) << readText(dir / "e");
    EXPECT_NE(readText(dir / "e").find("shadowcull: 9/9 chunks, "), std::string::npos) << readText(dir / "e");
    // The first line as the scan begins (issue 35: a large world's log was silent for its
    // whole scan): the log says at once that the bake is under way.
    EXPECT_EQ(readText(dir / "e").rfind("shadowcull: scanning the space: 0/9 chunk files, ", 0), 0u) << readText(dir / "e");
    ASSERT_EQ(runCli(bake, dir / "o", dir / "e"), 0) << readText(dir / "e");
    EXPECT_NE(readText(dir / "e").find("shadowcull: 9/9 chunks (9 unchanged), "), std::string::npos) << readText(dir / "e");
    ASSERT_EQ(runCli(bake + " --quiet", dir / "o", dir / "e"), 0);
    EXPECT_EQ(readText(dir / "e"), "");
}

// The results do not depend on the number of threads (witness search per group is
// sequential; Embree's hits are ordered by distance, then object and triangle).
TEST(Cli, ResultsAreTheSameForAnyThreadCount) {
    SpaceBuilder b = manyChunks(3);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    for (int threads : {1, 2}) {
        const std::string json = (dir / ("r" + std::to_string(threads) + ".json")).string();
        ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --dry-run --quiet --threads " + std::to_string(threads) +
                             " --results '" + json + "'",
                         dir / "o", dir / "e"),
                  0)
            << readText(dir / "e");
    }
    const std::string one = readText(dir / "r1.json"), two = readText(dir / "r2.json");
    EXPECT_GT(one.size(), 1000u);
    EXPECT_EQ(one, two);
}

namespace {

// Moves the first model of a chunk file by 1 mm along x (its <row3>), as an edit would.
void nudgeFirstModel(const fs::path& chunk) {
    std::string text = readText(chunk);
    const size_t row3 = text.find("<row3>");
    ASSERT_NE(row3, std::string::npos);
    const size_t end = text.find("</row3>", row3);
    std::istringstream in(text.substr(row3 + 6, end - row3 - 6));
    double x, y, z;
    in >> x >> y >> z;
    text.replace(row3 + 6, end - row3 - 6, " " + std::to_string(x + 0.001) + " " + std::to_string(y) + " " + std::to_string(z) + " ");
    writeText(chunk, text);
}

cli::BakeResult bakeResume(const fs::path& dir) {
    cli::BakeOptions opt;
    opt.spaceDir = dir.string();
    opt.resume = true;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    EXPECT_TRUE(r) << (r ? "" : r.error().what());
    return r ? std::move(*r) : cli::BakeResult{};
}

}  // namespace

// --resume skips exactly the chunks whose window inputs and file bytes are unchanged.
TEST(Resume, SkipsUnchangedChunksAndRebakesWhatAnEditReaches) {
    SpaceBuilder b = manyChunks(4);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    cli::BakeResult first = bakeResume(dir / "space");
    EXPECT_EQ(first.chunksWritten, 16);
    EXPECT_EQ(first.chunksResumed, 0);
    ASSERT_TRUE(fs::exists(dir / "space" / ".shadowcull-bake-state.json"));
    const auto baked = chunkTexts(dir / "space");

    cli::BakeResult again = bakeResume(dir / "space");
    EXPECT_EQ(again.chunksResumed, 16);
    EXPECT_EQ(again.chunksWritten, 0);
    EXPECT_EQ(chunkTexts(dir / "space"), baked);

    // Move one model of chunk (1,1) by 1 mm: every chunk whose window holds (1,1) (the 3x3
    // block around it) is baked again; the other 7 are not.
    nudgeFirstModel(dir / "space" / "00010001o.chunk");
    cli::BakeResult edit = bakeResume(dir / "space");
    EXPECT_EQ(edit.chunksWritten, 9);
    EXPECT_EQ(edit.chunksResumed, 7);

    // A baked file changed by hand (a comment added) is baked again, alone.
    const fs::path touched = dir / "space" / "00030003o.chunk";
    writeText(touched, readText(touched) + "<!-- touched -->\n");
    cli::BakeResult touch = bakeResume(dir / "space");
    EXPECT_EQ(touch.chunksWritten, 1);
    EXPECT_EQ(touch.chunksResumed, 15);
}

// A chunk's resume record covers every chunk its shadows reach, however far: moving the
// ground three chunks away, where the tower's shadow lands, bakes the tower's chunk again;
// moving ground that no shadow of it reaches (chunk 4, below the shadow) does not.
TEST(Resume, AnEditWhereALongShadowLandsRebakesItsCaster) {
    auto rebaked = [](const cli::BakeResult& r) {
        std::set<std::string> out;
        for (const ChunkVerdicts& cv : r.chunks) out.insert(chunkFileName(cv.coord));
        return out;
    };
    SpaceBuilder b = longShadowOverChunks(LongShadow::LandsThreeChunksAway);
    b.addChunk(4, 0);
    b.addModel("ground", Affine::translation({400, 0, 0}), fixedUuid(14));
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    EXPECT_EQ(bakeResume(dir / "space").chunksWritten, 5);
    EXPECT_EQ(bakeResume(dir / "space").chunksResumed, 5);

    nudgeFirstModel(dir / "space" / "00030000o.chunk");
    const cli::BakeResult far = bakeResume(dir / "space");
    EXPECT_TRUE(rebaked(far).count("00000000o.chunk")) << "the tower's shadow lands on the edited ground";
    EXPECT_TRUE(rebaked(far).count("00030000o.chunk"));

    nudgeFirstModel(dir / "space" / "00040000o.chunk");
    const cli::BakeResult elsewhere = bakeResume(dir / "space");
    EXPECT_FALSE(rebaked(elsewhere).count("00000000o.chunk")) << "no shadow of chunk 0 reaches chunk 4";
    EXPECT_TRUE(rebaked(elsewhere).count("00040000o.chunk"));
}

// A --resume bake killed mid-run completes on the next --resume run, with the same files
// as an uninterrupted bake, and without baking again what was already committed.
TEST(Resume, AKilledBakeCompletesOnRerun) {
    SpaceBuilder b = manyChunks(10);
    fs::path dir = freshTestDir();
    b.write((dir / "space").string());
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --out '" + (dir / "ref").string() + "' --quiet", dir / "o", dir / "e"), 0);
    const auto complete = chunkTexts(dir / "ref");
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(runCli("bake '" + (dir / "space").string() + "' --out '" + (dir / "timed").string() + "' --quiet --resume", dir / "o", dir / "e"), 0);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(chunkTexts(dir / "timed"), complete);

    fs::copy(dir / "space", dir / "work", fs::copy_options::recursive);
    pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        const std::string work = (dir / "work").string();
        execl(SHADOWCULL_BIN, SHADOWCULL_BIN, "bake", work.c_str(), "--quiet", "--resume", static_cast<char*>(nullptr));
        _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds * 0.5));
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    for (const auto& [name, text] : chunkTexts(dir / "work"))
        EXPECT_TRUE(text == complete.at(name) || text == readText(dir / "space" / name)) << name;
    cli::BakeResult rerun = bakeResume(dir / "work");
    EXPECT_EQ(rerun.chunksWritten + rerun.chunksResumed, 100);
    EXPECT_EQ(chunkTexts(dir / "work"), complete);
}

// The raycast stage traces with flush-to-zero and restores the mode of the thread that
// called it. TBB tasks may still run with it afterwards (Embree's BVH builds leave it
// there): a task that needs gradual underflow (the geometry stage's CGAL filters) sets it
// with a FloatModeScope, which also restores what it found.
TEST(FloatMode, RaycastRestoresTheCallerAndScopesSetTheirMode) {
    constexpr unsigned kFtzDaz = FloatModeScope::kFtzDaz;
    ASSERT_EQ(_mm_getcsr() & kFtzDaz, 0u);
    fs::path dir = freshTestDir("-ftz");
    sampleSpace().write((dir / "space").string());
    cli::BakeOptions opt;
    opt.spaceDir = (dir / "space").string();
    opt.write = false;
    opt.useGeometry = false;
    opt.useGpu = false;
    Expected<cli::BakeResult> r = cli::runBake(opt);
    ASSERT_TRUE(r) << r.error().what();
    ASSERT_GT(r->stages.at(1).stats.raysCast, 0u);  // the rays were traced
    EXPECT_EQ(_mm_getcsr() & kFtzDaz, 0u) << "the calling thread was left in flush-to-zero mode";

    std::atomic<int> flushing{0}, restored{0};
    tbb::parallel_for(0, 64, [&](int) {
        const unsigned before = _mm_getcsr();
        {
            const FloatModeScope ieee(FloatModeScope::Underflow::Gradual);
            if (_mm_getcsr() & kFtzDaz) ++flushing;
            volatile double tiny = 1e-308;
            if (!(tiny / 1e10 > 0.0)) ++flushing;  // a denormal result survives
        }
        restored += _mm_getcsr() == before;
        std::this_thread::sleep_for(std::chrono::microseconds(100));
    });
    EXPECT_EQ(flushing.load(), 0);
    EXPECT_EQ(restored.load(), 64);
    {
        const FloatModeScope ftz(FloatModeScope::Underflow::FlushToZero);
        volatile double tiny = 1e-308;
        EXPECT_EQ(tiny / 1e10, 0.0);
    }
    EXPECT_EQ(_mm_getcsr() & kFtzDaz, 0u);
}
