// columnUnderTerrain: see terrain_column.h.
//
// Coordinates: window-local x-z, less the caster's first vertex o (every coordinate below
// is "caster-local"); heights likewise less o.y. Every quantity that decides is computed in
// Bounded arithmetic (core/rounding.h) from the exact doubles given (the vertices, the
// direction as normalised in double, the bias, the box's bounds); the column of that double
// direction is within s gamma(8) metres of the exact direction's (s <= the window's extent:
// far below the stage's margin, which every threshold below adds twice over).

#include "geometry/terrain_column.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>

#include "core/clip_polygon.h"
#include "core/rounding.h"

namespace shadowcull::geometry {

namespace {

// Casters and terrain cells whose normal has a smaller share upward (|n_y| against |n|_1)
// are not bounded: their planes' heights change by more than 1 / kLeastUpness per metre,
// and a proof there would rest on little. Such a cell only means "not proved".
constexpr double kLeastUpness = 0.05;

// An affine function of the caster-local x-z plane, f(q) = ax q.x + az q.z + c, whose
// coefficients carry their rounding bounds.
struct Affine2 {
    Bounded ax, az, c;
};
Affine2 operator+(const Affine2& f, const Affine2& g) { return {f.ax + g.ax, f.az + g.az, f.c + g.c}; }
Affine2 operator-(const Affine2& f, const Affine2& g) { return {f.ax - g.ax, f.az - g.az, f.c - g.c}; }
Affine2 operator*(const Bounded& k, const Affine2& f) { return {k * f.ax, k * f.az, k * f.c}; }
Affine2 operator-(const Affine2& f) { return {-f.ax, -f.az, -f.c}; }  // exact
Affine2 constant(const Bounded& c) { return {exactly(0.0), exactly(0.0), c}; }
Bounded absUpper(const Bounded& b) { return exactly((std::abs(b.value) + b.error) * (1 + 2 * kUnitRoundoff)); }

// The inward half-plane of the x-z edge a -> b of triangle (a, b, c): (-ez, ex) . (q - a),
// turned to hold c. Nothing when c's side is not certain (a triangle too thin to orient).
std::optional<Affine2> inwardEdge(const Bounded3& a, const Bounded3& b, const Bounded3& c) {
    const Bounded ex = b.x - a.x, ez = b.z - a.z;
    const Affine2 h = {-ez, ex, ez * a.x - ex * a.z};
    const int inward = certainSign(h.ax * c.x + h.az * c.z + h.c);
    if (inward == 0) return std::nullopt;
    return inward > 0 ? h : -h;
}

// The half-plane f >= 0 as the clip tests it: relaxed by f's rounding bound over |q| <= reach
// (its coefficients' errors; the evaluation's own rounding, gamma(4) of its terms), and by
// `drift` metres of slack for the clip's rounded crossing points (each within a few units
// of roundoff of the polygon's extent of the exact crossing: drift, the stage's margin, is
// a million times more). Keeping every point where the relaxed value is >= 0 keeps every
// point where the exact f is.
struct Relaxed {
    double ax, az, c;
    Relaxed(const Affine2& f, double reach, double drift) : ax(f.ax.value), az(f.az.value) {
        const double slope = std::abs(ax) + std::abs(az);
        const double slack = (f.ax.error + f.az.error) * reach + f.c.error + slope * drift +
                             gamma(4) * (slope * reach + std::abs(f.c.value));
        c = f.c.value + slack * (1 + 4 * kUnitRoundoff);
    }
    double at(const glm::dvec2& q) const { return ax * q.x + az * q.y + c; }
};

// A convex polygon of the x-z plane (x in .x, z in .y), clipped in place.
class Polygon {
public:
    explicit Polygon(const std::array<glm::dvec2, 4>& box) : n_(4) { std::copy(box.begin(), box.end(), buffers_[0].begin()); }
    // (A polygon that outgrew its buffer is never empty: conservative.)
    bool empty() const { return n_ == 0 && !overflow_; }
    void clip(const Relaxed& h) {
        if (n_ == 0 || overflow_) return;
        const std::array<glm::dvec2, kMax>& in = buffers_[current_];
        std::array<glm::dvec2, kMax>& out = buffers_[1 - current_];
        size_t m = 0;
        clipPolygon(
            in.data(), n_, [&](const glm::dvec2& p) { return h.at(p); }, closedSide,
            [](const glm::dvec2& p, const glm::dvec2& q, double fp, double fq) { return p + (q - p) * (fp / (fp - fq)); },
            [&](const glm::dvec2& p) {
                if (m < kMax) out[m++] = p;
                else overflow_ = true;
            });
        current_ = 1 - current_;
        n_ = m;
    }

private:
    // A convex polygon clipped by a half-plane gains at most one vertex: 4 + the at most 12
    // half-planes of a cell's program stays under this.
    static constexpr size_t kMax = 32;
    std::array<std::array<glm::dvec2, kMax>, 2> buffers_;
    int current_ = 0;
    size_t n_;
    bool overflow_ = false;
};

// The caster, caster-local, and what every cell's test shares.
struct Column {
    std::array<Bounded3, 3> p;  // the caster's vertices less o (p[0] = 0)
    Bounded3 n;                 // its normal, n.y > 0
    Bounded nd;                 // n . d: < 0 where the light meets the caster's front
    glm::dvec3 d{0.0};          // the light's direction, unit (as rounded), d.y < 0
    Bounded3 dExact;            // d as exact inputs
    double sLeast = 0;          // the least s counted (the bias, rounded down)
    // The caster's x-z edges as inward half-planes h_i(q) = b_i . (q - p_i) >= 0, and
    // b_i . e (e: d's x-z part): a point q - s e lies on the caster's projection when every
    // h_i(q) - s (b_i . e) >= 0.
    std::array<Affine2, 3> edge;
    std::array<Bounded, 3> edgeAlong;
    std::array<int, 3> side{};  // b_i . e's sign: > 0 an upper bound on s, < 0 a lower, 0 uncertain
    // Each lower bound at most each upper (h_l / b_l.e <= h_u / b_u.e, times b_l.e b_u.e < 0):
    // b_u.e h_l - b_l.e h_u >= 0; the caster's alone, shared by every cell.
    std::array<Affine2, 2> pairs;
    int pairCount = 0;
    Aabb localBox;  // the caster's box, caster-local (rounded outward)
};

// The part s in [sLo, sHi] of the column's parameters whose points can lie over the x-z box
// [lo, hi] (caster-local): false when none can. Rounded outward.
bool paramsOver(const Column& col, const glm::dvec2& lo, const glm::dvec2& hi, double& sLo, double& sHi) {
    const double e[2] = {col.d.x, col.d.z};
    const double cMin[2] = {col.localBox.min.x, col.localBox.min.z}, cMax[2] = {col.localBox.max.x, col.localBox.max.z};
    const double bLo[2] = {lo.x, lo.y}, bHi[2] = {hi.x, hi.y};
    for (int a = 0; a < 2; ++a) {
        if (e[a] > 0) {
            sLo = std::max(sLo, (bLo[a] - cMax[a]) / e[a]);
            sHi = std::min(sHi, (bHi[a] - cMin[a]) / e[a]);
        } else if (e[a] < 0) {
            sLo = std::max(sLo, (bHi[a] - cMin[a]) / e[a]);
            sHi = std::min(sHi, (bLo[a] - cMax[a]) / e[a]);
        } else if (cMax[a] < bLo[a] || cMin[a] > bHi[a]) {
            return false;
        }
    }
    // Two roundings each (a difference, a quotient): widen by far more.
    const double widen = 1e-12 * (std::abs(sLo) + std::abs(sHi)) + 1e-300;
    sLo -= widen;
    sHi += widen;
    return sLo <= sHi;
}

// n_g.y c, c = -tolerance - 2 margin |n_g|_1 / n_g.y: below every height over g's plane
// that the terrain rule keeps (its margin is once |n_g| / n_g.y).
Bounded thresholdOf(const Bounded3& ng, double tolerance, double margin) {
    return -(ng.y * exactly(tolerance)) - exactly(2 * margin) * (absUpper(ng.x) + absUpper(ng.y) + absUpper(ng.z));
}

// The cheap bound: the caster's vertices' heights over g's plane (times n_g.y: n_g . (p - g0),
// at the exact window-local vertices) plus s (n_g . d) at its most over [sLo, sHi] (0 <= sLo:
// at sLo where n_g . d < 0 for certain, else at most sHi |n_g . d|), below the threshold.
bool clearByVertices(const Column& col, const Triangle& t, const Triangle& cell, const Bounded3& ng, const Bounded& threshold,
                     double sLo, double sHi) {
    const Bounded ngd = dot(ng, col.dExact);
    const Bounded sTerm = certainSign(ngd) < 0 ? exactly(sLo) * ngd : exactly(sHi) * absUpper(ngd);
    const BoundedPlane over(ng, cell[0], sTerm - threshold);
    for (const glm::dvec3& p : t)
        if (!(certainSign(over.at(p)) < 0)) return false;
    return true;
}

// One terrain cell's linear program, s eliminated: the half-planes over the caster-local x-z
// plane that a column point's q = x.xz must satisfy, clipped into one polygon. Empty: no
// column point there (each half-plane relaxed: Relaxed).
class CellProgram {
public:
    CellProgram(const Column& col, double sLo, double sHi, double margin, double reach)
        : col_(col), sLo_(sLo), sHi_(sHi), margin_(margin), reach_(reach),
          poly_({glm::dvec2(-reach, -reach), glm::dvec2(reach, -reach), glm::dvec2(reach, reach), glm::dvec2(-reach, reach)}) {}
    bool empty() const { return poly_.empty(); }

    // Over cell g (caster-local vertices): its x-z triangle's inward half-planes, grown by 2
    // margin (the terrain rule's prisms are grown by one). False when the cell is too thin
    // to orient.
    bool overCell(const std::array<Bounded3, 3>& g) {
        for (int i = 0; i < 3 && !empty(); ++i) {
            std::optional<Affine2> h = inwardEdge(g[size_t(i)], g[size_t((i + 1) % 3)], g[size_t((i + 2) % 3)]);
            if (!h) return false;
            h->c = h->c + exactly(2 * margin_) * (absUpper(h->ax) + absUpper(h->az));
            clip(*h);
        }
        return true;
    }

    // Some s in [sLo, sHi] puts q - s e on the caster: h_i(q) - s b_i.e >= 0 is s <= h_i / b_i.e
    // (upper) where b_i.e > 0, s >= h_i / b_i.e (lower) where < 0; an edge along e bounds q
    // alone (h_i(q) >= s b_i.e >= -sHi |b_i.e|). Then each lower at most each upper, sLo and
    // sHi included (Fourier-Motzkin; the caster's own pairs made once, Column::pairs); an
    // edge whose sign is uncertain only widens.
    void reachableFromCaster() {
        for (int i = 0; i < 3 && !empty(); ++i) {
            const Affine2& h = col_.edge[size_t(i)];
            const Bounded& be = col_.edgeAlong[size_t(i)];
            const int side = col_.side[size_t(i)];
            if (side == 0)
                clip(h + constant(exactly(sHi_) * absUpper(be)));
            else  // against the constant bound on the other side: upper vs sLo, lower vs sHi
                clip(h - constant(exactly(side > 0 ? sLo_ : sHi_) * be));
        }
        for (int k = 0; k < col_.pairCount && !empty(); ++k) clip(col_.pairs[size_t(k)]);
    }

    // Near enough to the ground: phi(q) + s rate >= 0 for the s the caster's point over q can
    // take (heightTerms). rate < 0: s at its least, max(sLo, the lower bounds): phi + rate sLo
    // >= 0 and, per lower l, phi + rate h_l / b_l.e >= 0, times b_l.e < 0:
    // -(b_l.e phi + rate h_l) >= 0. rate > 0: s at its most, likewise with the uppers. rate's
    // sign uncertain: phi + |rate| sHi (s >= 0).
    void nearTheGround(const Affine2& phi, const Bounded& rate) {
        const int rateSign = certainSign(rate);
        if (rateSign == 0) {
            clip(phi + constant(absUpper(rate) * exactly(sHi_)));
            return;
        }
        clip(phi + constant(rate * exactly(rateSign < 0 ? sLo_ : sHi_)));
        for (int i = 0; i < 3 && !empty(); ++i) {
            if (col_.side[size_t(i)] != rateSign) continue;  // the bounds on s's side that counts
            const Affine2 bound = col_.edgeAlong[size_t(i)] * phi + rate * col_.edge[size_t(i)];
            clip(rateSign < 0 ? -bound : bound);
        }
    }

private:
    // The clip's rounded crossing points drift by far less than the margin (Relaxed).
    void clip(const Affine2& f) { poly_.clip(Relaxed(f, reach_, margin_)); }

    const Column& col_;
    double sLo_, sHi_, margin_, reach_;
    Polygon poly_;
};

// The height of a column point over cell g's plane, less c (thresholdOf), times
// N = n_c.y n_g.y > 0, as phi(q) + s rate at q = x.xz: x.y is the caster's plane height at q
// (through o: T(q) = -(n_c.x q.x + n_c.z q.z) / n_c.y) plus s times d.y - grad(T) . e, and
// g's plane height G(q) is affine too. Returns phi; `rate` = n_g.y (n_c . d).
Affine2 heightTerms(const Column& col, const std::array<Bounded3, 3>& g, const Bounded3& ng, const Bounded& threshold,
                    Bounded& rate) {
    const Bounded3& nc = col.n;
    const Affine2 nT = {-(ng.y * nc.x), -(ng.y * nc.z), exactly(0.0)};                                        // N T(q)
    const Affine2 nG = {-(nc.y * ng.x), -(nc.y * ng.z), nc.y * (ng.y * g[0].y + ng.x * g[0].x + ng.z * g[0].z)};  // N G(q)
    rate = ng.y * col.nd;
    return nT - nG - constant(nc.y * threshold);
}

// True when no point x = p + s d (p on the caster, s in [sLo, sHi]) over terrain cell `g`
// (caster-local; its x-z triangle grown by 2 margin) lies less than the tolerance (plus 2
// margin, scaled to the cell's slope) under g's plane: the cell's linear program is empty.
bool cellClear(const Column& col, const std::array<Bounded3, 3>& g, const Bounded3& ng, const Bounded& threshold, double sLo,
               double sHi, double margin, double reach) {
    Bounded rate;
    const Affine2 phi = heightTerms(col, g, ng, threshold, rate);
    CellProgram program(col, sLo, sHi, margin, reach);
    if (!program.overCell(g)) return false;  // not proved
    // The depth half-planes right after the cell's: with them the polygon is most often
    // empty already, and the caster's edges are not clipped at all (the same set in any
    // order; R's geometry stage 5 % faster than with them last).
    program.nearTheGround(phi, rate);
    if (!program.empty()) program.reachableFromCaster();
    return program.empty();
}

// The caster, caster-local; false when it is too steep to bound.
std::optional<Column> makeColumn(const Triangle& t, const glm::dvec3& d, double bias) {
    Column col;
    col.p = {exactly(glm::dvec3(0.0)), difference(t[1], t[0]), difference(t[2], t[0])};
    col.n = cross(col.p[1], col.p[2]);
    if (col.n.y.value < 0) col.n = -col.n;
    const glm::dvec3 nv = col.n.value();
    if (!(certainSign(col.n.y) > 0) || !(nv.y >= kLeastUpness * (std::abs(nv.x) + std::abs(nv.y) + std::abs(nv.z)))) return std::nullopt;
    col.d = d;
    col.dExact = exactly(d);
    col.nd = dot(col.n, col.dExact);
    col.sLeast = bias * (1 - 1e-12);  // the depth along the exact direction is s (1 +- gamma(8))
    for (int i = 0; i < 3; ++i) {
        const std::optional<Affine2> h = inwardEdge(col.p[size_t(i)], col.p[size_t((i + 1) % 3)], col.p[size_t((i + 2) % 3)]);
        if (!h) return std::nullopt;
        col.edge[size_t(i)] = *h;
        col.edgeAlong[size_t(i)] = h->ax * exactly(d.x) + h->az * exactly(d.z);
        col.side[size_t(i)] = certainSign(col.edgeAlong[size_t(i)]);
    }
    for (size_t l = 0; l < 3; ++l)
        for (size_t u = 0; u < 3; ++u)
            if (col.side[l] < 0 && col.side[u] > 0 && col.pairCount < 2)
                col.pairs[size_t(col.pairCount++)] = col.edgeAlong[u] * col.edge[l] - col.edgeAlong[l] * col.edge[u];
    for (const Bounded3& p : col.p) {
        const glm::dvec3 v = p.value(), e = p.error();
        col.localBox.extend(v - e * (1 + 4 * kUnitRoundoff));
        col.localBox.extend(v + e * (1 + 4 * kUnitRoundoff));
    }
    return col;
}

// Past this parameter no point of the column is inside the window's box `limits` (as
// shadowBox: each axis's far slab over the caster's vertices), rounded up.
double exitParameter(const Triangle& t, const glm::dvec3& d, const Aabb& limits, double margin) {
    double sEnd = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0) continue;
        double far = -std::numeric_limits<double>::infinity();
        for (const glm::dvec3& v : t) far = std::max(far, ((d[a] > 0 ? limits.max[a] : limits.min[a]) - v[a]) / d[a]);
        sEnd = std::min(sEnd, far);
    }
    return std::max(sEnd, 0.0) * (1 + 1e-9) + margin;
}

// The window-local x-z rectangle {x0, z0, x1, z1} holding the column's points of parameters
// [s0, s1]: the caster's box moved by s e, grown by 4 margin (and far more than its
// rounding), then moved back by o.
std::array<double, 4> lsFootprint(const Column& col, const glm::dvec3& o, double s0, double s1, double margin) {
    const glm::dvec2 boxLo(col.localBox.min.x, col.localBox.min.z), boxHi(col.localBox.max.x, col.localBox.max.z);
    const glm::dvec2 e(col.d.x, col.d.z);
    const glm::dvec2 a = boxLo + s0 * e, b = boxLo + s1 * e, c = boxHi + s0 * e, f = boxHi + s1 * e;
    const double widen = 1e-12 * (glm::length(c) + glm::length(f) + glm::length(a) + glm::length(b)) + 4 * margin;
    const glm::dvec2 lo = glm::min(a, b) - glm::dvec2(widen), hi = glm::max(c, f) + glm::dvec2(widen);
    return {lo.x + o.x, lo.y + o.z, hi.x + o.x, hi.y + o.z};
}

// From `sEnd` down: the parameter past which every point of the column lies under the
// lowest ground of its footprint less the tolerance (highest + s d.y < low - tolerance -
// 2 margin; the terrain rule, and every terrain surface above), narrowed twice (a smaller
// footprint, a higher lowest ground). Nothing where part of a footprint has no terrain.
std::optional<double> sinkParameter(const BakeWindow& w, const Column& col, const Triangle& t, double sEnd, double margin) {
    const double highest = std::max({t[0].y, t[1].y, t[2].y});
    for (int pass = 0; pass < 2 && sEnd > col.sLeast; ++pass) {
        const std::array<double, 4> r = lsFootprint(col, t[0], col.sLeast, sEnd, margin);
        const std::optional<double> low = w.lsTerrainMinOver(r[0], r[1], r[2], r[3]);
        if (!low) return std::nullopt;  // part of it has no terrain: the rule says nothing there
        const double sDeep = (highest - (*low - w.terrainTolerance - 2 * margin)) / -col.d.y * (1 + 1e-9) + margin;
        if (!(sDeep < sEnd)) break;
        sEnd = sDeep;
    }
    return sEnd;
}

// Every terrain cell under the column's parameters [sLeast, sEnd] clear: the cheap bound,
// else the cell's program. False at the first that is not (or that is too steep to bound).
bool cellsClear(const BakeWindow& w, const Column& col, const Triangle& t, double sEnd, double margin) {
    const glm::dvec3& o = t[0];
    const std::array<double, 4> r = lsFootprint(col, o, col.sLeast, sEnd, margin);
    thread_local std::vector<std::array<glm::dvec3, 3>> ground;
    ground.clear();
    // (Cells wholly beside the footprint left out: no column point lies over them.)
    const Aabb keep{glm::dvec3(r[0], 0.0, r[1]), glm::dvec3(r[2], 0.0, r[3])};
    if (!w.lsTerrainTrianglesOver(r[0], r[1], r[2], r[3], keep, ground)) return false;
    // Every caster-local coordinate the clips meet lies within `reach` of o.
    const double reach = std::max({std::abs(r[0] - o.x), std::abs(r[2] - o.x), std::abs(r[1] - o.z), std::abs(r[3] - o.z)}) *
                             (1 + 1e-9) + 8 * margin;
    for (const auto& cell : ground) {
        // The parameters whose points can lie over the cell's box (grown by 2 margin, as below).
        glm::dvec2 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        for (const glm::dvec3& v : cell) {
            lo = glm::min(lo, glm::dvec2(v.x - o.x, v.z - o.z));
            hi = glm::max(hi, glm::dvec2(v.x - o.x, v.z - o.z));
        }
        const double grow = 2 * margin + 1e-12 * (glm::length(lo) + glm::length(hi));
        double sLo = col.sLeast, sHi = sEnd;
        if (!paramsOver(col, lo - glm::dvec2(grow), hi + glm::dvec2(grow), sLo, sHi)) continue;
        Bounded3 ng = crossOfDifferences(cell[1] - cell[0], cell[2] - cell[0]);
        if (ng.y.value < 0) ng = -ng;
        const glm::dvec3 nv = ng.value();
        if (!(certainSign(ng.y) > 0) || !(nv.y >= kLeastUpness * (std::abs(nv.x) + std::abs(nv.y) + std::abs(nv.z))))
            return false;
        const Bounded threshold = thresholdOf(ng, w.terrainTolerance, margin);
        if (clearByVertices(col, t, cell, ng, threshold, sLo, sHi)) continue;
        const std::array<Bounded3, 3> g = {difference(cell[0], o), difference(cell[1], o), difference(cell[2], o)};
        if (!cellClear(col, g, ng, threshold, sLo, sHi, margin, reach)) return false;
    }
    return true;
}

}  // namespace

bool columnUnderTerrain(const BakeWindow& w, const Triangle& t, const glm::dvec3& direction, double bias,
                        const Aabb& lsLimits, double margin) {
    if (!w.hasTerrain || !(glm::length(direction) > 0)) return false;
    const glm::dvec3 d = glm::normalize(direction);
    if (!(d.y < -0.01)) return false;  // a light from the side or below: the column does not sink
    const std::optional<Column> col = makeColumn(t, d, bias);
    if (!col) return false;
    // Where the column leaves the loaded window, then where it sinks under all the ground.
    const double sExit = exitParameter(t, d, lsLimits, margin);
    if (!(sExit > col->sLeast)) return false;  // (no column inside: left to the broad phase)
    const std::optional<double> sEnd = sinkParameter(w, *col, t, sExit, margin);
    if (!sEnd) return false;
    if (!(*sEnd > col->sLeast)) return true;  // wholly under the lowest ground from the bias on
    return cellsClear(w, *col, t, *sEnd, margin);
}

}  // namespace shadowcull::geometry
