// Per-mesh vertex trees, built once per unique mesh, so that the boxes of a mesh's placed
// instances cost a few leaves instead of every vertex (issue 13: a 180,000-triangle rock
// placed 500 times is 90,000 vertices mapped per placement and per window otherwise).
//
// Exactness. In real arithmetic the box of the transformed vertices is the box of the
// transformed vertices of the hull, but the stages compare the double boxes the vertex loop
// computes bit for bit (witness rays end at them, the results JSON prints them), and rounding
// can put an interior vertex a few ulps beyond a hull vertex. So the trees are not hulls:
// a query is a branch and bound over the tree in mesh coordinates that evaluates the very
// expression the loop evaluates (RowTransform::apply) at every vertex of every node whose
// conservative bound (the node's box mapped in real arithmetic, widened by
// kPlacementRounding of its magnitude for the rounding of both sides, core/rounding.h) can reach the best value so far. The extreme it
// returns is therefore the loop's extreme, bit for bit. One exception: a zero extreme, where
// -0 and +0 compare equal and the loop keeps the first it met; such queries say so and the
// caller runs its loop (a box coordinate exactly at the window origin is rare).
#pragma once

#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "core/median_split.h"

namespace shadowcull {

struct Mesh;
struct RowTransform;

// A box tree over items of a mesh (a subset of its vertices, or its triangles), in mesh
// coordinates (metres). Leaves hold up to 16 vertices or 4 triangles; a node's box is the
// exact box of its items' vertices (no rounding: min/max).
class MeshTree {
public:
    struct Node {
        glm::dvec3 lo{0.0}, hi{0.0};
        uint32_t begin = 0, end = 0;  // range in order()
        int32_t left = -1, right = -1;  // children (both or neither)
    };
    MeshTree() = default;
    // A tree over vertices (indices into `positions`): median splits; or, with `nodes`
    // (medianSplit's layout over the vertices in the order given), those nodes, boxed.
    MeshTree(const std::vector<glm::dvec3>& positions, std::vector<uint32_t> vertices, std::vector<SplitNode> nodes = {});
    // A tree over every triangle of the mesh (items: triangle indices), leaves of up to
    // kTriangleLeaf, each leaf's triangles in the order splits down to kTriangleOrder would
    // give them (so every walk meets the triangles in the order of that finer tree, as it
    // did when the leaves were of 4: the same first candidates, samples and witnesses).
    // Leaves of 16, not 4: a quarter of the nodes (13 MB less on world D, whose first
    // window pays for every MiB it touches), and a walk tests a leaf's triangles by their
    // own boxes, which reject all a finer node's box would (every test is monotone in the
    // box). World D's bake: 0.73 -> 0.67 s.
    static constexpr uint32_t kTriangleLeaf = 16, kTriangleOrder = 4;
    static MeshTree overTriangles(const Mesh& mesh);
    bool empty() const { return order_.empty(); }
    size_t size() const { return order_.size(); }
    const std::vector<Node>& nodes() const { return nodes_; }
    const std::vector<uint32_t>& order() const { return order_; }  // items, by leaf

    // The largest eval(item) over the tree's items (-infinity when empty), where
    // upper(lo, hi) bounds eval over every item in the box [lo, hi] from above
    // (conservatively, rounding included). Nodes are visited best bound first and skipped
    // when their bound is below the best value found: the result is the maximum of eval,
    // exactly, whatever the bound's slack.
    template <class Upper, class Eval>
    double maximum(const Upper& upper, const Eval& eval) const;
    // Calls visit(item) for every item of every leaf whose box and every ancestor's box
    // `may(lo, hi)` accepts (a conservative filter: false only where no item can matter).
    template <class May, class Visit>
    void forEach(const May& may, const Visit& visit) const;

private:
    // Median splits along the longest side of the items' centres: balanced, so that the
    // queries' stacks stay shallow. box(item, lo, hi) extends lo, hi by the item.
    // With `given` nodes, the items' order is kept and those nodes are boxed instead.
    template <class Box>
    void build(const Box& box, uint32_t leafSize, uint32_t orderLeaf = 0, std::vector<SplitNode> given = {});
    std::vector<Node> nodes_;
    std::vector<uint32_t> order_;
};
using VertexTree = MeshTree;

// The trees of one mesh, and what the stages count per group.
struct MeshVertexIndex {
    const VertexTree* positions = nullptr;  // every vertex, used or not
    const VertexTree* used = nullptr;       // every vertex a triangle uses
    // Per group: the vertices of its triangles; of its triangles with three distinct
    // vertices (hasRepeatedVertex). Subsets equal to another share its tree.
    std::vector<const VertexTree*> group, groupWithArea;
    std::vector<uint64_t> groupTriangles;   // per group: its triangles
    std::vector<uint64_t> groupTrianglesWithArea;  // per group: those with three distinct vertices
    // Per group: the sum of its triangles' areas in mesh coordinates (m^2, rounded: a sum
    // in double, relative error below 1e-12 for any mesh the limits allow).
    std::vector<double> groupArea;
    MeshTree triangles;                     // every triangle (leaves of MeshTree::kTriangleLeaf)
    std::deque<VertexTree> trees;           // the storage behind the pointers
};

// Built on first use and kept with the mesh (thread-safe). The mesh must not change after.
const MeshVertexIndex& vertexIndex(const Mesh& mesh);

// Holds a mesh's index: built lazily, never copied (a copy of a mesh starts without one).
class LazyMeshIndex {
public:
    LazyMeshIndex() = default;
    LazyMeshIndex(const LazyMeshIndex&) {}
    LazyMeshIndex& operator=(const LazyMeshIndex&) {
        std::lock_guard<std::mutex> lock(mutex_);
        index_.reset();
        return *this;
    }

private:
    friend const MeshVertexIndex& vertexIndex(const Mesh& mesh);
    mutable std::mutex mutex_;
    mutable std::shared_ptr<const MeshVertexIndex> index_;
};

// Bounds on the factor by which t's linear part scales the area of any triangle: every
// placed triangle's area lies in [first, second] times its mesh area (conservative,
// rounding included; equal up to rounding for a rotation with a uniform scale).
std::pair<double, double> areaScaleBounds(const RowTransform& t);

// The box of t.apply(p) over the tree's vertices p: bit for bit the box a loop over them
// with Aabb::extend computes (min and max per axis). Nothing when a coordinate of the box
// is zero (its sign would depend on the loop's order: the caller runs the loop), or when the
// tree is empty. Returns lo, hi.
std::optional<std::pair<glm::dvec3, glm::dvec3>> placedBox(const VertexTree& tree, const std::vector<glm::dvec3>& positions,
                                                           const RowTransform& t);

// The bound VertexTree::maximum needs for s * t.apply(p)[axis] (s = +1 or -1): the exact
// extreme over the box of the affine function, plus kPlacementRounding of its magnitude (the
// rounding of apply and of this bound) and 1e-300 (underflow, flushed or gradual).
double placedCoordinateUpper(const RowTransform& t, int axis, double s, const glm::dvec3& lo, const glm::dvec3& hi);

// The bound VertexTree::maximum needs for dot(d, t.apply(p)) (the expression evaluated as
// written: apply, then glm::dot): the exact maximum over the box of the affine function,
// computed in double and widened by kPlacementRounding of the magnitude of every term (the
// rounding of apply, the dot and this bound) and by 1e-300 (underflow).
double placedDotUpper(const RowTransform& t, const glm::dvec3& d, const glm::dvec3& lo, const glm::dvec3& hi);

template <class Upper, class Eval>
double MeshTree::maximum(const Upper& upper, const Eval& eval) const {
    double best = -std::numeric_limits<double>::infinity();
    if (nodes_.empty()) return best;
    struct Entry {
        int32_t node;
        double bound;
    };
    // Depth-first, the child with the larger bound first; the stack stays ~2 log n deep.
    Entry stack[128];
    int top = 0;
    stack[top++] = {0, upper(nodes_[0].lo, nodes_[0].hi)};
    while (top > 0) {
        const Entry e = stack[--top];
        if (e.bound < best) continue;
        const Node& n = nodes_[size_t(e.node)];
        if (n.left < 0) {
            for (uint32_t k = n.begin; k < n.end; ++k) {
                const double v = eval(order_[k]);
                if (v > best) best = v;
            }
            continue;
        }
        const Node &a = nodes_[size_t(n.left)], &b = nodes_[size_t(n.right)];
        Entry ea{n.left, upper(a.lo, a.hi)}, eb{n.right, upper(b.lo, b.hi)};
        if (ea.bound > eb.bound) std::swap(ea, eb);
        if (ea.bound >= best) stack[top++] = ea;
        if (eb.bound >= best) stack[top++] = eb;
    }
    return best;
}

template <class May, class Visit>
void MeshTree::forEach(const May& may, const Visit& visit) const {
    if (nodes_.empty()) return;
    int32_t stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& n = nodes_[size_t(stack[--top])];
        if (!may(n.lo, n.hi)) continue;
        if (n.left < 0) {
            for (uint32_t k = n.begin; k < n.end; ++k) visit(order_[k]);
            continue;
        }
        stack[top++] = n.right;
        stack[top++] = n.left;
    }
}

}  // namespace shadowcull
