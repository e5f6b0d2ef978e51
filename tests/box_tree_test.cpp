// core/box_tree.h: nodes hold the exact boxes of their items; a walk meets the accepted
// leaves' items in the items' order (depth first, left child first), stops when a leaf
// says so, and prunes only what the filter rejects; maximum is the exact maximum.

#include <algorithm>
#include <limits>
#include <random>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <gtest/gtest.h>

#include "core/box_tree.h"
#include "core/median_split.h"

namespace shadowcull {
namespace {

BoxTree<> pointTree(const std::vector<glm::dvec3>& points, uint32_t leafSize) {
    std::vector<SplitEntry> entries(points.size());
    for (uint32_t k = 0; k < points.size(); ++k) entries[k] = {points[k], k};
    const std::vector<SplitNode> split = medianSplit(entries, leafSize);
    std::vector<uint32_t> items(entries.size());
    for (size_t k = 0; k < entries.size(); ++k) items[k] = entries[k].item;
    return BoxTree<>(std::move(items), split, [&](uint32_t i, glm::dvec3& lo, glm::dvec3& hi) {
        lo = glm::min(lo, points[i]);
        hi = glm::max(hi, points[i]);
    });
}

TEST(BoxTree, ExactBoxesWalksInItemOrderAndStops) {
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(-10.0, 10.0);
    for (size_t n : {0u, 1u, 5u, 300u, 20000u}) {
        SCOPED_TRACE("n " + std::to_string(n));
        std::vector<glm::dvec3> points(n);
        for (glm::dvec3& p : points) p = {u(rng), u(rng), 0.1 * u(rng)};
        const BoxTree<> tree = pointTree(points, 6);
        EXPECT_EQ(tree.size(), n);
        for (const BoxTree<>::Node& node : tree.nodes()) {
            glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
            for (uint32_t i = node.begin; i < node.end; ++i) lo = glm::min(lo, points[tree.items()[i]]), hi = glm::max(hi, points[tree.items()[i]]);
            EXPECT_TRUE(lo == node.lo && hi == node.hi);
        }
        std::vector<uint32_t> all;
        EXPECT_FALSE(tree.visit([](const glm::dvec3&, const glm::dvec3&) { return true; }, [&](uint32_t i) { all.push_back(i); }));
        EXPECT_EQ(all, tree.items());
        if (n == 0) continue;
        // Stops at the first item with x > 5 in the items' order.
        const auto firstFar = std::find_if(tree.items().begin(), tree.items().end(), [&](uint32_t i) { return points[i].x > 5; });
        std::vector<uint32_t> seen;
        const bool stopped = tree.visit([](const glm::dvec3&, const glm::dvec3& hi) { return hi.x > 5; }, [&](uint32_t i) {
            seen.push_back(i);
            return points[i].x > 5;
        });
        EXPECT_EQ(stopped, firstFar != tree.items().end());
        if (stopped) {
            EXPECT_EQ(seen.back(), *firstFar);
        }
        // The exact maximum of a linear function, with a loose but conservative bound.
        const glm::dvec3 d(0.3, -0.7, 2.0);
        const double best = tree.maximum(
            [&](const glm::dvec3& lo, const glm::dvec3& hi) {
                double b = 0;
                for (int a = 0; a < 3; ++a) b += std::max(d[a] * lo[a], d[a] * hi[a]);
                return b + 1e-9;
            },
            [&](uint32_t i) { return glm::dot(d, points[i]); });
        double loop = -std::numeric_limits<double>::infinity();
        for (const glm::dvec3& p : points) loop = std::max(loop, glm::dot(d, p));
        EXPECT_EQ(best, loop);
    }
}

}  // namespace
}  // namespace shadowcull
