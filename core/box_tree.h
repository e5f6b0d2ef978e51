// A box tree (bounding-volume hierarchy) over items: the one behind every tree of the
// stages (a mesh's vertices and triangles, core/mesh_index.h; a window's objects, the
// geometry stage's broad phase; a mesh's drawable triangles, the GPU confirmation).
//
// Its shape is medianSplit's (core/median_split.h): the caller chooses the items' centres,
// the leaf size and how ties split. A node's box is the exact box of its items' boxes (min
// and max, no rounding), in the items' own coordinates: a query that needs room to spare
// (a placement's rounding) widens the box it is given, the tree stores none.
//
// Walks go depth first, left child first: the items come in the order of items(), the
// split order, so what a walk finds first depends only on the items and the splits.
#pragma once

#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "core/median_split.h"

namespace shadowcull {

template <class Item = uint32_t>
class BoxTree {
public:
    struct Node {
        glm::dvec3 lo{0.0}, hi{0.0};  // the exact box of its items
        uint32_t begin = 0, end = 0;  // its items: items()[begin, end)
        int32_t left = -1;            // inner node: the left child (the right one is left + 1); leaf: -1
        int32_t right() const { return left + 1; }
    };

    BoxTree() = default;
    // `items` in the order medianSplit left their entries, `split` its nodes over them (or
    // nodes of the same layout: root first, siblings side by side after their parent, no
    // node without items). extend(item, lo, hi) widens lo, hi to hold the item.
    template <class Extend>
    BoxTree(std::vector<Item> items, const std::vector<SplitNode>& split, const Extend& extend);

    bool empty() const { return items_.empty(); }
    size_t size() const { return items_.size(); }
    const std::vector<Node>& nodes() const { return nodes_; }
    const std::vector<Item>& items() const { return items_; }  // leaf by leaf

    // Calls leaf(item) for every item of every leaf whose box, and every ancestor's,
    // may(lo, hi) accepts (a conservative filter: false only where no item can matter).
    // A leaf that returns true stops the walk (visit returns true); one returning nothing
    // never does.
    template <class May, class Leaf>
    bool visit(const May& may, const Leaf& leaf) const;

    // The largest eval(item) over the items (-infinity when empty), where upper(lo, hi)
    // bounds eval over every item in the box [lo, hi] from above (conservatively, rounding
    // included). Nodes are visited best bound first and skipped when their bound is below
    // the best value found: the result is the maximum of eval, exactly, whatever the
    // bound's slack.
    template <class Upper, class Eval>
    double maximum(const Upper& upper, const Eval& eval) const;

private:
    // A walk's stack holds one pending sibling per level plus the two children pushed;
    // median splits halve the items, so the depth is about log2(n / leaf size) + 1.
    static constexpr int kMaxStack = 128;
    std::vector<Node> nodes_;
    std::vector<Item> items_;
};

template <class Item>
template <class Extend>
BoxTree<Item>::BoxTree(std::vector<Item> items, const std::vector<SplitNode>& split, const Extend& extend)
    : items_(std::move(items)) {
    // Bottom up (children after parents in `split`): a leaf's box from its items, an inner
    // node's from its children's (min and max are exact: each is its items' exact box).
    nodes_.resize(split.size());
    for (size_t k = split.size(); k-- > 0;) {
        const SplitNode& s = split[k];
        Node& n = nodes_[k];
        n.begin = s.begin;
        n.end = s.end;
        n.left = s.left;
        if (s.left < 0) {
            n.lo = glm::dvec3(std::numeric_limits<double>::infinity());
            n.hi = glm::dvec3(-std::numeric_limits<double>::infinity());
            for (uint32_t i = s.begin; i < s.end; ++i) extend(items_[i], n.lo, n.hi);
        } else {
            const Node &a = nodes_[size_t(s.left)], &b = nodes_[size_t(s.left) + 1];
            n.lo = glm::min(a.lo, b.lo);
            n.hi = glm::max(a.hi, b.hi);
        }
    }
}

template <class Item>
template <class May, class Leaf>
bool BoxTree<Item>::visit(const May& may, const Leaf& leaf) const {
    if (nodes_.empty()) return false;
    int32_t stack[kMaxStack];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& n = nodes_[size_t(stack[--top])];
        if (!may(n.lo, n.hi)) continue;
        if (n.left < 0) {
            for (uint32_t k = n.begin; k < n.end; ++k) {
                if constexpr (std::is_void_v<decltype(leaf(items_[k]))>) leaf(items_[k]);
                else if (leaf(items_[k])) return true;
            }
            continue;
        }
        stack[top++] = n.right();
        stack[top++] = n.left;
    }
    return false;
}

template <class Item>
template <class Upper, class Eval>
double BoxTree<Item>::maximum(const Upper& upper, const Eval& eval) const {
    double best = -std::numeric_limits<double>::infinity();
    if (nodes_.empty()) return best;
    struct Entry {
        int32_t node;
        double bound;
    };
    // Depth first, the child with the larger bound first.
    Entry stack[kMaxStack];
    int top = 0;
    stack[top++] = {0, upper(nodes_[0].lo, nodes_[0].hi)};
    while (top > 0) {
        const Entry e = stack[--top];
        if (e.bound < best) continue;
        const Node& n = nodes_[size_t(e.node)];
        if (n.left < 0) {
            for (uint32_t k = n.begin; k < n.end; ++k) {
                const double v = eval(items_[k]);
                if (v > best) best = v;
            }
            continue;
        }
        const Node &a = nodes_[size_t(n.left)], &b = nodes_[size_t(n.right())];
        Entry ea{n.left, upper(a.lo, a.hi)}, eb{n.right(), upper(b.lo, b.hi)};
        if (ea.bound > eb.bound) std::swap(ea, eb);
        if (ea.bound >= best) stack[top++] = ea;
        if (eb.bound >= best) stack[top++] = eb;
    }
    return best;
}

}  // namespace shadowcull
