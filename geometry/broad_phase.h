// The geometry stage's broad phase: box trees (core/box_tree.h) queried with a predicate on
// boxes, one over a window's objects (ObjectTree: median splits of the boxes' centres,
// leaves of 4), and a mesh's triangles walked in the mesh index's tree (TriangleTree).
//
// The predicate decides whether a subtree may hold an answer; it must be conservative
// (true whenever a box it was asked about could hold one): a walk only ever skips what it
// says cannot.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include <tbb/parallel_invoke.h>

#include "core/box_tree.h"
#include "core/median_split.h"
#include "core/mesh.h"
#include "core/mesh_index.h"
#include "core/window.h"

namespace shadowcull::geometry {

class ObjectTree {
public:
    ObjectTree() = default;
    // `boxes[k]` bounds item k. Items with an empty box are left out.
    explicit ObjectTree(const std::vector<Aabb>& boxes) {
        std::vector<SplitEntry> entries;
        entries.reserve(boxes.size());
        for (uint32_t k = 0; k < boxes.size(); ++k)
            if (!boxes[k].empty()) entries.push_back({0.5 * (boxes[k].min + boxes[k].max), k});
        if (entries.empty()) return;
        const std::vector<SplitNode> split = medianSplit(entries, kLeafSize);
        std::vector<Item> items(entries.size());
        for (size_t k = 0; k < entries.size(); ++k) items[k] = {boxes[entries[k].item], entries[k].item};
        tree_ = BoxTree<Item>(std::move(items), split, [](const Item& i, glm::dvec3& lo, glm::dvec3& hi) {
            lo = glm::min(lo, i.box.min);
            hi = glm::max(hi, i.box.max);
        });
    }

    // Calls leaf(k) for every item whose box passes `mayHold` along with every box of
    // the nodes above it, until leaf returns true (then returns true: stopped early).
    // Depth first, left child first.
    template <class Pred, class Leaf>
    bool visit(const Pred& mayHold, const Leaf& leaf) const {
        return tree_.visit([&](const glm::dvec3& lo, const glm::dvec3& hi) { return mayHold(Aabb{lo, hi}); },
                           [&](const Item& i) { return mayHold(i.box) && leaf(i.index); });
    }
    size_t size() const { return tree_.size(); }

private:
    struct Item {
        Aabb box;  // kept with the item: a leaf tests its items' boxes without a look-up
        uint32_t index = 0;
    };
    static constexpr uint32_t kLeafSize = 4;
    BoxTree<Item> tree_;
};

// A mesh's triangles as the broad phase walks them: the mesh index's triangle tree
// (core/mesh_index.h: built once per mesh and shared with the other stages), walked as
// ObjectTree is. Triangles with a repeated vertex are left out (never a receiver, nor a
// caster); an item's box is its three vertices' box, in mesh coordinates.
class TriangleTree {
public:
    explicit TriangleTree(const Mesh& mesh) : mesh_(mesh), tree_(vertexIndex(mesh).triangles) {}

    // leaf(triangle) for every triangle whose box passes `mayHold` along with every node box
    // above it, until leaf returns true (then returns true: stopped early). Depth first,
    // left child first.
    template <class Pred, class Leaf>
    bool visit(const Pred& mayHold, const Leaf& leaf) const {
        return visit(mayHold, [](uint32_t) { return false; }, leaf);
    }

    // visit, with `known(t)` asked of a triangle before its box: true only where leaf(t)
    // would return false (a receiver the rules excluded already), so the same answers
    // without the box test.
    template <class Pred, class Known, class Leaf>
    bool visit(const Pred& mayHold, const Known& known, const Leaf& leaf) const {
        return tree_.visit([&](const glm::dvec3& lo, const glm::dvec3& hi) { return mayHold(Aabb{lo, hi}); },
                           [&](uint32_t t) {
                               if (known(t)) return false;
                               Aabb box;
                               return itemBox(t, box) && mayHold(box) && leaf(t);
                           });
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
        const BoxTree<>::Node& n = tree_.nodes()[size_t(node)];
        if (n.begin >= first.load(std::memory_order_relaxed) || !mayHold(Aabb{n.lo, n.hi}, n.end - n.begin)) return;
        if (n.left < 0) {
            const std::vector<uint32_t>& order = tree_.items();
            for (uint32_t i = n.begin; i < n.end && i < first.load(std::memory_order_relaxed); ++i)
                if (!hasRepeatedVertex(mesh_, order[i])) leaf(order[i], i);
        } else if (n.end - n.begin >= parallelAbove) {
            tbb::parallel_invoke([&] { walkOrdered(n.left, mayHold, leaf, first, parallelAbove); },
                                 [&] { walkOrdered(n.right(), mayHold, leaf, first, parallelAbove); });
        } else {
            walkOrdered(n.left, mayHold, leaf, first, parallelAbove);
            walkOrdered(n.right(), mayHold, leaf, first, parallelAbove);
        }
    }
    const Mesh& mesh_;
    const BoxTree<>& tree_;
};

}  // namespace shadowcull::geometry
