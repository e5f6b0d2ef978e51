// CPU side of the conservative rasterisation used by the confirmation stage: triangles
// and edges of the window, projected in double precision into a light view and handed to
// the geometry shader as one point each ("pieces"). The shader then decides coverage and
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

// One triangle (kind 0) or edge segment (kind 1, p2 == p1) in pixel coordinates, with the
// plane of s over the pixel plane: s(x, y) = s0 + a (x - x0) + b (y - y0), s being the depth
// for orthographic views and 1/z for perspective ones (both are affine in pixel
// coordinates over a planar triangle). 17 x 4 bytes, the vertex layout of the point draw.
struct RasterPiece {
    float x0, y0, x1, y1;
    float x2, y2, s0, orient;         // orient: +1 / -1 robustly CCW / CW, 0 unknown or not wanted
    float a, b, zmin, zmax;           // plane gradient; depth range of the piece's vertices
    float dilate, margin, planeValid, kind;  // extra half-width (px); coverage margin (px); plane usable; 0 tri / 1 edge
    uint32_t id;                      // query index (casters), else 0
};
static_assert(sizeof(RasterPiece) == 17 * 4, "vertex layout");

class PieceBuilder {
public:
    // nearZ: perspective views only (> 0).
    PieceBuilder(const LightView& view, double nearZ);
    // Appends the pieces of triangle (a, b, c) (window-local). `expectOrient` (+1/-1):
    // the screen orientation the triangle must have for "pixel centre inside" tests (a
    // piece found otherwise gets orient 0); 0 when no such test is wanted.
    void triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, int expectOrient, float dilatePx,
                  uint32_t id, std::vector<RasterPiece>& out) const;
    // Appends the segment a-b (an edge that cracks an occluder's cover).
    void segment(const glm::dvec3& a, const glm::dvec3& b, std::vector<RasterPiece>& out) const;

private:
    void emit(const glm::dvec3* v, int expectOrient, float dilatePx, float kind, uint32_t id,
              std::vector<RasterPiece>& out) const;
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
