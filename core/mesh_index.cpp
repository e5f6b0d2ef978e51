// Per-mesh vertex trees and exact placed boxes (core/mesh_index.h).

#include "core/mesh_index.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/common.hpp>

#include "core/mesh.h"
#include "core/scene.h"
#include "core/window.h"

namespace shadowcull {

namespace {

constexpr uint32_t kLeafSize = 16;

}  // namespace

template <class Box>
void MeshTree::build(const Box& box) {
    if (order_.empty()) return;
    nodes_.reserve(2 * (order_.size() / kLeafSize + 1));
    std::vector<int32_t> todo{0};
    nodes_.push_back({glm::dvec3(0.0), glm::dvec3(0.0), 0, uint32_t(order_.size()), -1, -1});
    // Each item's box centre, for the splits (by item index: the order is permuted).
    std::vector<glm::dvec3> centre;
    uint32_t maxItem = 0;
    for (uint32_t i : order_) maxItem = std::max(maxItem, i);
    centre.resize(size_t(maxItem) + 1);
    for (uint32_t i : order_) {
        glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        box(i, lo, hi);
        centre[i] = 0.5 * (lo + hi);
    }
    while (!todo.empty()) {
        const int32_t ni = todo.back();
        todo.pop_back();
        Node n = nodes_[size_t(ni)];
        n.lo = glm::dvec3(std::numeric_limits<double>::infinity());
        n.hi = glm::dvec3(-std::numeric_limits<double>::infinity());
        glm::dvec3 clo = n.lo, chi = n.hi;
        for (uint32_t k = n.begin; k < n.end; ++k) {
            box(order_[k], n.lo, n.hi);
            clo = glm::min(clo, centre[order_[k]]);
            chi = glm::max(chi, centre[order_[k]]);
        }
        if (n.end - n.begin > kLeafSize) {
            const glm::dvec3 side = chi - clo;
            const int axis = side.x >= side.y && side.x >= side.z ? 0 : side.y >= side.z ? 1 : 2;
            const uint32_t mid = n.begin + (n.end - n.begin) / 2;
            std::nth_element(order_.begin() + n.begin, order_.begin() + mid, order_.begin() + n.end,
                             [&](uint32_t a, uint32_t b) { return centre[a][axis] < centre[b][axis]; });
            n.left = int32_t(nodes_.size());
            n.right = n.left + 1;
            nodes_.push_back({glm::dvec3(0.0), glm::dvec3(0.0), n.begin, mid, -1, -1});
            nodes_.push_back({glm::dvec3(0.0), glm::dvec3(0.0), mid, n.end, -1, -1});
            todo.push_back(n.left);
            todo.push_back(n.right);
        }
        nodes_[size_t(ni)] = n;
    }
}

MeshTree::MeshTree(const std::vector<glm::dvec3>& positions, std::vector<uint32_t> vertices) : order_(std::move(vertices)) {
    build([&](uint32_t v, glm::dvec3& lo, glm::dvec3& hi) {
        lo = glm::min(lo, positions[v]);
        hi = glm::max(hi, positions[v]);
    });
}

MeshTree MeshTree::overTriangles(const Mesh& mesh) {
    MeshTree tree;
    tree.order_.resize(mesh.triangles.size());
    for (uint32_t t = 0; t < tree.order_.size(); ++t) tree.order_[t] = t;
    tree.build([&](uint32_t t, glm::dvec3& lo, glm::dvec3& hi) {
        for (uint32_t v : mesh.triangles[t]) {
            lo = glm::min(lo, mesh.positions[v]);
            hi = glm::max(hi, mesh.positions[v]);
        }
    });
    return tree;
}

namespace {

// The index of a mesh: each subset as its sorted vertex list, one tree per distinct list.
// (Lists, not flags per vertex: a glTF mesh may have hundreds of groups.)
std::shared_ptr<const MeshVertexIndex> buildIndex(const Mesh& m) {
    auto index = std::make_shared<MeshVertexIndex>();
    const size_t nv = m.positions.size(), ng = m.groups.size();
    std::vector<std::vector<uint32_t>> subsets;  // distinct subsets
    std::vector<const VertexTree*> trees;        // their trees, in the same order
    auto treeOf = [&](std::vector<uint32_t> vertices) -> const VertexTree* {
        for (size_t k = 0; k < subsets.size(); ++k)
            if (subsets[k] == vertices) return trees[k];
        subsets.push_back(vertices);
        index->trees.emplace_back(m.positions, std::move(vertices));
        trees.push_back(&index->trees.back());
        return trees.back();
    };
    // The vertices of `triangles` (indices into m.triangles), sorted, once each.
    std::vector<uint32_t> stamp(nv, 0);
    uint32_t pass = 0;
    auto verticesOf = [&](const std::vector<uint32_t>& triangles) {
        ++pass;
        std::vector<uint32_t> out;
        for (uint32_t t : triangles)
            for (uint32_t v : m.triangles[t])
                if (stamp[v] != pass) stamp[v] = pass, out.push_back(v);
        std::sort(out.begin(), out.end());
        return out;
    };
    std::vector<uint32_t> all;
    std::vector<std::vector<uint32_t>> group(ng), withArea(ng);
    index->groupTriangles.assign(ng, 0);
    for (uint32_t t = 0; t < m.triangles.size(); ++t) {
        all.push_back(t);
        const size_t g = m.triangleGroup[t];
        if (g >= ng) continue;
        ++index->groupTriangles[g];
        group[g].push_back(t);
        const auto& tri = m.triangles[t];
        if (!hasRepeatedVertex(m.positions[tri[0]], m.positions[tri[1]], m.positions[tri[2]])) withArea[g].push_back(t);
    }
    index->triangles = MeshTree::overTriangles(m);
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
    std::lock_guard<std::mutex> lock(mesh.index.mutex_);
    if (!mesh.index.index_) mesh.index.index_ = buildIndex(mesh);
    return *mesh.index.index_;
}

double placedCoordinateUpper(const RowTransform& t, int axis, double s, const glm::dvec3& lo, const glm::dvec3& hi) {
    double extreme = s * t.rows[3][axis], magnitude = std::abs(t.rows[3][axis]);
    for (int k = 0; k < 3; ++k) {
        const double c = s * t.rows[size_t(k)][axis];
        extreme += std::max(lo[k] * c, hi[k] * c);
        magnitude += std::max(std::abs(lo[k]), std::abs(hi[k])) * std::abs(c);
    }
    return extreme + 1e-12 * magnitude + 1e-300;
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
    return extreme + 1e-12 * magnitude + 1e-300;
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
