// The exact light ray through a preview pixel's receiver point (see preview_witness.h).
// Ray-triangle crossings: T. Moller, B. Trumbore, "Fast, Minimum Storage Ray-Triangle
// Intersection", Journal of Graphics Tools 2(1), 1997; in double, window-local.
#include "gpu/preview_witness.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "core/line_crossing.h"
#include "core/mesh_index.h"

namespace shadowcull::gpu {

namespace {

constexpr double kPi = 3.14159265358979323846;
// Barycentric slack, relative: a crossing this close to a triangle's edge is not "inside"
// for a lit point (a witness must be certain), but still blocks light (so must a blocker).
constexpr double kEdgeSlack = 1e-9;

// Whether the segment origin + s * dir, s in [0, tEnd], can meet the box.
bool segmentMeetsBox(const glm::dvec3& origin, const glm::dvec3& dir, double tEnd, const Aabb& box) {
    return rayBoxEntry(box, origin, dir) <= tEnd;
}

}  // namespace

ExactLightRays::ExactLightRays(const BakeWindow& w, const Light& L, std::vector<std::vector<uint8_t>> culled)
    : w_(w), L_(L), culled_(std::move(culled)) {
    const glm::dvec3 ext = glm::max(glm::abs(w.lsBounds.min), glm::abs(w.lsBounds.max));
    const double diag = w.lsBounds.empty() ? 1.0 : glm::length(w.lsBounds.max - w.lsBounds.min);
    // 1e-9 of the window's scale: depths here are differences of doubles computed from
    // coordinates of that size, each rounded far below it.
    margin_ = 1e-9 * (std::max({ext.x, ext.y, ext.z}) + diag) + 1e-12;
    backDist_ = diag + 1.0;
}

std::vector<ExactLightRays::Hit> ExactLightRays::hitsAlong(const glm::dvec3& origin, const glm::dvec3& dir,
                                                            double tEnd) const {
    std::vector<Hit> hits;
    for (uint32_t k = 0; k < w_.objects.size(); ++k) {
        const WindowObject& o = w_.objects[k];
        if (o.lsBounds.empty() || !segmentMeetsBox(origin, dir, tEnd, o.lsBounds)) continue;
        vertexIndex(*o.mesh).triangles.visit(
            [&](const glm::dvec3& lo, const glm::dvec3& hi) {
                return segmentMeetsBox(origin, dir, tEnd, placedBounds(Aabb{lo, hi}, o.lsTransform));
            },
            [&](uint32_t t) {
                if (hasRepeatedVertex(*o.mesh, t)) return;
                const auto [a, b, c] = o.lsTriangle(t);
                const glm::dvec3 e1 = b - a, e2 = c - a;
                const LineCrossing x = lineCrossing(origin, dir, a, e1, e2);
                if (!(std::abs(x.det) > 1e-12 * glm::length(glm::cross(e1, e2)))) return;  // edge-on
                const double u = x.u, v = x.v, s = x.t;
                if (!(s > 0 && s < tEnd) || u < -kEdgeSlack || v < -kEdgeSlack || u + v > 1 + kEdgeSlack) return;
                hits.push_back({s, k, t, u > kEdgeSlack && v > kEdgeSlack && u + v < 1 - kEdgeSlack});
            });
    }
    std::sort(hits.begin(), hits.end(), [](const Hit& x, const Hit& y) { return x.t < y.t; });
    return hits;
}

std::optional<RayWitness> ExactLightRays::culledCasterShadowing(uint32_t receiverObject, const glm::dvec3& q,
                                                                const glm::dvec3& nFront, double beta) const {
    // Condition 3 at q: within range and cone, not deeper than the tolerance under terrain.
    const bool local = L_.type != LightType::Directional;
    auto withinReach = [&](const glm::dvec3& x) {
        if (!local) return true;
        const glm::dvec3 v = x - L_.position;
        const double d = glm::length(v);
        if (!(d <= L_.range - margin_)) return false;
        if (L_.type != LightType::Spot) return true;
        if (!(d > margin_)) return false;
        return std::acos(std::clamp(glm::dot(v / d, L_.direction), -1.0, 1.0)) <= L_.coneHalfAngleDeg * kPi / 180.0 - 1e-9;
    };
    if (!withinReach(q)) return std::nullopt;
    if (w_.hasTerrain && w_.objects[receiverObject].kind != ChunkObject::Kind::Terrain) {
        const std::optional<double> ground = w_.lsTerrainHeight(q.x, q.z);
        if (ground && !(q.y >= *ground - w_.terrainTolerance + margin_)) return std::nullopt;
    }
    // Condition 5: the engine looks the shadow up at q'.
    const glm::dvec3 qLookup = q + L_.normalBias * nFront;
    glm::dvec3 origin, dir;
    double tq;
    if (local) {
        origin = L_.position;
        tq = glm::length(qLookup - origin);
        if (!(tq > margin_)) return std::nullopt;
        dir = (qLookup - origin) / tq;
    } else {
        dir = L_.direction;
        origin = qLookup - dir * backDist_;
        tq = backDist_;
    }
    // Conditions 1 and 2: walk the surfaces from the light; the first culled caster point
    // q' lies more than beta behind is a witness, unless light was blocked before it.
    for (const Hit& h : hitsAlong(origin, dir, tq)) {
        const WindowObject& o = w_.objects[h.object];
        const uint32_t group = o.mesh->triangleGroup[h.triangle];
        const bool culled = h.object < culled_.size() && group < culled_[h.object].size() && culled_[h.object][group];
        if (culled && h.inside && tq - h.t > beta + margin_ && withinReach(origin + dir * h.t))
            return RayWitness{h.object, group, origin + dir * h.t, tq - h.t};
        if (o.blocksLight(group)) break;  // every later point on the ray is unlit
    }
    return std::nullopt;
}

}  // namespace shadowcull::gpu
