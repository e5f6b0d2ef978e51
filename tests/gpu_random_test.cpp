// gpu/ on random worlds: no bit with a witness ray culled on random little worlds (hills,
// mirrored, sunk, floating, alpha-tested, two-sided, open and non-manifold meshes; roofs of
// slabs with 5 mm to 5 cm gaps) and on dense jagged ones; pruning, sliver sheets and the
// tree selection changing nothing; the window's edges; the light-view render.
// Every test that needs GL skips, saying why, where no offscreen context can be made.

#include "io/scene_reader.h"
#include "tests/support/gpu_scenes.h"

using namespace shadowcull;
using namespace shadowcull::testing;
namespace fs = std::filesystem;

namespace {

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

