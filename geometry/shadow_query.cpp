#include "geometry/shadow_query.h"

#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "core/rounding.h"

namespace shadowcull::geometry {

namespace {

double norm1(const glm::dvec3& v) { return std::abs(v.x) + std::abs(v.y) + std::abs(v.z); }

// Relative rounding allowance of every double evaluation below (core/rounding.h): a
// half-space's v = fl(n . fl(x - o) + k) is within gamma(5) (|n|_1 |x - o|_1 + |k|) of its
// exact value (one difference, a three-term dot, one sum); a box corner's best value
// likewise; inMesh's n'_i = n . r_i (gamma(3)), c = n . (r3 - o) + k (gamma(5)), the
// evaluation of n' . y + c (gamma(4)) and the receivers' own mapped vertices (gamma(4) of
// sum |y_i| |r_i| + |r3|) each stay within gamma(5) of the terms inMesh weighs them by;
// gamma(8) for the bound's own rounding. The world's placement rounding (window-local
// coordinates, the choice of an extreme point by rounded dots) is the stage's margin's.
constexpr double kRound = gamma(8);

// The largest component of a vector of rounding bounds: |(n - n*) . v| <= it times |v|_1.
double maxOf(const glm::dvec3& e) { return std::max({e.x, e.y, e.z}); }

}  // namespace

void ShadowQuery::addSlabs(std::array<HalfSpace, 16>& to, int& count, const glm::dvec3& axis) const {
    const double k0 = dilation_ > 0 ? dilation_ * (1 + 1e-9) : 0.0;
    if (pointLight_) {
        // Seen along `axis`, the cone {L + l (p - L) : l > 0} over the points is a wedge
        // from L; its bounding planes contain L and `axis` and pass through an extreme point
        // p_j: normal n = axis x (p_j - L), every point on its non-negative side. (None when
        // L is inside the points' shadow along the axis.) Every cone point has
        // n . (x - L) = l n . (p - L) >= 0.
        // Which side of a plane each point lies on is decided beyond rounding (sideOf); a point
        // within rounding of the plane may lie a hair on its negative side, and the cone
        // through it leaves the plane by l times that: the half-space's relative allowance
        // takes it, over |x - L| >= l * (the points' distance from L).
        Aabb box;
        for (int i = 0; i < pointCount_; ++i) box.extend(pts_[size_t(i)]);
        const double reach = distanceToBox(light_, box) * (1 - 1e-9);
        if (!(reach > 0)) return;  // the light among the points: no wedge bounds them
        glm::dvec3 found[2];
        int nFound = 0;
        for (int j = 0; j < pointCount_ && nFound < 2; ++j) {
            const glm::dvec3 pj = pts_[size_t(j)] - light_;
            bool again = false;  // p_j on a plane already found (a box's corners pair up along its axes)
            for (int f = 0; f < nFound; ++f)
                again |= certainSign(dot(exactly(found[f]), difference(pts_[size_t(j)], light_))) == 0;
            if (again) continue;
            glm::dvec3 n = glm::cross(axis, pj);
            const double len = glm::length(n);
            const double scale = glm::length(axis) * glm::length(pj) + len;
            if (!(len > 1e-9 * scale)) continue;
            // v = fl(n . fl(p_i - L)) against the exact n . (p_i - L) for this (double) n: the
            // difference rounds once per component (gamma(1) |p_i - L|), the three-term dot
            // by gamma(3) sum |n_k||q_k| (core/rounding.h): |error| <= gamma(4) sum |n_k||q_k|,
            // gamma(5) for the bound's own rounding.
            int sign = 0;
            double uncertain = 0;  // the largest |exact v| a point within rounding of the plane may have
            for (int i = 0; i < pointCount_ && sign != 2; ++i) {
                const glm::dvec3 q = pts_[size_t(i)] - light_;
                const double v = glm::dot(n, q);
                const double err = gamma(5) * glm::dot(glm::abs(n), glm::abs(q));
                const int si = v > err ? 1 : v < -err ? -1 : 0;
                if (si != 0) sign = sign == 0 || sign == si ? si : 2;
                else uncertain = std::max(uncertain, std::abs(v) + err);
            }
            if (sign == 2 || sign == 0) continue;  // points on both sides, or no side certain: not a bounding plane
            if (sign < 0) n = -n;
            found[nFound++] = n;
            // n is exact as used (a double vector); every point certainly on its side keeps
            // the cone there, the rest move it by at most `uncertain` per unit of l.
            add(to, count, HalfSpace{n, light_, k0 * len, uncertain * (1 + gamma(4)) / reach, margin_ * len});
            if (count + 2 > int(to.size())) return;
        }
        return;
    }
    // n = d x axis is across the light: every point p + s d of the column has n . x = n . p
    // up to s (n . d), which is rounding only (|n . d| = |(n - n*) . d|, n* . d = 0; s |d|
    // at most the window's size): rel covers it per unit of |x - o|_1.
    const Bounded3 nb = cross(exactly(direction_), exactly(axis));
    const glm::dvec3 n = nb.value();
    const double len = glm::length(n);
    if (!(len > 1e-9 * glm::length(direction_) * glm::length(axis))) return;  // axis along the light: no slab
    const double rel = maxOf(nb.error()) * (1 + gamma(2));
    for (const glm::dvec3& m : {n, -n}) {
        int lo = 0;
        for (int i = 1; i < pointCount_; ++i)
            if (glm::dot(m, pts_[size_t(i)]) < glm::dot(m, pts_[size_t(lo)])) lo = i;
        add(to, count, HalfSpace{m, pts_[size_t(lo)], k0 * len, rel, margin_ * len});
    }
}

// A plane's double normal n is within n.error() of the exact one n*: a point with
// n* . (x - o) >= -r |n*| has n . (x - o) >= -(maxOf(n.error()) |x - o|_1 + r |n| +
// r |n.error()|_1): rel and (with the margin) abs. Moved outward by the dilation r: k = r |n|
// (rounded up, as the exact test does).
ShadowQuery::HalfSpace ShadowQuery::fromBounded(const Bounded3& nb, const glm::dvec3& o, double dilation, double margin) {
    const glm::dvec3 n = nb.value(), err = nb.error();
    const double len = glm::length(n);
    return HalfSpace{n, o, dilation > 0 ? dilation * len * (1 + 1e-9) : 0.0, maxOf(err) * (1 + gamma(2)),
                     margin * len + dilation * (err.x + err.y + err.z) * 2};
}

ShadowQuery::ShadowQuery(const Triangle& t, const LightGeometry& light, double dilation, double margin) {
    // Moving a half-space outward by the dilation r: k = r |n| (rounded up, as the exact test does).
    // As FrustumFilter: a sign is trusted only when certain (core/rounding.h).
    auto plane = [&](const Bounded3& nb, const glm::dvec3& o) { return fromBounded(nb, o, dilation, margin); };
    Bounded3 n = crossOfDifferences(t[1] - t[0], t[2] - t[0]);
    const int facing = certainSign(light.directional ? BoundedPlane(n, glm::dvec3(0.0), exactly(0.0)).at(light.direction)
                                                     : BoundedPlane(n, light.position, exactly(0.0)).at(t[0]));
    if (facing != 0) {
        if (facing < 0) n = -n;
        add(hs_, count_, plane(n, t[0]));  // beyond the caster's plane
        for (int e = 0; e < 3; ++e) {
            SidePlane side;
            if (doubleSidePlane(t, e, light, side)) add(hs_, count_, plane(side.n, side.o));  // uncertain: left out
        }
    }
    if (!light.directional) {
        // The frustum {L + l (p - L) : l > 1} lies beyond the caster's nearest point.
        pointLight_ = true;
        light_ = light.position;
        Aabb box;
        for (const glm::dvec3& p : t) box.extend(p);
        near_ = distanceToBox(light.position, box) * (1 - 1e-9) - margin - dilation;
        frustumCount_ = count_;
        pts_ = {t[0], t[1], t[2]};
        pointCount_ = 3;
        dilation_ = dilation;
        margin_ = margin;
        for (const glm::dvec3& e : {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)}) addSlabs(hs_, count_, e);
        pack();
        return;
    }
    // Depth: every point p + s d (s > 0) lies deeper than p.
    const glm::dvec3 w = glm::normalize(light.direction);
    int shallowest = 0;
    for (int i = 1; i < 3; ++i)
        if (glm::dot(w, t[size_t(i)]) < glm::dot(w, t[size_t(shallowest)])) shallowest = i;
    // (w . d > 0 by far; the shallowest vertex is chosen by rounded dots, which the margin holds.)
    add(hs_, count_, HalfSpace{w, t[size_t(shallowest)], dilation > 0 ? dilation * (1 + 1e-9) : 0.0, kRound, margin});
    frustumCount_ = count_;
    directional_ = true;
    pts_ = {t[0], t[1], t[2]};
    pointCount_ = 3;
    direction_ = light.direction;
    dilation_ = dilation;
    margin_ = margin;
    for (const glm::dvec3& e : {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)}) addSlabs(hs_, count_, e);
    pack();
}

void ShadowQuery::pack() {
    packed_ = {};
    for (int i = 0; i < count_; ++i) {
        const HalfSpace& h = hs_[size_t(i)];
        const size_t j = size_t(i);
        packed_.nx[j] = h.n.x, packed_.ny[j] = h.n.y, packed_.nz[j] = h.n.z;
        packed_.ox[j] = h.o.x, packed_.oy[j] = h.o.y, packed_.oz[j] = h.o.z;
        packed_.k[j] = h.k, packed_.rel[j] = h.rel, packed_.abs[j] = h.abs, packed_.n1[j] = norm1(h.n);
    }
}

ShadowQuery ShadowQuery::ofCluster(const Aabb& b, const RowTransform& m, const LightGeometry& light, double dilation, double margin) {
    ShadowQuery q;
    q.directional_ = light.directional;
    q.pointLight_ = !light.directional;
    q.direction_ = light.direction;
    q.light_ = light.position;
    q.dilation_ = dilation;
    q.margin_ = margin;
    q.pointCount_ = 8;
    // Corners mapped to the window. The caster's own vertices are the rounded maps of mesh
    // points inside the box: within a few ulps of the exact map, far inside the margin
    // (1e-9 of the window's extent) that every half-space below allows.
    Aabb corners;
    const std::array<glm::dvec3, 8> placed = placedCorners(b, m);
    for (int k = 0; k < 8; ++k) {
        q.pts_[size_t(k)] = placed[size_t(k)];
        corners.extend(q.pts_[size_t(k)]);
    }
    const double k0 = dilation > 0 ? dilation * (1 + 1e-9) : 0.0;
    auto extreme = [&](const glm::dvec3& n, bool lowest) {
        int e = 0;
        for (int i = 1; i < 8; ++i) {
            const double a = glm::dot(n, q.pts_[size_t(i)]), c = glm::dot(n, q.pts_[size_t(e)]);
            if (lowest ? a < c : a > c) e = i;
        }
        return q.pts_[size_t(e)];
    };
    if (light.directional) {
        // Depth: not nearer the light than the box's nearest corner.
        const glm::dvec3 w = glm::normalize(light.direction);
        add(q.hs_, q.count_, HalfSpace{w, extreme(w, true), k0, kRound, margin});
    } else {
        // Every point L + l (x - L), l > 1, is at least as far from L as the box is.
        q.near_ = distanceToBox(light.position, corners) * (1 - 1e-9) - margin - dilation;
    }
    // Faces the light enters by. Directional: a face normal f (outward) with f . d < 0;
    // the column x + s d (s > 0) only moves further inside: f . (x + s d) <= max of f . x.
    // Point: a face whose plane has L strictly outside (f . L > max of f . x); for l >= 1,
    // f . (L + l (x - L)) = f . L + l (f . x - f . L) <= f . x.
    for (int i = 0; i < 3; ++i) {
        // The normal of the faces spanned by the other two axes, with its rounding bound.
        Bounded3 fb = cross(exactly(m.rows[size_t((i + 1) % 3)]), exactly(m.rows[size_t((i + 2) % 3)]));
        if (light.directional) {
            const int along = certainSign(dot(fb, exactly(light.direction)));
            if (along == 0) continue;  // edge-on: left out
            if (along > 0) fb = -fb;   // now f* . d < 0
        } else {
            // The side of the box the light is on, if it is certainly outside the slab of
            // these faces (beyond every corner).
            int side = 0;
            for (int k = 0; k < 8 && side != 2; ++k) {
                const int sk = certainSign(dot(fb, difference(light.position, q.pts_[size_t(k)])));
                side = sk == 0 ? 2 : side == 0 || side == sk ? sk : 2;
            }
            if (side == 2) continue;  // L between the two faces (or too near one): neither bounds the cone
            if (side < 0) fb = -fb;
        }
        add(q.hs_, q.count_, fromBounded(-fb, extreme(fb.value(), false), dilation, margin));
    }
    // Slabs (or wedges) of the box's own axes.
    for (int i = 0; i < 3; ++i) {
        q.addSlabs(q.hs_, q.count_, m.rows[size_t(i)]);
        q.axes_[size_t(i)] = m.rows[size_t(i)];
    }
    q.axisCount_ = 3;
    q.frustumCount_ = q.count_;
    // The world's axes, but for one the box's own already is (an unturned instance, or a
    // window-local box: the occluders' column): its slabs would be the same half-spaces
    // again, bit for bit, tested twice at every node.
    for (const glm::dvec3& e : {glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)})
        if (e != m.rows[0] && e != m.rows[1] && e != m.rows[2]) q.addSlabs(q.hs_, q.count_, e);
    q.pack();
    return q;
}

Aabb shadowBox(const glm::dvec3* pts, int count, const Light& L, const Aabb& limits, double margin) {
    Aabb box;
    for (int i = 0; i < count; ++i) box.extend(pts[i]);
    if (L.type != LightType::Directional) {
        // Within range: beyond the points by at most range / (their distance).
        Aabb sphere;
        sphere.min = L.position - glm::dvec3(L.range);
        sphere.max = L.position + glm::dvec3(L.range);
        const double dMin = distanceToBox(L.position, box) * (1 - 1e-9);
        if (dMin > 1e-9) {
            const double lMax = L.range / dMin * (1 + 1e-9) + 1e-9;
            for (int i = 0; i < count; ++i) box.extend(L.position + lMax * (pts[i] - L.position));
            box.min = glm::max(box.min, sphere.min);
            box.max = glm::min(box.max, sphere.max);
        } else {
            box = sphere;
        }
    } else {
        // A ray parameter past which no ray from a point of the points' hull is inside the
        // window box. A ray leaves the box at exit(p) = min over axes of the far slab's
        // parameter f_a(p), affine in p; exit is concave, so its largest value over the hull
        // may lie inside it, not at a point given (a terrain triangle larger than the window:
        // the column through its middle reaches further than those through its corners; a
        // false cull the exact reference found: ExactReference.LongRunFindingsStayFixed).
        // Bounded by min over axes of the largest f_a over the points (each f_a affine: its
        // maximum is at a point).
        const glm::dvec3& d = L.direction;
        double sMax = std::numeric_limits<double>::infinity();
        for (int a = 0; a < 3; ++a) {
            if (d[a] == 0) continue;
            double far = -std::numeric_limits<double>::infinity();
            for (int i = 0; i < count; ++i)
                far = std::max(far, ((d[a] > 0 ? limits.max[a] : limits.min[a]) - pts[i][a]) / d[a]);
            sMax = std::min(sMax, far);
        }
        sMax = std::max(sMax, 0.0);
        sMax = sMax * (1 + 1e-9) + margin;
        for (int i = 0; i < count; ++i) box.extend(pts[i] + sMax * d);
    }
    box.min -= glm::dvec3(margin + L.filterRadius);
    box.max += glm::dvec3(margin + L.filterRadius);
    return box;
}

Aabb ShadowQuery::columnBox(const Light& L, const Aabb& limits) const { return shadowBox(pts_.data(), pointCount_, L, limits, margin_); }

bool ShadowQuery::clusterMisses(const Triangle& r, double beta) const {
    if (misses(r)) return true;
    if (dilation_ > 0) return false;  // the receiver may be up to r off the rays: no more
    const LightGeometry light{directional_, direction_, light_};
    // The receiver's plane in front of every corner (receiverPlaneInFrontOf: affine in the
    // caster point, so the corners decide the whole box; point lights without the bias).
    if (pointLight_) return receiverPlaneInFrontOf(r, pts_.data(), pointCount_, light, 0.0, margin_, false);
    // Depth: a receiver point behind a caster point p by more than beta is deeper than p by
    // more than beta |d| along w = d / |d|; none when the receiver's deepest vertex is not
    // deeper than the cluster's nearest corner by that.
    const glm::dvec3 w = glm::normalize(direction_);
    const double dLen = glm::length(direction_);
    double deepest = -std::numeric_limits<double>::infinity(), nearest = std::numeric_limits<double>::infinity(), size = 0;
    for (const glm::dvec3& x : r) {
        deepest = std::max(deepest, glm::dot(w, x));
        size = std::max(size, norm1(x));
    }
    for (int i = 0; i < pointCount_; ++i) {
        nearest = std::min(nearest, glm::dot(w, pts_[size_t(i)]));
        size = std::max(size, norm1(pts_[size_t(i)]));
    }
    // Each rounded dot is within gamma(8) |x|_1 of w* . x (w = fl(d / |d|) within gamma(4) of
    // w*, three products and sums); 1 - 1e-9 takes |d|'s and the sum's rounding.
    if (deepest < nearest + beta * dLen * (1 - 1e-9) - margin_ - 2 * gamma(8) * size) return true;
    return receiverPlaneInFrontOf(r, pts_.data(), pointCount_, light, beta, margin_, false);
}

// The farthest point of the box from the light is nearer than every point of the frustum.
bool ShadowQuery::tooNear(const Aabb& b) const {
    if (!pointLight_ || !(near_ > 0)) return false;
    const glm::dvec3 far = glm::max(glm::abs(b.min - light_), glm::abs(b.max - light_));
    return glm::length(far) * (1 + 1e-9) < near_;
}

// The broad phase's box and triangle tests, four half-spaces (or mesh planes) at a time
// with AVX where the processor has it (chosen at run time); without it, the loops
// (mayHoldByLoop, missesByLoop). There is no FMA, so each lane makes the same roundings in
// the same order as the loops (_mm256_max_pd(y, x) is std::max(x, y): x unless x < y; the
// negation flips the sign bit): the answers are the loops' bit for bit. On worlds of many
// instances these tests are a third of the geometry stage. Entries past `count` are zero
// and hold every box.
//
// Half-spaces, per axis a in order (best from k, spread from 0, terms from |k|):
//   lo = b.min[a] - o[a], hi = b.max[a] - o[a]; far = max(|lo|, |hi|);
//   best += max(n[a] lo, n[a] hi); spread += far; terms += |n[a]| far;
// none holds the box when best < -(rel spread + abs + kRound terms) - 1e-300.
// Planes: none holds the box when
//   c + max(nx lo.x, nx hi.x) + max(ny lo.y, ny hi.y) + max(nz lo.z, nz hi.z)
//     < -(err + (wx far.x + wy far.y + wz far.z)) - 1e-300,   far = max(|lo|, |hi|).
namespace {

bool gAvx = __builtin_cpu_supports("avx");

__attribute__((target("avx"))) bool halfSpacesHoldAvx(const PackedHalfSpaces& p, int count, const Aabb& b) {
    const __m256d sign = _mm256_set1_pd(-0.0), tiny = _mm256_set1_pd(1e-300), round = _mm256_set1_pd(kRound);
    for (size_t j = 0; j < size_t(count); j += 4) {
        const __m256d k = _mm256_load_pd(&p.k[j]);
        __m256d best = k, spread = _mm256_setzero_pd(), terms = _mm256_andnot_pd(sign, k);
        auto axis = [&](double bMin, double bMax, const double* n, const double* o) __attribute__((target("avx"))) {
            const __m256d nv = _mm256_load_pd(n), ov = _mm256_load_pd(o);
            const __m256d lo = _mm256_sub_pd(_mm256_set1_pd(bMin), ov), hi = _mm256_sub_pd(_mm256_set1_pd(bMax), ov);
            best = _mm256_add_pd(best, _mm256_max_pd(_mm256_mul_pd(nv, hi), _mm256_mul_pd(nv, lo)));
            const __m256d far = _mm256_max_pd(_mm256_andnot_pd(sign, hi), _mm256_andnot_pd(sign, lo));
            spread = _mm256_add_pd(spread, far);
            terms = _mm256_add_pd(terms, _mm256_mul_pd(_mm256_andnot_pd(sign, nv), far));
        };
        axis(b.min.x, b.max.x, &p.nx[j], &p.ox[j]);
        axis(b.min.y, b.max.y, &p.ny[j], &p.oy[j]);
        axis(b.min.z, b.max.z, &p.nz[j], &p.oz[j]);
        const __m256d allowed = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(_mm256_load_pd(&p.rel[j]), spread), _mm256_load_pd(&p.abs[j])), _mm256_mul_pd(round, terms));
        const __m256d bound = _mm256_sub_pd(_mm256_xor_pd(allowed, sign), tiny);
        if (_mm256_movemask_pd(_mm256_cmp_pd(best, bound, _CMP_LT_OQ))) return false;
    }
    return true;
}

__attribute__((target("avx"))) bool planesHoldAvx(const PackedPlanes& p, int count, const Aabb& b) {
    const glm::dvec3 far = glm::max(glm::abs(b.min), glm::abs(b.max));
    const __m256d loX = _mm256_set1_pd(b.min.x), loY = _mm256_set1_pd(b.min.y), loZ = _mm256_set1_pd(b.min.z);
    const __m256d hiX = _mm256_set1_pd(b.max.x), hiY = _mm256_set1_pd(b.max.y), hiZ = _mm256_set1_pd(b.max.z);
    const __m256d farX = _mm256_set1_pd(far.x), farY = _mm256_set1_pd(far.y), farZ = _mm256_set1_pd(far.z);
    const __m256d tiny = _mm256_set1_pd(1e-300), sign = _mm256_set1_pd(-0.0);
    for (size_t i = 0; i < size_t(count); i += 4) {
        const __m256d nx = _mm256_load_pd(&p.nx[i]), ny = _mm256_load_pd(&p.ny[i]), nz = _mm256_load_pd(&p.nz[i]);
        __m256d best = _mm256_add_pd(_mm256_load_pd(&p.c[i]), _mm256_max_pd(_mm256_mul_pd(nx, hiX), _mm256_mul_pd(nx, loX)));
        best = _mm256_add_pd(best, _mm256_max_pd(_mm256_mul_pd(ny, hiY), _mm256_mul_pd(ny, loY)));
        best = _mm256_add_pd(best, _mm256_max_pd(_mm256_mul_pd(nz, hiZ), _mm256_mul_pd(nz, loZ)));
        const __m256d dot = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(_mm256_load_pd(&p.wx[i]), farX), _mm256_mul_pd(_mm256_load_pd(&p.wy[i]), farY)),
            _mm256_mul_pd(_mm256_load_pd(&p.wz[i]), farZ));
        const __m256d bound = _mm256_sub_pd(_mm256_xor_pd(_mm256_add_pd(_mm256_load_pd(&p.err[i]), dot), sign), tiny);
        if (_mm256_movemask_pd(_mm256_cmp_pd(best, bound, _CMP_LT_OQ))) return false;
    }
    return true;
}

// misses: the triangle lies outside a half-space when every vertex x has
//   v = ((nx dx + ny dy) + nz dz) + k < -(((rel |d|_1 + abs) + kRound (|n|_1 |d|_1 + |k|)) + 1e-300),
// d = x - o, |d|_1 = (|dx| + |dy|) + |dz|.
__attribute__((target("avx"))) bool triangleMissesAvx(const PackedHalfSpaces& p, int count, const Triangle& r) {
    const __m256d sign = _mm256_set1_pd(-0.0), tiny = _mm256_set1_pd(1e-300), round = _mm256_set1_pd(kRound);
    for (size_t j = 0; j < size_t(count); j += 4) {
        const __m256d nx = _mm256_load_pd(&p.nx[j]), ny = _mm256_load_pd(&p.ny[j]), nz = _mm256_load_pd(&p.nz[j]);
        const __m256d ox = _mm256_load_pd(&p.ox[j]), oy = _mm256_load_pd(&p.oy[j]), oz = _mm256_load_pd(&p.oz[j]);
        const __m256d k = _mm256_load_pd(&p.k[j]), rel = _mm256_load_pd(&p.rel[j]), abs = _mm256_load_pd(&p.abs[j]);
        const __m256d n1 = _mm256_load_pd(&p.n1[j]), absK = _mm256_andnot_pd(sign, k);
        __m256d out = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        for (const glm::dvec3& x : r) {
            const __m256d dx = _mm256_sub_pd(_mm256_set1_pd(x.x), ox), dy = _mm256_sub_pd(_mm256_set1_pd(x.y), oy),
                          dz = _mm256_sub_pd(_mm256_set1_pd(x.z), oz);
            const __m256d v =
                _mm256_add_pd(_mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(nx, dx), _mm256_mul_pd(ny, dy)), _mm256_mul_pd(nz, dz)), k);
            const __m256d d1 =
                _mm256_add_pd(_mm256_add_pd(_mm256_andnot_pd(sign, dx), _mm256_andnot_pd(sign, dy)), _mm256_andnot_pd(sign, dz));
            const __m256d bound = _mm256_add_pd(
                _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(rel, d1), abs), _mm256_mul_pd(round, _mm256_add_pd(_mm256_mul_pd(n1, d1), absK))),
                tiny);
            out = _mm256_and_pd(out, _mm256_cmp_pd(v, _mm256_xor_pd(bound, sign), _CMP_LT_OQ));
        }
        if (_mm256_movemask_pd(out)) return true;
    }
    return false;
}

}  // namespace

bool ShadowQuery::useAvx(bool on) {
    const bool was = gAvx;
    gAvx = on && __builtin_cpu_supports("avx");
    return was;
}

bool ShadowQuery::misses(const Triangle& r) const {
    if (!gAvx) return missesByLoop(r);
    return triangleMissesAvx(packed_, count_, r) || triangleTooNear(r);
}

bool ShadowQuery::triangleTooNear(const Triangle& r) const {
    if (!pointLight_) return false;
    Aabb b;
    for (const glm::dvec3& x : r) b.extend(x);
    return tooNear(b);
}

bool ShadowQuery::missesByLoop(const Triangle& r) const {
    for (int i = 0; i < count_; ++i) {
        const HalfSpace& h = hs_[size_t(i)];
        bool out = true;
        for (const glm::dvec3& x : r) {
            const glm::dvec3 d = x - h.o;
            const double v = glm::dot(h.n, d) + h.k;
            const double bound = h.rel * norm1(d) + h.abs + kRound * (norm1(h.n) * norm1(d) + std::abs(h.k)) + 1e-300;
            if (!(v < -bound)) {
                out = false;
                break;
            }
        }
        if (out) return true;
    }
    return triangleTooNear(r);
}

bool ShadowQuery::mayHoldByLoop(const Aabb& b) const {
    if (tooNear(b)) return false;
    for (int i = 0; i < count_; ++i) {
        const HalfSpace& h = hs_[size_t(i)];
        double best = h.k, spread = 0, terms = std::abs(h.k);
        for (int a = 0; a < 3; ++a) {
            const double lo = b.min[a] - h.o[a], hi = b.max[a] - h.o[a];
            best += std::max(h.n[a] * lo, h.n[a] * hi);
            const double far = std::max(std::abs(lo), std::abs(hi));
            spread += far;
            terms += std::abs(h.n[a]) * far;
        }
        if (best < -(h.rel * spread + h.abs + kRound * terms) - 1e-300) return false;
    }
    return true;
}

bool ShadowQuery::mayHold(const Aabb& b) const {
    if (!gAvx) return mayHoldByLoop(b);
    return !tooNear(b) && halfSpacesHoldAvx(packed_, count_, b);
}

ShadowQuery::InMesh ShadowQuery::inMesh(const RowTransform& m) const {
    // x = y.x r0 + y.y r1 + y.z r2 + r3, so n . (x - o) + k = n' . y + c with
    // n'_i = n . r_i and c = n . (r3 - o) + k. The bound of a window-local point x,
    // rel |x - o|_1 + abs, is at most rel (sum_i |y_i| |r_i|_1 + |r3 - o|_1) + abs; the
    // rounding of n', c and of the receivers' own mapped vertices (each within a few ulps
    // of sum_i |y_i| |r_i| + |r3|) adds kRound |n|_1 times the same sizes.
    std::array<HalfSpace, 16> hs;
    int count = 0;
    for (int i = 0; i < frustumCount_; ++i) add(hs, count, hs_[size_t(i)]);
    // The slabs of the instance's own axes (the mesh axes mapped to the window: r_i).
    // (An axis the query already has, the same instance's or an unturned one's, adds nothing.)
    if (directional_ || pointLight_)
        for (int i = 0; i < 3; ++i) {
            const glm::dvec3& axis = m.rows[size_t(i)];
            bool known = false;
            for (int j = 0; j < axisCount_ && !known; ++j) known = glm::length(glm::cross(axes_[size_t(j)], axis)) == 0.0;
            if (!known) addSlabs(hs, count, axis);
        }
    InMesh q;
    q.count_ = count;  // mayHold's last four may reach past it: zero planes, holding every box
    if (pointLight_ && near_ > 0) {
        q.query_ = this;
        q.map_ = m;
    }
    const double r1[3] = {norm1(m.rows[0]), norm1(m.rows[1]), norm1(m.rows[2])};
    for (int i = 0; i < count; ++i) {
        const HalfSpace& h = hs[size_t(i)];
        const glm::dvec3 n = {glm::dot(h.n, m.rows[0]), glm::dot(h.n, m.rows[1]), glm::dot(h.n, m.rows[2])};
        const glm::dvec3 toOrigin = m.rows[3] - h.o;
        const double c = glm::dot(h.n, toOrigin) + h.k;
        const double nAbs = norm1(h.n);
        // Also the rounding of evaluating n' . y + c itself (kRound of its terms' sizes).
        glm::dvec3 yWeight;
        for (int a = 0; a < 3; ++a) yWeight[a] = (h.rel + kRound * nAbs) * r1[a] + kRound * std::abs(n[a]);
        PackedPlanes& p = q.planes_;
        const size_t k = size_t(i);
        p.nx[k] = n.x, p.ny[k] = n.y, p.nz[k] = n.z, p.c[k] = c;
        p.wx[k] = yWeight.x, p.wy[k] = yWeight.y, p.wz[k] = yWeight.z;
        p.err[k] = h.rel * norm1(toOrigin) + h.abs + kRound * (nAbs * (norm1(m.rows[3]) + norm1(h.o)) + std::abs(h.k) + std::abs(c));
    }
    return q;
}

bool ShadowQuery::InMesh::mayHoldByLoop(const Aabb& b) const {
    const glm::dvec3 far = glm::max(glm::abs(b.min), glm::abs(b.max));
    const PackedPlanes& p = planes_;
    for (size_t i = 0; i < size_t(count_); ++i) {
        const double best = p.c[i] + std::max(p.nx[i] * b.min.x, p.nx[i] * b.max.x) +
                            std::max(p.ny[i] * b.min.y, p.ny[i] * b.max.y) + std::max(p.nz[i] * b.min.z, p.nz[i] * b.max.z);
        if (best < -(p.err[i] + glm::dot(glm::dvec3(p.wx[i], p.wy[i], p.wz[i]), far)) - 1e-300) return false;
    }
    return query_ ? !query_->tooNear(lsBoxOf(b)) : true;
}

Aabb ShadowQuery::InMesh::lsBoxOf(const Aabb& b) const {
    // The window-local box of the mapped box, grown by the rounding of the mapping.
    const glm::dvec3 c = 0.5 * (b.min + b.max), h = 0.5 * (b.max - b.min);
    const glm::dvec3 centre = map_.apply(c);
    glm::dvec3 half = h.x * glm::abs(map_.rows[0]) + h.y * glm::abs(map_.rows[1]) + h.z * glm::abs(map_.rows[2]);
    const glm::dvec3 size = glm::abs(c.x * map_.rows[0]) + glm::abs(c.y * map_.rows[1]) + glm::abs(c.z * map_.rows[2]) +
                            glm::abs(map_.rows[3]) + half;
    half += kRound * size;
    Aabb ls;
    ls.min = centre - half;
    ls.max = centre + half;
    return ls;
}

bool ShadowQuery::InMesh::mayHold(const Aabb& b) const {
    if (!gAvx) return mayHoldByLoop(b);
    if (!planesHoldAvx(planes_, count_, b)) return false;
    return query_ ? !query_->tooNear(lsBoxOf(b)) : true;
}

}  // namespace shadowcull::geometry
