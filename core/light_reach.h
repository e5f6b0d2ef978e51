// Conservative reach tests of point and spot lights against boxes: true only when no point
// of the box can be within the light's range (or cone). Distances and angles are compared
// with a margin far above double rounding and far below any tolerance a user sets.
#pragma once

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/scene.h"
#include "core/window.h"

namespace shadowcull {

constexpr double kReachRelMargin = 1e-9;

inline double distanceToBox(const glm::dvec3& p, const Aabb& b) {
    glm::dvec3 d = glm::max(glm::max(b.min - p, p - b.max), glm::dvec3(0.0));
    return glm::length(d);
}

// Point and spot lights: the whole box lies beyond the range sphere.
inline bool boxBeyondRange(const Light& L, const Aabb& b) {
    if (L.type == LightType::Directional) return false;
    return distanceToBox(L.position, b) > L.range * (1 + kReachRelMargin) + kReachRelMargin;
}

// Spot lights: the box's bounding sphere lies wholly outside the cone.
inline bool boxOutsideCone(const Light& L, const Aabb& b) {
    if (L.type != LightType::Spot) return false;
    const glm::dvec3 c = 0.5 * (b.min + b.max);
    const double r = 0.5 * glm::length(b.max - b.min);
    const glm::dvec3 toC = c - L.position;
    const double d = glm::length(toC);
    if (!(d > r * (1 + kReachRelMargin) + kReachRelMargin)) return false;  // light inside or at the sphere
    const double angle = std::acos(std::clamp(glm::dot(toC / d, L.direction), -1.0, 1.0));
    const double halfSpan = std::asin(std::min(1.0, r / d));
    const double cone = L.coneHalfAngleDeg * 3.14159265358979323846 / 180.0;
    return angle - halfSpan > cone + 1e-7;
}

// Point and spot lights: no point of the box is within the light's reach (range and cone),
// so it holds no p and no q (semantics.md, condition 3).
inline bool boxOutOfReach(const Light& L, const Aabb& b) { return boxBeyondRange(L, b) || boxOutsideCone(L, b); }

}  // namespace shadowcull
