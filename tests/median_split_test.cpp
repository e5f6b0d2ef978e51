// The median-split builder behind every BoxTree (core/box_tree.h)
// (core/median_split.h): every item once, leaves of at most leafSize, each split at the
// median along the longest side of its items' centres, parents before children with
// siblings side by side, and the same nodes and order on one thread as on many.

#include <algorithm>
#include <limits>
#include <random>

#include <gtest/gtest.h>
#include <glm/common.hpp>
#include <tbb/global_control.h>

#include "core/median_split.h"

namespace shadowcull {
namespace {

// Centres on a jagged sheet (mostly flat: the longest side alternates between x and z),
// with clusters of equal centres (ties).
std::vector<glm::dvec3> sheetCentres(size_t n, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<glm::dvec3> c(n);
    for (size_t k = 0; k < n; ++k) c[k] = k % 7 == 3 && k > 0 ? c[k - 1] : glm::dvec3(40.0 * u(rng), 0.03 * u(rng), 25.0 * u(rng));
    return c;
}

void expectValidSplit(const std::vector<SplitNode>& nodes, const std::vector<uint32_t>& order,
                      const std::vector<glm::dvec3>& centres, uint32_t leafSize, size_t items) {
    ASSERT_FALSE(nodes.empty());
    std::vector<uint32_t> sorted = order;
    std::sort(sorted.begin(), sorted.end());
    for (size_t k = 0; k < sorted.size(); ++k) ASSERT_EQ(sorted[k], k) << "order is not a permutation of the items";
    EXPECT_EQ(nodes[0].begin, 0u);
    EXPECT_EQ(nodes[0].end, items);
    std::vector<int> parents(nodes.size(), 0);
    size_t leafItems = 0;
    for (size_t k = 0; k < nodes.size(); ++k) {
        const SplitNode& n = nodes[k];
        const uint32_t count = n.end - n.begin;
        if (n.left < 0) {
            EXPECT_LE(count, leafSize) << "node " << k;
            EXPECT_GE(count, 1u);
            leafItems += count;
            continue;
        }
        ASSERT_GT(count, leafSize) << "node " << k;
        ASSERT_GT(size_t(n.left), k) << "a child before its parent";
        ASSERT_LT(size_t(n.left) + 1, nodes.size());
        ++parents[size_t(n.left)];
        ++parents[size_t(n.left) + 1];
        const SplitNode &l = nodes[size_t(n.left)], &r = nodes[size_t(n.left) + 1];
        const uint32_t mid = n.begin + count / 2;
        EXPECT_EQ(l.begin, n.begin);
        EXPECT_EQ(l.end, mid);
        EXPECT_EQ(r.begin, mid);
        EXPECT_EQ(r.end, n.end);
        // The median along the longest side of the centres' box (ties: x, then y).
        glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        for (uint32_t i = n.begin; i < n.end; ++i) lo = glm::min(lo, centres[order[i]]), hi = glm::max(hi, centres[order[i]]);
        const glm::dvec3 side = hi - lo;
        const int axis = side.x >= side.y && side.x >= side.z ? 0 : side.y >= side.z ? 1 : 2;
        double leftMax = -std::numeric_limits<double>::infinity(), rightMin = std::numeric_limits<double>::infinity();
        for (uint32_t i = n.begin; i < mid; ++i) leftMax = std::max(leftMax, centres[order[i]][axis]);
        for (uint32_t i = mid; i < n.end; ++i) rightMin = std::min(rightMin, centres[order[i]][axis]);
        EXPECT_LE(leftMax, rightMin) << "node " << k << " is not split at its median along axis " << axis;
    }
    EXPECT_EQ(leafItems, items) << "leaves do not hold every item once";
    EXPECT_EQ(parents[0], 0);
    for (size_t k = 1; k < nodes.size(); ++k) EXPECT_EQ(parents[k], 1) << "node " << k << " has no parent, or two";
}

TEST(MedianSplit, SplitsAtTheMedianOfTheLongestSideAndKeepsEveryItem) {
    std::mt19937 rng(3);
    for (size_t n : {1u, 4u, 5u, 17u, 1000u, 40000u})  // 40,000: the parallel path too
        for (uint32_t leaf : {1u, 4u, 16u}) {
            SCOPED_TRACE("n " + std::to_string(n) + " leaf " + std::to_string(leaf));
            const std::vector<glm::dvec3> centres = sheetCentres(n, rng);
            std::vector<uint32_t> order(n);
            for (uint32_t k = 0; k < n; ++k) order[k] = k;
            const std::vector<SplitNode> nodes = medianSplit(order, centres, leaf);
            expectValidSplit(nodes, order, centres, leaf, n);
        }
}

// A subset of the items (a vertex tree over some vertices): only they are placed.
TEST(MedianSplit, ASubsetOfTheItems) {
    std::mt19937 rng(4);
    const std::vector<glm::dvec3> centres = sheetCentres(3000, rng);
    std::vector<uint32_t> order;
    for (uint32_t k = 0; k < 3000; k += 3) order.push_back(k);
    const std::vector<uint32_t> before = order;
    const std::vector<SplitNode> nodes = medianSplit(order, centres, 16);
    std::vector<uint32_t> a = order, b = before;
    std::sort(a.begin(), a.end());
    EXPECT_EQ(a, b);
    EXPECT_EQ(nodes[0].end, 1000u);
}

// Leaves of 16 ordered as leaves of 4 (the mesh index's triangle trees): the items in
// exactly the finer tree's order, and the nodes exactly the finer tree's nodes down to
// those of at most 16 items (the rest of it, below them, left out). Both entry points.
TEST(MedianSplit, CoarseLeavesOrderedAsAFinerTree) {
    std::mt19937 rng(6);
    for (size_t n : {3u, 16u, 17u, 1000u, 40000u}) {
        SCOPED_TRACE("n " + std::to_string(n));
        const std::vector<glm::dvec3> centres = sheetCentres(n, rng);
        auto build = [&](uint32_t leaf, uint32_t orderLeaf, std::vector<uint32_t>& order) {
            std::vector<SplitEntry> entries(n);
            for (uint32_t k = 0; k < n; ++k) entries[k] = {centres[k], k};
            std::vector<SplitNode> nodes = medianSplit(entries, leaf, orderLeaf);
            order.resize(n);
            for (size_t k = 0; k < n; ++k) order[k] = entries[k].item;
            return nodes;
        };
        std::vector<uint32_t> fineOrder, coarseOrder;
        const std::vector<SplitNode> fine = build(4, 0, fineOrder), coarse = build(16, 4, coarseOrder);
        EXPECT_EQ(coarseOrder, fineOrder);
        expectValidSplit(coarse, coarseOrder, centres, 16, n);
        // The finer tree's nodes that are not below one of at most 16 items.
        std::vector<std::pair<uint32_t, uint32_t>> kept, got;
        std::vector<int> stack{0};
        while (!stack.empty()) {
            const SplitNode& f = fine[size_t(stack.back())];
            stack.pop_back();
            kept.emplace_back(f.begin, f.end);
            if (f.left >= 0 && f.end - f.begin > 16) stack.insert(stack.end(), {f.left + 1, f.left});
        }
        for (const SplitNode& c : coarse) got.emplace_back(c.begin, c.end);
        std::sort(kept.begin(), kept.end());
        std::sort(got.begin(), got.end());
        EXPECT_EQ(got, kept);
    }
}

// Ties by item (the GPU confirmation's tree): every node holds the same items whatever the
// entries' order before the splits, on centres with many ties.
TEST(MedianSplit, TiesByItemDependOnlyOnTheSetOfEntries) {
    std::mt19937 rng(8);
    for (size_t n : {9u, 1000u, 40000u}) {
        SCOPED_TRACE("n " + std::to_string(n));
        const std::vector<glm::dvec3> centres = sheetCentres(n, rng);
        std::vector<SplitEntry> sorted(n), shuffled;
        for (uint32_t k = 0; k < n; ++k) sorted[k] = {centres[k], k};
        shuffled = sorted;
        std::shuffle(shuffled.begin(), shuffled.end(), rng);
        const std::vector<SplitNode> a = medianSplit(sorted, 8, 0, SplitTies::ByItem);
        const std::vector<SplitNode> b = medianSplit(shuffled, 8, 0, SplitTies::ByItem);
        std::vector<uint32_t> order(n);
        for (size_t k = 0; k < n; ++k) order[k] = sorted[k].item;
        expectValidSplit(a, order, centres, 8, n);
        ASSERT_EQ(a.size(), b.size());
        for (size_t k = 0; k < a.size(); ++k) {
            ASSERT_EQ(a[k].begin, b[k].begin);
            ASSERT_EQ(a[k].end, b[k].end);
            ASSERT_EQ(a[k].left, b[k].left);
            std::vector<uint32_t> x, y;
            for (uint32_t i = a[k].begin; i < a[k].end; ++i) x.push_back(sorted[i].item), y.push_back(shuffled[i].item);
            std::sort(x.begin(), x.end());
            std::sort(y.begin(), y.end());
            ASSERT_EQ(x, y) << "node " << k;
        }
    }
}

TEST(MedianSplit, TheSameOnOneThreadAsOnMany) {
    std::mt19937 rng(5);
    const std::vector<glm::dvec3> centres = sheetCentres(100000, rng);
    auto build = [&](std::vector<uint32_t>& order) {
        order.resize(centres.size());
        for (uint32_t k = 0; k < order.size(); ++k) order[k] = k;
        return medianSplit(order, centres, 4);
    };
    std::vector<uint32_t> many, one;
    const std::vector<SplitNode> a = build(many);
    std::vector<SplitNode> b;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        b = build(one);
    }
    EXPECT_EQ(many, one);
    ASSERT_EQ(a.size(), b.size());
    for (size_t k = 0; k < a.size(); ++k) {
        EXPECT_EQ(a[k].begin, b[k].begin);
        EXPECT_EQ(a[k].end, b[k].end);
        EXPECT_EQ(a[k].left, b[k].left);
    }
}

}  // namespace
}  // namespace shadowcull
