// Exact shadow-frustum tests (the only CGAL translation unit of geometry/).
//
// A caster triangle t = (a, b, c) under a light casts its shadow into the frustum
//   directional d:  { p + s d      : p in t, s > beta }
//   point at L:     { L + l (p - L) : p in t, l > 1 + beta / Dmax }   (Dmax >= |p - L|)
// The union of these frusta over a group's triangles is the group's shadow volume (the
// silhouette extrusion of a closed mesh bounds the same set; per triangle it is also
// correct for open and non-manifold meshes). The point-light form replaces the per-ray
// bias by its smallest value over t, so it is a superset: conservative.
//
// Each frustum is the intersection of three closed side half-spaces and one open near
// half-space. A receiver triangle r reaches the frustum when some point of r lies in all
// of them; decided by clipping r exactly (CGAL Epeck: exact predicates and exact
// constructions), so touching, coplanar and grazing receivers are decided exactly: a
// receiver touching the caster, or lying in its plane, is not strictly behind it.
// With a filter radius r > 0, every half-space is moved outward by r (a superset of the
// frustum dilated by a ball of radius r).
#pragma once

#include <array>
#include <atomic>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "core/rounding.h"
#include "core/window.h"

namespace shadowcull::geometry {

using Triangle = std::array<glm::dvec3, 3>;  // window-local metres

// Opaque triangles (window-local) that may lie between the light and the points of a
// window-local box (a superset is fine, each is tested exactly), and whether the exact
// tests dropped a reached part because one of them shaded it wholly (for a proof's reason).
// `walk` calls `visit` on them one by one, in a fixed order, until it returns true (the
// first that shades the part ends the walk: most parts are shaded by one of the first few,
// and the rest of a long column towards the light is never walked).
struct OccluderSource {
    using Visit = std::function<bool(const Triangle&)>;
    using Walk = std::function<void(const std::array<glm::dvec3, 2>& lsBox, const Visit& visit)>;
    // A source that gives all its triangles at once (appended to `out`).
    using Find = std::function<void(const std::array<glm::dvec3, 2>& lsBox, std::vector<Triangle>& out)>;
    explicit OccluderSource(Walk w) : walk(std::move(w)) {}
    explicit OccluderSource(Find f)
        : walk([find = std::move(f)](const std::array<glm::dvec3, 2>& lsBox, const Visit& visit) {
              std::vector<Triangle> all;
              find(lsBox, all);
              for (const Triangle& t : all)
                  if (visit(t)) return;
          }) {}
    Walk walk;
    mutable std::atomic<bool> shadedSome{false};
};

struct LightGeometry {
    bool directional = true;
    glm::dvec3 direction{0.0, -1.0, 0.0};  // directional: the way light travels
    glm::dvec3 position{0.0};              // point and spot
};

class ExactFrustum {
public:
    struct Impl;

    // Builds the frustum of `caster` (three distinct vertices). `dilation` is the filter
    // radius in metres (0: none). A directional light in the caster's plane (edge-on, or
    // no area) gives a sheet, bounded exactly in that plane. Degenerate only when no exact
    // region is built (a point light in the caster's plane, or a caster that is a line
    // along the light): the caller must then treat every nearby receiver as reached.
    ExactFrustum(const Triangle& caster, const LightGeometry& light, double dilation);
    ~ExactFrustum();
    ExactFrustum(ExactFrustum&&) noexcept;
    ExactFrustum& operator=(ExactFrustum&&) noexcept;

    bool degenerate() const;
    // True when some point of `receiver` lies in the frustum with bias `beta` (metres,
    // >= 0; pass a lower bound of the true bias: smaller is conservative). Exact. When
    // true and `reachedPart` is given, it receives a box (rounded outward) holding every
    // point of the receiver inside the frustum's side half-spaces (for the terrain rule),
    // and `inside` a point of the receiver in the frustum (rounded to double: where a
    // witness ray may be aimed, not a proof of anything).
    // With `occluders` (a directional light, no dilation): a reached part that one of the
    // triangles they give shades wholly (each point's caster point p lies strictly behind
    // it along the light: p is not lit, condition 1 of semantics.md) does not count, so
    // the answer may be false where reaches() without them is true. Exact.
    bool reaches(const Triangle& receiver, double beta, std::array<glm::dvec3, 2>* reachedPart = nullptr,
                 glm::dvec3* inside = nullptr, const OccluderSource* occluders = nullptr) const;
    // The same answer without the interval fast path or the double pre-filter (every step
    // in the exact kernel, occluders included): the reference the tests compare the fast
    // path with.
    bool reachesExactly(const Triangle& receiver, double beta, const OccluderSource* occluders = nullptr) const;
    // The terrain rule, exactly: true when some point of `receiver` lies in the
    // frustum (as reaches()) and is not deeper than `tolerance` (metres) under the ground,
    // that is, lies in the vertical prism of one of the `ground` triangles (window-local,
    // any winding, none vertical) and not more than `tolerance` below its plane, or over
    // one of the `openings` (closed squares with no terrain: any height receives there).
    // The caller passes every ground triangle and opening over the part reaches()
    // reported; points over neither would count as not receiving. Where several terrains overlap, a point above any of them counts (the
    // lowest surface decides, as BakeWindow::lsTerrainHeight). Exact; a degenerate ground
    // triangle makes it answer true (conservative). `inside`, when true: such a point
    // (rounded to double, as for reaches()).
    bool reachesAboveGround(const Triangle& receiver, double beta, const std::vector<Triangle>& ground,
                            const std::vector<GroundOpening>& openings, double tolerance, glm::dvec3* inside = nullptr,
                            const OccluderSource* occluders = nullptr) const;

private:
    std::unique_ptr<Impl> impl_;
};

// A double-only filter in front of ExactFrustum, cheap to build for every caster triangle
// (no CGAL): certainlyMisses(r) is true only when the receiver cannot reach the frustum
// for any bias >= 0, with every rounding covered by its derived bound (core/rounding.h). It rejects a
// receiver that lies strictly outside one side or wholly in front of the caster's plane,
// or whose plane lies in front of the caster along every ray of the caster's column (a
// large terrain triangle above a buried caster: its vertices lie on both sides of every
// plane of the frustum, but where it crosses the column it is nearer the light),
// where "strictly" also holds, exactly, for a receiver vertex that *is* a caster vertex on
// that plane (bitwise equal): a neighbour of the same mesh that shares an edge or a
// vertex with the caster meets the frustum's closure only in that edge or vertex, which
// lies in the caster's plane and so is never strictly behind it. Without dilation only;
// with a filter radius the shared-vertex rule is off (the frustum then grows past the
// caster's edges). When the caster is (nearly) edge-on or a sign is uncertain the filter
// says nothing and the exact test decides.
class FrustumFilter {
public:
    FrustumFilter(const Triangle& caster, const LightGeometry& light, double dilation);
    // `beta`: the receiver's bias (metres, >= 0; a lower bound, as for reaches()). Used
    // for directional lights; point lights are filtered as if it were 0 (weaker, still
    // sound).
    bool certainlyMisses(const Triangle& receiver, double beta) const;
    // True when every one of `pts` lies in front of the caster's plane moved back by the bias
    // (beyond rounding), so that no point of their convex hull is behind the caster by more
    // than it; true for none at all. False when the filter is off (edge-on caster). Used
    // for the part of a receiver above the ground (the terrain rule).
    bool allInFront(const glm::dvec3* pts, size_t count, double beta) const;

private:
    struct Plane {
        BoundedPlane f;             // inside: f(x) > 0 (sides closed, near open); offset: the dilation
        int onPlane[2] = {-1, -1};  // caster vertices that lie on this plane exactly
    };
    static Plane makePlane(const Bounded3& n, const glm::dvec3& o, double dilation, int v0, int v1);
    // True when the exact frustum's function of `p` at x, less beta n.d for the near plane,
    // is certainly negative (beyond every rounding of its double evaluation).
    bool beyond(const Plane& p, const glm::dvec3& x, double beta) const;
    bool outside(const Plane& p, const Triangle& r, double beta) const;
    bool receiverPlaneInFront(const Triangle& r, double beta) const;
    Triangle caster_;
    LightGeometry light_;
    bool valid_ = false, shared_ = false;
    Bounded nearK_;  // directional: n . d of the caster's normal (away from the light), with its bound
    Plane planes_[4];  // three sides, then the near plane (the caster's own)
};

// The side half-space of a caster's frustum through edge e (vertices e and e + 1), in
// double: normal `n` (not unit) towards the frustum's inside, with its rounding bound
// (core/rounding.h), through `o` (the edge's first vertex, or a point light's position).
// Nothing when the side is not certain in double (the third vertex on the plane within
// rounding: the caster edge-on).
struct SidePlane {
    Bounded3 n;
    glm::dvec3 o{0.0};
};
bool doubleSidePlane(const Triangle& caster, int e, const LightGeometry& light, SidePlane& out);

// Along the light's ray through each of `pts` (a caster triangle's vertices, or a caster
// cluster's box corners), the receiver's plane lies at s(p) = n.(r0 - p) / n.d beyond p
// (directional), or l(p) - 1 = n.(r0 - p) / n.(p - L) (point light; pass beta 0).
// Numerators and denominators are affine in p, so when at every point they have certain
// and opposite signs (the denominators of one sign), s(p) < beta over the points' whole
// convex hull: the plane, and every receiver point in it, lies in front of the bias there.
// `slack` (metres) widens every bound (points known only up to it). With `sharedOnPlane`
// and beta 0, a point that is bitwise a receiver vertex has numerator exactly 0 and is let
// through (the plane touches the column there, in the caster's own plane). Double only,
// every rounding covered by its derived bound (core/rounding.h).
bool receiverPlaneInFrontOf(const Triangle& receiver, const glm::dvec3* pts, int count, const LightGeometry& light,
                            double beta, double slack, bool sharedOnPlane);

// Exact facing: +1 when the light meets the receiver's front (counter-clockwise side, or
// the other side when `mirrored`), -1 when it meets the back, 0 when the light is in the
// receiver's plane (grazing: a one-sided receiver then receives nothing).
int exactFacing(const Triangle& receiver, bool mirrored, const LightGeometry& light);

}  // namespace shadowcull::geometry
