// The box tree over one mesh's triangles that the GPU confirmation selects triangles with,
// in mesh coordinates (core/box_tree.h): built once per unique mesh and kept while the mesh
// is loaded (every instance in every window uses the same tree), so that the stage finds
// the triangles of an object that can reach the pixels it examines without looking at the
// others.
//
// Every selection made with the tree is a superset of the triangles the per-triangle tests
// keep: a query sees each node's box widened by a pad (kPad of the mesh's size, far above
// the rounding of an instance's transform), so the padded box still holds its triangles'
// exact vertices and their placed, rounded images; a test that is monotone in the hull of
// the points (hullReach: a hull inside another has its reach inside the other's) never
// drops, by a node, a triangle it would keep on its own.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "core/box_tree.h"
#include "core/scene.h"
#include "core/window.h"

namespace shadowcull::gpu {

class SelectionTree {
public:
    // Over the mesh triangles with three distinct vertices (hasRepeatedVertex, in mesh
    // coordinates: the same triangles as WindowTriangles lists).
    explicit SelectionTree(const Mesh& mesh);

    // The mesh triangles with three distinct vertices, ascending.
    const std::vector<uint32_t>& triangles() const { return triangles_; }

    // Calls leaf(triangle) for every triangle under a leaf whose box, and the box of every
    // node above it, pass `keep(box)` (mesh coordinates, padded). Depth first; the order
    // of the triangles is the tree's (callers sort what they need in mesh order).
    template <class Keep, class Leaf>
    void visit(const Keep& keep, const Leaf& leaf) const {
        tree_.visit(
            [&](const glm::dvec3& lo, const glm::dvec3& hi) {
                return keep(Aabb{lo - glm::dvec3(pad_), hi + glm::dvec3(pad_)});
            },
            [&](uint32_t t) { leaf(t); });
    }
    size_t nodeCount() const { return tree_.nodes().size(); }

    // Triangles per leaf, at most.
    static constexpr uint32_t kLeafSize = 8;

private:
    std::vector<uint32_t> triangles_;
    double pad_ = 0.0;  // metres, mesh coordinates: what every node box is widened by
    BoxTree<> tree_;
};

// (placedCorners, core/window.h: the corners of a mesh-coordinate box placed in the window;
// their convex hull holds the placed box, so every placed point of the box. placedBounds,
// core/window.h: the axis-aligned box of those, rounding included.)

}  // namespace shadowcull::gpu
