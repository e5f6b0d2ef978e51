// A bounding-volume hierarchy over boxes, queried with a predicate on boxes: the
// geometry stage's broad phase (one tree over a window's objects; a mesh's triangles are
// walked in the mesh index's tree the same way: TriangleTree, below).
//
// Median splits on the longest axis of the centres (core/median_split.h), leaves of
// kLeafSize. The predicate decides whether a subtree may hold an answer; it must be
// conservative (true whenever a box it was asked about could hold one): the tree only ever
// skips what it says cannot.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include <tbb/parallel_invoke.h>

#include "core/mesh.h"
#include "core/mesh_index.h"
#include "core/window.h"

namespace shadowcull::geometry {

class BoxTree {
public:
    BoxTree() = default;
    // `boxes[k]` bounds item k. Items with an empty box are left out.
    explicit BoxTree(const std::vector<Aabb>& boxes);

    // Calls leaf(k) for every item whose box passes `mayHold` along with every box of
    // the nodes above it, until leaf returns true (then returns true: stopped early).
    template <class Pred, class Leaf>
    bool visit(const Pred& mayHold, const Leaf& leaf) const {
        if (nodes_.empty()) return false;
        uint32_t stack[kMaxDepth];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& n = nodes_[stack[--top]];
            if (!mayHold(n.box)) continue;
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i)
                    if (mayHold(items_[i].box) && leaf(items_[i].index)) return true;
            } else {
                stack[top++] = n.first + 1;  // the left child is visited first
                stack[top++] = n.first;
            }
        }
        return false;
    }
    size_t size() const { return items_.size(); }

private:
    struct Node {
        Aabb box;
        uint32_t first = 0;  // leaf: first index into items_; inner: index of the left child
        uint32_t count = 0;  // leaf: items; inner: 0
    };
    struct Item {
        Aabb box;
        uint32_t index = 0;
    };
    static constexpr uint32_t kLeafSize = 4;
    // Median splits halve the items, so the depth is about log2(n / kLeafSize) + 1 and the
    // stack (one pending sibling per level, plus the two children pushed) stays far below.
    static constexpr int kMaxDepth = 96;
    std::vector<Item> items_;  // leaf by leaf
    std::vector<Node> nodes_;
};

// A mesh's triangles as the broad phase walks them: the mesh index's triangle tree
// (core/mesh_index.h, built once per mesh and freed with it: one tree per mesh for every
// stage, where the geometry stage used to build a second one of its own, the largest part
// of a dense world's first window), walked as BoxTree is. Triangles with a repeated vertex
// are left out (never a receiver, nor a caster); an item's box is its three vertices' box,
// in mesh coordinates.
class TriangleTree {
public:
    explicit TriangleTree(const Mesh& mesh) : mesh_(mesh), tree_(vertexIndex(mesh).triangles) {}

    // leaf(triangle) for every triangle whose box passes `mayHold` along with every node box
    // above it, until leaf returns true (then returns true: stopped early). Depth first,
    // left child first.
    template <class Pred, class Leaf>
    bool visit(const Pred& mayHold, const Leaf& leaf) const {
        const std::vector<MeshTree::Node>& nodes = tree_.nodes();
        const std::vector<uint32_t>& order = tree_.order();
        if (nodes.empty()) return false;
        int32_t stack[kMaxDepth];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const MeshTree::Node& n = nodes[size_t(stack[--top])];
            if (!mayHold(Aabb{n.lo, n.hi})) continue;
            if (n.left < 0) {
                for (uint32_t i = n.begin; i < n.end; ++i) {
                    Aabb box;
                    if (itemBox(order[i], box) && mayHold(box) && leaf(order[i])) return true;
                }
            } else {
                stack[top++] = n.right;  // the left child is visited first
                stack[top++] = n.left;
            }
        }
        return false;
    }

    static constexpr uint32_t kNone = 0xffffffffu;
    // For a search that wants the first triangle in depth-first order (visit's order) that
    // passes: mayHold(box, items) is asked about nodes only, with the number of triangles
    // under the node; leaf(triangle, position) gets the triangle's position in that order
    // and returns nothing; the caller lowers `first` (atomically) when a triangle passes.
    // In parallel over subtrees of at least `parallelAbove` triangles (TBB); subtrees
    // wholly after `first` are skipped. Whatever the threads, every triangle before the
    // first passing one is visited, once.
    template <class Pred, class Leaf>
    void visitNodesOrdered(const Pred& mayHold, const Leaf& leaf, const std::atomic<uint32_t>& first,
                           uint32_t parallelAbove) const {
        if (!tree_.nodes().empty()) walkOrdered(0, mayHold, leaf, first, parallelAbove);
    }

private:
    // False for a triangle left out (a repeated vertex).
    bool itemBox(uint32_t t, Aabb& box) const {
        if (hasRepeatedVertex(mesh_, t)) return false;
        const auto& i = mesh_.triangles[t];
        const glm::dvec3 &a = mesh_.positions[i[0]], &b = mesh_.positions[i[1]], &c = mesh_.positions[i[2]];
        box.min = glm::min(a, glm::min(b, c));
        box.max = glm::max(a, glm::max(b, c));
        return true;
    }
    template <class Pred, class Leaf>
    void walkOrdered(int32_t node, const Pred& mayHold, const Leaf& leaf, const std::atomic<uint32_t>& first,
                     uint32_t parallelAbove) const {
        const MeshTree::Node& n = tree_.nodes()[size_t(node)];
        if (n.begin >= first.load(std::memory_order_relaxed) || !mayHold(Aabb{n.lo, n.hi}, n.end - n.begin)) return;
        if (n.left < 0) {
            const std::vector<uint32_t>& order = tree_.order();
            for (uint32_t i = n.begin; i < n.end && i < first.load(std::memory_order_relaxed); ++i)
                if (!hasRepeatedVertex(mesh_, order[i])) leaf(order[i], i);
        } else if (n.end - n.begin >= parallelAbove) {
            tbb::parallel_invoke([&] { walkOrdered(n.left, mayHold, leaf, first, parallelAbove); },
                                 [&] { walkOrdered(n.right, mayHold, leaf, first, parallelAbove); });
        } else {
            walkOrdered(n.left, mayHold, leaf, first, parallelAbove);
            walkOrdered(n.right, mayHold, leaf, first, parallelAbove);
        }
    }
    // Median splits halve the triangles: the depth is about log2(n / 16) + 1.
    static constexpr int kMaxDepth = 96;
    const Mesh& mesh_;
    const MeshTree& tree_;
};

}  // namespace shadowcull::geometry
