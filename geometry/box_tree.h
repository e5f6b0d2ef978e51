// A bounding-volume hierarchy over boxes, queried with a predicate on boxes: the
// geometry stage's broad phase (one tree over a window's objects, one per unique mesh in
// mesh coordinates, shared by its instances and kept across windows).
//
// Median splits on the longest axis of the centres (core/median_split.h), leaves of
// kLeafSize. The predicate decides whether a subtree may hold an answer; it must be
// conservative (true whenever a box it was asked about could hold one): the tree only ever
// skips what it says cannot.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <tbb/parallel_invoke.h>

#include "core/mesh.h"
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
        return walk<true>(mayHold, leaf);
    }
    // As visit(), but `mayHold(box, items)` is asked about nodes only (not each item's own
    // box), with the number of items under the node.
    template <class Pred, class Leaf>
    bool visitNodes(const Pred& mayHold, const Leaf& leaf) const {
        return walk<false>(mayHold, leaf);
    }
    static constexpr uint32_t kNone = 0xffffffffu;
    // As visitNodes, in parallel over subtrees of at least `parallelAbove` items (TBB), for a
    // search that wants the first item in depth-first order that passes: leaf(index,
    // position) gets the item's position in that order and returns nothing; the caller
    // lowers `first` (atomically) when an item passes, and subtrees wholly after `first`
    // are skipped. Whatever the threads, every item before the first passing one is visited.
    template <class Pred, class Leaf>
    void visitNodesOrdered(const Pred& mayHold, const Leaf& leaf, const std::atomic<uint32_t>& first,
                           uint32_t parallelAbove) const {
        if (!nodes_.empty()) walkOrdered(0, mayHold, leaf, first, parallelAbove);
    }
    size_t size() const { return items_.size(); }

private:
    template <class Pred, class Leaf>
    void walkOrdered(uint32_t node, const Pred& mayHold, const Leaf& leaf, const std::atomic<uint32_t>& first,
                     uint32_t parallelAbove) const {
        const Node& n = nodes_[node];
        if (n.begin >= first.load(std::memory_order_relaxed) || !mayHold(n.box, n.items)) return;
        if (n.count > 0) {
            for (uint32_t i = n.first; i < n.first + n.count && i < first.load(std::memory_order_relaxed); ++i)
                leaf(items_[i].index, i);
        } else if (n.items >= parallelAbove) {
            tbb::parallel_invoke([&] { walkOrdered(n.first, mayHold, leaf, first, parallelAbove); },
                                 [&] { walkOrdered(n.first + 1, mayHold, leaf, first, parallelAbove); });
        } else {
            walkOrdered(n.first, mayHold, leaf, first, parallelAbove);
            walkOrdered(n.first + 1, mayHold, leaf, first, parallelAbove);
        }
    }
    template <bool kTestItems, class Pred, class Leaf>
    bool walk(const Pred& mayHold, const Leaf& leaf) const {
        if (nodes_.empty()) return false;
        uint32_t stack[kMaxDepth];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& n = nodes_[stack[--top]];
            if constexpr (kTestItems) {
                if (!mayHold(n.box)) continue;
            } else {
                if (!mayHold(n.box, n.items)) continue;
            }
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i)
                    if constexpr (kTestItems) {
                        if (mayHold(items_[i].box) && leaf(items_[i].index)) return true;
                    } else {
                        if (leaf(items_[i].index)) return true;
                    }
            } else {
                stack[top++] = n.first + 1;  // the left child is visited first
                stack[top++] = n.first;
            }
        }
        return false;
    }
    struct Node {
        Aabb box;
        uint32_t first = 0;  // leaf: first index into items_; inner: index of the left child
        uint32_t count = 0;  // leaf: items; inner: 0
        uint32_t items = 0;  // items under the node
        uint32_t begin = 0;  // position (in items_) of its first item: items are leaf by leaf
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

// A tree per mesh over its triangles with three distinct vertices (boxes in mesh
// coordinates), built on first use and kept while windows hold the mesh. Thread-safe:
// tasks of one window build different meshes' trees in parallel; a tree is built once.
// Keyed by address: valid while every mesh lives as long as any window that holds it (the
// whole bake today). A loader that frees meshes as windows slide (issue 16) must call
// keepOnly() before a freed mesh's address can be reused, or key by something stabler.
class MeshTreeCache {
public:
    // The tree of `mesh` (built now if needed). Valid until the next keepOnly().
    const BoxTree& tree(const Mesh& mesh);
    // Drops the trees of meshes not in `meshes` (called once per window, before any task).
    void keepOnly(const std::unordered_set<const Mesh*>& meshes);
    // Drops the trees of `meshes` (about to be freed).
    void forget(const std::unordered_set<const Mesh*>& meshes);
    size_t size() const;

private:
    struct Entry {
        std::once_flag once;
        BoxTree tree;
    };
    mutable std::mutex mutex_;
    std::unordered_map<const Mesh*, std::unique_ptr<Entry>> entries_;
};

}  // namespace shadowcull::geometry
