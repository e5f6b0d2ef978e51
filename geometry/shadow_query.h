// The broad phase's shape of one caster triangle's shadow: a few half-spaces, in double,
// that hold the triangle's exact frustum (exact_frustum.h) for every bias >= 0 and the
// given dilation. A box none of whose points lies in all of them, beyond every rounding,
// holds no point of the frustum; so the boxes of a hierarchy can be skipped by it,
// in window-local coordinates (objects) or in an object's mesh coordinates (its mesh's
// tree, shared by every instance). Conservative only: the filters and the exact test
// decide what passes.
//
// Half-spaces: the frustum's own (three sides through the caster's edges, and the
// caster's plane: the shadow lies beyond it), each kept only when its orientation is
// certain in double (a caster edge-on to the light keeps none). For directional lights
// also its depth (not nearer the light than the caster) and, for each axis e of the boxes
// tested (the world axes, or an instance's mesh axes mapped to the window), the slab
// across the light normal to d x e that holds the caster: seen along the light the column
// is the caster's triangle and a box is a hexagon with edges along the axes, so with the
// three sides these are every separating axis of the two (the separating axis theorem)
// and a box beside the column is never let through for want of one. Point lights get the
// same along the same axes: the two planes through the light and the axis that bound the
// cone seen along it, and a least distance from the light.
//
// With a filter radius r, every half-space is moved outward by r: the set then holds every
// point within r of the frustum, which is where the spec's filter reaches (a receiver
// within lateral distance r of a ray). The exact test's own dilated region (its planes
// moved by r, exact_frustum.h) is larger still near sharp edges; the broad phase bounds
// the spec's set, not that looser one.
#pragma once

#include <array>

#include "core/scene.h"
#include "core/window.h"
#include "geometry/exact_frustum.h"

namespace shadowcull::geometry {

// A window-local box holding every point of the frustum of the points' convex hull (a
// caster triangle, or a cluster's corners) that lies inside `limits` (the loaded window)
// and, for point and spot lights, within range; grown by `margin` and the filter radius.
Aabb shadowBox(const glm::dvec3* pts, int count, const Light& L, const Aabb& limits, double margin);

// ShadowQuery's half-spaces (value n . (x - o) + k, allowed down to -(rel |x - o|_1 + abs +
// rounding)) and InMesh's planes (value n . y + c, within err + w . |y|) by component, for
// box tests four at a time: entries past the count are zero (hold every box).
struct PackedHalfSpaces {
    alignas(32) std::array<double, 16> nx{}, ny{}, nz{}, ox{}, oy{}, oz{}, k{}, rel{}, abs{};
    alignas(32) std::array<double, 16> n1{};  // |n|_1
};
struct PackedPlanes {
    alignas(32) std::array<double, 16> nx{}, ny{}, nz{}, c{}, wx{}, wy{}, wz{}, err{};
};

class ShadowQuery {
public:
    // `margin`: metres of slack for the rounding of window-local coordinates (the stage's
    // margin); `dilation`: the light's filter radius (metres, >= 0).
    ShadowQuery(const Triangle& caster, const LightGeometry& light, double dilation, double margin);
    ShadowQuery() = default;

    // The union of the frusta of every caster triangle inside a box of an object's mesh
    // (a node of its mesh tree), for a directional light: the box's column
    // {x + s d : x in the box, s > 0}. `msBox` is in the mesh coordinates of the object
    // placed by `lsFromMesh`. Its half-spaces: depth, the box's faces that the light enters
    // by (the column stays on their inner side), and the slabs across the light (the
    // mapped box's axes; the world's and a receiver instance's are added as for a triangle).
    static ShadowQuery ofCluster(const Aabb& msBox, const RowTransform& lsFromMesh, const LightGeometry& light, double dilation,
                                 double margin);

    // False only when no point of the window-local box lies in the frustum.
    bool mayHold(const Aabb& lsBox) const;
    // The same, one half-space at a time: the reference, and mayHold without AVX.
    bool mayHoldByLoop(const Aabb& lsBox) const;
    // Tests: whether mayHold, misses and InMesh::mayHold take four half-spaces at a time
    // with AVX (where the processor has it: the default) or go one at a time (the loops);
    // returns the previous choice. Not while another thread tests.
    static bool useAvx(bool on);
    // Clusters (ofCluster) only: true only when no caster point of the cluster has a
    // receiver point of `r` behind it by more than `beta` (metres, >= 0) on its ray: `r`
    // misses the column (misses()), or lies wholly nearer the light than the cluster's
    // nearest point plus the bias, or its plane lies in front of every point of the cluster
    // along the light (as FrustumFilter's test, over the cluster box's corners).
    bool clusterMisses(const Triangle& r, double beta) const;
    // Window-local box of the column within `limits` (the window), for the object tree.
    // Clusters: a window-local box of the column within `limits` (the window) and, for
    // point and spot lights, within range.
    Aabb columnBox(const Light& L, const Aabb& limits) const;
    // True only when no point of the window-local triangle lies in the frustum: all its
    // vertices outside one half-space, or (point lights) all nearer the light than every
    // point of the caster. Tighter than a box for a triangle across a corner of the frustum.
    bool misses(const Triangle& lsTriangle) const;
    // The same, one half-space at a time: the reference, and misses without AVX.
    bool missesByLoop(const Triangle& lsTriangle) const;

    // The same half-spaces in the mesh coordinates of an object placed by `lsFromMesh`
    // (valid while this query lives). The receivers of the object are the mesh's
    // triangles mapped by lsFromMesh.apply(), rounded: the bounds cover that too.
    class InMesh {
    public:
        // False only when no point of the mesh box, mapped to the window, lies in the frustum.
        bool mayHold(const Aabb& msBox) const;
        // The same, one plane at a time: the reference, and mayHold without AVX.
        bool mayHoldByLoop(const Aabb& msBox) const;

    private:
        friend class ShadowQuery;
        // The planes in mesh coordinates, each within err + w . |y| of the window's value.
        PackedPlanes planes_;
        int count_ = 0;
        // Point lights: the window-local box of the mapped mesh box, grown by its rounding.
        Aabb lsBoxOf(const Aabb& msBox) const;
        // Point lights: the window-local box of the mapped mesh box (centre M c + r3, half
        // extents |M| h), whose farthest point from the light must not be nearer than `near`.
        const ShadowQuery* query_ = nullptr;
        RowTransform map_;
    };
    InMesh inMesh(const RowTransform& lsFromMesh) const;

private:
    // value(x) = n . (x - o) + k; the frustum's points have value >= -(rel |x - o|_1 + abs).
    struct HalfSpace {
        glm::dvec3 n{0.0}, o{0.0};
        double k = 0;
        double rel = 0, abs = 0;
    };
    static void add(std::array<HalfSpace, 16>& to, int& count, const HalfSpace& h) { to[size_t(count++)] = h; }
    // The half-space n . (x - o) >= 0 of a normal known within its rounding bound, grown by
    // the dilation, with the allowances that bound covers (shadow_query.cpp).
    static HalfSpace fromBounded(const Bounded3& n, const glm::dvec3& o, double dilation, double margin);
    // Directional lights: the two half-spaces of the slab normal to d x axis holding the caster.
    void addSlabs(std::array<HalfSpace, 16>& to, int& count, const glm::dvec3& axis) const;
    bool tooNear(const Aabb& lsBox) const;
    // Point lights: tooNear of the triangle's box (false for other lights).
    bool triangleTooNear(const Triangle& lsTriangle) const;
    // hs_ by component for mayHold; made by pack() once hs_ is complete.
    void pack();
    std::array<HalfSpace, 16> hs_;  // frustum_ then the world axes' slabs
    PackedHalfSpaces packed_;
    int frustumCount_ = 0, count_ = 0;
    // Directional lights: the caster and light, for the slabs of an instance's axes.
    bool directional_ = false;
    // The axes whose slabs (or wedges) the frustum's half-spaces (hs_ up to frustumCount_)
    // hold: a cluster's box axes; none for a triangle.
    std::array<glm::dvec3, 3> axes_{};
    int axisCount_ = 0;
    std::array<glm::dvec3, 8> pts_{};  // the caster (3 points) or the cluster box's corners (8)
    int pointCount_ = 0;
    glm::dvec3 direction_{0.0};
    double dilation_ = 0, margin_ = 0;
    // Point lights: every point of the frustum is at least `near_` from the light.
    bool pointLight_ = false;
    glm::dvec3 light_{0.0};
    double near_ = -1;
};

}  // namespace shadowcull::geometry
