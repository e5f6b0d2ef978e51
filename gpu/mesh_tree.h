// A bounding-volume hierarchy over one mesh's triangles, in mesh coordinates, for the GPU
// confirmation: built once per unique mesh and kept while the mesh is loaded (every
// instance in every window uses the same tree), so that the stage finds the triangles of an
// object that can reach the pixels it examines without looking at the others. On windows
// of dense meshes (world D: neighbours of 50k-180k triangles) the examined pixels touch a
// small part of each neighbour, and classifying, transforming and testing every triangle of
// every neighbour in the view was most of the stage's CPU time.
//
// Every selection made with the tree is a superset of the triangles the per-triangle tests
// keep: a node's box holds its triangles' vertices with room to spare (kPad, far above the
// rounding of an instance's transform), so a test that is monotone in the hull of the points
// (hullReach: a hull inside another has its reach inside the other's) never drops, by a
// node, a triangle it would keep on its own.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.h"
#include "core/window.h"

namespace shadowcull::gpu {

class MeshTree {
public:
    // Over the mesh triangles with three distinct vertices (hasRepeatedVertex, in mesh
    // coordinates: the same triangles as WindowTriangles lists).
    explicit MeshTree(const Mesh& mesh);

    // The mesh triangles with three distinct vertices, ascending.
    const std::vector<uint32_t>& triangles() const { return triangles_; }

    // Calls leaf(triangle) for every triangle under a leaf whose box, and the box of every
    // node above it, pass `keep(box)` (mesh coordinates, padded). Depth first; the order
    // of the triangles is the tree's (callers sort what they need in mesh order).
    template <class Keep, class Leaf>
    void visit(const Keep& keep, const Leaf& leaf) const {
        if (nodes_.empty()) return;
        uint32_t stack[64];
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& n = nodes_[stack[--top]];
            if (!keep(n.box)) continue;
            if (n.count > 0) {
                for (uint32_t i = n.first; i < n.first + n.count; ++i) leaf(order_[i]);
            } else {
                stack[top++] = n.right;
                stack[top++] = n.first;
            }
        }
    }
    size_t nodeCount() const { return nodes_.size(); }

    // Triangles per leaf, at most.
    static constexpr uint32_t kLeafSize = 8;

private:
    struct Node {
        Aabb box;            // of the triangles' vertices, widened by kPad of the mesh's extent
        uint32_t first = 0;  // leaf: order_[first, first + count); inner node: the left child
        uint32_t count = 0;  // 0: an inner node
        uint32_t right = 0;  // inner node: the right child
    };
    std::vector<uint32_t> triangles_;
    std::vector<uint32_t> order_;
    std::vector<Node> nodes_;
};

// (placedCorners, core/window.h: the corners of a mesh-coordinate box placed in the window;
// their convex hull holds the placed box, so every placed point of the box. placedBounds,
// core/window.h: the axis-aligned box of those, rounding included.)

}  // namespace shadowcull::gpu
