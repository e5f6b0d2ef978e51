// The exact test of one receiver against one caster triangle's frustum: see exact_reach.h.

#include "geometry/exact_reach.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "core/rounding.h"

namespace shadowcull::geometry {

namespace {

// A bound on how far a receiver triangle moved by `by` metres along its unit normal, as
// computed in double (offset = (by / |n|) n with n = (b - a) x (c - a), then added to each
// vertex), can lie from the same move in exact arithmetic; infinity where the computed
// normal's direction is not known to within a quarter turn. Derivation (u = 2^-53,
// gamma(n) = n u / (1 - n u), core/rounding.h): each edge is rounded once, each cross
// component is a difference of two products, so |n_c - n| <= E = 2 gamma(4) |e1| |e2|;
// normalising moves a vector by at most twice its error over its length, plus the
// rounding of the length, the division and the scaling, so |offset_c - offset| <= by
// (2 E / |n_c| + gamma(7)); adding it to a vertex rounds by gamma(1) of the sum.
double normalOffsetError(const Triangle& t, double by) {
    const glm::dvec3 e1 = t[1] - t[0], e2 = t[2] - t[0];
    const double nl = glm::length(glm::cross(e1, e2));
    const double E = 2 * gamma(4) * glm::length(e1) * glm::length(e2);
    if (!(E < 0.5 * nl)) return std::numeric_limits<double>::infinity();
    double reach = 0;
    for (const glm::dvec3& v : t) reach = std::max(reach, glm::length(v));
    return by * (2 * E / nl + gamma(7)) + gamma(2) * (reach + by);
}

}  // namespace

ExactReach::ExactReach(const BakeWindow& w, const Triangle& caster, const LightGeometry& lg, const Light& L, double margin,
                       const OccluderSource* occluders)
    : w_(w), caster_(caster), lg_(lg), L_(L), margin_(margin), occluders_(occluders) {
    const glm::dvec3 ext = glm::max(glm::abs(w.lsBounds.min), glm::abs(w.lsBounds.max));
    slack_ = 1e-9 * (std::max({ext.x, ext.y, ext.z}) + L.normalBias + 1.0);
}

bool ExactReach::reaches(const Receiver& r, double beta, std::array<glm::dvec3, 2>& part, glm::dvec3& at) {
    if (!(L_.normalBias > 0)) return reachesSurface(frustum(plain_, L_.filterRadius), r, r.tri, beta, glm::dvec3(0.0), part, at);
    glm::dvec3 n = glm::cross(r.tri[1] - r.tri[0], r.tri[2] - r.tri[0]);
    if (r.mirrored) n = -n;
    const double nl = glm::length(n);
    if (nl > 0 && normalOffsetError(r.tri, L_.normalBias) <= slack_) {
        for (double sign : {1.0, -1.0}) {
            if (sign < 0 && !r.twoSided) break;
            const glm::dvec3 offset = (sign * L_.normalBias / nl) * n;
            const Triangle moved{r.tri[0] + offset, r.tri[1] + offset, r.tri[2] + offset};
            if (reachesSurface(frustum(moved_, L_.filterRadius + slack_), r, moved, beta, offset, part, at)) return true;
        }
        return false;
    }
    return reachesSurface(frustum(broad_, L_.filterRadius + L_.normalBias), r, r.tri, beta, glm::dvec3(0.0), part, at);
}

bool ExactReach::reachesSurface(ExactFrustum& f, const Receiver& r, const Triangle& surface, double beta, const glm::dvec3& offset,
                                std::array<glm::dvec3, 2>& part, glm::dvec3& at) {
    if (!f.reaches(surface, beta, &part, &at, occluders_)) return false;
    at -= offset;
    if (!w_.hasTerrain || r.terrain) return true;
    const bool moved = offset != glm::dvec3(0.0);
    const double grow = moved ? slack_ + margin_ : 0.0;
    const std::array<glm::dvec3, 2> own{part[0] - offset - grow, part[1] - offset + grow};
    // The terrain rule on the part of the receiver the shadow reaches: a rock half in
    // the ground receives only with its part above ground. The box of that part against
    // the lowest sample first (cheap), then exactly, the part against the terrain
    // triangles over it (a slope under a small box differs from its lowest sample by the
    // cell's relief, which left most terrains of a hilly map undecided).
    if (underTerrain(w_, own, margin_)) return false;
    if (moved) return true;
    ground_.clear();
    openings_.clear();
    // Squares with no terrain (the world's edge) are openings: the rule holds over the
    // rest of the part.
    if (!w_.lsGroundOver(part[0].x, part[0].z, part[1].x, part[1].z, ground_, &openings_)) return true;
    // Only the ground triangles the part may lie over and not wholly deeper than the
    // tolerance under (both in double with the margin: a triangle left out holds no
    // point of the part, or only points under it).
    const double tol = w_.terrainTolerance;
    ground_.erase(std::remove_if(ground_.begin(), ground_.end(),
                                 [&](const Triangle& g) {
                                     const Aabb gb = triangleBox(g);
                                     return gb.max.x < part[0].x - margin_ || gb.min.x > part[1].x + margin_ ||
                                            gb.max.z < part[0].z - margin_ || gb.min.z > part[1].z + margin_ ||
                                            part[1].y < gb.min.y - tol - margin_;
                                 }),
                  ground_.end());
    return f.reachesAboveGround(r.tri, beta, ground_, openings_, tol, &at, occluders_);
}

}  // namespace shadowcull::geometry
