// geometry/'s broad phase: the box tree returns every item a predicate lets through, the
// mesh-tree cache follows the window, and the shadow queries (one caster triangle, or a
// cluster of a mesh tree) never skip a receiver the exact test reaches: in window-local
// boxes, in an instance's mesh coordinates (turned, scaled, mirrored, far from the
// origin), and for the cluster filters, for directional and point lights, with and
// without bias and dilation.

#include <algorithm>
#include <atomic>
#include <mutex>
#include <random>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include <gtest/gtest.h>

#include "geometry/broad_phase.h"
#include "geometry/exact_frustum.h"
#include "geometry/shadow_query.h"

using namespace shadowcull;
using namespace shadowcull::geometry;

namespace {

Aabb boxOf(const Triangle& t) {
    Aabb b;
    for (const glm::dvec3& p : t) b.extend(p);
    return b;
}

bool overlap(const Aabb& a, const Aabb& b) {
    for (int i = 0; i < 3; ++i)
        if (a.max[i] < b.min[i] || a.min[i] > b.max[i]) return false;
    return true;
}

// A random placement: a turn about a random axis, a scale of 0.3-3 per axis (mirrored
// one time in four), and a move of up to `reach` metres.
RowTransform randomPlacement(std::mt19937_64& rng, double reach) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    glm::dquat q(u(rng), u(rng), u(rng), u(rng));
    q = glm::normalize(q);
    const glm::dmat3 r = glm::mat3_cast(q);
    glm::dvec3 s(std::exp(u(rng) * 1.2), std::exp(u(rng) * 1.2), std::exp(u(rng) * 1.2));
    if (rng() % 4 == 0) s.x = -s.x;
    RowTransform m;
    // Row i is the image of mesh axis i: the scaled axis turned.
    for (int i = 0; i < 3; ++i) m.rows[size_t(i)] = r * (s[i] * glm::dvec3(i == 0, i == 1, i == 2));
    m.rows[3] = glm::dvec3(u(rng), u(rng), u(rng)) * reach;
    return m;
}

// Mesh coordinates of a window-local point (inverse of the placement, in double).
glm::dvec3 toMesh(const RowTransform& m, const glm::dvec3& x) {
    const glm::dmat3 a(m.rows[0], m.rows[1], m.rows[2]);  // columns: x = a y + r3
    return glm::inverse(a) * (x - m.rows[3]);
}

}  // namespace

TEST(ObjectTree, VisitsExactlyTheOverlappingItems) {
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(0.0, 100.0), s(0.0, 3.0);
    for (size_t n : {size_t(0), size_t(1), size_t(7), size_t(1000), size_t(40000)}) {
        std::vector<Aabb> boxes(n);
        for (Aabb& b : boxes) {
            const glm::dvec3 c(u(rng), u(rng), u(rng));
            b.min = c - glm::dvec3(s(rng), s(rng), s(rng));
            b.max = c + glm::dvec3(s(rng), s(rng), s(rng));
        }
        if (n > 3) boxes[3] = Aabb{};  // an empty box is left out
        const ObjectTree tree(boxes);
        EXPECT_EQ(tree.size(), n > 3 ? n - 1 : n);
        for (int q = 0; q < 20; ++q) {
            Aabb query;
            const glm::dvec3 c(u(rng), u(rng), u(rng));
            query.min = c - glm::dvec3(5.0);
            query.max = c + glm::dvec3(5.0);
            std::vector<int> seen(n, 0);
            tree.visit([&](const Aabb& b) { return overlap(b, query); },
                       [&](uint32_t k) {
                           ++seen[k];
                           return false;
                       });
            for (size_t k = 0; k < n; ++k)
                ASSERT_EQ(seen[k], !boxes[k].empty() && overlap(boxes[k], query) ? 1 : 0) << "n " << n << " item " << k;
        }
    }
}

// The parallel ordered walk finds the same first passing triangle as the sequential walk,
// and visits every triangle before it once (the stage's notes and proofs rest on both).
TEST(TriangleTree, OrderedParallelWalkFindsTheSequentialFirst) {
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 100.0), small(-0.5, 0.5);
    Mesh m;
    for (uint32_t k = 0; k < 20000; ++k) {
        const glm::dvec3 c(u(rng), u(rng), u(rng));
        for (int v = 0; v < 3; ++v) m.positions.push_back(c + glm::dvec3(small(rng), small(rng), small(rng)));
        m.triangles.push_back({3 * k, 3 * k + 1, 3 * k + 2});
        m.triangleGroup.push_back(0);
    }
    m.groups.resize(1);
    const TriangleTree tree(m);
    auto all = [](const Aabb&) { return true; };
    for (int trial = 0; trial < 30; ++trial) {
        std::vector<char> passes(m.triangles.size());
        const int rate = 1 + trial * 97;  // from every triangle to very few
        for (char& p : passes) p = rng() % uint64_t(rate) == 0;
        uint32_t sequentialFirst = TriangleTree::kNone;  // the triangle visit stops at
        tree.visit(all, [&](uint32_t t) {
            if (!passes[t]) return false;
            sequentialFirst = t;
            return true;
        });
        std::atomic<uint32_t> first{TriangleTree::kNone};
        std::mutex mutex;
        uint32_t firstTriangle = TriangleTree::kNone;
        std::vector<std::atomic<int>> seen(m.triangles.size());
        tree.visitNodesOrdered([](const Aabb&, uint32_t) { return true; },
                               [&](uint32_t t, uint32_t position) {
                                   seen[t].fetch_add(1);
                                   if (!passes[t]) return;
                                   const std::lock_guard<std::mutex> lock(mutex);
                                   if (position < first.load()) {
                                       first.store(position);
                                       firstTriangle = t;
                                   }
                               },
                               first, 64);
        ASSERT_EQ(firstTriangle, sequentialFirst) << "trial " << trial;
        // Every triangle the sequential walk visited before stopping was visited once.
        bool reached = false;
        tree.visit(all, [&](uint32_t t) {
            if (t == sequentialFirst) reached = true;
            if (reached) return true;
            EXPECT_EQ(seen[t].load(), 1) << "triangle " << t;
            return false;
        });
    }
}

// The geometry stage's walk of a mesh's triangles (the mesh index's tree): every triangle
// with three distinct vertices whose box meets the query box, and only those, once each;
// the ordered walk visits them in increasing positions, on any number of threads.
TEST(TriangleTree, WalksEveryTriangleTheQueryMeetsAndLeavesOutRepeatedVertices) {
    std::mt19937_64 rng(41);
    std::uniform_real_distribution<double> u(-10.0, 10.0), small(-0.4, 0.4);
    Mesh m;
    for (int k = 0; k < 3000; ++k) {
        const glm::dvec3 c(u(rng), u(rng), u(rng));
        const uint32_t v = uint32_t(m.positions.size());
        m.positions.push_back(c);
        m.positions.push_back(c + glm::dvec3(small(rng), small(rng), small(rng)));
        m.positions.push_back(c + glm::dvec3(small(rng), small(rng), small(rng)));
        m.triangles.push_back(k % 11 == 5 ? std::array<uint32_t, 3>{v, v, v + 1} : std::array<uint32_t, 3>{v, v + 1, v + 2});
        m.triangleGroup.push_back(0);
    }
    m.groups.resize(1);
    const TriangleTree tree(m);
    for (int q = 0; q < 20; ++q) {
        const glm::dvec3 c(u(rng), u(rng), u(rng));
        const Aabb query{c - glm::dvec3(3.0), c + glm::dvec3(3.0)};
        auto meets = [&](const Aabb& b) {
            return !(b.max.x < query.min.x || b.min.x > query.max.x || b.max.y < query.min.y || b.min.y > query.max.y ||
                     b.max.z < query.min.z || b.min.z > query.max.z);
        };
        std::vector<uint32_t> expected;
        for (uint32_t t = 0; t < m.triangles.size(); ++t) {
            const auto& i = m.triangles[t];
            if (hasRepeatedVertex(m.positions[i[0]], m.positions[i[1]], m.positions[i[2]])) continue;
            Aabb b;
            for (uint32_t v : i) b.extend(m.positions[v]);
            if (meets(b)) expected.push_back(t);
        }
        std::vector<uint32_t> seen;
        tree.visit(meets, [&](uint32_t t) {
            seen.push_back(t);
            return false;
        });
        std::sort(seen.begin(), seen.end());
        EXPECT_EQ(seen, expected) << "query " << q;
        // Ordered, in parallel: the same triangles (node boxes only), positions increasing
        // along the tree's order.
        std::mutex mutex;
        std::vector<std::pair<uint32_t, uint32_t>> ordered;
        const std::atomic<uint32_t> none{TriangleTree::kNone};
        tree.visitNodesOrdered([&](const Aabb& b, uint32_t) { return meets(b); },
                               [&](uint32_t t, uint32_t position) {
                                   const std::lock_guard<std::mutex> lock(mutex);
                                   ordered.emplace_back(position, t);
                               },
                               none, 64);
        std::sort(ordered.begin(), ordered.end());
        for (size_t k = 1; k < ordered.size(); ++k) EXPECT_LT(ordered[k - 1].first, ordered[k].first);
        std::vector<uint32_t> fromOrdered;
        for (const auto& [position, t] : ordered) {
            const auto& i = m.triangles[t];
            EXPECT_FALSE(hasRepeatedVertex(m.positions[i[0]], m.positions[i[1]], m.positions[i[2]]));
            fromOrdered.push_back(t);
        }
        std::sort(fromOrdered.begin(), fromOrdered.end());
        for (uint32_t t : expected) EXPECT_TRUE(std::binary_search(fromOrdered.begin(), fromOrdered.end(), t)) << t;
    }
}

// Every receiver the exact frustum reaches passes every broad-phase test of its caster
// triangle and of every cluster box holding that triangle.
TEST(ShadowQuery, NeverSkipsWhatTheExactTestReaches) {
    std::mt19937_64 rng(29);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    size_t reached = 0, pairs = 0, skippedInMesh = 0, skippedCluster = 0;
    for (int trial = 0; trial < 300; ++trial) {
        LightGeometry light;
        light.directional = trial % 3 != 0;
        light.direction = trial % 7 == 0 ? glm::dvec3(0, -1, 0) : glm::normalize(glm::dvec3(u(rng) * 0.8, -1.0, u(rng) * 0.8));
        const double dilation = trial % 5 == 0 ? 0.01 : 0.0;
        const double reach = trial % 2 == 0 ? 1.0 : 150.0;  // near the origin, or far in the window
        const double margin = 1e-9 * (reach + 10.0 + 1.0) + 1e-9;
        const RowTransform casterPlace = randomPlacement(rng, reach), receiverPlace = randomPlacement(rng, reach);
        // A cluster box in the caster's mesh coordinates, and caster triangles inside it.
        const glm::dvec3 c(u(rng), u(rng), u(rng));
        const glm::dvec3 h = glm::dvec3(0.05) + 0.3 * glm::abs(glm::dvec3(u(rng), u(rng), u(rng)));
        Aabb cluster;
        cluster.min = c - h;
        cluster.max = c + h;
        auto inCluster = [&] { return c + h * glm::dvec3(u(rng), u(rng), u(rng)); };
        const glm::dvec3 centre = casterPlace.apply(c);
        light.position = centre + glm::dvec3(u(rng), 1.5 + std::abs(u(rng)), u(rng));
        const glm::dvec3 along = light.directional ? light.direction : glm::normalize(centre - light.position);
        const ShadowQuery cq = ShadowQuery::ofCluster(cluster, casterPlace, light, dilation, margin);
        const ShadowQuery::InMesh cqMesh = cq.inMesh(receiverPlace);
        for (int ct = 0; ct < 4; ++ct) {
            const Triangle t = {casterPlace.apply(inCluster()), casterPlace.apply(inCluster()), casterPlace.apply(inCluster())};
            if (hasRepeatedVertex(t[0], t[1], t[2])) continue;
            // With a filter radius the queries hold every point within that radius of the
            // frustum (the spec's reach), not the exact test's looser dilated region: test
            // them on what reaches the frustum itself, and on receivers moved off it below.
            const ExactFrustum exact(t, light, 0.0);
            if (exact.degenerate()) continue;
            const ShadowQuery q(t, light, dilation, margin);
            const ShadowQuery::InMesh qMesh = q.inMesh(receiverPlace);
            for (int k = 0; k < 40; ++k) {
                // A receiver around and behind the caster, in the receiver instance's mesh
                // coordinates; its window-local triangle is what the stage computes.
                const glm::dvec3 p = t[size_t(k % 3)] + along * (0.05 + 2.0 * std::abs(u(rng))) +
                                     glm::dvec3(u(rng), u(rng), u(rng)) * (k % 4 == 0 ? 0.02 : 0.4);
                const double size = k % 5 == 0 ? 2.0 : 0.2;
                const Triangle y = {toMesh(receiverPlace, p), toMesh(receiverPlace, p + glm::dvec3(u(rng), u(rng), u(rng)) * size),
                                    toMesh(receiverPlace, p + glm::dvec3(u(rng), u(rng), u(rng)) * size)};
                Triangle r = {receiverPlace.apply(y[0]), receiverPlace.apply(y[1]), receiverPlace.apply(y[2])};
                if (hasRepeatedVertex(r[0], r[1], r[2])) continue;
                skippedInMesh += !qMesh.mayHold(boxOf(y));
                skippedCluster += !cqMesh.mayHold(boxOf(y));
                for (double beta : {0.0, 0.02}) {
                    ++pairs;
                    if (!exact.reaches(r, beta)) continue;
                    ++reached;
                    if (dilation > 0) {
                        // Moved by up to the radius in any direction: still within reach.
                        const glm::dvec3 shift = glm::normalize(glm::dvec3(u(rng), u(rng), u(rng))) * dilation * 0.999;
                        const Triangle moved = {r[0] + shift, r[1] + shift, r[2] + shift};
                        const Triangle movedY = {toMesh(receiverPlace, moved[0]), toMesh(receiverPlace, moved[1]),
                                                 toMesh(receiverPlace, moved[2])};
                        ASSERT_FALSE(q.misses(moved)) << "trial " << trial;
                        ASSERT_TRUE(q.mayHold(boxOf(moved))) << "trial " << trial;
                        ASSERT_TRUE(cq.mayHold(boxOf(moved))) << "trial " << trial;
                        // The mesh box of the moved receiver, grown by the inverse's rounding.
                        Aabb yb = boxOf(movedY);
                        yb.min -= glm::dvec3(1e-9);
                        yb.max += glm::dvec3(1e-9);
                        ASSERT_TRUE(qMesh.mayHold(yb)) << "trial " << trial;
                        ASSERT_TRUE(cqMesh.mayHold(yb)) << "trial " << trial;
                    }
                    ASSERT_FALSE(q.misses(r)) << "trial " << trial;
                    ASSERT_TRUE(q.mayHold(boxOf(r))) << "trial " << trial;
                    ASSERT_TRUE(qMesh.mayHold(boxOf(y))) << "trial " << trial;
                    ASSERT_TRUE(cq.mayHold(boxOf(r))) << "trial " << trial;
                    ASSERT_TRUE(cqMesh.mayHold(boxOf(y))) << "trial " << trial;
                    ASSERT_FALSE(cq.clusterMisses(r, beta)) << "trial " << trial << " beta " << beta;
                }
            }
        }
    }
    // Meaningful only if receivers are both reached and skipped often.
    EXPECT_GT(reached, pairs / 20) << pairs << " pairs";
    EXPECT_GT(skippedInMesh, pairs / 10) << pairs << " pairs";
    EXPECT_GT(skippedCluster, pairs / 20) << pairs << " pairs";
    std::printf("%zu pairs, %zu reached, %zu receivers skipped by a triangle's query, %zu by a cluster's\n", pairs, reached,
                skippedInMesh, skippedCluster);
}

// With AVX, mayHold and misses test four half-spaces (or mesh planes) at a time: every
// answer is the one-at-a-time loop's (mayHoldByLoop, missesByLoop), for triangles' and
// clusters' queries, directional and point lights, counts of half-spaces that are and are not a
// multiple of four, boxes near and 100 km from the origin, boxes that are points, boxes
// with a coordinate of zero, and boxes a rounding step either side of where the loop's
// answer turns (where the allowances for rounding decide).
TEST(ShadowQuery, FourAtATimeIsOneAtATime) {
    std::mt19937_64 rng(31);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    size_t held = 0, skipped = 0, boundaries = 0;
    if (!__builtin_cpu_supports("avx")) GTEST_SKIP() << "no AVX here: mayHold and misses are the loops";
    const bool avx = ShadowQuery::useAvx(true);  // the default where the processor has it
    for (int trial = 0; trial < 600; ++trial) {
        LightGeometry light;
        light.directional = trial % 3 != 0;
        light.direction = trial % 7 == 0 ? glm::dvec3(0, -1, 0) : glm::normalize(glm::dvec3(u(rng) * 0.8, -1.0, u(rng) * 0.8));
        const double dilation = trial % 5 == 0 ? 0.01 : 0.0;
        const double reach = trial % 4 == 0 ? 1e5 : trial % 2 == 0 ? 1.0 : 150.0;
        const double margin = 1e-9 * (reach + 11.0) + 1e-9;
        const RowTransform casterPlace = randomPlacement(rng, reach), receiverPlace = randomPlacement(rng, reach);
        const glm::dvec3 c(u(rng), u(rng), u(rng));
        const glm::dvec3 h = glm::dvec3(0.05) + 0.3 * glm::abs(glm::dvec3(u(rng), u(rng), u(rng)));
        const Triangle t = {casterPlace.apply(c + h * glm::dvec3(u(rng), u(rng), u(rng))),
                            casterPlace.apply(c + h * glm::dvec3(u(rng), u(rng), u(rng))),
                            casterPlace.apply(c + h * glm::dvec3(u(rng), u(rng), u(rng)))};
        light.position = casterPlace.apply(c) + glm::dvec3(u(rng), 1.5 + std::abs(u(rng)), u(rng));
        const ShadowQuery q(t, light, dilation, margin);
        const ShadowQuery cq = ShadowQuery::ofCluster(Aabb{c - h, c + h}, casterPlace, light, dilation, margin);
        const ShadowQuery::InMesh qMesh = q.inMesh(receiverPlace), cqMesh = cq.inMesh(receiverPlace);
        const glm::dvec3 along = light.directional ? light.direction : glm::normalize(t[0] - light.position);
        for (int k = 0; k < 60; ++k) {
            const glm::dvec3 p = t[size_t(k % 3)] + along * (2.0 * u(rng)) + glm::dvec3(u(rng), u(rng), u(rng)) * 0.6;
            glm::dvec3 e = glm::abs(glm::dvec3(u(rng), u(rng), u(rng))) * (k % 6 == 0 ? 0.0 : k % 2 ? 0.05 : 1.5);
            Aabb ls{p - e, p + e};
            if (k % 9 == 0) ls.min.x = 0.0, ls.max.x = std::max(0.0, ls.max.x);  // a coordinate of zero
            const Aabb ms{toMesh(receiverPlace, p) - e, toMesh(receiverPlace, p) + e};
            const Triangle tri = {ls.min, ls.max + glm::dvec3(u(rng), u(rng), u(rng)) * 0.1,
                                  k % 7 == 0 ? ls.min : ls.min + glm::dvec3(u(rng), u(rng), u(rng)) * 0.3};
            for (const ShadowQuery* query : {&q, &cq}) {
                const bool answer = query->mayHoldByLoop(ls);
                ASSERT_EQ(answer, query->mayHold(ls)) << "trial " << trial << " box " << k;
                (answer ? held : skipped) += 1;
                const bool missed = query->missesByLoop(tri);
                ASSERT_EQ(missed, query->misses(tri)) << "trial " << trial << " triangle " << k;
                (missed ? skipped : held) += 1;
            }
            for (const ShadowQuery::InMesh* query : {&qMesh, &cqMesh}) {
                const bool answer = query->mayHoldByLoop(ms);
                ASSERT_EQ(answer, query->mayHold(ms)) << "trial " << trial << " mesh box " << k;
                (answer ? held : skipped) += 1;
            }
            // Where the answer turns: the box (or triangle) moved along v until the loop's
            // answer changes, then bisected to adjacent positions, where the rounding
            // allowances decide; there both answers must agree.
            if (k % 3 != 0) continue;
            const glm::dvec3 v = glm::normalize(glm::dvec3(u(rng), u(rng), u(rng)));
            auto turning = [&](const auto& loop, const auto& fast, const char* what) {
                double in = 0.0, out = 1.0;
                const bool start = loop(in);
                while (loop(out) == start && out < 1e7) out *= 2;
                if (loop(out) == start) return;
                for (int step = 0; step < 200 && std::nextafter(in, out) != out; ++step) {
                    const double mid = 0.5 * (in + out);
                    (loop(mid) == start ? in : out) = mid;
                }
                ++boundaries;
                for (double at : {in, out, std::nextafter(in, -1e300), std::nextafter(out, 1e300)})
                    ASSERT_EQ(loop(at), fast(at)) << what << ", trial " << trial << " #" << k << " at " << at;
            };
            auto movedBox = [&](const Aabb& b, double at) { return Aabb{b.min + v * at, b.max + v * at}; };
            auto movedTriangle = [&](double at) { return Triangle{tri[0] + v * at, tri[1] + v * at, tri[2] + v * at}; };
            for (const ShadowQuery* query : {&q, &cq}) {
                turning([&](double at) { return query->mayHoldByLoop(movedBox(ls, at)); },
                        [&](double at) { return query->mayHold(movedBox(ls, at)); }, "box");
                turning([&](double at) { return query->missesByLoop(movedTriangle(at)); },
                        [&](double at) { return query->misses(movedTriangle(at)); }, "triangle");
            }
            for (const ShadowQuery::InMesh* query : {&qMesh, &cqMesh})
                turning([&](double at) { return query->mayHoldByLoop(movedBox(ms, at)); },
                        [&](double at) { return query->mayHold(movedBox(ms, at)); }, "mesh box");
        }
    }
    EXPECT_GT(boundaries, 5000u);
    ShadowQuery::useAvx(avx);
    // Meaningful only if both answers are common.
    EXPECT_GT(held, 10000u);
    EXPECT_GT(skipped, 10000u);
}
