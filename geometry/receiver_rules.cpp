// The receiver rules: see receiver_rules.h. Every double test here discards a receiver only
// when it clearly cannot receive (margins on the side of keeping it).

#include "geometry/receiver_rules.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <glm/geometric.hpp>

#include "core/clip_polygon.h"
#include "core/light_reach.h"
#include "core/rounding.h"
#include "geometry/geometry_stage.h"

namespace shadowcull::geometry {

// True when every point of the box lies deeper than the tolerance under the terrain
// (conservative: the box's top against the lowest terrain sample around it).
bool underTerrain(const BakeWindow& w, const std::array<glm::dvec3, 2>& box, double margin) {
    std::optional<double> ground = w.lsTerrainMinOver(box[0].x, box[0].z, box[1].x, box[1].z);
    return ground && box[1].y < *ground - w.terrainTolerance - margin;
}

namespace {

// Keeps the part of the convex polygon `poly` where n . (x - o) + k >= -slack (double;
// `slack` covers the rounding of the clip, so the result holds every point of the exact
// part: a superset).
void clipOutward(std::vector<glm::dvec3>& poly, const glm::dvec3& n, const glm::dvec3& o, double k, double slack) {
    thread_local std::vector<glm::dvec3> out;  // scratch: this runs for every reached receiver
    out.clear();
    clipPolygon(
        poly.data(), poly.size(), [&](const glm::dvec3& p) { return glm::dot(n, p - o) + k + slack; }, closedSide,
        [](const glm::dvec3& p, const glm::dvec3& q, double fp, double fq) { return p + (q - p) * (fp / (fp - fq)); },
        [](const glm::dvec3& p) { out.push_back(p); });
    poly.swap(out);
}

// The part of receiver triangle `t` (box `box`) that the terrain rule lets receive: over
// each terrain triangle under it, `t` clipped in double to that triangle's vertical prism
// and to not deeper than the tolerance under its plane, every half-space moved outward by
// `margin` (metres; far above the clipping's rounding), so that every point of `t` the
// rule lets receive lies in the convex hull of `out` (a superset: conservative). Empty
// when `t` lies wholly deeper than the tolerance under the ground. False when `t` is not
// wholly over terrain (the rule then says nothing). Depends on the receiver alone: the
// receiver rules compute it once (a rock's crown, not the lowest ground under its box: on
// a slope that left most of a half-buried rock to the exact test, caster by caster).
bool partAboveGround(const BakeWindow& w, const Triangle& t, const Aabb& box, double margin, std::vector<glm::dvec3>& out) {
    out.clear();
    thread_local std::vector<Triangle> ground;  // scratch, as the polygon
    thread_local std::vector<glm::dvec3> poly;
    ground.clear();
    // Ground triangles beside the box (grown by the margin) are skipped below: not made.
    const Aabb near{box.min - glm::dvec3(margin), box.max + glm::dvec3(margin)};
    if (!w.lsTerrainTrianglesOver(box.min.x, box.min.z, box.max.x, box.max.z, near, ground)) return false;
    for (const Triangle& g : ground) {
        const Aabb gb = triangleBox(g);
        if (gb.max.x < box.min.x - margin || gb.min.x > box.max.x + margin || gb.max.z < box.min.z - margin ||
            gb.min.z > box.max.z + margin || box.max.y < gb.min.y - w.terrainTolerance - margin)
            continue;
        glm::dvec3 n = glm::cross(g[1] - g[0], g[2] - g[0]);
        const double len = glm::length(n);
        if (!(len > 0) || !(std::abs(n.y) > 1e-9 * len)) return false;  // a vertical or degenerate cell: no bound
        if (n.y < 0) n = -n;
        n /= len;
        poly.assign(t.begin(), t.end());
        // The vertical prism: three half-spaces through the edges, horizontal normals inward.
        for (int e = 0; e < 3 && !poly.empty(); ++e) {
            const glm::dvec3 &a = g[size_t(e)], &b = g[size_t((e + 1) % 3)], &c = g[size_t((e + 2) % 3)];
            glm::dvec3 side = glm::cross(b - a, glm::dvec3(0, 1, 0));
            const double sl = glm::length(side);
            if (!(sl > 0)) return false;
            side /= sl;
            if (glm::dot(side, c - a) < 0) side = -side;
            clipOutward(poly, side, a, 0.0, margin);
        }
        // Not deeper than the tolerance under the plane: n . (x - g0) + tolerance * n.y >= 0.
        if (!poly.empty()) clipOutward(poly, n, g[0], w.terrainTolerance * n.y, margin);
        out.insert(out.end(), poly.begin(), poly.end());
    }
    return true;
}

}  // namespace

bool ReceiverRules::facesAway(const Receiver& r) const {
    // Facing: a one-sided receiver the light meets from behind or edge-on gets nothing.
    if (!r.twoSided && exactFacing(r.tri, r.mirrored, lg_) <= 0) return true;
    // Range and cone.
    return boxOutOfReach(L_, r.box);
}

double ReceiverRules::computeRest(uint32_t object, uint32_t triangle, const Receiver& r, Entry& e) const {
    // Terrain (terrain itself exempt): wholly deeper than the tolerance under the ground
    // (ReceiverGround: once per receiver, for every light).
    if (w_.hasTerrain && !r.terrain) {
        const ReceiverGround::Answer g = ground_.of(object, triangle, r);
        if (g.buried) return -1;
        if (g.part) e.part.store(g.part, std::memory_order_release);
    }
    return bias(r);
}

ReceiverGround::Answer ReceiverGround::of(uint32_t object, uint32_t triangle, const Receiver& r) const {
    Entry& e = table_.at(object, triangle);
    uint8_t state = e.state.load(std::memory_order_acquire);  // after the part it publishes
    if (state == kUnknown) {
        // Wholly deeper than the tolerance under the lowest ground under its box (cheap),
        // then under the ground triangles over it.
        state = kAbove;
        if (underTerrain(w_, {r.box.min, r.box.max}, margin_)) {
            state = kBuried;
        } else if (bound_) {
            thread_local std::vector<glm::dvec3> part;  // scratch: copied into the arena when kept
            if (partAboveGround(w_, r.tri, r.box, margin_, part)) {
                if (part.empty()) {
                    state = kBuried;
                } else {
                    auto* points = static_cast<glm::dvec3*>(
                        arena_.allocate(part.size() * sizeof(glm::dvec3), alignof(glm::dvec3)));
                    std::copy(part.begin(), part.end(), points);
                    GroundPart* made = arena_.make<GroundPart>();
                    made->points = points;
                    made->count = part.size();
                    // Else another thread's (the same) part won; ours stays unused in the arena.
                    const GroundPart* expected = nullptr;
                    e.part.compare_exchange_strong(expected, made, std::memory_order_acq_rel);
                }
            }
        }
        e.state.store(state, std::memory_order_release);
    }
    if (state == kBuried) return Answer{true, nullptr};
    return Answer{false, e.part.load(std::memory_order_acquire)};
}

double ReceiverRules::bias(const Receiver& r) const { return biasLowerBound(L_, r.tri); }

namespace {

// A lower bound of slopeBias tan(theta) = slopeBias |n* x d| / |n* . d| (n* the exact normal
// of `tri`, d the light's direction: both exact for the double inputs), even once the caller
// multiplies nothing more; 0 where nothing useful is certain. The cross and dot products
// carry their rounding bounds (core/rounding.h): |n* x d| >= |c| - |c.error()|_1 and
// |n* . d| <= |t| + t.error. Then (u = 2^-53, gamma(n) = n u / (1 - n u)): the length of c
// rounds by gamma(3), so fl-length(c) (1 - gamma(4)) <= |c| once rounded; the error's sum
// times 1 + gamma(3) is at least the exact sum; the subtraction rounds num up by at most
// (1 + u), the denominator is rounded up by its factor 1 + gamma(2); the quotient and the
// two products round by (1 + u) each: (1 + u)^4 (1 - 6u) < 1 leaves the result below.
// A receiver within 1e-6 of edge-on (tan > 1e6) gets no slope term: nothing is lost that a
// witness could show (the raycast stage asks cos(theta) > 1e-6 too).
double slopeTermLowerBound(const Light& L, const Triangle& tri) {
    const Bounded3 n = cross(difference(tri[1], tri[0]), difference(tri[2], tri[0]));
    const Bounded3 c = cross(n, exactly(L.direction));
    const Bounded t = dot(n, exactly(L.direction));
    const glm::dvec3 ce = c.error();
    const double num = glm::length(c.value()) * (1 - gamma(4)) - (ce.x + ce.y + ce.z) * (1 + gamma(3));
    const double den = (std::abs(t.value) + t.error) * (1 + gamma(2));
    if (!(num > 0) || !(num < 1e6 * den)) return 0.0;
    return L.slopeBias * (num / den * (1 - gamma(6)));
}

}  // namespace

// bias + the slope term's lower bound y, rounded down: fl(bias + y) <= (bias + y)(1 + u),
// times the double 1 - gamma(2) (= 1 - 2u) and rounded again: (1 + u)^2 (1 - 2u) < 1.
double biasLowerBound(const Light& L, const Triangle& tri) {
    if (!(L.slopeBias > 0) || L.type != LightType::Directional) return L.bias;  // exact: nothing rounds
    const double y = slopeTermLowerBound(L, tri);
    return std::max(L.bias, (L.bias + y) * (1 - gamma(2)));
}

}  // namespace shadowcull::geometry
