// Per-mesh vertex trees and exact placed boxes (core/mesh_index.h).

#include "core/mesh_index.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "core/median_split.h"
#include "core/mesh.h"
#include "core/scene.h"
#include "core/window.h"

namespace shadowcull {

namespace {

// The nodes of a tree that mirrors `tree` (a triangle tree) over items placed in its order:
// node k's items are [before[tree[k].begin], before[tree[k].end]). Nodes with no items are
// left out, an inner node with one child that has items is replaced by it; the layout is
// medianSplit's (root first, siblings side by side after their parent). At least one item.
std::vector<SplitNode> mirroredNodes(const std::vector<BoxTree<>::Node>& tree, const std::vector<uint32_t>& before) {
    auto empty = [&](int32_t k) { return before[tree[size_t(k)].begin] == before[tree[size_t(k)].end]; };
    // The node that stands for k: down through inner nodes with an empty child.
    auto standIn = [&](int32_t k) {
        while (tree[size_t(k)].left >= 0) {
            const BoxTree<>::Node& n = tree[size_t(k)];
            if (empty(n.left)) k = n.right();
            else if (empty(n.right())) k = n.left;
            else break;
        }
        return k;
    };
    std::vector<SplitNode> nodes(1);
    std::vector<std::pair<uint32_t, int32_t>> stack{{0u, standIn(0)}};  // (slot, tree node)
    while (!stack.empty()) {
        const auto [slot, k] = stack.back();
        stack.pop_back();
        const BoxTree<>::Node& n = tree[size_t(k)];
        nodes[slot].begin = before[n.begin];
        nodes[slot].end = before[n.end];
        if (n.left < 0) continue;
        const uint32_t left = uint32_t(nodes.size());
        nodes[slot].left = int32_t(left);
        nodes.resize(nodes.size() + 2);
        stack.push_back({left + 1, standIn(n.right())});
        stack.push_back({left, standIn(n.left)});
    }
    return nodes;
}

}  // namespace

namespace {

// Median splits over `items` by the centres of their boxes, down to leaves of `leafSize`
// ordered as leaves of `orderLeaf` would be (core/median_split.h); or, with `given` nodes,
// the items' order kept and those nodes boxed. box(item, lo, hi) extends lo, hi by the item.
template <class Box>
BoxTree<> boxTree(std::vector<uint32_t> items, const Box& box, uint32_t leafSize, uint32_t orderLeaf,
                  const std::vector<SplitNode>& given) {
    if (items.empty()) return {};
    if (!given.empty()) return BoxTree<>(std::move(items), given, box);
    std::vector<SplitNode> split;
    {
        std::vector<SplitEntry> entries(items.size());
        for (size_t k = 0; k < items.size(); ++k) {
            glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
            box(items[k], lo, hi);
            entries[k] = {0.5 * (lo + hi), items[k]};
        }
        split = medianSplit(entries, leafSize, orderLeaf);
        for (size_t k = 0; k < items.size(); ++k) items[k] = entries[k].item;
    }  // the entries are freed before the nodes are made
    return BoxTree<>(std::move(items), split, box);
}

}  // namespace

VertexTree makeVertexTree(const std::vector<glm::dvec3>& positions, std::vector<uint32_t> vertices,
                          const std::vector<SplitNode>& nodes) {
    return boxTree(std::move(vertices), [&](uint32_t v, glm::dvec3& lo, glm::dvec3& hi) {
        lo = glm::min(lo, positions[v]);
        hi = glm::max(hi, positions[v]);
    }, kVertexLeaf, 0, nodes);
}

BoxTree<> makeTriangleTree(const Mesh& mesh) {
    std::vector<uint32_t> triangles(mesh.triangles.size());
    for (uint32_t t = 0; t < triangles.size(); ++t) triangles[t] = t;
    return boxTree(std::move(triangles), [&](uint32_t t, glm::dvec3& lo, glm::dvec3& hi) {
        for (uint32_t v : mesh.triangles[t]) {
            lo = glm::min(lo, mesh.positions[v]);
            hi = glm::max(hi, mesh.positions[v]);
        }
    }, kTriangleLeaf, kTriangleOrder, {});
}

namespace {

// The index of a mesh: each subset as its sorted vertex list, one tree per distinct list.
// (Lists, not flags per vertex: a glTF mesh may have hundreds of groups.)
std::shared_ptr<const MeshVertexIndex> buildIndex(const Mesh& m) {
    auto index = std::make_shared<MeshVertexIndex>();
    const size_t nv = m.positions.size(), ng = m.groups.size();
    std::vector<std::vector<uint32_t>> subsets;  // distinct subsets
    std::vector<const VertexTree*> trees;        // their trees, in the same order
    // A vertex tree's queries are exact maxima whatever the tree's shape (core/mesh_index.h),
    // so its vertices are not sorted: they are taken in the order the triangle tree first
    // uses them, and the tree mirrors the triangle tree. The vertices a triangle node first
    // uses are a contiguous run of that order, and lie in its triangles' box; a node whose
    // run is empty is left out (its sibling takes its place). Sorting them was a fifth of
    // a dense mesh's index. A subset with vertices no triangle uses (the tree of every
    // vertex, rarely) gets median splits instead.
    // Stamps (== pass): verticesOf's marks, and treeOf's vertices not placed yet.
    std::vector<uint32_t> stamp(nv, 0);
    uint32_t pass = 0;
    std::vector<uint32_t> before;  // per position in the triangle order: vertices placed before it
    auto treeOf = [&](std::vector<uint32_t> vertices) -> const VertexTree* {
        for (size_t k = 0; k < subsets.size(); ++k)
            if (subsets[k] == vertices) return trees[k];
        ++pass;
        for (uint32_t v : vertices) stamp[v] = pass;
        const std::vector<uint32_t>& triangleOrder = index->triangles.items();
        std::vector<uint32_t> ordered;
        ordered.reserve(vertices.size());
        before.resize(triangleOrder.size() + 1);
        for (size_t i = 0; i < triangleOrder.size(); ++i) {
            before[i] = uint32_t(ordered.size());
            for (uint32_t v : m.triangles[triangleOrder[i]])
                if (stamp[v] == pass) stamp[v] = 0, ordered.push_back(v);
        }
        before[triangleOrder.size()] = uint32_t(ordered.size());
        std::vector<SplitNode> nodes;  // none: median splits
        if (ordered.size() < vertices.size()) ordered = vertices;
        else if (!ordered.empty()) nodes = mirroredNodes(index->triangles.nodes(), before);
        subsets.push_back(std::move(vertices));
        index->trees.push_back(makeVertexTree(m.positions, std::move(ordered), nodes));
        trees.push_back(&index->trees.back());
        return trees.back();
    };
    // The vertices of `triangles` (indices into m.triangles), sorted, once each: marked,
    // then gathered in index order (no sort: a dense mesh's lists were three sorts of
    // 90,000 indices).
    auto verticesOf = [&](const std::vector<uint32_t>& triangles) {
        ++pass;
        size_t count = 0;
        for (uint32_t t : triangles)
            for (uint32_t v : m.triangles[t])
                if (stamp[v] != pass) stamp[v] = pass, ++count;
        std::vector<uint32_t> out;
        out.reserve(count);
        for (uint32_t v = 0; v < nv && out.size() < count; ++v)
            if (stamp[v] == pass) out.push_back(v);
        return out;
    };
    std::vector<uint32_t> all;
    std::vector<std::vector<uint32_t>> group(ng), withArea(ng);
    index->groupTriangles.assign(ng, 0);
    index->groupTrianglesWithArea.assign(ng, 0);
    index->groupArea.assign(ng, 0.0);
    for (uint32_t t = 0; t < m.triangles.size(); ++t) {
        all.push_back(t);
        const size_t g = m.triangleGroup[t];
        if (g >= ng) continue;
        ++index->groupTriangles[g];
        group[g].push_back(t);
        const auto& tri = m.triangles[t];
        const glm::dvec3 &a = m.positions[tri[0]], &b = m.positions[tri[1]], &c = m.positions[tri[2]];
        index->groupArea[g] += 0.5 * glm::length(glm::cross(b - a, c - a));
        if (hasRepeatedVertex(a, b, c)) continue;
        withArea[g].push_back(t);
        ++index->groupTrianglesWithArea[g];
    }
    index->triangles = makeTriangleTree(m);
    index->used = treeOf(verticesOf(all));
    std::vector<uint32_t> every(nv);
    for (uint32_t v = 0; v < nv; ++v) every[v] = v;
    index->positions = treeOf(std::move(every));
    for (size_t g = 0; g < ng; ++g) {
        index->group.push_back(treeOf(verticesOf(group[g])));
        index->groupWithArea.push_back(treeOf(verticesOf(withArea[g])));
    }
    return index;
}

}  // namespace

const MeshVertexIndex& vertexIndex(const Mesh& mesh) {
    if (const MeshVertexIndex* built = mesh.index.built_.load(std::memory_order_acquire)) return *built;
    std::lock_guard<std::mutex> lock(mesh.index.mutex_);
    if (!mesh.index.index_) mesh.index.index_ = buildIndex(mesh);
    mesh.index.built_.store(mesh.index.index_.get(), std::memory_order_release);
    return *mesh.index.index_;
}

double placedCoordinateUpper(const RowTransform& t, int axis, double s, const glm::dvec3& lo, const glm::dvec3& hi) {
    double extreme = s * t.rows[3][axis], magnitude = std::abs(t.rows[3][axis]);
    for (int k = 0; k < 3; ++k) {
        const double c = s * t.rows[size_t(k)][axis];
        extreme += std::max(lo[k] * c, hi[k] * c);
        magnitude += std::max(std::abs(lo[k]), std::abs(hi[k])) * std::abs(c);
    }
    return extreme + kPlacementRounding * magnitude + 1e-300;
}

double placedDotUpper(const RowTransform& t, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi) {
    // dot(d, apply(x)) = sum_k x_k dot(d, rows[k]) + dot(d, rows[3]); the magnitude bounds
    // sum_a |d_a| (sum_k |x_k rows[k][a]| + |rows[3][a]|), what apply and dot round against.
    double extreme = 0.0, magnitude = 0.0;
    for (int a = 0; a < 3; ++a) {
        extreme += d[a] * t.rows[3][a];
        magnitude += std::abs(d[a] * t.rows[3][a]);
    }
    for (int k = 0; k < 3; ++k) {
        double c = 0.0, cAbs = 0.0;
        for (int a = 0; a < 3; ++a) {
            c += d[a] * t.rows[size_t(k)][a];
            cAbs += std::abs(d[a] * t.rows[size_t(k)][a]);
        }
        extreme += std::max(lo[k] * c, hi[k] * c);
        magnitude += std::max(std::abs(lo[k]), std::abs(hi[k])) * cAbs;
    }
    return extreme + kPlacementRounding * magnitude + 1e-300;
}

std::pair<double, double> areaScaleBounds(const RowTransform& t) {
    // A maps a triangle's area by |cof(A) n| (n its unit normal), between the least and
    // the largest product of two singular values, so between the extreme eigenvalues of
    // the Gram matrix G = A^T A (the squared singular values). Gershgorin's discs bound
    // those; they are exact for a rotation with a uniform scale (G diagonal).
    double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
    for (int i = 0; i < 3; ++i) {
        double off = 0.0;
        for (int j = 0; j < 3; ++j)
            if (j != i) off += std::abs(glm::dot(t.rows[size_t(i)], t.rows[size_t(j)]));
        const double diag = glm::dot(t.rows[size_t(i)], t.rows[size_t(i)]);
        lo = std::min(lo, diag - off);
        hi = std::max(hi, diag + off);
    }
    // The dot products' rounding: a relative 1e-12 covers it many times over.
    return {std::max(0.0, lo * (1 - 1e-12)), hi * (1 + 1e-12)};
}

std::optional<std::pair<glm::dvec3, glm::dvec3>> placedBox(const VertexTree& tree, const std::vector<glm::dvec3>& positions,
                                                           const RowTransform& t) {
    if (tree.empty()) return std::nullopt;
    glm::dvec3 lo, hi;
    for (int axis = 0; axis < 3; ++axis)
        for (double s : {1.0, -1.0}) {
            // The loop's value, negated exactly for the minimum.
            const double best = tree.maximum(
                [&](const glm::dvec3& a, const glm::dvec3& b) { return placedCoordinateUpper(t, axis, s, a, b); },
                [&](uint32_t v) { return s * t.apply(positions[v])[axis]; });
            if (best == 0.0) return std::nullopt;
            (s > 0 ? hi : lo)[axis] = s * best;
        }
    return std::make_pair(lo, hi);
}

}  // namespace shadowcull
