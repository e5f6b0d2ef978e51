// Per-mesh box trees, built once per unique mesh: so that the boxes of a mesh's placed
// instances cost a few leaves instead of every vertex, and walks over its triangles a few
// leaves instead of every triangle.
//
// Exactness. In real arithmetic the box of the transformed vertices is the box of the
// transformed vertices of the hull, but the stages compare the double boxes the vertex loop
// computes bit for bit (witness rays end at them, the results JSON prints them), and rounding
// can put an interior vertex a few ulps beyond a hull vertex. So the trees are not hulls:
// a query is a branch and bound over the tree in mesh coordinates that evaluates the very
// expression the loop evaluates (RowTransform::apply) at every vertex of every node whose
// conservative bound (the node's box mapped in real arithmetic, widened by
// kPlacementRounding of its magnitude for the rounding of both sides, core/rounding.h) can
// reach the best value so far. The extreme it returns is therefore the loop's extreme, bit
// for bit. One exception: a zero extreme, where -0 and +0 compare equal and the loop keeps
// the first it met; such queries say so and the caller runs its loop (a box coordinate
// exactly at the window origin is rare).
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "core/box_tree.h"
#include "core/median_split.h"

namespace shadowcull {

struct Mesh;
struct RowTransform;

// A tree over a subset of a mesh's vertices (items: vertex indices), in mesh coordinates
// (metres); leaves of up to kVertexLeaf vertices.
using VertexTree = BoxTree<>;
constexpr uint32_t kVertexLeaf = 16;
// Median splits over `vertices` (indices into `positions`); or, with `nodes` (medianSplit's
// layout over the vertices in the order given), those nodes, boxed.
VertexTree makeVertexTree(const std::vector<glm::dvec3>& positions, std::vector<uint32_t> vertices,
                          const std::vector<SplitNode>& nodes = {});

// A tree over every triangle of a mesh (items: triangle indices; an item's box is its
// three vertices' box), leaves of up to kTriangleLeaf, each leaf's triangles in the order
// splits down to kTriangleOrder would give them: every walk meets the triangles in the
// order of that finer tree (the same first candidates, samples and witnesses), with a
// quarter of its nodes (a walk tests a leaf's triangles by their own boxes, which reject
// all a finer node's box would: every test is monotone in the box).
constexpr uint32_t kTriangleLeaf = 16, kTriangleOrder = 4;
BoxTree<> makeTriangleTree(const Mesh& mesh);

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
    BoxTree<> triangles;                    // every triangle (makeTriangleTree)
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
        built_.store(nullptr, std::memory_order_release);
        index_.reset();
        return *this;
    }

private:
    friend const MeshVertexIndex& vertexIndex(const Mesh& mesh);
    mutable std::mutex mutex_;
    mutable std::shared_ptr<const MeshVertexIndex> index_;
    // index_ once built (published after it, read without the lock): the geometry stage asks
    // for a mesh's index once per caster triangle and receiving object, from every thread,
    // and the lock cost more than the walk it guarded on a small mesh.
    mutable std::atomic<const MeshVertexIndex*> built_{nullptr};
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

}  // namespace shadowcull
