// gpu/: the OSMesa passes on tiny scenes.
//  - known pixel counts: a quad covering exactly a quarter of an orthographic view, for the
//    baseline (point samples) and the conservative passes (over- and under-estimation);
//  - the baseline's terrain pass, and the baseline reproducing the known masks on scenes
//    coarse enough for it;
//  - the confirmation stage proving 0 for a cube under a slab and a trunk under an opaque
//    canopy (directional, point and spot lights), and never for a cube lit through a 2 cm
//    slit or a 5 mm rod, which the baseline at 1024 px misses (culls): the reason the
//    analytic pipeline exists;
//  - the rules applied only in the conservative direction (terrain, filter radius, skipped
//    objects, lamps touching or grazing geometry);
//  - soundness: no known 1 culled on any known-answer scene, and no bit with a witness ray
//    culled on random worlds (hills, mirrored, sunk, floating, alpha-tested, two-sided,
//    open and non-manifold meshes; roofs of slabs with 5 mm to 5 cm gaps);
//  - the pixels handed to the raycast stage, the light-view render, and the behaviour
//    without a GL context.
// Every test that needs GL skips, saying why, where no offscreen context can be made.

#include <cstdlib>
#include <cstdio>
#include <functional>
#include <map>
#include <set>
#include <tuple>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>
#include <png.h>

#include "core/scene.h"
#include "core/stage.h"
#include "core/window.h"
#include "gpu/baseline.h"
#include "gpu/confirm_stage.h"
#include "gpu/gl_context.h"
#include "gpu/light_view.h"
#include "gpu/render.h"
#include "raycast/raycast_stage.h"
#include "tests/support/bake_lookup.h"
#include "core/space_source.h"
#include "core/window_plan.h"
#include "tests/support/gl_available.h"
#include "tests/support/sample_space.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

// --- Loading a written space into a bake window ----------------------------------------

struct Loaded {
    Space space;
    TerrainMeshes terrainMeshes;
    BakeWindow window;
    ChunkVerdicts verdicts;

    // The verdict row of a model (by uuid) or of the terrain ("terrain") of chunk (0, 0).
    std::optional<size_t> find(const std::string& key) const {
        for (size_t oi = 0; oi < verdicts.objects.size(); ++oi) {
            const ObjectVerdicts& ov = verdicts.objects[oi];
            if (key == "terrain" ? ov.terrain : ov.uuid == key) return oi;
        }
        return std::nullopt;
    }
    size_t object(const std::string& key) const {
        if (std::optional<size_t> oi = find(key)) return *oi;
        ADD_FAILURE() << "no object " << key;
        return 0;
    }
    const Decision& at(const std::string& key, int group, int light) const {
        return verdicts.at(object(key), group, light);
    }
};

std::unique_ptr<Loaded> load(const SpaceBuilder& b, const std::string& suffix = "") {
    const fs::path dir = freshTestDir(suffix);
    b.write(dir.string());
    auto l = std::make_unique<Loaded>();
    Expected<Space> space = loadSpace(dir.string(), "");
    EXPECT_TRUE(space) << (space ? "" : space.error().what());
    if (!space) return nullptr;
    l->space = std::move(*space);
    // The window the analytic bake gives chunk (0, 0): what its shadows reach.
    Expected<SpaceSource> source = SpaceSource::scan(dir.string(), "");
    EXPECT_TRUE(source) << (source ? "" : source.error().what());
    if (!source) return nullptr;
    const WindowPlanner planner(source->settings(), source->chunks(), true);
    l->window = buildWindow(l->space, ChunkCoord{0, 0}, planner.plan(ChunkCoord{0, 0}).chunks, l->terrainMeshes);
    l->verdicts = makeChunkVerdicts(l->space, l->window);
    return l;
}

std::string keyOf(const KnownAnswer& a) { return a.key.rfind("terrain:", 0) == 0 ? "terrain" : a.key; }

template <class StageT>
void runStage(StageT& stage, Loaded& l) {
    StageStats st;
    Status s = stage.run(l.window, l.verdicts, st);
    ASSERT_TRUE(s) << s.error().what();
}

const gpu::GroupPixels* findPixels(const gpu::GpuConfirmStage& stage, size_t object, int group, int light) {
    for (const gpu::GroupPixels& g : stage.passedPixels())
        if (g.object == object && g.group == group && g.light == light) return &g;
    return nullptr;
}

const glm::dvec3 kDown{0, -1, 0};
const glm::dvec3 kTiltedSun{0.3, -1.0, 0.2};

// --- Scenes ----------------------------------------------------------------------------

// Straight-down light over the 100 m chunk (0,0): a ground quad over the whole chunk at
// y = 0 and a quad over x, z in [0, 50] at y = 1, both facing up. At 64 px the small quad
// covers exactly the 32 x 32 pixels of one quarter of the view.
SpaceBuilder quarterQuad() {
    SpaceBuilder b;
    b.addMesh("ground", MeshSpec::quad({0, 0, 0}, {0, 0, 100}, {100, 0, 100}, {100, 0, 0}));
    b.addMesh("small", MeshSpec::quad({0, 1, 0}, {0, 1, 50}, {50, 1, 50}, {50, 1, 0}));
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    b.addModel("ground", Affine::translation({0, 0, 0}), fixedUuid(1));
    b.addModel("small", Affine::translation({0, 0, 0}), fixedUuid(2));
    return b;
}

// Flat terrain at 0 and a two-sided quad over x, z in [0, 50] at `depth` below it; light
// straight down with a 1 mm bias (a surface is never behind itself by more than that).
SpaceBuilder quadUnderTerrain(double depth) {
    SpaceBuilder b;
    GroupSpec twoSided = GroupSpec::named("sheet");
    twoSided.doubleSidedOverride = true;
    b.addMesh("sheet", MeshSpec::quad({0, 0, 0}, {0, 0, 50}, {50, 0, 50}, {50, 0, 0}, twoSided), true);
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.001));
    b.addModel("sheet", Affine::translation({0, -depth, 0}), fixedUuid(1));
    return b;
}

// A tree: a 0.5 m trunk (group 0) from the ground up to an opaque 6 x 1 x 6 m canopy
// (group 1), on flat terrain, under the tilted sun. Traced back to the sun, every point of
// the trunk crosses the canopy's bottom (y = 4) within 1.5 m of the trunk: trunk 0,
// canopy 1 (its shadow lands on the terrain), terrain 0.
SpaceBuilder trunkUnderCanopy() {
    SpaceBuilder b;
    MeshSpec tree = MeshSpec::box({-0.25, 0, -0.25}, {0.25, 4, 0.25}, GroupSpec::named("bark"));
    tree.append(MeshSpec::box({-3, 4, -3}, {3, 5, 3}, GroupSpec::named("leaves")));
    b.addMesh("tree", tree);
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("sun", kTiltedSun).withBias(0.05));
    const std::string t = b.addModel("tree", Affine::translation({50, 0, 50}), fixedUuid(1));
    b.expect(t, 0, 0, "the trunk is never lit: the canopy hides it");
    b.expect(t, 1, 1, "the canopy's shadow falls on the terrain");
    b.expect(SpaceBuilder::terrainKey(0, 0), 0, 0, "nothing below the flat terrain");
    return b;
}

// A 1 m cube on flat terrain under a roof of two slabs with a 2 cm slit between them
// (x in [49.99, 50.01]) above the cube's middle; light straight down. Light falls through
// the slit on a 2 cm strip of the cube's top and the terrain lies 1 m behind it: cube 1.
// The slit is centred on a pixel border of the 1024 px view (x = 50 m of [0, 100]), so
// the nearest pixel centres (49.95, 50.05) both fall on the slabs: the point-sampled
// baseline sees no lit sample. (At other offsets a 2 cm slit meets one pixel column in
// five at ~9.8 cm pixels; the sampled answer depends on luck, never on the geometry.)
SpaceBuilder cubeUnderSlit() {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("slabA", MeshSpec::box({40, 3, 40}, {49.99, 3.2, 60}));
    b.addMesh("slabB", MeshSpec::box({50.01, 3, 40}, {60, 3.2, 60}));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    const std::string cube = b.addModel("cube", Affine::translation({49.5, 0, 49.5}), fixedUuid(1));
    b.addModel("slabA", Affine::translation({0, 0, 0}), fixedUuid(2));
    b.addModel("slabB", Affine::translation({0, 0, 0}), fixedUuid(3));
    b.expect(cube, 0, 1, "lit through the 2 cm slit; the terrain lies 1 m behind");
    return b;
}

// A 2 m rod, 5 mm thick, 2 m above flat terrain, light straight down; the rod's 5 mm
// (z in [49.9975, 50.0025]) lies between two pixel-centre rows of the 1024 px view. (Under
// thinRod()'s tilted sun the baseline's answer is luck: no sample at 256 and 512 px, one
// at 1024, six at 2048.)
SpaceBuilder rodBetweenPixelCentres() {
    SpaceBuilder b;
    b.addMesh("rod", MeshSpec::rod(2.0, 0.005));
    b.addFlatTerrain(0, 0, 0.0);
    b.addLight(LightSpec::directional("down", kDown).withBias(0.05));
    const std::string rod = b.addModel("rod", Affine::translation({49, 2, 50}), fixedUuid(1));
    b.expect(rod, 0, 1, "thin, but lit, and the terrain lies 2 m behind it");
    return b;
}

// hiddenUnderRoof's cube and roof, lit by a point lamp or a spot torch (cone 40 degrees, one
// view; or 80 degrees, six cube faces) 2.8 m above the roof's middle: every ray from the
// light to the cube crosses the roof (which spans 10 m around), so the cube is 0; the
// roof's shadow falls on the cube and the terrain: 1.
SpaceBuilder lampOverRoof(bool spot, double cone = 40) {
    SpaceBuilder b;
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    b.addMesh("roof", MeshSpec::box({-10, 0, -10}, {10, 0.2, 10}));
    b.addFlatTerrain(0, 0, 0.0);
    if (spot) b.addLight(LightSpec::spot("torch", {50.5, 6, 50.5}, {0, -1, 0}, 30, cone));
    else b.addLight(LightSpec::point("lamp", {50.5, 6, 50.5}, 30));
    const std::string cube = b.addModel("cube", Affine::translation({50, 0, 50}), fixedUuid(1));
    const std::string roof = b.addModel("roof", Affine::translation({50.5, 3, 50.5}), fixedUuid(2));
    b.expect(cube, 0, 0, "hidden from the light by the roof");
    b.expect(roof, 0, 1, "the roof's shadow falls on the cube and the terrain");
    return b;
}

// The builder's known-answer scenes and this file's own, each with its expectations.
const std::vector<NamedScene>& gpuKnownAnswerScenes() {
    static const std::vector<NamedScene> s = [] {
        std::vector<NamedScene> all = knownAnswerScenes();
        all.insert(all.end(), {
                                  {"trunkUnderCanopy", trunkUnderCanopy},
                                  {"cubeUnderSlit", cubeUnderSlit},
                                  {"rodBetweenPixelCentres", rodBetweenPixelCentres},
                                  {"lampOverRoof", [] { return lampOverRoof(false); }},
                                  {"torchOverRoof", [] { return lampOverRoof(true); }},
                                  {"wideTorchOverRoof", [] { return lampOverRoof(true, 80); }},
                              });
        return all;
    }();
    return s;
}

// --- Light views (no GL) ----------------------------------------------------------------

TEST(GpuLightView, StraightDownIsAlignedWithTheChunkGrid) {
    glm::dvec3 U, V;
    gpu::lightBasis(kDown, U, V);
    EXPECT_EQ(U, glm::dvec3(1, 0, 0));
    EXPECT_EQ(V, glm::dvec3(0, 0, -1));
    EXPECT_EQ(glm::cross(U, V), -kDown) << "U x V = -W (OpenGL's camera convention)";
}

TEST(GpuLightView, ViewsCoverWhatEachLightReaches) {
    std::unique_ptr<Loaded> l = load(rangeAndCone());
    ASSERT_TRUE(l);
    const std::vector<gpu::LightView> lamp = gpu::lightViews(l->window, l->window.lsLights[0], 32);
    ASSERT_EQ(lamp.size(), 6u) << "a point light: six cube faces";
    const std::vector<gpu::LightView> torch = gpu::lightViews(l->window, l->window.lsLights[1], 32);
    ASSERT_EQ(torch.size(), 1u) << "a 30 degree spot: one view over its cone";
    EXPECT_NEAR(torch[0].t, std::tan(30 * 3.14159265358979323846 / 180), 1e-12);
    // Every direction falls in some cube face (closed frusta).
    for (const glm::dvec3 d : {glm::dvec3(1, 1, 1), glm::dvec3(-0.2, 0.9, 0.1), glm::dvec3(0, 0, -1)}) {
        bool inside = false;
        for (const gpu::LightView& v : lamp) {
            const glm::dvec3 p = v.toView(lamp[0].eye + d);
            inside |= p.z > 0 && std::abs(p.x) <= p.z && std::abs(p.y) <= p.z;
        }
        EXPECT_TRUE(inside);
    }
    // Pixel mapping round trip.
    const glm::dvec3 p = torch[0].pointAt(10.5, 20.25, 3.0);
    const glm::dvec2 px = torch[0].viewToPixel(torch[0].toView(p));
    EXPECT_NEAR(px.x, 10.5, 1e-9);
    EXPECT_NEAR(px.y, 20.25, 1e-9);
}

// --- Without a context ------------------------------------------------------------------

TEST(GpuContext, NoContextIsAnInternalErrorAndDecidesNothing) {
    const char* before = std::getenv("SHADOWCULL_NO_GL");
    const std::string saved = before ? before : "";
    ::setenv("SHADOWCULL_NO_GL", "1", 1);
    Expected<std::unique_ptr<gpu::GlContext>> ctx = gpu::createOffscreenContext(8, 8);
    EXPECT_FALSE(ctx);
    if (!ctx) {
        EXPECT_EQ(ctx.error().kind, ErrorKind::Internal);
    }
    std::unique_ptr<Loaded> l = load(cubeOnTerrain());
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage;
    StageStats st;
    Status s = stage.run(l->window, l->verdicts, st);
    if (before) ::setenv("SHADOWCULL_NO_GL", saved.c_str(), 1);
    else ::unsetenv("SHADOWCULL_NO_GL");
    ASSERT_FALSE(s);
    EXPECT_EQ(s.error().kind, ErrorKind::Internal);
    EXPECT_NE(s.error().message.find("no offscreen OpenGL context"), std::string::npos) << s.error().message;
    for (const ObjectVerdicts& ov : l->verdicts.objects)
        for (const Decision& d : ov.decisions) EXPECT_EQ(d.verdict, Verdict::Undecided);
}

TEST(GpuContext, ChosenBackendGivesACoreContext) {
    REQUIRE_GL();
    Expected<std::unique_ptr<gpu::GlContext>> ctx = gpu::createOffscreenContext(8, 8);
    ASSERT_TRUE(ctx);
    EXPECT_TRUE((*ctx)->makeCurrent());
    // OSMesa has a framebuffer of its own; an EGL context has none (the passes use FBOs).
    EXPECT_EQ((*ctx)->width(), (*ctx)->backend() == "OSMesa" ? 8 : 0);
    const gpu::GlBackend chosen = gpu::glChoice().backend;
    if (chosen == gpu::GlBackend::OsMesa) {
        EXPECT_EQ((*ctx)->backend(), "OSMesa");
    }
    if (chosen == gpu::GlBackend::Egl) {
        EXPECT_EQ((*ctx)->backend().rfind("EGL ", 0), 0u) << (*ctx)->backend();
    }
    EXPECT_FALSE((*ctx)->vendor().empty());
    EXPECT_FALSE((*ctx)->renderer().empty());
    EXPECT_NE((*ctx)->description().find("OpenGL 4."), std::string::npos) << (*ctx)->description();
    EXPECT_NE((*ctx)->getProcAddress("glDrawArrays"), nullptr);
}

// --- Known pixel counts -----------------------------------------------------------------

TEST(GpuBaseline, QuarterQuadPassesExactlyItsPixelCount) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(quarterQuad());
    ASSERT_TRUE(l);
    gpu::GpuBaselineMethod baseline({64});
    runStage(baseline, *l);
    // The small quad is nearest at the 32 x 32 pixel centres of its quarter, with the
    // ground behind (stencil 2): 1024 samples. The ground has nothing behind: 0.
    std::map<std::string, uint64_t> samples;
    for (const gpu::BaselineCount& c : baseline.lastCounts())
        samples[l->verdicts.objects[c.object].uuid] += c.samples;
    EXPECT_EQ(samples[fixedUuid(2)], 1024u);
    EXPECT_EQ(samples[fixedUuid(1)], 0u);
    const Decision& small = l->at(fixedUuid(2), 0, 0);
    EXPECT_EQ(small.verdict, Verdict::Kept);
    EXPECT_EQ(small.stage, "gpu-baseline");
    EXPECT_EQ(small.reason(), "1024 samples passed at 64 px");
    const Decision& ground = l->at(fixedUuid(1), 0, 0);
    EXPECT_EQ(ground.verdict, Verdict::Culled);
    EXPECT_EQ(ground.reason(), "0 samples passed at 64 px");
}

TEST(GpuConfirm, QuarterQuadKnownCoverage) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(quarterQuad());
    ASSERT_TRUE(l);
    gpu::GpuConfirmOptions opt;
    opt.resolution = 64;
    opt.maxPixelsPerGroup = 8192;
    opt.collectViewStats = true;
    gpu::GpuConfirmStage stage(opt);
    runStage(stage, *l);
    ASSERT_EQ(stage.viewStats().size(), 1u);
    const gpu::ConfirmViewStats& vs = stage.viewStats()[0];
    // Occluders are under-estimated: a pixel is blocked only when the sheet covers it
    // whole and no crack (boundary) edge touches it. The ground's border edges run on the
    // view's border, so its outer ring of pixels is lost: 62 x 62. (The small quad's own
    // 30 x 30 blocked pixels lie inside.)
    EXPECT_EQ(vs.occluderPixels, 62 * 62);
    EXPECT_EQ(vs.occluderSheets, 2);
    // Receivers are over-estimated: the ground reaches every pixel.
    EXPECT_EQ(vs.receiverPixels, 64 * 64);
    // The small quad is over-estimated: every pixel whose closed square touches
    // [0,32] x [32,64] in pixels, i.e. 33 x 33, may be lit with the ground behind.
    const gpu::GroupPixels* small = findPixels(stage, l->object(fixedUuid(2)), 0, 0);
    ASSERT_NE(small, nullptr);
    std::set<std::pair<int, int>> pixels;
    for (const gpu::PassedPixel& p : small->pixels) pixels.insert({p.px, p.py});
    EXPECT_EQ(pixels.size(), 33u * 33u);
    EXPECT_EQ(*pixels.begin(), std::make_pair(0, 31));
    EXPECT_EQ(*pixels.rbegin(), std::make_pair(32, 63));
    EXPECT_EQ(l->at(fixedUuid(2), 0, 0).verdict, Verdict::Undecided);
    // The ground may be lit outside the quad's 30 x 30 blocked pixels, but nothing lies
    // behind it deeper than the bias (its own depth span over a pixel is 0 here).
    const gpu::GroupPixels* ground = findPixels(stage, l->object(fixedUuid(1)), 0, 0);
    ASSERT_NE(ground, nullptr);
    EXPECT_GE(ground->litSamples, uint64_t(64 * 64 - 30 * 30));
    EXPECT_EQ(ground->passedSamples, 0u);
    const Decision& g = l->at(fixedUuid(1), 0, 0);
    EXPECT_EQ(g.verdict, Verdict::Culled);
    EXPECT_EQ(g.stage, "gpu");
    EXPECT_EQ(g.reason().rfind("nothing behind", 0), 0u) << g.reason();
}

// --- The baseline -----------------------------------------------------------------------

TEST(GpuBaseline, TerrainPassDiscardsReceiversUnderTheTerrain) {
    REQUIRE_GL();
    // 1 m under the terrain (tolerance 0.01): the sheet does not count behind the terrain.
    std::unique_ptr<Loaded> deep = load(quadUnderTerrain(1.0), "deep");
    ASSERT_TRUE(deep);
    gpu::GpuBaselineMethod baseline({64});
    runStage(baseline, *deep);
    EXPECT_EQ(deep->at("terrain", 0, 0).verdict, Verdict::Culled) << deep->at("terrain", 0, 0).reason();
    EXPECT_EQ(deep->at("terrain", 0, 0).reason(), "0 samples passed at 64 px");
    EXPECT_EQ(deep->at(fixedUuid(1), 0, 0).verdict, Verdict::Culled) << "the sheet is never lit";
    // 5 mm under (within the tolerance): it counts, at the 32 x 32 pixels of its quarter.
    std::unique_ptr<Loaded> shallow = load(quadUnderTerrain(0.005), "shallow");
    ASSERT_TRUE(shallow);
    gpu::GpuBaselineMethod baseline2({64});
    runStage(baseline2, *shallow);
    EXPECT_EQ(shallow->at("terrain", 0, 0).verdict, Verdict::Kept);
    EXPECT_EQ(shallow->at("terrain", 0, 0).reason(), "1024 samples passed at 64 px");
}

TEST(GpuBaseline, ReproducesTheKnownMasksOnCoarseScenes) {
    REQUIRE_GL();
    for (const char* name :
         {"cubeOnTerrain", "twoFloatingCubes", "rangeAndCone", "twoLightsMasks", "hiddenUnderOpaqueRoof",
          "hiddenUnderAlphaRoof", "trunkUnderCanopy", "lampOverRoof", "torchOverRoof", "wideTorchOverRoof"}) {
        SCOPED_TRACE(name);
        const NamedScene& scene =
            *std::find_if(gpuKnownAnswerScenes().begin(), gpuKnownAnswerScenes().end(),
                          [&](const NamedScene& s) { return std::string(s.name) == name; });
        const SpaceBuilder b = scene.make();
        std::unique_ptr<Loaded> l = load(b, name);
        ASSERT_TRUE(l);
        gpu::GpuBaselineMethod baseline({256});
        runStage(baseline, *l);
        for (const KnownAnswer& a : b.expectations()) {
            const size_t oi = l->object(keyOf(a));
            EXPECT_EQ(l->verdicts.groupMask(oi, a.group), a.mask) << a.key << " group " << a.group << ": " << a.why;
        }
    }
}

// --- Proofs of 0 --------------------------------------------------------------------------

void expectNeverLit(const Decision& d) {
    EXPECT_EQ(d.verdict, Verdict::Culled);
    EXPECT_EQ(d.stage, "gpu");
    EXPECT_EQ(d.reason().rfind("never lit", 0), 0u) << d.reason();
}

TEST(GpuConfirm, ProvesACubeUnderASlabIsNeverLit) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(hiddenUnderRoof(Roof::Opaque));
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({256});
    runStage(stage, *l);
    expectNeverLit(l->at(fixedUuid(1), 0, 0));
    EXPECT_NE(l->at(fixedUuid(2), 0, 0).verdict, Verdict::Culled) << "the roof's shadow is visible";
}

TEST(GpuConfirm, ProvesATrunkUnderAnOpaqueCanopyIsNeverLit) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(trunkUnderCanopy());
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({256});
    runStage(stage, *l);
    expectNeverLit(l->at(fixedUuid(1), 0, 0));
    EXPECT_NE(l->at(fixedUuid(1), 1, 0).verdict, Verdict::Culled) << "the canopy's shadow is visible";
}

TEST(GpuConfirm, ProvesNeverLitForPointAndSpotLights) {
    REQUIRE_GL();
    for (const double cone : {0.0, 40.0, 80.0}) {  // 0: a point light
        SCOPED_TRACE(cone);
        std::unique_ptr<Loaded> l = load(lampOverRoof(cone > 0, cone), std::to_string(int(cone)));
        ASSERT_TRUE(l);
        EXPECT_EQ(gpu::lightViews(l->window, l->window.lsLights[0], 8).size(), cone == 40.0 ? 1u : 6u);
        gpu::GpuConfirmStage stage({128});
        runStage(stage, *l);
        expectNeverLit(l->at(fixedUuid(1), 0, 0));
        EXPECT_NE(l->at(fixedUuid(2), 0, 0).verdict, Verdict::Culled);
    }
}

// A lamp (range 10 m, bias 5 cm) and one group in two parts: a face 7 m away turned to the
// lamp, whose shadow passes over the far edge of a floor, and a patch 20 m away (beyond
// range) over the floor. Only the face can hold p; the patch's pixels passed (the floor's
// triangles reach into range) until the casters were limited to their triangles within
// reach. (The geometry stage proves the same bit at any bias: GeometryStage.HardCases.)
TEST(GpuConfirm, CasterTrianglesBeyondRangeAreNotDrawn) {
    REQUIRE_GL();
    SpaceBuilder b;
    b.addLight(LightSpec::point("lamp", {50, 5, 50}, 10).withBias(0.05));
    b.addMesh("parts", faceAndFarPatch());
    b.addMesh("floor", MeshSpec::quad({0, 0, 0}, {0, 0, 50}, {50, 0, 50}, {50, 0, 0}));
    b.addModel("parts", Affine::translation({50, 0, 50}), fixedUuid(1));
    b.addModel("floor", Affine::translation({30, 0, 30}), fixedUuid(2));
    std::unique_ptr<Loaded> l = load(b);
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({1024});
    runStage(stage, *l);
    const Decision& d = l->at(fixedUuid(1), 0, 0);
    EXPECT_EQ(d.verdict, Verdict::Culled) << (d.notes().empty() ? "" : d.notes()[0].text);
    EXPECT_EQ(d.stage, "gpu");
}

TEST(GpuConfirm, AlphaTestedRoofLetsLightThrough) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(hiddenUnderRoof(Roof::AlphaTested));
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({256});
    runStage(stage, *l);
    EXPECT_EQ(l->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
}

TEST(GpuConfirm, TerrainRuleOnlyExcludesReceiversWhollyUnderTheTerrain) {
    REQUIRE_GL();
    // 1 m under the terrain: the sheet cannot receive (terrainTolerance 0.01), so nothing
    // lies behind the terrain. The sheet is culled too (the terrain hides it except in the
    // view's border ring of pixels, which the terrain's border edges crack; nothing lies
    // behind it there).
    std::unique_ptr<Loaded> deep = load(quadUnderTerrain(1.0), "deep");
    ASSERT_TRUE(deep);
    gpu::GpuConfirmOptions withTerrain;
    withTerrain.resolution = 64;
    withTerrain.includeTerrain = true;
    gpu::GpuConfirmStage stage(withTerrain);
    runStage(stage, *deep);
    EXPECT_EQ(deep->at("terrain", 0, 0).verdict, Verdict::Culled) << deep->at("terrain", 0, 0).reason();
    EXPECT_EQ(deep->at("terrain", 0, 0).reason().rfind("nothing behind", 0), 0u) << deep->at("terrain", 0, 0).reason();
    EXPECT_EQ(deep->at(fixedUuid(1), 0, 0).verdict, Verdict::Culled);
    EXPECT_EQ(deep->at(fixedUuid(1), 0, 0).stage, "gpu");
    // 5 mm under (within the tolerance, deeper than the 1 mm bias): the terrain's shadow
    // falls on it, a 1.
    std::unique_ptr<Loaded> shallow = load(quadUnderTerrain(0.005), "shallow");
    ASSERT_TRUE(shallow);
    gpu::GpuConfirmStage stage2(withTerrain);
    runStage(stage2, *shallow);
    EXPECT_EQ(shallow->at("terrain", 0, 0).verdict, Verdict::Undecided);
    // By default terrain groups are not examined (they stay undecided), the rest is.
    std::unique_ptr<Loaded> byDefault = load(quadUnderTerrain(1.0), "default");
    ASSERT_TRUE(byDefault);
    gpu::GpuConfirmStage stage3({64});
    runStage(stage3, *byDefault);
    EXPECT_EQ(byDefault->at("terrain", 0, 0).verdict, Verdict::Undecided);
    EXPECT_EQ(byDefault->at(fixedUuid(1), 0, 0).verdict, Verdict::Culled);
}

// A 1 x 1 m one-sided quad 2 m up (caster) and a receiver quad on the ground beside its
// shadow, `gap` metres from it; light straight down, or a lamp 4 m above the caster.
SpaceBuilder receiverBesideShadow(bool lamp, double filterRadius) {
    SpaceBuilder b;
    b.addMesh("caster", MeshSpec::quad({50, 2, 50}, {50, 2, 51}, {51, 2, 51}, {51, 2, 50}));
    // Straight down the shadow ends at x = 51; from the lamp at (50.5, 6) at x = 51.25.
    const double x0 = lamp ? 51.6 : 51.3;
    b.addMesh("ground", MeshSpec::quad({x0, 0, 50}, {x0, 0, 51}, {53, 0, 51}, {53, 0, 50}));
    LightSpec light = lamp ? LightSpec::point("lamp", {50.5, 6, 50.5}, 20) : LightSpec::directional("down", kDown);
    b.addLight(light.withFilterRadius(filterRadius).withBias(0.001));
    b.addModel("caster", Affine::translation({0, 0, 0}), fixedUuid(1));
    b.addModel("ground", Affine::translation({0, 0, 0}), fixedUuid(2));
    return b;
}

TEST(GpuConfirm, FilterRadiusWidensTheReceivers) {
    REQUIRE_GL();
    for (bool lamp : {false, true}) {
        SCOPED_TRACE(lamp ? "lamp" : "sun");
        // No filter: the receiver lies 0.3 / 0.35 m beside every shadow ray: nothing behind.
        std::unique_ptr<Loaded> sharp = load(receiverBesideShadow(lamp, 0.0), lamp ? "lamp0" : "sun0");
        ASSERT_TRUE(sharp);
        gpu::GpuConfirmStage stage({128});
        runStage(stage, *sharp);
        EXPECT_EQ(sharp->at(fixedUuid(1), 0, 0).verdict, Verdict::Culled);
        EXPECT_EQ(sharp->at(fixedUuid(1), 0, 0).reason().rfind("nothing behind", 0), 0u);
        // A 0.5 m filter reaches it (semantics.md, condition 4): never culled.
        std::unique_ptr<Loaded> soft = load(receiverBesideShadow(lamp, 0.5), lamp ? "lamp5" : "sun5");
        ASSERT_TRUE(soft);
        gpu::GpuConfirmStage stage2({128});
        runStage(stage2, *soft);
        EXPECT_EQ(soft->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
    }
}

TEST(GpuConfirm, SkippedObjectsLeaveOnlyNeverLitProofs) {
    REQUIRE_GL();
    // quarterQuad's ground is proved "nothing behind" (QuarterQuadKnownCoverage); with an
    // object that could not be loaded, which might have been a receiver, it is not.
    SpaceBuilder b = quarterQuad();
    b.addModel("models/missing.obj", Affine::translation({10, 0, 10}), fixedUuid(9));
    std::unique_ptr<Loaded> l = load(b);
    ASSERT_TRUE(l);
    ASSERT_EQ(l->window.skippedObjects, 1);
    gpu::GpuConfirmStage stage({64});
    runStage(stage, *l);
    EXPECT_EQ(l->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
}

TEST(GpuConfirm, LampsTouchingOrGrazingGeometry) {
    REQUIRE_GL();
    // A lamp on the roof's top face: no near plane lies below the geometry; the light is
    // left alone (its bits stay undecided and are not examined).
    SpaceBuilder touching = hiddenUnderRoof(Roof::Opaque);
    touching.addLight(LightSpec::point("onRoof", {52, 3.2, 52}, 20));
    std::unique_ptr<Loaded> l = load(touching, "touching");
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({64});
    runStage(stage, *l);
    EXPECT_EQ(l->at(fixedUuid(1), 0, 1).verdict, Verdict::Undecided);
    EXPECT_EQ(findPixels(stage, l->object(fixedUuid(1)), 0, 1), nullptr);
    expectNeverLit(l->at(fixedUuid(1), 0, 0));  // the sun's bit is still proved
    // A lamp 2 cm above a cube's top: the near plane comes very close, and the cube, lit,
    // with the terrain behind it, is not culled.
    SpaceBuilder grazing;
    grazing.addMesh("cube", MeshSpec::box({0, 0, 0}, {1, 1, 1}));
    grazing.addFlatTerrain(0, 0, 0.0);
    grazing.addLight(LightSpec::point("lamp", {50.5, 1.02, 50.5}, 10));
    grazing.addModel("cube", Affine::translation({50, 0, 50}), fixedUuid(1));
    std::unique_ptr<Loaded> g = load(grazing, "grazing");
    ASSERT_TRUE(g);
    gpu::GpuConfirmStage stage2({64});
    runStage(stage2, *g);
    EXPECT_EQ(g->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
    const gpu::GroupPixels* gp = findPixels(stage2, g->object(fixedUuid(1)), 0, 0);
    ASSERT_NE(gp, nullptr);
    EXPECT_GT(gp->passedSamples, 0u);
}

// --- Thin features: the baseline misses them, the confirmation never culls them ---------

TEST(GpuThinFeatures, BaselineAt1024MissesASlitAndARodThatConfirmationKeeps) {
    REQUIRE_GL();
    for (const char* name : {"cubeUnderSlit", "rodBetweenPixelCentres"}) {
        SCOPED_TRACE(name);
        const SpaceBuilder b = std::string(name) == "cubeUnderSlit" ? cubeUnderSlit() : rodBetweenPixelCentres();
        // The baseline at 1024 px: no sample lands on the lit strip: a false cull.
        std::unique_ptr<Loaded> base = load(b, std::string(name) + "-baseline");
        ASSERT_TRUE(base);
        gpu::GpuBaselineMethod baseline({1024});
        runStage(baseline, *base);
        const Decision& missed = base->at(fixedUuid(1), 0, 0);
        EXPECT_EQ(missed.verdict, Verdict::Culled) << "the baseline was expected to miss it: " << missed.reason();
        EXPECT_EQ(missed.reason(), "0 samples passed at 1024 px");
        // The conservative pass at the same resolution never proves it 0, and says where
        // to look: the pixels that passed cover the lit strip.
        std::unique_ptr<Loaded> conf = load(b, std::string(name) + "-confirm");
        ASSERT_TRUE(conf);
        gpu::GpuConfirmStage stage({1024});
        runStage(stage, *conf);
        EXPECT_EQ(conf->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
        const gpu::GroupPixels* gp = findPixels(stage, conf->object(fixedUuid(1)), 0, 0);
        ASSERT_NE(gp, nullptr);
        EXPECT_GT(gp->passedSamples, 0u);
        ASSERT_FALSE(gp->pixels.empty());
        // On the lit strip: the slit over the cube's middle (x = 50 +- 0.1 m, a pixel),
        // or the rod's top (x in [49, 51], z = 50 +- 0.1 m).
        const bool slit = std::string(name) == "cubeUnderSlit";
        for (const gpu::PassedPixel& p : gp->pixels) {
            const glm::dvec3 ws = p.lsPoint + conf->window.wsOrigin;
            if (slit) {
                EXPECT_NEAR(ws.x, 50.0, 0.11);
                EXPECT_NEAR(ws.z, 50.0, 0.6);
            } else {
                EXPECT_NEAR(ws.x, 50.0, 1.11);
                EXPECT_NEAR(ws.z, 50.0, 0.11);
            }
        }
    }
}

TEST(GpuThinFeatures, ConfirmationKeepsTheTiltedThinRod) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(thinRod());
    ASSERT_TRUE(l);
    gpu::GpuConfirmStage stage({512});
    runStage(stage, *l);
    EXPECT_EQ(l->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
}

// --- Soundness on every known-answer scene ---------------------------------------------

TEST(GpuConfirm, NeverCullsAKnownOne) {
    REQUIRE_GL();
    for (const NamedScene& scene : gpuKnownAnswerScenes()) {
        SCOPED_TRACE(scene.name);
        const SpaceBuilder b = scene.make();
        std::unique_ptr<Loaded> l = load(b, scene.name);
        ASSERT_TRUE(l);
        gpu::GpuConfirmStage stage({128});
        runStage(stage, *l);
        int culled = 0;
        for (const KnownAnswer& a : b.expectations()) {
            const std::optional<size_t> found = l->find(keyOf(a));
            if (!found && !(b.locateObjects().at(a.key).chunk == ChunkId{0, 0})) continue;  // baked in another window
            ASSERT_TRUE(found) << a.key;
            const size_t oi = *found;
            for (int light = 0; light < l->verdicts.lightCount; ++light) {
                const Decision& d = l->verdicts.at(oi, a.group, light);
                if (a.mask >> light & 1u) {
                    EXPECT_NE(d.verdict, Verdict::Culled)
                        << "false cull: " << a.key << " group " << a.group << " light " << light + 1 << ": " << d.reason();
                }
                culled += d.verdict == Verdict::Culled;
            }
        }
        RecordProperty(std::string(scene.name) + "_culled", culled);
    }
}

TEST(GpuConfirm, OnlyLooksAtUndecidedBitsAndHandsOverPixelsOnTheGroup) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(cubeOnTerrain());
    ASSERT_TRUE(l);
    // A bit decided before stays as it was and is not examined.
    decide(l->verdicts.at(l->object("terrain"), 0, 0), Verdict::Kept, "test", "decided before");
    gpu::GpuConfirmStage stage({256});
    StageStats st;
    ASSERT_TRUE(stage.run(l->window, l->verdicts, st));
    EXPECT_EQ(l->at("terrain", 0, 0).stage, "test");
    EXPECT_EQ(findPixels(stage, l->object("terrain"), 0, 0), nullptr);
    EXPECT_EQ(st.bitsExamined, 1u);
    // The cube may be lit with the terrain behind: it stays undecided, and every pixel
    // handed over lies on a light ray that passes within a pixel of the cube. (Along the
    // ray, the point is at the nearest depth of the cube's face over the pixel square: on a
    // face nearly along the light, a few pixel sizes from the cube when the view frames the
    // cube alone.)
    EXPECT_EQ(l->at(fixedUuid(1), 0, 0).verdict, Verdict::Undecided);
    const gpu::GroupPixels* gp = findPixels(stage, l->object(fixedUuid(1)), 0, 0);
    ASSERT_NE(gp, nullptr);
    ASSERT_FALSE(gp->pixels.empty());
    const Aabb cube = l->window.objects[size_t(l->verdicts.objects[l->object(fixedUuid(1))].windowObject)].lsBounds;
    const double reach = glm::length(cube.max - cube.min) + 1.0;
    for (const gpu::PassedPixel& p : gp->pixels) {
        double nearest = 1e300;
        for (double t = -reach; t <= reach; t += p.footprint / 8) {
            const glm::dvec3 x = p.lsPoint + t * p.lsDirection;
            nearest = std::min(nearest, glm::length(glm::max(glm::max(cube.min - x, x - cube.max), glm::dvec3(0.0))));
        }
        EXPECT_LE(nearest, 2 * p.footprint) << p.px << "," << p.py;
        EXPECT_NEAR(glm::length(p.lsDirection - glm::normalize(kTiltedSun)), 0.0, 1e-12);
    }
}

// A random little world: hilly terrain on the centre chunk and a neighbour, boxes, an open
// box, two cubes sharing an edge and one-sided quads (some mirrored, turned, sunk into the
// terrain, floating, alpha-tested or two-sided, some with two groups), a tilted sun, a
// point lamp and a spot torch.
SpaceBuilder randomWorld(uint64_t seed) {
    DeterministicRng rng(seed);
    SpaceBuilder b;
    auto hills = [](double x, double z) { return 2.0 + 2.0 * std::sin(x / 7.0) * std::cos(z / 9.0); };
    b.addTerrain(0, 0, 9, hills, 0.0, 4.0);
    b.addTerrain(1, 0, 5, hills, 0.0, 4.0);
    MeshSpec two = MeshSpec::box({0, 0, 0}, {1, 2, 1}, GroupSpec::named("stone"));
    two.append(MeshSpec::box({-1.5, 2, -1.5}, {2.5, 2.6, 2.5}, GroupSpec::named("slate")));
    b.addMesh("two", two);
    b.addMesh("leaf", MeshSpec::box({-2, 0, -2}, {2, 0.3, 2}, GroupSpec::named("leaf", true)));
    GroupSpec twoSided = GroupSpec::named("cloth");
    twoSided.doubleSidedOverride = true;
    b.addMesh("cloth", MeshSpec::quad({0, 0, 0}, {0, 0, 3}, {3, 0, 3}, {3, 0, 0}, twoSided), true);
    b.addMesh("panel", MeshSpec::quad({0, 0, 0}, {0, 2.5, 0}, {2.5, 2.5, 0}, {2.5, 0, 0}));
    b.addMesh("open", MeshSpec::openBox({0, 0, 0}, {2, 1.5, 2}));
    b.addMesh("pair", MeshSpec::edgeSharingCubes(1.0));
    for (int k = 0; k < 4; ++k) {
        const double sx = rng.uniform(0.2, 4), sy = rng.uniform(0.2, 4), sz = rng.uniform(0.2, 4);
        b.addMesh("box" + std::to_string(k), MeshSpec::box({0, 0, 0}, {sx, sy, sz}));
    }
    const char* kinds[] = {"two", "leaf", "cloth", "panel", "open", "pair", "box0", "box1", "box2", "box3"};
    for (int k = 0; k < 14; ++k) {
        const std::string mesh = kinds[rng.below(10)];
        const double x = rng.uniform(35, 70), z = rng.uniform(35, 65);
        const double ground = b.terrainHeightAt(x, z).value_or(0.0);
        const int where = rng.below(3);  // resting, sunk, floating
        const double y = where == 0 ? ground : where == 1 ? ground - rng.uniform(0.2, 1.0) : ground + rng.uniform(1, 8);
        Affine place = Affine::rotationY(rng.uniform(0, 360));
        if (rng.below(4) == 0) place = Affine::scaling({-1, 1, 1}).then(place);  // mirrored
        if (mesh == "panel" && rng.below(2)) place = Affine::rotationY(90).then(place);
        b.addModel(mesh, place.then(Affine::translation({x, y, z})));
    }
    b.addModel("box0", Affine::translation({103, b.terrainHeightAt(103, 50).value_or(0), 50}));  // a neighbour
    b.addLight(LightSpec::directional("sun", {rng.uniform(-0.6, 0.6), -1, rng.uniform(-0.6, 0.6)})
                   .withBias(rng.below(2) ? 0.0 : 0.05));
    b.addLight(LightSpec::point("lamp", {rng.uniform(40, 60), rng.uniform(9, 14), rng.uniform(40, 60)},
                                rng.uniform(25, 50))
                   .withBias(rng.below(2) ? 0.0 : 0.02));
    const glm::dvec3 torch(rng.uniform(35, 65), rng.uniform(10, 16), rng.uniform(35, 65));
    b.addLight(LightSpec::spot("torch", torch, glm::dvec3(50, 0, 50) - torch, rng.uniform(30, 60), rng.uniform(20, 80)));
    return b;
}

// Adversarial for the occluder sheets: a roof of slabs at random heights with gaps of
// 5 mm to 5 cm between them, cubes and rods below, a tilted sun and a lamp above.
SpaceBuilder gappyWorld(uint64_t seed) {
    DeterministicRng rng(seed * 7919);
    SpaceBuilder b;
    b.addFlatTerrain(0, 0, 0.0);
    double x = 40;
    for (int k = 0; x < 60; ++k) {
        const double width = rng.uniform(0.3, 3.0), y = rng.uniform(2.5, 3.5);
        const std::string name = "slab" + std::to_string(k);
        b.addMesh(name, MeshSpec::box({x, y, 40}, {x + width, y + rng.uniform(0.05, 0.3), 60}));
        b.addModel(name, Affine::translation({0, 0, 0}));
        x += width + rng.uniform(0.005, 0.05);
    }
    b.addMesh("cube", MeshSpec::box({0, 0, 0}, {0.6, 0.6, 0.6}));
    b.addMesh("rod", MeshSpec::rod(1.5, 0.01));
    for (int k = 0; k < 10; ++k) {
        const bool rod = rng.below(3) == 0;
        b.addModel(rod ? "rod" : "cube", Affine::rotationY(rng.uniform(0, 360))
                                             .then(Affine::translation({rng.uniform(44, 56), rng.uniform(0, 1.5),
                                                                        rng.uniform(44, 56)})));
    }
    b.addLight(LightSpec::directional("sun", {rng.uniform(-0.3, 0.3), -1, rng.uniform(-0.3, 0.3)}).withBias(0.01));
    b.addLight(LightSpec::point("lamp", {rng.uniform(45, 55), rng.uniform(5, 8), rng.uniform(45, 55)}, 30));
    return b;
}

// The strongest soundness check available: a bit the raycast stage proves 1 with a
// witness ray must never be culled by the GPU stage (semantics.md: a false cull is a
// defect at any setting). For a longer soak: SHADOWCULL_GPU_SEEDS=200 SHADOWCULL_GPU_RAYS=100000
// SHADOWCULL_GPU_RESOLUTION=64 (or 1024).
int envInt(const char* name, int fallback) {
    const char* v = std::getenv(name);
    return v ? std::atoi(v) : fallback;
}

TEST(GpuConfirm, NeverCullsABitWithAWitnessOnRandomWorlds) {
    REQUIRE_GL();
    int proved = 0, witnesses = 0;
    const int seeds = envInt("SHADOWCULL_GPU_SEEDS", 6), resolution = envInt("SHADOWCULL_GPU_RESOLUTION", 256);
    for (uint64_t seed = 1; seed <= uint64_t(seeds); ++seed) {
        SCOPED_TRACE("seed " + std::to_string(seed));
        const SpaceBuilder b = seed % 2 ? randomWorld(seed) : gappyWorld(seed);
        std::unique_ptr<Loaded> rays = load(b, "rays" + std::to_string(seed));
        std::unique_ptr<Loaded> gpuRun = load(b, "gpu" + std::to_string(seed));
        ASSERT_TRUE(rays && gpuRun);
        raycast::RaycastOptions ro;
        ro.areaSamples = envInt("SHADOWCULL_GPU_RAYS", 4096);
        raycast::RaycastStage raycaster(ro);
        runStage(raycaster, *rays);
        gpu::GpuConfirmStage stage({resolution});
        runStage(stage, *gpuRun);
        for (size_t oi = 0; oi < rays->verdicts.objects.size(); ++oi) {
            const ObjectVerdicts& ov = rays->verdicts.objects[oi];
            for (int g = 0; g < ov.groupCount; ++g)
                for (int l = 0; l < rays->verdicts.lightCount; ++l) {
                    const Decision& witness = rays->verdicts.at(oi, g, l);
                    const Decision& gpuBit = gpuRun->verdicts.at(oi, g, l);
                    proved += gpuBit.verdict == Verdict::Culled;
                    if (witness.verdict != Verdict::Kept) continue;
                    ++witnesses;
                    EXPECT_NE(gpuBit.verdict, Verdict::Culled)
                        << "false cull of element " << ov.elementIndex << " group " << g << " light " << l + 1
                        << ": " << gpuBit.reason() << " (witness p at " << witness.witness()->wsP.x << ","
                        << witness.witness()->wsP.y << "," << witness.witness()->wsP.z << ")";
                }
        }
    }
    EXPECT_GT(witnesses, 50);
    EXPECT_GT(proved, 0) << "the stage should prove some bits 0 on these worlds";
    RecordProperty("witnesses", witnesses);
    RecordProperty("gpuCulled", proved);
}

// The pruning (casters' pixel cells, objects and triangles that cannot reach them, sheets
// behind every caster, receivers never behind one) only leaves out what cannot change a
// count: with it and without it (collectViewStats draws whole views), every examined bit
// has the same lit and passed sample counts, so the same verdict. Terrain groups included,
// so that large casters are pruned against too.
// Runs the stage with options `ao` and with `bo` on a fresh load of each scene, and checks
// that every examined bit has the same lit and passed sample counts and the same verdict
// in both; `each` then sees both stages (for more checks). Counts the bits compared and
// those culled.
template <class F>
void expectSameCounts(const std::vector<NamedScene>& scenes, const gpu::GpuConfirmOptions& ao,
                      const gpu::GpuConfirmOptions& bo, int& compared, int& culled, F each) {
    for (size_t k = 0; k < scenes.size(); ++k) {
        SCOPED_TRACE(std::string(scenes[k].name) + " #" + std::to_string(k));
        const SpaceBuilder b = scenes[k].make();
        std::unique_ptr<Loaded> la = load(b, "a" + std::to_string(k)), lb = load(b, "b" + std::to_string(k));
        ASSERT_TRUE(la && lb);
        gpu::GpuConfirmStage a(ao), c(bo);
        runStage(a, *la);
        runStage(c, *lb);
        ASSERT_EQ(a.passedPixels().size(), c.passedPixels().size());
        for (size_t q = 0; q < a.passedPixels().size(); ++q) {
            const gpu::GroupPixels &p = a.passedPixels()[q], &w = c.passedPixels()[q];
            ASSERT_EQ(p.object, w.object);
            ASSERT_EQ(p.group, w.group);
            ASSERT_EQ(p.light, w.light);
            EXPECT_EQ(p.litSamples, w.litSamples) << "object " << p.object << " group " << p.group << " light " << p.light;
            EXPECT_EQ(p.passedSamples, w.passedSamples) << "object " << p.object << " group " << p.group << " light " << p.light;
            EXPECT_EQ(la->verdicts.at(p.object, p.group, p.light).verdict, lb->verdicts.at(w.object, w.group, w.light).verdict);
            ++compared;
            culled += p.passedSamples == 0;
        }
        each(a, c);
    }
}

SpaceBuilder denseJaggedWorld(uint64_t seed);

// Dense jagged worlds, seeds 1 to n.
void addDenseWorlds(std::vector<NamedScene>& scenes, uint64_t n) {
    for (uint64_t seed = 1; seed <= n; ++seed) scenes.push_back({"dense", [seed] { return denseJaggedWorld(seed); }});
}

// Random worlds (odd seeds) and gappy ones (even seeds), seeds first to last.
void addRandomWorlds(std::vector<NamedScene>& scenes, uint64_t first, uint64_t last) {
    for (uint64_t seed = first; seed <= last; ++seed)
        scenes.push_back({seed % 2 ? "random" : "gappy", [seed] { return seed % 2 ? randomWorld(seed) : gappyWorld(seed); }});
}

TEST(GpuConfirm, PruningChangesNoCount) {
    REQUIRE_GL();
    std::vector<NamedScene> scenes = gpuKnownAnswerScenes();
    scenes.push_back({"sample", sampleSpace});
    addRandomWorlds(scenes, 1, 4);
    addDenseWorlds(scenes, 2);  // sheets behind the casters piece by piece (behindCasters)
    gpu::GpuConfirmOptions pruned;
    pruned.resolution = 128;
    pruned.includeTerrain = true;
    gpu::GpuConfirmOptions whole = pruned;
    whole.collectViewStats = true;
    int compared = 0, culled = 0;
    expectSameCounts(scenes, pruned, whole, compared, culled, [](const gpu::GpuConfirmStage&, const gpu::GpuConfirmStage&) {});
    EXPECT_GT(compared, 100);
    EXPECT_GT(culled, 0);
}

// A dense scanned-looking scene for the GPU stage at 256 px (0.4 m per pixel): jagged
// sheets of 7,200 triangles (5 cm quads, heights zigzagging by 4 cm), tilted, resting on,
// sunk into and floating over hilly terrain, with boxes between them; a tilted sun and a
// lamp. Most triangles are far below a pixel, so the occluder sheets split into slivers.
SpaceBuilder denseJaggedWorld(uint64_t seed) {
    DeterministicRng rng(seed * 104729);
    SpaceBuilder b;
    auto hills = [](double x, double z) { return 1.5 + 1.2 * std::sin(x / 9.0) * std::cos(z / 11.0); };
    b.addTerrain(0, 0, 9, hills, 0.0, 3.0);
    MeshSpec sheet;
    {
        const int n = 60;
        const double cell = 0.05, zig = 0.04;
        const int g = sheet.addGroup(GroupSpec{});
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) sheet.addVertex({i * cell, ((i + j) % 2) * zig, j * cell});
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const int a = j * (n + 1) + i, c = a + n + 1;
                sheet.addTriangle(a, c, a + 1, g);
                sheet.addTriangle(a + 1, c, c + 1, g);
            }
    }
    b.addMesh("sheet", sheet);
    b.addMesh("box", MeshSpec::box({0, 0, 0}, {1.5, 1.0, 1.5}));
    for (int k = 0; k < 10; ++k) {
        const double x = rng.uniform(35, 65), z = rng.uniform(35, 65);
        const double ground = b.terrainHeightAt(x, z).value_or(0.0);
        const int where = rng.below(3);  // resting, sunk, floating
        const double y = where == 0 ? ground : where == 1 ? ground - rng.uniform(0.1, 0.6) : ground + rng.uniform(0.5, 4);
        const Affine place = Affine::rotationY(rng.uniform(0, 360));
        b.addModel(k % 3 == 2 ? "box" : "sheet", place.then(Affine::translation({x, y, z})));
    }
    b.addLight(LightSpec::directional("sun", {rng.uniform(-0.5, 0.5), -1, rng.uniform(-0.5, 0.5)}).withBias(0.02));
    b.addLight(LightSpec::point("lamp", {rng.uniform(45, 55), rng.uniform(6, 9), rng.uniform(45, 55)}, 30).withBias(0.02));
    return b;
}


// Sheets that hold no whole pixel block nothing: leaving them out changes no count and no
// blocked pixel, whole views drawn (on the dense scenes it leaves out many sheets).
TEST(GpuConfirm, SliverSheetsBlockNothing) {
    REQUIRE_GL();
    std::vector<NamedScene> scenes = gpuKnownAnswerScenes();
    addDenseWorlds(scenes, 2);
    gpu::GpuConfirmOptions dropped;
    dropped.resolution = 256;
    dropped.collectViewStats = true;
    gpu::GpuConfirmOptions kept = dropped;
    kept.dropSliverSheets = false;
    int compared = 0, culled = 0, fewer = 0;
    expectSameCounts(scenes, dropped, kept, compared, culled, [&](const gpu::GpuConfirmStage& a, const gpu::GpuConfirmStage& c) {
        ASSERT_EQ(a.viewStats().size(), c.viewStats().size());
        for (size_t v = 0; v < a.viewStats().size(); ++v) {
            EXPECT_EQ(a.viewStats()[v].occluderPixels, c.viewStats()[v].occluderPixels) << "view " << v;
            EXPECT_LE(a.viewStats()[v].occluderSheets, c.viewStats()[v].occluderSheets);
            fewer += a.viewStats()[v].occluderSheets < c.viewStats()[v].occluderSheets;
        }
    });
    EXPECT_GT(compared, 20);
    EXPECT_GT(culled, 0);
    EXPECT_GT(fewer, 0) << "the dense scenes should have sliver sheets";
}

// The triangles found through the meshes' trees are all that can reach the examined
// pixels: with the trees and with every triangle of every near object classified, every
// examined bit has the same lit and passed counts, verdict and passed pixels (which aim the
// dense witness search). Dense jagged scenes (sun and lamp, where most of a neighbour lies
// away from the examined pixels), the known-answer scenes and random worlds (mirrored,
// scaled, sunk, non-manifold meshes); terrains examined too, so that large casters are.
TEST(GpuConfirm, TreeSelectionChangesNothing) {
    REQUIRE_GL();
    std::vector<NamedScene> scenes = gpuKnownAnswerScenes();
    addDenseWorlds(scenes, 3);
    addRandomWorlds(scenes, 5, 8);
    gpu::GpuConfirmOptions tree;
    tree.resolution = 256;
    tree.includeTerrain = true;
    gpu::GpuConfirmOptions every = tree;
    every.treeSelection = false;
    int compared = 0, culled = 0, fewer = 0;
    expectSameCounts(scenes, tree, every, compared, culled, [&](const gpu::GpuConfirmStage& a, const gpu::GpuConfirmStage& c) {
        for (size_t q = 0; q < a.passedPixels().size(); ++q) {
            const auto &p = a.passedPixels()[q].pixels, &r = c.passedPixels()[q].pixels;
            ASSERT_EQ(p.size(), r.size()) << "bit " << q;
            for (size_t k = 0; k < p.size(); ++k) {
                EXPECT_EQ(std::make_tuple(p[k].view, p[k].px, p[k].py), std::make_tuple(r[k].view, r[k].px, r[k].py));
                EXPECT_EQ(p[k].lsPoint, r[k].lsPoint);
            }
        }
        EXPECT_LE(a.trianglesClassified(), c.trianglesClassified());
        fewer += a.trianglesClassified() < c.trianglesClassified();
    });
    EXPECT_GT(compared, 40);
    EXPECT_GT(culled, 0);
    EXPECT_GE(fewer, 2) << "the trees should leave out the triangles away from the examined pixels";
}

// The window slides: the stage keeps the edge adjacency of the meshes the window still
// holds and drops the rest (each chunk's terrain), so memory follows the window.
TEST(GpuConfirm, EdgesFollowTheWindow) {
    REQUIRE_GL();
    const fs::path dir = freshTestDir("-slide");
    manyChunks(5).write(dir.string());
    Expected<Space> space = loadSpace(dir.string(), "");
    ASSERT_TRUE(space) << space.error().what();
    TerrainMeshes terrain;
    gpu::GpuConfirmStage stage({64});
    size_t held = 0;
    for (ChunkCoord c : {ChunkCoord{0, 0}, ChunkCoord{4, 4}, ChunkCoord{3, 3}}) {
        const BakeWindow w = buildWindow(*space, c, terrain);
        ChunkVerdicts cv = makeChunkVerdicts(*space, w);
        StageStats st;
        ASSERT_TRUE(stage.run(w, cv, st));
        ASSERT_GT(st.bitsExamined, 0u);
        EXPECT_LE(stage.meshesWithEdges(), w.meshes().size()) << "window " << c.x << "," << c.z;
        EXPECT_LE(stage.meshesWithTrees(), w.meshes().size()) << "window " << c.x << "," << c.z;
        held = std::max(held, stage.meshesWithEdges());
    }
    EXPECT_GT(held, 0u);
}

// --- Render --------------------------------------------------------------------------------

std::vector<unsigned char> readPngRgb(const std::string& path, int& w, int& h) {
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    std::vector<unsigned char> px;
    if (!png_image_begin_read_from_file(&img, path.c_str())) return px;
    img.format = PNG_FORMAT_RGB;
    px.resize(PNG_IMAGE_SIZE(img));
    if (!png_image_finish_read(&img, nullptr, px.data(), 0, nullptr)) px.clear();
    w = int(img.width), h = int(img.height);
    return px;
}

TEST(GpuRender, ColoursTheLightViewByVerdict) {
    REQUIRE_GL();
    std::unique_ptr<Loaded> l = load(hiddenUnderRoof(Roof::Opaque));
    ASSERT_TRUE(l);
    // Terrain culled (red), roof kept (green), cube undecided (yellow, if visible at all).
    decide(l->verdicts.at(l->object("terrain"), 0, 0), Verdict::Culled, "test", "");
    decide(l->verdicts.at(l->object(fixedUuid(2)), 0, 0), Verdict::Kept, "test", "");
    const std::string png = (freshTestDir("png") / "sun.png").string();
    gpu::RenderRequest rq;
    rq.resolution = 128;
    Expected<gpu::RenderReport> r = gpu::renderLightView(l->window, l->verdicts, rq, png);
    ASSERT_TRUE(r) << r.error().what();
    int w = 0, h = 0;
    const std::vector<unsigned char> px = readPngRgb(png, w, h);
    ASSERT_FALSE(px.empty());
    EXPECT_EQ(w, r->width);
    EXPECT_EQ(h, r->height);
    EXPECT_EQ(r->tile, 128);
    // The view tile only: the title and legend around it have swatches of the same colours.
    int red = 0, green = 0, other = 0;
    for (int y = r->viewY; y < r->viewY + 128; ++y)
        for (int x = r->viewX; x < r->viewX + 128; ++x) {
            const size_t k = (size_t(y) * size_t(w) + size_t(x)) * 3;
            const int R = px[k], G = px[k + 1], B = px[k + 2];
            if (R > 2 * G && R > 2 * B) ++red;
            else if (G > 2 * R && G > 2 * B) ++green;
            else ++other;
        }
    EXPECT_GT(red, 128 * 128 / 2) << "the terrain fills most of the view";
    EXPECT_GT(green, 100) << "the 20 m roof of a 100 m chunk";
    // A point light: six faces, 3 x 2.
    std::unique_ptr<Loaded> lamp = load(lampOverRoof(false), "lamp");
    ASSERT_TRUE(lamp);
    const std::string png2 = (freshTestDir("lamp-png") / "lamp.png").string();
    rq.resolution = 32;
    Expected<gpu::RenderReport> r2 = gpu::renderLightView(lamp->window, lamp->verdicts, rq, png2);
    ASSERT_TRUE(r2) << r2.error().what();
    EXPECT_EQ(r2->cols, 3);
    EXPECT_EQ(r2->rows, 2);
    // Bad light number.
    rq.light = 3;
    Expected<gpu::RenderReport> bad = gpu::renderLightView(l->window, l->verdicts, rq, png);
    ASSERT_FALSE(bad);
    EXPECT_EQ(bad.error().kind, ErrorKind::BadInput);
}

}  // namespace
