// The exact part of the geometry stage: see exact_frustum.h. All CGAL use of the project
// is kept in this file (each CGAL translation unit costs ~11 s and 0.7 GB to compile).
// Kernel: CGAL Exact_predicates_exact_constructions_kernel (lazy exact arithmetic over
// interval filters), so every sign below is exact for the double inputs.

#include "geometry/exact_frustum.h"

#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <CGAL/Exact_predicates_exact_constructions_kernel.h>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "core/clip_polygon.h"
#include "core/rounding.h"

namespace shadowcull::geometry {

namespace {

using K = CGAL::Exact_predicates_exact_constructions_kernel;
using FT = K::FT;
using Point = K::Point_3;
using Vector = K::Vector_3;

Point toPoint(const glm::dvec3& p) { return Point(p.x, p.y, p.z); }
Vector toVector(const glm::dvec3& v) { return Vector(v.x, v.y, v.z); }

// An affine function f(x) = n . (x - o) + k; the half-space is f >= 0 (or > 0). Over the
// exact kernel, or over intervals (the fast path, below).
template <class Kn>
struct HalfSpaceT {
    typename Kn::Vector_3 n;
    typename Kn::Point_3 o;
    typename Kn::FT k;
    typename Kn::FT operator()(const typename Kn::Point_3& x) const { return n * (x - o) + k; }
};
using HalfSpace = HalfSpaceT<K>;
// Intervals in double (CGAL's filter arithmetic, rounding upward under
// Protect_FPU_rounding): each sign either certain or an Uncertain_conversion_exception.
using IK = CGAL::Simple_cartesian<CGAL::Interval_nt<false>>;
using IHalfSpace = HalfSpaceT<IK>;

IHalfSpace approx(const HalfSpace& h) { return IHalfSpace{h.n.approx(), h.o.approx(), h.k.approx()}; }

// Upper bound of |n| in double, for moving a half-space outward by a distance.
double normUpper(const Vector& n) {
    const double x = CGAL::to_double(n.x()), y = CGAL::to_double(n.y()), z = CGAL::to_double(n.z());
    return std::sqrt(x * x + y * y + z * z) * (1.0 + 1e-9) + 1e-300;
}

// A point given as doubles (an interval point of zero width) that is bitwise `x`.
bool isExactly(const IK::Point_3& p, const glm::dvec3& x) {
    return p.x().inf() == x.x && p.x().sup() == x.x && p.y().inf() == x.y && p.y().sup() == x.y && p.z().inf() == x.z &&
           p.z().sup() == x.z;
}
bool isExactly(const Point&, const glm::dvec3&) { return false; }  // exact values need no help

// Keeps the part of the convex polygon `poly` where f >= 0 (core/clip_polygon.h). Exact
// over K; over intervals a sign that is not certain throws (the caller then starts over
// exactly), leaving `poly` as it was. `zeros`: points known to lie on f's plane exactly
// (f = 0 there; the interval of f would hold 0 without being it, and the clip would throw).
template <class Kn>
void clip(std::vector<typename Kn::Point_3>& poly, const HalfSpaceT<Kn>& f, const std::array<glm::dvec3, 2>* zeros = nullptr) {
    if (poly.empty()) return;
    using P = typename Kn::Point_3;
    using N = typename Kn::FT;
    std::vector<P> out;
    out.reserve(poly.size() + 1);
    clipPolygon(
        poly.data(), poly.size(),
        [&](const P& p) { return zeros && (isExactly(p, (*zeros)[0]) || isExactly(p, (*zeros)[1])) ? N(0) : f(p); },
        [](const N& v) {
            const CGAL::Sign s = CGAL::sign(v);  // uncertain: throws
            return int(s);
        },
        [](const P& p, const P& q, const N& vp, const N& vq) { return p + (q - p) * (vp / (vp - vq)); },
        [&](const P& p) { out.push_back(p); });
    poly.swap(out);
}

}  // namespace

// The same half-space in double, for a filter in front of the exact test: its normal
// computed by the same formula from the same exact doubles, carrying its rounding bound
// (core/rounding.h), and the same offset (the dilation, the same double). Evaluated in
// round-to-nearest only (before the interval path's upward rounding starts).
struct FastHalfSpace {
    BoundedPlane f;
    // True when every vertex of r lies strictly outside (f < 0) beyond any rounding.
    bool rejects(const Triangle& r) const {
        for (const glm::dvec3& x : r)
            if (certainSign(f.at(x)) >= 0) return false;
        return true;
    }
};

// Condition 1 of semantics.md on a reached part: the caster's plane and the light's
// direction, and where to find occluders. Directional lights only: every point q of the
// part lies on the ray through the caster point p(q) = q - beta(q) d, beta(q) =
// n . (q - a) / (n . d).
template <class Kn>
struct ShadeTest {
    typename Kn::Vector_3 n;  // the caster's normal, n . d > 0
    typename Kn::Point_3 a;   // a caster vertex
    typename Kn::FT nd;       // n . d
    typename Kn::Vector_3 d;
    const OccluderSource* source;
};

struct ExactFrustum::Impl {
    bool degenerate = false;
    bool directional = true;
    std::vector<HalfSpace> sides;  // closed
    // Per side (the triangle frustum's, without dilation): the two caster vertices that lie
    // on it exactly, where the interval clip takes the value 0 instead of an interval
    // around it (a receiver sharing the caster's edge or vertex: a mesh neighbour).
    std::vector<std::array<glm::dvec3, 2>> sideVertices;
    std::vector<FastHalfSpace> fastSides;
    // Near half-space, completed per query with the bias:
    //   directional: nearN . (x - a) - beta * nearK + dilate > 0, nearK = nearN . d > 0
    //   point:       nearN . (x - L) - (1 + beta / dmax) * nearK + dilate > 0, nearK = nearN . (a - L) > 0
    Vector nearN;
    Point nearO;
    FT nearK;
    // Directional light, a caster with area, no dilation: the light's direction, for the
    // occluder test (nearN is then the caster's plane, nearO a vertex, nearK = nearN . d).
    bool shadeable = false;
    Vector dir;
    double dmax = 0.0;      // point lights: upper bound of |p - L| over the caster
    double nearDilate = 0;  // dilation * |nearN|, rounded up
    // Sheets (edge-on casters, directional): the caster's edges the light enters by, in
    // the sheet's plane. Each is an open half-space completed per query like the near one:
    //   m . (x - e) - beta * (m . d) + dilate > 0, with m the edge's normal into the caster
    //   and m . d > 0,
    // so the sheet is exactly {p + s d : p in t, s > beta} in its plane (the two lines
    // along d bound it sideways), not the looser "deeper than the nearest vertex".
    struct Entry {
        Vector m;  // inward (-outward) in-plane normal of the edge
        Point e;   // a point of the edge
        FT mDotD;  // per metre of bias: m . d > 0 (directional), m . (e - L) / dmax > 0 (point)
        double dilate = 0;
    };
    std::vector<Entry> entries;

    // The same half-spaces over intervals, for the fast path of reaches() (made by
    // makeApprox() once the exact ones are built).
    std::vector<IHalfSpace> iSides;
    IHalfSpace iNear;  // k: the dilation only; the bias term is added per query
    IK::FT iNearK;
    struct IEntry {
        IHalfSpace h;  // k: the dilation only
        IK::FT mDotD;
    };
    std::vector<IEntry> iEntries;
    void makeApprox();

    std::vector<Point> insideSides(const Triangle& r) const;
    std::vector<HalfSpace> opens(double beta) const;
    std::vector<IK::Point_3> iInsideSides(const Triangle& r) const;
    bool outsideASide(const Triangle& r) const;
    std::vector<IHalfSpace> iOpens(double beta) const;
    // The occluder test's data, or nothing (no source, or not shadeable).
    std::optional<ShadeTest<K>> shade(const OccluderSource* source) const {
        if (!source || !shadeable) return std::nullopt;
        return ShadeTest<K>{nearN, nearO, nearK, dir, source};
    }
    std::optional<ShadeTest<IK>> iShade(const OccluderSource* source) const {
        if (!source || !shadeable) return std::nullopt;
        return ShadeTest<IK>{nearN.approx(), nearO.approx(), nearK.approx(), dir.approx(), source};
    }
};

namespace {

// A directional light in the caster's plane (edge-on caster, or a caster without area):
// the shadow is the sheet { p + s d : p in t, s > beta } inside the plane spanned by the
// caster and d. Bounded, conservatively, by that plane (two closed half-spaces), the two
// lines along d through the caster's extreme vertices, and the depth of its nearest vertex.
// Returns false when there is no such plane (all vertices on one line along d).
bool buildSheet(ExactFrustum::Impl& m, const Point (&v)[3], const Vector& d, double dilation) {
    Vector n = CGAL::cross_product(v[1] - v[0], v[2] - v[0]);
    if (n == CGAL::NULL_VECTOR) {  // no area: the plane of its longest extent and d
        for (int e = 0; e < 3 && n == CGAL::NULL_VECTOR; ++e) n = CGAL::cross_product(v[(e + 1) % 3] - v[e], d);
        if (n == CGAL::NULL_VECTOR) return false;
    }
    const Vector w = CGAL::cross_product(n, d);  // in the plane, across the light
    int lo = 0, hi = 0, nearest = 0;
    for (int k = 1; k < 3; ++k) {
        if (w * (v[k] - v[lo]) < 0) lo = k;
        if (w * (v[k] - v[hi]) > 0) hi = k;
        if (d * (v[k] - v[nearest]) < 0) nearest = k;
    }
    auto grown = [&](const Vector& a) { return FT(dilation > 0 ? dilation * normUpper(a) : 0.0); };
    m.sides = {HalfSpace{n, v[0], grown(n)}, HalfSpace{-n, v[0], grown(n)}, HalfSpace{w, v[lo], grown(w)},
               HalfSpace{-w, v[hi], grown(w)}};
    m.nearN = d;
    m.nearO = v[nearest];
    m.nearK = d * d;
    m.nearDilate = dilation > 0 ? dilation * normUpper(d) : 0.0;
    // The edges the light enters the caster by: in-plane normal m of edge (p, q) pointing
    // into the caster (towards the third vertex; for a caster without area, towards where
    // the light goes); an edge with m . d > 0 faces the light, and every point p + s d of
    // the sheet lies on its inner side, beyond it by more than beta along d.
    for (int k = 0; k < 3; ++k) {
        const Point &p = v[k], &q = v[(k + 1) % 3], &r = v[(k + 2) % 3];
        if (p == q) continue;
        Vector mk = CGAL::cross_product(n, q - p);  // in the plane, across the edge
        const CGAL::Sign toR = CGAL::sign(mk * (r - p));
        if (toR == CGAL::NEGATIVE) mk = -mk;
        else if (toR == CGAL::ZERO && CGAL::sign(mk * d) == CGAL::NEGATIVE) mk = -mk;  // no area: towards d
        const FT md = mk * d;
        if (CGAL::sign(md) != CGAL::POSITIVE) continue;  // along the light or facing away: no bound
        m.entries.push_back({mk, p, md, dilation > 0 ? dilation * normUpper(mk) : 0.0});
    }
    return true;
}

// A point light in the caster's plane: the shadow is the wedge { L + l (p - L) : p in t,
// l > 1 + beta / dmax } inside that plane. Bounded by the plane (two closed half-spaces),
// the two lines from L through the caster's angular extremes (closed), and, open, the
// edges the light enters by: with m an edge's in-plane normal into the caster and
// m . (e - L) > 0, every point of the wedge has m . (x - e) > (beta / dmax) m . (e - L)
// (a superset of the wedge: conservative). Returns false when there is no such wedge:
// the light on the caster's line or inside or on the caster, seen from which it spans
// half a turn or more.
bool buildPointSheet(ExactFrustum::Impl& m, const Point (&v)[3], const Point& L, double dilation) {
    Vector n = CGAL::cross_product(v[1] - v[0], v[2] - v[0]);
    if (n == CGAL::NULL_VECTOR) {  // no area: the plane of its line and the light
        for (int e = 0; e < 3 && n == CGAL::NULL_VECTOR; ++e) n = CGAL::cross_product(v[(e + 1) % 3] - v[e], L - v[e]);
        if (n == CGAL::NULL_VECTOR) return false;
    }
    // Angular extremes seen from L: every vertex on the inner side of the line from L
    // through `lo` (turning one way about n), and of the line through `hi` (the other).
    auto side = [&](int from, int k) { return CGAL::sign(n * CGAL::cross_product(v[from] - L, v[k] - L)); };
    int lo = -1, hi = -1;
    for (int i = 0; i < 3; ++i) {
        bool allLeft = true, allRight = true;
        for (int k = 0; k < 3; ++k) {
            if (v[k] == L) return false;
            const CGAL::Sign sk = side(i, k);
            allLeft = allLeft && sk != CGAL::NEGATIVE;
            allRight = allRight && sk != CGAL::POSITIVE;
        }
        if (allLeft && lo < 0) lo = i;
        if (allRight && hi < 0) hi = i;
    }
    if (lo < 0 || hi < 0 || lo == hi) return false;  // the caster surrounds the light, or lies on one ray from it
    auto grown = [&](const Vector& a) { return FT(dilation > 0 ? dilation * normUpper(a) : 0.0); };
    const Vector wLo = CGAL::cross_product(n, v[lo] - L), wHi = CGAL::cross_product(n, v[hi] - L);
    HalfSpace sLo{wLo, L, grown(wLo)}, sHi{wHi, L, grown(wHi)};
    // Orient each wedge side towards the caster's other vertices (its interior).
    for (int k = 0; k < 3; ++k) {
        if (CGAL::sign(wLo * (v[k] - L)) == CGAL::NEGATIVE) sLo.n = -wLo;
        if (CGAL::sign(wHi * (v[k] - L)) == CGAL::NEGATIVE) sHi.n = -wHi;
    }
    m.sides = {HalfSpace{n, v[0], grown(n)}, HalfSpace{-n, v[0], grown(n)}, sLo, sHi};
    double dm = 0;
    for (const Point& p : v) dm = std::max(dm, std::sqrt(CGAL::to_double(CGAL::squared_distance(p, L))));
    m.dmax = dm * (1.0 + 1e-9) + 1e-300;
    for (int k = 0; k < 3; ++k) {
        const Point &p = v[k], &q = v[(k + 1) % 3], &r = v[(k + 2) % 3];
        if (p == q) continue;
        Vector mk = CGAL::cross_product(n, q - p);
        const CGAL::Sign toR = CGAL::sign(mk * (r - p));
        if (toR == CGAL::NEGATIVE) mk = -mk;
        else if (toR == CGAL::ZERO && CGAL::sign(mk * (p - L)) == CGAL::NEGATIVE) mk = -mk;  // no area: away from L
        const FT facing = mk * (p - L);
        if (CGAL::sign(facing) != CGAL::POSITIVE) continue;  // the light does not enter by this edge
        m.entries.push_back({mk, p, facing / FT(m.dmax), dilation > 0 ? dilation * normUpper(mk) : 0.0});
    }
    if (m.entries.empty()) return false;
    // The near half-space: the first entry edge again (the opens need one).
    const ExactFrustum::Impl::Entry& first = m.entries.front();
    m.directional = false;
    m.nearN = first.m;
    m.nearO = L;
    m.nearK = first.m * (first.e - L);
    m.nearDilate = first.dilate;
    return true;
}

}  // namespace

ExactFrustum::ExactFrustum(const Triangle& t, const LightGeometry& light, double dilation) : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    m.directional = light.directional;
    const Point a = toPoint(t[0]), b = toPoint(t[1]), c = toPoint(t[2]);
    const Point L = toPoint(light.position);
    const Vector d = toVector(light.direction);
    const Point v[3] = {a, b, c};
    Vector n = CGAL::cross_product(b - a, c - a);
    // Orient the caster's normal away from the light.
    const FT facing = light.directional ? n * d : n * (a - L);
    const CGAL::Sign s = CGAL::sign(facing);
    if (s == CGAL::ZERO) {
        m.degenerate = !(light.directional ? buildSheet(m, v, d, dilation) : buildPointSheet(m, v, L, dilation));
        if (!m.degenerate) m.makeApprox();
        return;
    }
    if (s == CGAL::NEGATIVE) n = -n;
    m.nearN = n;
    m.nearO = light.directional ? a : L;
    m.nearK = s == CGAL::NEGATIVE ? -facing : facing;
    m.shadeable = light.directional && !(dilation > 0);
    m.dir = d;
    if (!light.directional) {
        double dm = 0;
        for (const glm::dvec3& p : t) dm = std::max(dm, glm::length(p - light.position));
        m.dmax = dm * (1.0 + 1e-9) + 1e-300;
    }
    m.nearDilate = dilation > 0 ? dilation * normUpper(n) : 0.0;

    for (int e = 0; e < 3; ++e) {
        const Point& p = v[e];
        const Point& q = v[(e + 1) % 3];
        const Point& r = v[(e + 2) % 3];
        Vector sn = light.directional ? CGAL::cross_product(q - p, d) : CGAL::cross_product(p - L, q - L);
        const Point o = light.directional ? p : L;
        const CGAL::Sign inside = CGAL::sign(sn * (r - o));
        if (inside == CGAL::ZERO) {  // cannot happen when the caster is not edge-on; stay safe
            m.degenerate = true;
            return;
        }
        if (inside == CGAL::NEGATIVE) sn = -sn;
        const double dil = dilation > 0 ? dilation * normUpper(sn) : 0.0;
        m.sides.push_back(HalfSpace{sn, o, FT(dil)});
        if (!(dilation > 0)) m.sideVertices.push_back({t[size_t(e)], t[size_t((e + 1) % 3)]});
        // The double twin: the same formula, the orientation the exact sign chose.
        const glm::dvec3 tp = t[size_t(e)], tq = t[size_t((e + 1) % 3)];
        Bounded3 fn = light.directional ? crossOfDifferences(tq - tp, light.direction)
                                        : crossOfDifferences(tp - light.position, tq - light.position);
        if (inside == CGAL::NEGATIVE) fn = -fn;
        m.fastSides.push_back(FastHalfSpace{BoundedPlane(fn, light.directional ? tp : light.position, exactly(dil))});
    }
    m.makeApprox();
}

ExactFrustum::~ExactFrustum() = default;
ExactFrustum::ExactFrustum(ExactFrustum&&) noexcept = default;
ExactFrustum& ExactFrustum::operator=(ExactFrustum&&) noexcept = default;

bool ExactFrustum::degenerate() const { return impl_->degenerate; }

namespace {

// Whether x > 0: 1 certainly, 0 certainly not, -1 not known (intervals only: an interval
// holding 0, as every vertex that clipping put on the plane has).
int positive(const FT& x) { return CGAL::sign(x) == CGAL::POSITIVE ? 1 : 0; }
int positive(const IK::FT& x) { return x.inf() > 0 ? 1 : x.sup() <= 0 ? 0 : -1; }

// True when the convex polygon `poly` (already inside every closed half-space of the
// frustum) holds a point strictly inside all of `opens`: clipped by their closures, each
// must keep some vertex strictly inside (then the vertices' mean is inside all of them).
// The mean of a polygon's vertices, rounded to double.
template <class PointT>
glm::dvec3 meanOf(const std::vector<PointT>& poly) {
    glm::dvec3 sum(0.0);
    for (const PointT& p : poly) sum += glm::dvec3(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z()));
    return sum / double(poly.size());
}

// Whether the opaque triangle `o` certainly shades the caster point of every point of the
// convex polygon `poly`: each lies in o's closed prism along d, and o's point on its ray lies
// strictly nearer the light than the caster's. Both conditions are affine in the point (the
// planes are fixed), so the polygon's vertices decide the whole polygon. Over intervals an
// uncertain sign answers false (conservative: see shadedWhole).
template <class Num>
int certainSign(const Num& x) {
    return positive(x) == 1 ? 1 : positive(-x) == 1 ? -1 : 0;
}
template <class Kn>
bool shadesWhole(const Triangle& o, const std::vector<typename Kn::Point_3>& poly, const ShadeTest<Kn>& t) {
    using P = typename Kn::Point_3;
    using V = typename Kn::Vector_3;
    using N = typename Kn::FT;
    const P v[3] = {P(o[0].x, o[0].y, o[0].z), P(o[1].x, o[1].y, o[1].z), P(o[2].x, o[2].y, o[2].z)};
    const V m = CGAL::cross_product(v[1] - v[0], v[2] - v[0]);
    const N md = m * t.d;
    const int sm = certainSign(md);
    if (sm == 0) return false;  // edge-on to the light (or uncertain): shades no area
    V side[3];
    for (int e = 0; e < 3; ++e) {
        side[e] = CGAL::cross_product(v[(e + 1) % 3] - v[e], t.d);
        const int inward = certainSign(side[e] * (v[(e + 2) % 3] - v[e]));
        if (inward == 0) return false;
        if (inward < 0) side[e] = -side[e];
    }
    for (const P& q : poly) {
        for (int e = 0; e < 3; ++e)
            if (positive(-(side[e] * (q - v[e]))) != 0) return false;  // not certainly >= 0
        // alpha - beta > 0, alpha = m . (q - v0) / md, beta = n . (q - a) / nd, nd > 0.
        N num = (m * (q - v[0])) * t.nd - (t.n * (q - t.a)) * md;
        if (sm < 0) num = -num;
        if (certainSign(num) <= 0) return false;
    }
    return true;
}

// True when some one occluder the source gives for the polygon's box shades all of it.
template <class Kn>
bool shadedWhole(const std::vector<typename Kn::Point_3>& poly, const ShadeTest<Kn>& t);

// With `inside`: when true, the mean of the clipped polygon's vertices (strictly inside,
// up to its rounding to double: a place to aim a witness ray at, never a proof).
template <class Kn>
bool holdsStrictlyInside(std::vector<typename Kn::Point_3> poly, const std::vector<HalfSpaceT<Kn>>& opens,
                         glm::dvec3* inside = nullptr, const ShadeTest<Kn>* shade = nullptr) {
    for (const HalfSpaceT<Kn>& h : opens) {
        clip(poly, h);
        if (poly.empty()) return false;
    }
    for (const HalfSpaceT<Kn>& h : opens) {
        // One vertex certainly strictly inside is enough, whichever: the vertices clipping
        // put on h's boundary (exactly 0, an interval around 0) must not stop the search
        // before it (they sent most fast-path tests of buried rocks to the exact kernel).
        // None certain but some unknown: the exact kernel decides.
        bool strictly = false, unknown = false;
        for (const typename Kn::Point_3& p : poly) {
            const int s = positive(h(p));
            if (s == 1) {
                strictly = true;
                break;
            }
            unknown |= s < 0;
        }
        if (!strictly && unknown) throw CGAL::Uncertain_conversion_exception("strictly inside: sign not certain");
        if (!strictly) return false;
    }
    // Reached, but no caster point of it lit: no witness can come from here.
    if (shade && shadedWhole<Kn>(poly, *shade)) return false;
    if (inside) *inside = meanOf(poly);
    return true;
}

// The terrain rule on the convex polygon `poly` (inside the frustum's closed sides): some
// point of it strictly inside all `opens`, in the vertical prism of a `ground` triangle
// and not more than `tolerance` under its plane, or over an opening (see
// reachesAboveGround).
template <class Kn>
bool aboveGround(const std::vector<typename Kn::Point_3>& poly, const std::vector<HalfSpaceT<Kn>>& opens,
                 const std::vector<Triangle>& ground, const std::vector<GroundOpening>& openings, double tolerance,
                 glm::dvec3* inside, const ShadeTest<Kn>* shade) {
    using P = typename Kn::Point_3;
    using V = typename Kn::Vector_3;
    using N = typename Kn::FT;
    const V up(0, 1, 0);
    for (const Triangle& g : ground) {
        const P v[3] = {P(g[0].x, g[0].y, g[0].z), P(g[1].x, g[1].y, g[1].z), P(g[2].x, g[2].y, g[2].z)};
        // The plane, its normal turned up; "not deeper than the tolerance under it":
        // n . (x - a) + tolerance * n.y >= 0 (n.y > 0; closed: at the limit q receives).
        V n = CGAL::cross_product(v[1] - v[0], v[2] - v[0]);
        const CGAL::Sign ny = CGAL::sign(n.y());
        if (ny == CGAL::ZERO) return true;  // vertical or no area: stay safe
        if (ny == CGAL::NEGATIVE) n = -n;
        std::vector<P> part = poly;
        // The vertical prism over the triangle: three closed half-spaces through its edges.
        for (int e = 0; e < 3 && !part.empty(); ++e) {
            const P& p = v[e];
            const P& q = v[(e + 1) % 3];
            V side = CGAL::cross_product(q - p, up);  // horizontal, across the edge
            if (CGAL::Sign(CGAL::sign(side * (v[(e + 2) % 3] - p))) == CGAL::NEGATIVE) side = -side;
            clip(part, HalfSpaceT<Kn>{side, p, N(0)});
        }
        if (part.empty()) continue;
        clip(part, HalfSpaceT<Kn>{n, v[0], N(tolerance) * n.y()});
        if (!part.empty() && holdsStrictlyInside<Kn>(part, opens, inside, shade)) return true;
    }
    // Over a square with no terrain: its closed vertical prism, at any height.
    for (const GroundOpening& g : openings) {
        std::vector<P> part = poly;
        const HalfSpaceT<Kn> sides[4] = {{V(1, 0, 0), P(g.x0, 0, 0), N(0)}, {V(-1, 0, 0), P(g.x1, 0, 0), N(0)},
                                         {V(0, 0, 1), P(0, 0, g.z0), N(0)}, {V(0, 0, -1), P(0, 0, g.z1), N(0)}};
        for (const HalfSpaceT<Kn>& h : sides)
            if (!part.empty()) clip(part, h);
        if (!part.empty() && holdsStrictlyInside<Kn>(part, opens, inside, shade)) return true;
    }
    return false;
}

template <class PointT>
std::array<glm::dvec3, 2> boxOf(const std::vector<PointT>& poly) {
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (const PointT& p : poly) {
        const std::pair<double, double> c[3] = {CGAL::to_interval(p.x()), CGAL::to_interval(p.y()), CGAL::to_interval(p.z())};
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], c[a].first);
            hi[a] = std::max(hi[a], c[a].second);
        }
    }
    return {lo, hi};
}

template <class Kn>
bool shadedWhole(const std::vector<typename Kn::Point_3>& poly, const ShadeTest<Kn>& t) {
    // One occluder certainly shading the whole part decides. One that only might (an
    // uncertain sign over intervals) counts as not shading: conservative, the part stays
    // reached; restarting exactly there instead (as clip() does) would cost many exact
    // restarts for parts the exact rule rarely shades. tests/filter_property_test.cpp
    // compares the fast path with the exact rule (never shaded where the exact rule is not,
    // and how often it keeps what the exact rule shades).
    const CGAL::FPU_CW_t testMode = CGAL::FPU_get_cw();  // the caller's: upward for intervals
    bool shaded = false;
    {
        // The source places triangles and walks trees in double, as every other stage
        // does: in round-to-nearest, not in the interval code's upward rounding:
        // placed upward, the caster's own triangle can come out an ulp nearer the light and
        // "shade" the caster: a false cull. Each occluder is tested in the caller's mode.
        CGAL::Protect_FPU_rounding<true> nearest(CGAL_FE_TONEAREST);
        t.source->walk(boxOf(poly), [&](const Triangle& o) {
            CGAL::Protect_FPU_rounding<true> testing(testMode);
            shaded = shadesWhole<Kn>(o, poly, t);
            return shaded;
        });
    }
    if (shaded) t.source->shadedSome.store(true, std::memory_order_relaxed);
    return shaded;
}

}  // namespace

// The receiver clipped by the frustum's closed sides (empty: it misses them), over either
// kernel.
template <class Kn>
std::vector<typename Kn::Point_3> clippedBySides(const std::vector<HalfSpaceT<Kn>>& sides, const Triangle& r,
                                                 const std::vector<std::array<glm::dvec3, 2>>& sideVertices) {
    using P = typename Kn::Point_3;
    std::vector<P> poly = {P(r[0].x, r[0].y, r[0].z), P(r[1].x, r[1].y, r[1].z), P(r[2].x, r[2].y, r[2].z)};
    for (size_t i = 0; i < sides.size(); ++i) {
        clip(poly, sides[i], i < sideVertices.size() ? &sideVertices[i] : nullptr);
        if (poly.empty()) break;
    }
    return poly;
}

std::vector<Point> ExactFrustum::Impl::insideSides(const Triangle& r) const { return clippedBySides<K>(sides, r, sideVertices); }

// The double twins of the sides reject what lies clearly outside one of them, before any
// interval or exact work (in round-to-nearest: their bounds assume it).
bool ExactFrustum::Impl::outsideASide(const Triangle& r) const {
    for (const FastHalfSpace& f : fastSides)
        if (f.rejects(r)) return true;
    return false;
}

// The frustum's open half-spaces for bias `beta`: the near one, and a sheet's entry edges.
std::vector<HalfSpace> ExactFrustum::Impl::opens(double beta) const {
    const FT factor = directional ? FT(beta) : FT(1) + FT(beta) / FT(dmax);
    std::vector<HalfSpace> out = {HalfSpace{nearN, nearO, FT(nearDilate) - factor * nearK}};
    for (const Entry& e : entries) out.push_back(HalfSpace{e.m, e.e, FT(e.dilate) - FT(beta) * e.mDotD});
    return out;
}

void ExactFrustum::Impl::makeApprox() {
    iSides.clear();
    for (const HalfSpace& h : sides) iSides.push_back(approx(h));
    iNear = IHalfSpace{nearN.approx(), nearO.approx(), IK::FT(nearDilate)};
    iNearK = nearK.approx();
    iEntries.clear();
    for (const Entry& e : entries) iEntries.push_back({IHalfSpace{e.m.approx(), e.e.approx(), IK::FT(e.dilate)}, e.mDotD.approx()});
}

std::vector<IK::Point_3> ExactFrustum::Impl::iInsideSides(const Triangle& r) const {
    return clippedBySides<IK>(iSides, r, sideVertices);
}

std::vector<IHalfSpace> ExactFrustum::Impl::iOpens(double beta) const {
    const IK::FT b(beta);
    const IK::FT factor = directional ? b : IK::FT(1) + b / IK::FT(dmax);
    std::vector<IHalfSpace> out = {IHalfSpace{iNear.n, iNear.o, iNear.k - factor * iNearK}};
    for (const IEntry& e : iEntries) out.push_back(IHalfSpace{e.h.n, e.h.o, e.h.k - b * e.mDotD});
    return out;
}

bool ExactFrustum::reaches(const Triangle& r, double beta, std::array<glm::dvec3, 2>* reachedPart,
                           glm::dvec3* inside, const OccluderSource* occluders) const {
    const Impl& m = *impl_;
    if (m.degenerate) {
        if (reachedPart) *reachedPart = {glm::min(glm::min(r[0], r[1]), r[2]), glm::max(glm::max(r[0], r[1]), r[2])};
        if (inside) *inside = (r[0] + r[1] + r[2]) / 3.0;
        return true;
    }
    if (m.outsideASide(r)) return false;
    // Fast path: the same steps over intervals. Every interval encloses the exact value of
    // the step it stands for, so a sign that is certain there is the exact sign, and the
    // answer is the exact one; the first uncertain sign throws and the exact kernel
    // decides from the start (most tests never need it: CGAL's lazy kernel costs ~10x).
    try {
        CGAL::Protect_FPU_rounding<true> upward;
        const std::vector<IK::Point_3> poly = m.iInsideSides(r);
        if (poly.empty()) return false;
        const std::optional<ShadeTest<IK>> shade = m.iShade(occluders);
        const bool reached = holdsStrictlyInside<IK>(poly, m.iOpens(beta), inside, shade ? &*shade : nullptr);
        if (reached && reachedPart) *reachedPart = boxOf(poly);
        return reached;
    } catch (const CGAL::Uncertain_conversion_exception&) {
    }
    const std::vector<Point> poly = m.insideSides(r);
    if (poly.empty()) return false;
    const std::optional<ShadeTest<K>> shade = m.shade(occluders);
    const bool reached = holdsStrictlyInside<K>(poly, m.opens(beta), inside, shade ? &*shade : nullptr);
    if (reached && reachedPart) *reachedPart = boxOf(poly);
    return reached;
}

bool ExactFrustum::reachesExactly(const Triangle& r, double beta, const OccluderSource* occluders) const {
    const Impl& m = *impl_;
    if (m.degenerate) return true;
    const std::vector<Point> poly = m.insideSides(r);
    if (poly.empty()) return false;
    const std::optional<ShadeTest<K>> shade = m.shade(occluders);
    return holdsStrictlyInside<K>(poly, m.opens(beta), nullptr, shade ? &*shade : nullptr);
}

bool ExactFrustum::reachesAboveGround(const Triangle& r, double beta, const std::vector<Triangle>& ground,
                                      const std::vector<GroundOpening>& openings, double tolerance, glm::dvec3* inside,
                                      const OccluderSource* occluders) const {
    const Impl& m = *impl_;
    if (m.degenerate) {
        if (inside) *inside = (r[0] + r[1] + r[2]) / 3.0;
        return true;
    }
    if (m.outsideASide(r)) return false;
    try {  // intervals first, as in reaches()
        CGAL::Protect_FPU_rounding<true> upward;
        const std::vector<IK::Point_3> poly = m.iInsideSides(r);
        if (poly.empty()) return false;
        const std::optional<ShadeTest<IK>> shade = m.iShade(occluders);
        return aboveGround<IK>(poly, m.iOpens(beta), ground, openings, tolerance, inside, shade ? &*shade : nullptr);
    } catch (const CGAL::Uncertain_conversion_exception&) {
    }
    const std::vector<Point> poly = m.insideSides(r);
    if (poly.empty()) return false;
    const std::optional<ShadeTest<K>> shade = m.shade(occluders);
    return aboveGround<K>(poly, m.opens(beta), ground, openings, tolerance, inside, shade ? &*shade : nullptr);
}

FrustumFilter::FrustumFilter(const Triangle& t, const LightGeometry& light, double dilation) : caster_(t), light_(light) {
    shared_ = !(dilation > 0);
    // The caster's normal, away from the light; an uncertain facing (edge-on) disables
    // the filter.
    Bounded3 n = crossOfDifferences(t[1] - t[0], t[2] - t[0]);
    const Bounded facing = light.directional ? BoundedPlane(n, glm::dvec3(0.0), exactly(0.0)).at(light.direction)
                                             : BoundedPlane(n, light.position, exactly(0.0)).at(t[0]);
    const int s = certainSign(facing);
    if (s == 0) return;
    if (s < 0) n = -n;
    // n . d, for the bias, with its bound: absolute, not relative to n . d (near edge-on,
    // n . d is the small difference of two products and its error is as large as theirs).
    nearK_ = light.directional ? Bounded{std::abs(facing.value), facing.error} : exactly(0.0);
    // Near plane: n . (x - a) > 0 is strictly behind the caster (the bias only shrinks it;
    // a dilation r moves it towards the light by r |n|).
    planes_[3] = makePlane(n, t[0], dilation, 0, 1);
    for (int e = 0; e < 3; ++e) {
        SidePlane side;
        if (!doubleSidePlane(t, e, light, side)) return;
        planes_[e] = makePlane(side.n, side.o, dilation, e, (e + 1) % 3);
    }
    // The near plane holds all three caster vertices; sides hold the two of their edge.
    valid_ = true;
}

// A plane of the filter, moved outward by `dilation` as the exact frustum moves its twin
// (dilation * normUpper(n*), n* the exact normal read back through CGAL's interval): the
// offsets differ by dilation (1 + 1e-9) | |to_double(n*)| - |n| | plus their roundings.
// |n - n*| <= |n.error()|_1; to_double(n*) lies in CGAL's interval around n*, whose width
// per operation is at most two ulps (4 u of the result, where Bounded allows u) and so at
// most 4 |n.error()|_1 in all: the normals differ by at most 5 |n.error()|_1, taken as 8
// for the products' own rounding; the two lengths, products and the 1e-9 factor round each
// offset by gamma(6): kError = 8 dilation |n.error()|_1 + gamma(12) k.
FrustumFilter::Plane FrustumFilter::makePlane(const Bounded3& n, const glm::dvec3& o, double dilation, int v0, int v1) {
    Bounded k = exactly(0.0);
    if (dilation > 0) {
        const glm::dvec3 err = n.error();
        const double offset = dilation * glm::length(n.value()) * (1 + 1e-9);
        k = Bounded{offset, 8 * dilation * (err.x + err.y + err.z) + gamma(12) * offset};
    }
    return Plane{BoundedPlane(n, o, k), {v0, v1}};
}

// n . (x - o) + k - beta K (K = n . d, the near plane only) in double against the exact
// frustum's n* . (x - o) + k* - beta n* . d: certainly negative (core/rounding.h).
bool FrustumFilter::beyond(const Plane& p, const glm::dvec3& x, double beta) const {
    const Bounded v = p.f.at(x);
    return certainSign(&p == &planes_[3] && beta != 0 ? v - exactly(beta) * nearK_ : v) < 0;
}

// Every vertex of r strictly outside `p` (beyond rounding), or, without dilation, equal
// to a caster vertex that lies on `p` exactly. `beta`: the bias (the near plane only).
bool FrustumFilter::outside(const Plane& p, const Triangle& r, double beta) const {
    for (const glm::dvec3& x : r) {
        if (beyond(p, x, beta)) continue;
        bool on = false;
        if (shared_) {
            if (&p == &planes_[3]) on = x == caster_[0] || x == caster_[1] || x == caster_[2];
            else on = x == caster_[size_t(p.onPlane[0])] || x == caster_[size_t(p.onPlane[1])];
        }
        if (!on) return false;
    }
    return true;
}

// Along the ray through caster point p the receiver's plane lies at (directional)
// s(p) = n.(r0 - p) / n.d beyond p, or (point light, ray L + l (p - L)) at
// l(p) - 1 = n.(r0 - p) / n.(p - L). Numerators and denominators are affine in p, so when
// at each caster vertex they have certain and opposite signs (and, for a point light, the
// denominators one sign), the plane is in front of the caster over the whole column, and
// so is every receiver point in it: none is behind the caster. A caster vertex shared
// with the receiver has numerator exactly 0 and is let through: the plane is then in front
// or in the caster's plane, never behind. Without dilation only.
bool FrustumFilter::receiverPlaneInFront(const Triangle& r, double beta) const {
    return receiverPlaneInFrontOf(r, caster_.data(), 3, light_, beta, 0.0, true);
}

bool FrustumFilter::certainlyMisses(const Triangle& r, double beta) const {
    if (!valid_) return false;
    if (!light_.directional) beta = 0;
    if (shared_ && receiverPlaneInFront(r, beta)) return true;
    // The near plane moved back by the bias: n . (x - a) - beta n.d > 0 (n.d > 0).
    if (outside(planes_[3], r, beta)) return true;
    // Convexity: a triangle with every vertex outside a closed side (or outside-or-on the
    // open near plane, or on a side only where the caster itself is) has no point in the
    // frustum but possibly the caster's own boundary, which is not behind the caster.
    for (int e = 0; e < 3; ++e)
        if (outside(planes_[e], r, 0.0)) return true;
    return false;
}

bool FrustumFilter::allInFront(const glm::dvec3* pts, size_t count, double beta) const {
    if (!valid_) return false;
    if (!light_.directional) beta = 0;
    for (size_t i = 0; i < count; ++i)
        if (!beyond(planes_[3], pts[i], beta)) return false;
    return true;
}

bool receiverPlaneInFrontOf(const Triangle& r, const glm::dvec3* pts, int count, const LightGeometry& light, double beta,
                            double slack, bool sharedOnPlane) {
    const Bounded3 n = crossOfDifferences(r[1] - r[0], r[2] - r[0]);
    // A point known only up to `slack` metres moves n* . p by at most slack |n*|.
    const glm::dvec3 nErr = n.error();
    const double extra = slack > 0 ? slack * (glm::length(n.value()) + nErr.x + nErr.y + nErr.z) * (1 + gamma(4)) : 0.0;
    // n . (p - L) (points; directional: n . d, the same for every p) and n . (p - r0).
    const BoundedPlane toward(n, light.directional ? glm::dvec3(0.0) : light.position, exactly(0.0));
    const BoundedPlane behind(n, r[0], exactly(0.0));
    const Bounded denDirectional = toward.at(light.direction);
    int denSign = 0;
    for (int i = 0; i < count; ++i) {
        const glm::dvec3& p = pts[i];
        const Bounded den = light.directional ? denDirectional : toward.at(p);
        const int ds = certainSign(den, extra);
        if (ds == 0 || (denSign != 0 && ds != denSign)) return false;
        denSign = ds;
        // A caster vertex that is a receiver vertex lies on the receiver's plane: its
        // numerator is exactly 0 (the plane touches the column there, in the caster's
        // own plane, which is not behind it).
        if (sharedOnPlane && beta == 0 && (p == r[0] || p == r[1] || p == r[2])) continue;
        // Directional: s - beta = (num - beta den) / den must be < 0 (beta is 0 for points);
        // slack moves num by extra at most (beta den moves with p for points only, where
        // beta is 0).
        const Bounded num = beta != 0 ? -behind.at(p) - exactly(beta) * den : -behind.at(p);
        const int ns = certainSign(num, extra);
        if (ns == 0 || ns == ds) return false;
    }
    return true;
}

bool doubleSidePlane(const Triangle& t, int e, const LightGeometry& light, SidePlane& out) {
    const glm::dvec3 tp = t[size_t(e)], tq = t[size_t((e + 1) % 3)], tr = t[size_t((e + 2) % 3)];
    out.o = light.directional ? tp : light.position;
    out.n = light.directional ? crossOfDifferences(tq - tp, light.direction)
                              : crossOfDifferences(tp - light.position, tq - light.position);
    const int inside = certainSign(BoundedPlane(out.n, out.o, exactly(0.0)).at(tr));
    if (inside == 0) return false;
    if (inside < 0) out.n = -out.n;
    return true;
}

int exactFacing(const Triangle& r, bool mirrored, const LightGeometry& light) {
    // Filter: the sign in double when it is certain (core/rounding.h), else exactly.
    {
        const Bounded3 n = crossOfDifferences(r[1] - r[0], r[2] - r[0]);
        const int along = certainSign(light.directional ? BoundedPlane(n, glm::dvec3(0.0), exactly(0.0)).at(light.direction)
                                                        : BoundedPlane(n, light.position, exactly(0.0)).at(r[0]));
        if (along != 0) return mirrored ? along : -along;
    }
    const Point a = toPoint(r[0]), b = toPoint(r[1]), c = toPoint(r[2]);
    const Vector n = CGAL::cross_product(b - a, c - a);
    // Front faces the light when the light travels against the normal.
    const FT along = light.directional ? n * toVector(light.direction) : n * (a - toPoint(light.position));
    int s = -int(CGAL::sign(along));
    return mirrored ? -s : s;
}

}  // namespace shadowcull::geometry
