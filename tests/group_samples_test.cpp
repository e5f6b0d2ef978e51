// Sample points for witness rays: on the group, spread by area, deterministic.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "cli/pipeline.h"
#include "io/scene_reader.h"
#include "raycast/embree_scene.h"
#include "raycast/group_samples.h"
#include "tests/support/bake_lookup.h"
#include "tests/support/space_builder.h"
#include "tests/test_files.h"

using namespace shadowcull;

namespace {

// Two groups: group 0 a 10 x 10 square (two triangles), group 1 a 0.005 x 2 sliver.
Mesh twoGroupMesh() {
    Mesh m;
    m.positions = {{0, 0, 0}, {10, 0, 0}, {10, 0, 10}, {0, 0, 10}, {20, 0, 0}, {20.005, 0, 0}, {20.005, 0, 2}, {20, 0, 2}};
    m.triangles = {{0, 2, 1}, {0, 3, 2}, {4, 6, 5}, {4, 7, 6}, {0, 0, 1}};
    m.triangleGroup = {0, 0, 1, 1, 1};  // the last triangle repeats a vertex
    m.groups = {PrimitiveGroup{"square", false, false, std::nullopt}, PrimitiveGroup{"rod", false, false, std::nullopt}};
    return m;
}

bool onTriangleOfGroup(const WindowObject& o, uint32_t group, const glm::dvec3& p) {
    for (size_t t = 0; t < o.mesh->triangles.size(); ++t) {
        if (o.mesh->triangleGroup[t] != group) continue;
        const auto& i = o.mesh->triangles[t];
        glm::dvec3 a = o.lsTransform.apply(o.mesh->positions[i[0]]), b = o.lsTransform.apply(o.mesh->positions[i[1]]),
                   c = o.lsTransform.apply(o.mesh->positions[i[2]]);
        glm::dvec3 n = glm::cross(b - a, c - a);
        double area2 = glm::length(n);
        if (area2 == 0) continue;
        double dist = std::abs(glm::dot(p - a, n / area2));
        double u = glm::dot(glm::cross(c - b, p - b), n) / (area2 * area2);
        double v = glm::dot(glm::cross(a - c, p - c), n) / (area2 * area2);
        double w = 1 - u - v;
        if (dist < 1e-9 && u > 0 && v > 0 && w > 0) return true;  // strictly inside
    }
    return false;
}

}  // namespace

TEST(GroupSamples, LieStrictlyInsideTheGroupsTriangles) {
    Mesh m = twoGroupMesh();
    WindowObject o;
    o.mesh = &m;
    o.lsTransform.rows[3] = glm::dvec3(100, 5, -3);
    for (uint32_t g : {0u, 1u}) {
        auto s = raycast::sampleGroup(o, g, 64, 64);
        ASSERT_FALSE(s.empty());
        for (const glm::dvec3& p : s) EXPECT_TRUE(onTriangleOfGroup(o, g, p)) << "group " << g;
    }
}

TEST(GroupSamples, AreaSamplesAreSpreadByArea) {
    Mesh m = twoGroupMesh();
    WindowObject o;
    o.mesh = &m;
    auto s = raycast::sampleGroup(o, 0, 256, 0);
    ASSERT_EQ(s.size(), 256u);
    // Each quadrant of the square gets a quarter of the samples, give or take a few.
    int quadrant[4] = {0, 0, 0, 0};
    for (const glm::dvec3& p : s) quadrant[(p.x >= 5 ? 1 : 0) + (p.z >= 5 ? 2 : 0)]++;
    for (int q : quadrant) EXPECT_NEAR(q, 64, 12);
    // Every prefix is spread too: the first 16 samples reach both triangles.
    int lower = 0;
    for (int k = 0; k < 16; ++k) lower += s[size_t(k)].x > s[size_t(k)].z;
    EXPECT_GT(lower, 3);
    EXPECT_LT(lower, 13);
}

TEST(GroupSamples, DegenerateTrianglesGetNoSamplesAndSamplingIsDeterministic) {
    Mesh m = twoGroupMesh();
    WindowObject o;
    o.mesh = &m;
    auto a = raycast::sampleGroup(o, 1, 32, 100);
    auto b = raycast::sampleGroup(o, 1, 32, 100);
    EXPECT_EQ(a, b);
    EXPECT_EQ(a.size(), 32u + 12u);  // two rod triangles x 6 features; the degenerate one none
    Mesh only;
    only.positions = {{0, 0, 0}, {1, 0, 0}};
    only.triangles = {{0, 1, 1}};
    only.triangleGroup = {0};
    only.groups = {PrimitiveGroup{}};
    o.mesh = &only;
    EXPECT_TRUE(raycast::sampleGroup(o, 0, 32, 32).empty());
}

TEST(GroupSamples, TheCacheSamplesEachMeshOnceAndPlacesItPerObject) {
    Mesh m = twoGroupMesh();
    WindowObject a, b;
    a.mesh = b.mesh = &m;
    a.lsTransform.rows[3] = glm::dvec3(100, 5, -3);
    b.lsTransform.rows[0] = glm::dvec3(0, 0, 1);  // a quarter turn about y, elsewhere
    b.lsTransform.rows[2] = glm::dvec3(-1, 0, 0);
    b.lsTransform.rows[3] = glm::dvec3(-40, 2, 7);
    raycast::GroupSampleCache cache(32, 100);
    for (const WindowObject* o : {&a, &b})
        for (uint32_t g : {0u, 1u}) EXPECT_EQ(cache.placed(*o, g), raycast::sampleGroup(*o, g, 32, 100));
    EXPECT_EQ(cache.meshGroups(), 2u);  // one entry per (mesh, group), not per placement
    // The same mesh points, placed: b's first point is a's first point moved by b's placement.
    const glm::dvec3 local = raycast::sampleMeshGroup(m, 0, 32, 100)[0];
    EXPECT_EQ(cache.placed(b, 0)[0], b.lsTransform.apply(local));
    EXPECT_EQ(cache.placed(a, 0)[0], a.lsTransform.apply(local));
}

// A search places its own samples a prefix at a time (placeSamples): every prefix, and
// the whole list at the end, the very points placed() gives at once; asking for fewer than
// are placed, or more than there are, changes nothing.
TEST(GroupSamples, PlacedAPrefixAtATimeTheSameAsAtOnce) {
    Mesh m = twoGroupMesh();
    WindowObject b;
    b.mesh = &m;
    b.lsTransform.rows[0] = glm::dvec3(0, 0, 1);
    b.lsTransform.rows[2] = glm::dvec3(-1, 0, 0);
    b.lsTransform.rows[3] = glm::dvec3(-40, 2, 7);
    raycast::GroupSampleCache cache(32, 100);
    for (uint32_t g : {0u, 1u}) {
        const std::vector<glm::dvec3>& ms = cache.meshPoints(m, g);
        const std::vector<glm::dvec3> all = cache.placed(b, g);
        ASSERT_GT(all.size(), 20u);
        std::vector<glm::dvec3> placed;
        for (size_t n : {size_t(0), size_t(16), size_t(5), size_t(17), all.size() - 1, all.size() + 64}) {
            raycast::placeSamples(b, ms, n, placed);
            const size_t expect = std::min(all.size(), std::max<size_t>(n, n == 5 ? 16 : 0));
            ASSERT_EQ(placed.size(), expect) << "asked for " << n;
            EXPECT_TRUE(std::equal(placed.begin(), placed.end(), all.begin())) << "asked for " << n;
        }
    }
}

// The window slides: prototypes of the meshes it left behind (each chunk's terrain) are
// released, so the scenes held follow the window, not the world.
TEST(EmbreeScenes, PrototypesFollowTheWindow) {
    const std::filesystem::path dir = shadowcull::testing::freshTestDir();
    shadowcull::testing::manyChunks(5).write(dir.string());
    Expected<Space> space = loadSpace(dir.string(), "");
    ASSERT_TRUE(space) << space.error().what();
    RTCDevice device = rtcNewDevice(nullptr);
    ASSERT_NE(device, nullptr);
    {
        raycast::EmbreeScenes scenes(device);
        TerrainMeshes terrain;
        auto meshesOf = [](const BakeWindow& w) { return w.meshes().size(); };
        const BakeWindow corner = buildWindow(*space, ChunkCoord{0, 0}, terrain);
        raycast::WindowScene a = scenes.buildWindow(corner);
        EXPECT_EQ(scenes.prototypeCount(), meshesOf(corner));  // 4 terrains and the cube
        a.reset();
        const BakeWindow far = buildWindow(*space, ChunkCoord{4, 4}, terrain);
        raycast::WindowScene b = scenes.buildWindow(far);
        EXPECT_EQ(scenes.prototypeCount(), meshesOf(far)) << "the first window's terrains are still held";
        const BakeWindow middle = buildWindow(*space, ChunkCoord{3, 3}, terrain);
        b.reset();
        raycast::WindowScene c = scenes.buildWindow(middle);
        EXPECT_EQ(scenes.prototypeCount(), meshesOf(middle));  // 9 terrains (4 kept from the last) and the cube
    }
    rtcReleaseDevice(device);
}

// --- Points within a point light's reach (issue 13) -----------------------------------------

namespace {

using shadowcull::testing::Affine;
using shadowcull::testing::GroupSpec;
using shadowcull::testing::LightSpec;
using shadowcull::testing::MeshSpec;
using shadowcull::testing::SpaceBuilder;

// An 80 m sheet of 3,200 triangles 2 m up, a floor 0.5 m under it, and a lamp of range 4 m
// over the sheet's far corner: the sheet's own points (by area over 6,400 m², and the
// vertices of its first triangles) miss the 30 m² the lamp reaches.
SpaceBuilder sheetUnderASmallLamp() {
    SpaceBuilder b;
    b.addLight(LightSpec::point("lamp", {86, 4, 86}, 4));
    b.addMesh("sheet", MeshSpec::jaggedSheet(40, 2.0, 0.0));
    b.addMesh("floor", MeshSpec::quad({0, 0, 0}, {0, 0, 100}, {100, 0, 100}, {100, 0, 0}));
    b.addModel("floor", Affine::translation({0, 1.5, 0}));
    return b;
}

}  // namespace

TEST(GroupSamples, PointsWithinReachLieOnTheTrianglesTheLightReaches) {
    Mesh m;
    const MeshSpec spec = MeshSpec::jaggedSheet(40, 2.0, 0.0);
    for (const glm::dvec3& p : spec.positions) m.positions.push_back(p);
    for (const auto& t : spec.triangles) m.triangles.push_back({{uint32_t(t[0]), uint32_t(t[1]), uint32_t(t[2])}});
    m.triangleGroup.assign(m.triangles.size(), 0);
    m.groups = {PrimitiveGroup{}};
    WindowObject o;
    o.mesh = &m;
    o.lsTransform.rows[3] = glm::dvec3(10, 2, 10);
    Light lamp;
    lamp.type = LightType::Point;
    lamp.position = {86, 4, 86};
    lamp.range = 4;
    const auto own = raycast::sampleGroup(o, 0, 256, 1024);
    const auto within = raycast::sampleGroupWithinReach(o, 0, lamp, 256, 1024);
    size_t ownWithin = 0;
    for (const glm::dvec3& p : own) ownWithin += glm::length(p - lamp.position) <= lamp.range;
    EXPECT_LE(ownWithin, 2u);  // what the whole group's points give
    ASSERT_GT(within.size(), 256u);  // by area, then 6 features per reached triangle (32 here)
    EXPECT_EQ((within.size() - 256) % 6, 0u);
    size_t inRange = 0;
    for (const glm::dvec3& p : within) {
        EXPECT_TRUE(onTriangleOfGroup(o, 0, p));
        // On a reached triangle: at most a cell's diagonal beyond the range.
        EXPECT_LE(glm::length(p - lamp.position), lamp.range + 2 * std::sqrt(2.0) + 1e-9);
        inRange += glm::length(p - lamp.position) <= lamp.range;
    }
    EXPECT_GT(inRange, within.size() / 3);
    EXPECT_EQ(within, raycast::sampleGroupWithinReach(o, 0, lamp, 256, 1024));  // deterministic
    // Nothing for a directional light, nor beyond the range.
    Light sun;
    EXPECT_TRUE(raycast::sampleGroupWithinReach(o, 0, sun, 256, 1024).empty());
    lamp.position = {200, 4, 200};
    EXPECT_TRUE(raycast::sampleGroupWithinReach(o, 0, lamp, 256, 1024).empty());
}

// Through the pipeline, the group's own witness rays alone: the sheet shades the floor
// under the lamp, a witness only points within the lamp's reach find (before, the bit was
// left to the receiver-side search and the next stages).
TEST(GroupSamples, AWitnessWithinAPointLightsReachIsFound) {
    SpaceBuilder b = sheetUnderASmallLamp();
    const std::string sheet = b.addModel("sheet", Affine::translation({10, 2, 10}));
    const std::filesystem::path dir = shadowcull::testing::freshTestDir();
    b.write((dir / "space").string());
    cli::BakeOptions opt;
    opt.spaceDir = (dir / "space").string();
    opt.write = false;
    opt.useGeometry = false;
    opt.useGpu = false;
    opt.raycast.receiverSamples = 0;  // the group's own points alone (the floor's would find it too)
    Expected<cli::BakeResult> r = cli::runBake(opt);
    ASSERT_TRUE(r) << r.error().what();
    const Decision* d = shadowcull::testing::findDecision(*r, b.locateObjects().at(sheet), 0, 0);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->verdict, Verdict::Kept);
    ASSERT_NE(d->witness(), nullptr);
    EXPECT_LE(glm::length(d->witness()->wsP - glm::dvec3(86, 4, 86)), 4.0);
}
