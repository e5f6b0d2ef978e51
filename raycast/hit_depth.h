// raycast/: where along a witness line a surface Embree hit lies, and how sure that is.
// Embree intersects float copies of the triangles along the float-rounded line: its hit
// point lies within `eps` of the hit triangle's plane (the stage's window-scaled bound on
// float positions, raycast_stage.cpp: makeTracer), so its distance lies within
// eps / |cos| of the true crossing (alongLineFromPlane, core/rounding.h; cos between the
// line and the triangle's normal). Recomputed in double against the triangle's vertices,
// the error is double rounding's, far below `exactEps`: what lets a witness through the
// thin places (a terrain's shadow on the 1 cm band of a half-buried rock is a fraction of
// a millimetre deep, less than eps).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "core/line_crossing.h"
#include "core/rounding.h"

namespace shadowcull::raycast {

// A distance along the line and the margin a comparison of it needs: the true crossing
// lies within [t - margin, t + margin].
struct HitDepth {
    double t;
    double margin;
};

// The depth of Embree's hit at float distance `floatT` on triangle `tri` (window-local),
// along the line (origin, unit dir). The double crossing with exactEps where it is
// well-conditioned (the line more than 1e-3 from edge-on), inside the triangle in double and
// within Embree's bound of its distance; otherwise Embree's distance with its bound
// eps / |cos|; and when the two disagree by more than that bound, they do not describe the
// same crossing: an infinite margin (no comparison passes, no witness rests on it). With eps
// alone, not over the cosine, a rock face at cos 7e-4 to a high sun placed p 1.7 cm before
// the face on world R, and a witness 3.9 cm deep passed a 5 cm bias.
inline HitDepth hitDepth(const glm::dvec3& origin, const glm::dvec3& dir, float floatT,
                         const std::array<glm::dvec3, 3>& tri, double eps, double exactEps) {
    const auto& [a, b, c] = tri;
    const glm::dvec3 e1 = b - a, e2 = c - a;
    const LineCrossing x = lineCrossing(origin, dir, a, e1, e2);
    const double area2 = glm::length(glm::cross(e1, e2));
    const double cosAbs = area2 > 0 ? std::min(1.0, std::abs(x.det) / area2) : 0.0;
    const HitDepth coarse{double(floatT), alongLineFromPlane(eps, cosAbs)};
    if (!(cosAbs > 1e-3)) return coarse;
    if (!(x.u >= 0 && x.v >= 0 && x.u + x.v <= 1)) return coarse;
    if (!(std::abs(x.t - coarse.t) <= coarse.margin)) return {coarse.t, HUGE_VAL};
    return {x.t, exactEps};
}

}  // namespace shadowcull::raycast
