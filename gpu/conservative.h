// CPU side of the conservative rasterisation used by the confirmation stage: triangles
// and edges of the window, projected in double precision into a light view and drawn as
// one instanced quad each ("pieces"). The fragment shader then decides coverage and
// depth bounds per pixel with margins that only ever admit more (see confirm_stage.cpp).
//
// Perspective views are clipped here, in double, against z >= near and a guard band
// |x|, |y| <= 2 t z, so that pixel coordinates stay within [-w/2, 3w/2] (float keeps them
// to ~1e-4 px) and 1/z stays finite. The near distance is chosen below the nearest
// geometry, so the clipped-away parts all lie outside the view's frustum.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "gpu/light_view.h"

namespace shadowcull::gpu {

// One triangle (kind 0) or edge segment (kind 1) in pixel coordinates, drawn as one
// instance of a four-vertex strip. Computed in double, stored in float:
//  - box: the bounding box (pixels);
//  - edge k: the unit normal n of edge k (vertex k to k+1) and the extent [lo, hi] of the
//    triangle along n (one bound is the edge's line, the other the opposite vertex). These
//    give both the separating-axis overlap test with a pixel square and the "inside by a
//    margin" test, without any orientation; a zero-length edge has n = 0 and lo = hi = 0;
//  - the plane of s over the pixel plane, s(x, y) = s0 + a (x - x0) + b (y - y0), s being
//    the depth for orthographic views and 1/z for perspective ones (both affine in pixel
//    coordinates over a planar triangle), usable only when planeValid; and the depth range
//    [zmin, zmax] of the piece's vertices, which always bounds it.
//  - cover: four corners (a triangle strip) of a shape holding every pixel centre whose
//    square, widened by 0.5 + dilate + margin, can touch the piece: the triangle with its
//    edges pushed out by that much where that is smaller than the widened bounding box,
//    else the box (sharp or degenerate triangles).
struct RasterPiece {
    float box[4];      // xmin, ymin, xmax, ymax
    float edge[3][4];  // nx, ny, lo, hi
    float plane[4];    // x0, y0, s0, a
    float plane2[4];   // b, zmin, zmax, planeValid (0/1)
    float misc[4];     // dilate (px, extra half-width), margin (px), kind (0 tri, 1 edge), 0
    uint32_t id;       // query index (casters), else 0
    float cover[8];    // x, y of four corners, triangle-strip order
};
static_assert(sizeof(RasterPiece) == 37 * 4, "vertex layout");

class PieceBuilder {
public:
    // nearZ: perspective views only (> 0).
    PieceBuilder(const LightView& view, double nearZ);
    // Appends the pieces of triangle (a, b, c) (window-local).
    void triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, float dilatePx, uint32_t id,
                  std::vector<RasterPiece>& out) const;
    // Appends the segment a-b (an edge that cracks an occluder's cover).
    void segment(const glm::dvec3& a, const glm::dvec3& b, std::vector<RasterPiece>& out) const;
    // Pixel bounds (x0, y0, x1, y1, unclamped) of the convex hull of pts: every piece
    // triangle() or segment() makes from points within that hull has its box inside them,
    // up to rounding. False when they cannot be bounded so: a perspective view with a
    // point not beyond the near plane (clipping there changes the shape).
    bool hullBounds(const glm::dvec3* pts, size_t n, double bounds[4]) const;
    // True when triangle() and segment() make no piece from anything within the convex hull
    // of pts: a perspective view with every point outside the same clip plane (behind the
    // near plane, or beyond a side of the guard band) by more than the rounding of the view
    // coordinates (the clip functions are affine in the point, so the hull lies outside too).
    // The parts of a point light's cube that look away from an object, or past it, give it
    // no piece; hullBounds cannot say so for points behind the near plane.
    bool clipsAway(const glm::dvec3* pts, size_t n) const;
    const LightView& view() const { return view_; }

private:
    void emit(const glm::dvec3* v, float dilatePx, float kind, uint32_t id, std::vector<RasterPiece>& out) const;
    const LightView& view_;
    double nearZ_;
    double guard_;
};

// Lower bound of the distance from p to triangle abc (exact up to rounding; robust for
// collinear triangles).
double pointTriangleDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c);

// Edge adjacency of a mesh by vertex position (model coordinates), over the triangles
// listed (those with three distinct vertices).
struct MeshEdges {
    struct Use {
        uint32_t triangle;
        bool forward;  // the triangle runs the edge from its lesser to its greater endpoint
    };
    std::vector<uint32_t> edgeOf;         // [3 * triangle + k]: edge from vertex k to k+1 (mesh triangle index)
    std::vector<uint32_t> start;          // uses of edge e: uses[start[e] .. start[e+1])
    std::vector<Use> uses;
    std::vector<std::array<uint32_t, 2>> ends;  // mesh vertex indices of each edge's endpoints
    MeshEdges(const Mesh& mesh, const std::vector<uint32_t>& triangles);
    size_t count() const { return ends.size(); }
};

}  // namespace shadowcull::gpu
