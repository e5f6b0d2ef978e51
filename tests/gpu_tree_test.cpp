// gpu/selection_tree.h: the box tree over a mesh's triangles that the GPU confirmation selects
// the triangles near the examined pixels with. Every triangle (with three distinct
// vertices) lies under exactly one leaf; a walk that keeps the nodes whose box meets a query
// box reaches every triangle whose own box meets it; and a node's placed box holds its
// triangles' placed vertices under turned, scaled, mirrored and far-off transforms.

#include <algorithm>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "core/mesh.h"
#include "core/scene.h"
#include "gpu/selection_tree.h"
#include "tests/support/space_builder.h"

using namespace shadowcull;
using namespace shadowcull::testing;

namespace {

// A jagged sheet of n x n quads with some repeated-vertex triangles among them.
Mesh jaggedSheet(int n, DeterministicRng& rng) {
    Mesh m;
    m.groups.resize(1);
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) m.positions.push_back({i * 0.05, rng.uniform(0, 0.04), j * 0.05});
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = uint32_t(j * (n + 1) + i), c = a + uint32_t(n) + 1;
            m.triangles.push_back({a, c, a + 1});
            m.triangles.push_back({a + 1, c, c + 1});
            if (rng.below(50) == 0) m.triangles.push_back({a, a, c});  // degenerate: not in the tree
        }
    m.triangleGroup.assign(m.triangles.size(), 0);
    return m;
}

bool meets(const Aabb& a, const Aabb& b) {
    return a.min.x <= b.max.x && b.min.x <= a.max.x && a.min.y <= b.max.y && b.min.y <= a.max.y && a.min.z <= b.max.z &&
           b.min.z <= a.max.z;
}

}  // namespace

TEST(GpuSelectionTree, EveryTriangleUnderOneLeaf) {
    DeterministicRng rng(7);
    const Mesh m = jaggedSheet(40, rng);
    const gpu::SelectionTree tree(m);
    std::vector<int> seen(m.triangles.size(), 0);
    tree.visit([](const Aabb&) { return true; }, [&](uint32_t t) { ++seen[t]; });
    size_t listed = 0;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        const auto& tri = m.triangles[t];
        const bool degenerate = hasRepeatedVertex(m.positions[tri[0]], m.positions[tri[1]], m.positions[tri[2]]);
        EXPECT_EQ(seen[t], degenerate ? 0 : 1) << "triangle " << t;
        listed += !degenerate;
    }
    EXPECT_EQ(tree.triangles().size(), listed);
    EXPECT_TRUE(std::is_sorted(tree.triangles().begin(), tree.triangles().end()));
    EXPECT_GT(tree.nodeCount(), listed / gpu::SelectionTree::kLeafSize);
}

TEST(GpuSelectionTree, BoxWalkReachesEveryTriangleThatMeetsTheBox) {
    DeterministicRng rng(11);
    const Mesh m = jaggedSheet(60, rng);
    const gpu::SelectionTree tree(m);
    for (int q = 0; q < 50; ++q) {
        Aabb query;
        const glm::dvec3 c{rng.uniform(-0.2, 3.2), rng.uniform(-0.05, 0.08), rng.uniform(-0.2, 3.2)};
        const glm::dvec3 h{rng.uniform(0, 0.4), rng.uniform(0, 0.03), rng.uniform(0, 0.4)};
        query.extend(c - h), query.extend(c + h);
        std::vector<char> got(m.triangles.size(), 0);
        size_t visited = 0;
        tree.visit([&](const Aabb& b) { return meets(b, query); }, [&](uint32_t t) { got[t] = 1, ++visited; });
        size_t wanted = 0;
        for (uint32_t t : tree.triangles()) {
            Aabb tb;
            for (uint32_t v : m.triangles[t]) tb.extend(m.positions[v]);
            if (!meets(tb, query)) continue;
            ++wanted;
            EXPECT_TRUE(got[t]) << "query " << q << " triangle " << t;
        }
        EXPECT_LE(wanted, visited);
        EXPECT_LT(visited, tree.triangles().size() / 2 + wanted) << "query " << q << ": the walk should prune";
    }
}

TEST(GpuSelectionTree, PlacedBoxesHoldThePlacedVertices) {
    DeterministicRng rng(13);
    const Mesh m = jaggedSheet(20, rng);
    const gpu::SelectionTree tree(m);
    for (int k = 0; k < 20; ++k) {
        // Turned about a random axis, scaled (0.001 to 1000, mirrored in half), far off.
        const double a = rng.uniform(0, 6.3), s = std::pow(10.0, rng.uniform(-3, 3)) * (k % 2 ? -1 : 1);
        const glm::dvec3 axis = glm::normalize(glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)) + 1e-3);
        RowTransform T;
        for (int r = 0; r < 3; ++r) {
            glm::dvec3 e(0.0);
            e[r] = 1;
            // Rodrigues' rotation of e, scaled.
            T.rows[size_t(r)] = s * (e * std::cos(a) + glm::cross(axis, e) * std::sin(a) +
                                     axis * glm::dot(axis, e) * (1 - std::cos(a)));
        }
        T.rows[3] = {rng.uniform(-1e5, 1e5), rng.uniform(-100, 100), rng.uniform(-1e5, 1e5)};
        tree.visit(
            [&](const Aabb& box) {
                // Every vertex in the node's box, placed as the stages place it.
                const Aabb placed = placedBounds(box, T);
                for (const glm::dvec3& v : m.positions) {
                    if (v.x < box.min.x || v.y < box.min.y || v.z < box.min.z || v.x > box.max.x || v.y > box.max.y ||
                        v.z > box.max.z)
                        continue;
                    const glm::dvec3 p = T.apply(v);
                    EXPECT_TRUE(p.x >= placed.min.x && p.y >= placed.min.y && p.z >= placed.min.z && p.x <= placed.max.x &&
                                p.y <= placed.max.y && p.z <= placed.max.z);
                }
                return box.max.x - box.min.x > 0.1;  // the upper levels only: the test stays small
            },
            [](uint32_t) {});
    }
}
