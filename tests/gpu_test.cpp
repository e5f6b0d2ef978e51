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
// Random worlds, pruning, the window's edges and the render: gpu_random_test.cpp.
// Every test that needs GL skips, saying why, where no offscreen context can be made.

#include <random>

#include "gpu/conservative.h"
#include "tests/support/gpu_scenes.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {


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

// The shape drawn for a piece (RasterPiece::cover) holds every pixel centre whose square,
// widened as the fragment shader's widest test does (0.5 + dilation + margin), touches the
// piece: the fragments a pass keeps do not depend on the cover. Long diagonal segments
// (crack edges), slivers and ordinary triangles, with and without a dilation, in
// double against the covers' float corners. (CPU only: no GL.)
TEST(GpuConservative, EveryCoverHoldsThePixelsItsPieceCanTouch) {
    gpu::LightView view;  // orthographic straight down: pixel (x, y) = (p.x, -p.z)
    view.u0 = 0, view.u1 = 512, view.v0 = 0, view.v1 = 512, view.w0 = -10, view.w1 = 10;
    view.width = view.height = 512;
    const gpu::PieceBuilder pb(view, 0.0);
    std::mt19937 rng(38);
    std::uniform_real_distribution<double> at(-20.0, 530.0), len(0.0, 1.0);
    auto point = [&](double x, double y) { return glm::dvec3(x, 0.1 * len(rng), -y); };
    auto insideQuad = [](const float* c, double x, double y) {  // strip order 0, 1, 3, 2: convex
        const int o[4] = {0, 1, 3, 2};
        double sign = 0;
        for (int k = 0; k < 4; ++k) {
            const float *a = c + 2 * o[k], *b = c + 2 * o[(k + 1) % 4];
            const double cross = (double(b[0]) - a[0]) * (y - a[1]) - (double(b[1]) - a[1]) * (x - a[0]);
            if (cross == 0) continue;
            if (sign == 0) sign = cross;
            if ((cross > 0) != (sign > 0)) return false;
        }
        return true;
    };
    size_t pieces = 0, centres = 0;
    for (int i = 0; i < 300; ++i) {
        std::vector<gpu::RasterPiece> out;
        const double x = at(rng), y = at(rng), l = 400 * len(rng) * len(rng), a = 6.283185307179586 * len(rng);
        const glm::dvec3 p0 = point(x, y), p1 = point(x + l * std::cos(a), y + l * std::sin(a));
        const float dilate = i % 3 == 0 ? float(3 * len(rng)) : 0.0f;
        if (i % 2 == 0) pb.segment(p0, p1, out);
        else {  // a sliver (width up to 0.3 px) or an ordinary triangle
            const double w = i % 4 == 1 ? 0.3 * len(rng) : 60 * len(rng), t = len(rng);
            pb.triangle(p0, p1, point(x + t * l * std::cos(a) - w * std::sin(a), y + t * l * std::sin(a) + w * std::cos(a)),
                        dilate, 0, out);
        }
        pieces += out.size();
        for (const gpu::RasterPiece& r : out) {
            const double h = 0.5 + double(r.misc[0]) + double(r.misc[1]);
            for (int py = int(std::floor(r.box[1] - h - 2)); py <= int(std::ceil(r.box[3] + h + 2)); ++py)
                for (int px = int(std::floor(r.box[0] - h - 2)); px <= int(std::ceil(r.box[2] + h + 2)); ++px) {
                    const double cx = px + 0.5, cy = py + 0.5;
                    // Separating axes: x, y (the box) and the edge normals with their extents.
                    bool touches = cx + h >= r.box[0] && cx - h <= r.box[2] && cy + h >= r.box[1] && cy - h <= r.box[3];
                    for (int k = 0; k < 3 && touches; ++k) {
                        const float* e = r.edge[k];
                        const double t = double(e[0]) * cx + double(e[1]) * cy, rr = h * (std::abs(e[0]) + std::abs(e[1]));
                        touches = t + rr >= e[2] && t - rr <= e[3];
                    }
                    if (!touches) continue;
                    ++centres;
                    EXPECT_TRUE(insideQuad(r.cover, cx, cy))
                        << "piece " << i << " (kind " << r.misc[2] << "), pixel " << px << "," << py;
                }
        }
    }
    EXPECT_GT(pieces, 250u);
    EXPECT_GT(centres, 10000u);
}

}  // namespace
