// Where a line crosses a triangle's plane, in double: the one ray-triangle computation the
// witness depths (raycast/hit_depth.h), the normal-bias lookups (raycast_stage.cpp) and the
// preview's exact light rays (gpu/preview_witness.cpp) share. T. Moller, B. Trumbore,
// "Fast, Minimum Storage Ray-Triangle Intersection", Journal of Graphics Tools 2(1), 1997.
#pragma once

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace shadowcull {

// The line origin + t dir against the plane of the triangle (a, a + e1, a + e2): det =
// -dir . (e1 x e2), zero when the line runs along the plane (callers compare |det| with the
// triangle's size before using the rest); (u, v) the crossing's barycentrics (inside the
// triangle: u, v >= 0 and u + v <= 1); t its distance along the line in units of |dir|.
struct LineCrossing {
    double det, u, v, t;
};

inline LineCrossing lineCrossing(const glm::dvec3& origin, const glm::dvec3& dir, const glm::dvec3& a,
                                 const glm::dvec3& e1, const glm::dvec3& e2) {
    const glm::dvec3 pv = glm::cross(dir, e2);
    const double det = glm::dot(e1, pv);
    const glm::dvec3 tv = origin - a, qv = glm::cross(tv, e1);
    return {det, glm::dot(tv, pv) / det, glm::dot(dir, qv) / det, glm::dot(e2, qv) / det};
}

}  // namespace shadowcull
