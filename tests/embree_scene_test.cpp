// The raycast stage's Embree scenes (raycast/embree_scene.h): dense prototypes built
// compact, built again in full once they have had their rays' worth, and the same hits
// either way.

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "raycast/embree_scene.h"

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

// Closest hits of rays falling onto both objects from above at slants.
std::vector<Hit> trace(RTCScene scene) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> x(-2.0f, 200.0f), slant(-0.4f, 0.4f);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    std::vector<Hit> hits;
    for (int k = 0; k < 20000; ++k) {
        RTCRayHit rh{};
        rh.ray.org_x = x(rng);
        rh.ray.org_y = 5.0f;
        rh.ray.org_z = x(rng);
        rh.ray.dir_x = slant(rng);
        rh.ray.dir_y = -1.0f;
        rh.ray.dir_z = slant(rng);
        rh.ray.tfar = 1e30f;
        rh.ray.mask = 0xffffffffu;
        rh.hit.geomID = rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
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

}  // namespace
}  // namespace shadowcull
