// Light views shared by the GPU passes: which projections cover what a light can reach in a
// bake window, and how window-local points map to pixels and depths. Also the window's
// triangles in window-local double coordinates, computed once per window.
#pragma once

#include <memory>
#include <mutex>

#include <array>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "core/window.h"

namespace shadowcull::gpu {

// Spot lights with a cone half-angle up to this get one perspective view over the cone;
// wider cones get the six faces of a point light (a frustum cannot open to 180 degrees, and
// near 90 its pixels would stretch without bound).
constexpr double kMaxSingleViewSpotDeg = 75.0;

// One projection of a light. The basis is orthonormal with U x V = -W (OpenGL's camera
// convention): W is the way light travels, and a triangle whose front faces the light is
// counter-clockwise in pixel coordinates.
//
// Orthographic (directional light): view coordinates (u, v, d) = (p.U, p.V, p.W - w0); the
// view rectangle [u0,u1] x [v0,v1] and the depths [0, w1-w0] cover the whole window.
// Perspective (point, spot): (x, y, z) = ((p-eye).U, (p-eye).V, (p-eye).W); the frustum is
// |x| <= t z, |y| <= t z (t = 1 for a cube face, tan(cone) for a spot). Depth is z (axial).
// Pixel coordinates run over [0, width] x [0, height]; pixel (i, j) is the square
// [i, i+1] x [j, j+1] with its centre at (i + 0.5, j + 0.5), row 0 at the bottom.
struct LightView {
    bool perspective = false;
    int face = 0;                 // 0..5 for a point light's cube faces, else 0
    glm::dvec3 U{1, 0, 0}, V{0, 0, -1}, W{0, -1, 0};
    glm::dvec3 eye{0.0};          // perspective: the light's position (window-local)
    double u0 = 0, u1 = 1, v0 = 0, v1 = 1, w0 = 0, w1 = 1;  // orthographic extents
    double t = 1;                 // perspective half-width (tangent)
    int width = 0, height = 0;

    // (u, v, d) or (x, y, z) as above.
    glm::dvec3 toView(const glm::dvec3& p) const;
    // Pixel coordinates of a view-space point (perspective: z must be > 0).
    glm::dvec2 viewToPixel(const glm::dvec3& v) const;
    // Window-local point at pixel position (px, py) and depth (d or z).
    glm::dvec3 pointAt(double px, double py, double depth) const;
    // Direction of light travel through pixel position (px, py) (unit).
    glm::dvec3 rayDirection(double px, double py) const;
    // Size of a pixel in metres at the given depth (the larger side).
    double pixelSize(double depth) const;
    // Column-major clip matrix from window-local coordinates for OpenGL; perspective views
    // clip at z in [nearZ, farZ], orthographic ones at the window's depth range widened by
    // `depthMargin` metres on both sides.
    std::array<float, 16> clipMatrix(double nearZ, double farZ, double depthMargin) const;
};

// The views covering everything light L can reach in window w: one orthographic view over
// the window's bounds for a directional light; the six cube faces for a point light; one
// perspective view over the cone for a spot light up to kMaxSingleViewSpotDeg, else six.
// Each view is resolution x resolution pixels.
// `lsFocus` (directional lights; ignored when null or empty): the view's rectangle covers
// only the rays through this box (window-local), its depths still the whole window. The
// confirmation stage reads pixels only where the casters it examines lie, so it frames a
// box around them: a window that holds every chunk a low sun's shadows reach
// (core/window_plan.h) is many chunks long, and framing it whole would spread the pixels.
std::vector<LightView> lightViews(const BakeWindow& w, const Light& L, int resolution, const Aabb* lsFocus = nullptr);

// A basis (U, V) perpendicular to W with U x V = -W; U lies along the world axis least
// aligned with W, so a light straight down gets U = +x, V = -z exactly.
void lightBasis(const glm::dvec3& W, glm::dvec3& U, glm::dvec3& V);

// Window-local triangles of the window's objects, double precision, each object's computed
// on first use (thread-safe) and kept: a window of dense meshes holds millions of
// triangles, of which a light's few undecided casters need a handful of objects.
class WindowTriangles {
public:
    struct Object {
        std::vector<glm::dvec3> positions;  // per mesh vertex, window-local
        std::vector<uint32_t> triangles;    // mesh triangle indices with three distinct vertices
        Aabb lsBounds;                      // of those triangles' vertices, from these positions
    };
    explicit WindowTriangles(const BakeWindow& w);
    // Parallel to BakeWindow::objects.
    const Object& object(size_t k) const;
    size_t size() const { return objects_.size(); }

private:
    const BakeWindow& w_;
    mutable std::vector<Object> objects_;
    mutable std::unique_ptr<std::once_flag[]> once_;
};

}  // namespace shadowcull::gpu
