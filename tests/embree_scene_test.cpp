// The raycast stage's Embree scenes (raycast/embree_scene.h): dense prototypes built
// compact, built again in full once they have had their rays' worth, and the same hits
// either way.

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "raycast/embree_scene.h"
#include "util/float_mode.h"

namespace shadowcull {
namespace {

// An n x n jagged sheet (heights zigzag by 3 cm), 1 m cells, one group: 2 n^2 triangles.
Mesh sheet(int n) {
    Mesh m;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) m.positions.push_back({double(i), (i + j) % 2 ? 0.03 : 0.0, double(j)});
    auto at = [&](int i, int j) { return uint32_t(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            m.triangles.push_back({at(i, j), at(i, j + 1), at(i + 1, j + 1)});
            m.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i + 1, j)});
        }
    m.triangleGroup.assign(m.triangles.size(), 0);
    m.groups = {PrimitiveGroup{"ground", false, false, std::nullopt}};
    return m;
}

struct Hit {
    unsigned inst, prim;
    float t, u, v;
    bool operator==(const Hit& o) const { return std::memcmp(this, &o, sizeof *this) == 0; }
};

// A ray from (x, 5, z) falling along (sx, -1, sz), to any distance, no hit yet.
RTCRayHit fallingRay(float x, float z, float sx, float sz) {
    RTCRayHit rh{};
    rh.ray.org_x = x;
    rh.ray.org_y = 5.0f;
    rh.ray.org_z = z;
    rh.ray.dir_x = sx;
    rh.ray.dir_y = -1.0f;
    rh.ray.dir_z = sz;
    rh.ray.tfar = 1e30f;
    rh.ray.mask = 0xffffffffu;
    rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

// Closest hits of rays falling onto both objects from above at slants.
std::vector<Hit> trace(RTCScene scene) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> x(-2.0f, 200.0f), slant(-0.4f, 0.4f);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    std::vector<Hit> hits;
    for (int k = 0; k < 20000; ++k) {
        const float ox = x(rng), oz = x(rng), sx = slant(rng), sz = slant(rng);
        RTCRayHit rh = fallingRay(ox, oz, sx, sz);
        rtcIntersect1(scene, &ctx, &rh);
        std::memset(&hits.emplace_back(), 0, sizeof(Hit));
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
        hits.back() = Hit{rh.hit.instID[0], rh.hit.primID, rh.ray.tfar, rh.hit.u, rh.hit.v};
    }
    return hits;
}

TEST(EmbreeScenes, DensePrototypesStartCompactAndGoFullAfterTheirRays) {
    const Mesh dense = sheet(182), small = sheet(20);  // 66,248 and 800 triangles
    ASSERT_GE(dense.triangles.size(), raycast::EmbreeScenes::kCompactFrom);
    BakeWindow w;
    for (const Mesh* m : {&dense, &small}) {
        WindowObject o;
        o.mesh = m;
        o.lsTransform.rows = {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1),
                              glm::dvec3(m == &dense ? 0.0 : 185.0, 0.0, 0.0)};
        w.objects.push_back(o);
    }
    RTCDevice device = rtcNewDevice(nullptr);
    ASSERT_NE(device, nullptr);
    {
        raycast::EmbreeScenes scenes(device);
        raycast::WindowScene first = scenes.buildWindow(w);
        EXPECT_TRUE(scenes.isCompact(&dense));
        EXPECT_FALSE(scenes.isCompact(&small));
        const std::vector<Hit> compactHits = trace(first.all());
        first.reset();
        size_t hitDense = 0, hitSmall = 0;
        for (const Hit& h : compactHits)
            if (h.t > 0) ++(h.inst == 0 ? hitDense : hitSmall);
        EXPECT_GT(hitDense, 1000u);
        EXPECT_GT(hitSmall, 10u);
        // Fewer rays than its threshold: still compact.
        const uint64_t threshold = raycast::EmbreeScenes::kFullAfterRays * dense.triangles.size();
        scenes.noteRays(threshold - 1);
        scenes.buildWindow(w).reset();
        EXPECT_TRUE(scenes.isCompact(&dense));
        // Its rays' worth: built again in full, and every hit the same, bit for bit.
        scenes.noteRays(1);
        raycast::WindowScene full = scenes.buildWindow(w);
        EXPECT_FALSE(scenes.isCompact(&dense));
        EXPECT_TRUE(trace(full.all()) == compactHits);
        full.reset();
        // For the rest of the bake.
        scenes.noteRays(100 * threshold);
        scenes.buildWindow(w).reset();
        EXPECT_FALSE(scenes.isCompact(&dense));
    }
    rtcReleaseDevice(device);
}

// The opaque scene names a hit by the triangle's index among its mesh's opaque ones;
// WindowScene::meshTriangle maps it back. A sheet whose rows alternate between an
// alpha-tested and an opaque group (so the index shifts by a different amount on every
// row), placed twice, once as an object that casts no shadow, and a plain sheet: every
// closest hit in the opaque scene, mapped, is the closest hit in the whole scene that
// skips what lets light pass (skipTransparent), bit for bit: the hit the raycast stage's
// search for p takes from either.
TEST(EmbreeScenes, OpaqueHitsNameTheirMeshTriangles) {
    Mesh striped = sheet(20);
    striped.groups = {PrimitiveGroup{"leaves", true, false, std::nullopt}, PrimitiveGroup{"bark", false, false, std::nullopt}};
    for (size_t t = 0; t < striped.triangles.size(); ++t) striped.triangleGroup[t] = (t / 40) % 2 == 0 ? 0 : 1;
    const Mesh plain = sheet(20);
    BakeWindow w;
    w.hasAlphaTested = w.hasNonCasters = true;
    const std::pair<const Mesh*, double> placed[] = {{&striped, 0.0}, {&plain, 25.0}, {&striped, 50.0}};
    for (const auto& [mesh, x] : placed) {
        WindowObject o;
        o.mesh = mesh;
        o.lsTransform.rows = {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1), glm::dvec3(x, 0.0, 0.0)};
        o.castsShadow = x < 40.0;
        w.objects.push_back(o);
    }
    RTCDevice device = rtcNewDevice(nullptr);
    ASSERT_NE(device, nullptr);
    {
        raycast::EmbreeScenes scenes(device);
        const raycast::WindowScene scene = scenes.buildWindow(w);
        ASSERT_NE(scene.opaque(), scene.all());
        const FloatModeScope ftz(FloatModeScope::Underflow::FlushToZero);
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> x(-2.0f, 75.0f), z(-2.0f, 22.0f), slant(-0.4f, 0.4f);
        size_t onStriped = 0, shifted = 0, misses = 0;
        for (int k = 0; k < 20000; ++k) {
            const float ox = x(rng), oz = z(rng), sx = slant(rng), sz = slant(rng);
            RTCRayHit ray = fallingRay(ox, oz, sx, sz), whole = ray;
            RTCIntersectContext plainCtx;
            rtcInitIntersectContext(&plainCtx);
            rtcIntersect1(scene.opaque(), &plainCtx, &ray);
            raycast::TransparentSkip skip;
            rtcInitIntersectContext(&skip.ctx);
            skip.ctx.filter = &raycast::skipTransparent;
            skip.window = &w;
            skip.object = skip.group = ~0u;  // no group of its own: every surface that lets light pass is skipped
            rtcIntersect1(scene.all(), &skip.ctx, &whole);
            ASSERT_EQ(ray.hit.geomID == RTC_INVALID_GEOMETRY_ID, whole.hit.geomID == RTC_INVALID_GEOMETRY_ID) << "ray " << k;
            if (whole.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
                ++misses;
                continue;
            }
            const uint32_t object = raycast::hitObject(ray.hit.instID[0], ray.hit.geomID);
            ASSERT_EQ(object, raycast::hitObject(whole.hit.instID[0], whole.hit.geomID)) << "ray " << k;
            const uint32_t triangle = scene.meshTriangle(object, ray.hit.primID);
            EXPECT_EQ(triangle, whole.hit.primID) << "ray " << k;
            EXPECT_EQ(ray.ray.tfar, whole.ray.tfar) << "ray " << k;
            onStriped += object == 0;
            shifted += triangle != ray.hit.primID;
            EXPECT_EQ(w.objects[object].mesh->triangleGroup[triangle], object == 0 ? 1u : 0u);  // bark, or the plain sheet
        }
        EXPECT_GT(onStriped, 1000u);
        EXPECT_GT(shifted, 1000u);  // the map did something
        EXPECT_GT(misses, 1000u);   // through the leaves, and the third sheet, to nothing
    }
    rtcReleaseDevice(device);
}

}  // namespace
}  // namespace shadowcull
