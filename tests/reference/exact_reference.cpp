// The exact reference: see exact_reference.h. Every number below is an exact rational
// (the doubles of the window converted without rounding); where an irrational quantity
// enters (|d|, tan theta, cos of the cone) it is replaced by a rational bound on the side
// that keeps the answer true: lower bounds for a Zero, upper bounds for a One.

#include "tests/reference/exact_reference.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include "tests/reference/exact_lp.h"

namespace shadowcull::reference {

namespace {

using Q = Rational;
using Lp = ExactLp;

struct QVec {
    Q x, y, z;
    QVec() = default;
    QVec(Q a, Q b, Q c) : x(std::move(a)), y(std::move(b)), z(std::move(c)) {}
    explicit QVec(const glm::dvec3& v) : x(v.x), y(v.y), z(v.z) {}
    const Q& operator[](int k) const { return k == 0 ? x : k == 1 ? y : z; }
    Q& operator[](int k) { return k == 0 ? x : k == 1 ? y : z; }
};
QVec operator-(const QVec& a, const QVec& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
QVec operator+(const QVec& a, const QVec& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
QVec operator*(const Q& s, const QVec& a) { return {s * a.x, s * a.y, s * a.z}; }
Q dot(const QVec& a, const QVec& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
QVec cross(const QVec& a, const QVec& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
Q abs1(const QVec& a) { return abs(a.x) + abs(a.y) + abs(a.z); }
glm::dvec3 toDouble(const QVec& a) { return {a.x.get_d(), a.y.get_d(), a.z.get_d()}; }

// Rational bounds of sqrt(x), x >= 0: lower <= sqrt(x) <= upper, checked exactly.
Q sqrtLower(const Q& x) {
    if (x <= 0) return 0;
    Q y(std::sqrt(x.get_d()) * (1 - 1e-9));
    while (y * y > x) y *= Q(1, 2);
    return y;
}
Q sqrtUpper(const Q& x) {
    if (x <= 0) return 0;
    Q y(std::sqrt(x.get_d()) * (1 + 1e-9));
    if (y <= 0) y = Q(1, 1) / Q(mpz_class(1) << 1000);
    while (y * y < x) y *= 2;
    return y;
}

struct Tri {
    QVec v[3];
    QVec n;  // (v1 - v0) x (v2 - v0), unnormalised
    bool repeated = false;
    const RefTriangle* src = nullptr;
};

struct LightQ {
    bool directional = true, spot = false;
    QVec d;         // directional: the way light travels; spot: its axis
    QVec L;         // point, spot
    Q range, rangeSq;
    Q bias, slopeBias, filterRadius, normalBias;
    Q dLenLo, dLenHi;  // directional: bounds of |d|
    Q dSq;
    Q cosHi;  // spot: an upper bound of the cosine of the cone's half-angle
};

LightQ lightOf(const Light& l) {
    LightQ q;
    q.directional = l.type == LightType::Directional;
    q.spot = l.type == LightType::Spot;
    q.d = QVec(l.direction);
    q.L = QVec(l.position);
    q.range = Q(l.range);
    q.rangeSq = q.range * q.range;
    q.bias = Q(l.bias);
    q.slopeBias = Q(l.slopeBias);
    q.filterRadius = Q(l.filterRadius);
    q.normalBias = Q(l.normalBias);
    q.dSq = dot(q.d, q.d);
    q.dLenLo = sqrtLower(q.dSq);
    q.dLenHi = sqrtUpper(q.dSq);
    // cos(angle) in double is within an ulp or two; 1e-12 covers it (and the degrees-to-
    // radians rounding) with room.
    const double c = std::cos(l.coneHalfAngleDeg * 3.14159265358979323846 / 180.0);
    q.cosHi = Q(std::max(0.0, c) + 1e-12);
    return q;
}

// The exact facing of a receiver: +1 front towards the light, -1 back, 0 edge-on.
int facing(const Tri& r, const LightQ& L) {
    const Q along = L.directional ? dot(r.n, L.d) : dot(r.n, r.v[0] - L.L);
    const int s = along < 0 ? 1 : along > 0 ? -1 : 0;  // light travels against the front normal
    return r.src->mirrored ? -s : s;
}

// tan(theta)^2 between the light ray (direction `ray`) and the receiver's normal; nothing
// when the ray lies in its plane (tan infinite).
std::optional<Q> tanSquared(const QVec& n, const QVec& ray) {
    const Q nd = dot(n, ray);
    if (nd == 0) return std::nullopt;
    const QVec c = cross(n, ray);
    return dot(c, c) / (nd * nd);
}

bool inReach(const QVec& x, const LightQ& L) {
    if (L.directional) return true;
    const QVec v = x - L.L;
    const Q dd = dot(v, v);
    if (dd > L.rangeSq) return false;
    if (!L.spot) return true;
    const Q along = dot(v, L.d);
    if (!(along > 0)) return false;
    return along * along >= L.cosHi * L.cosHi * dd * L.dSq;
}

// --- The pair program ---------------------------------------------------------------------
//
// Variables: w0..w2 (caster weights; point lights: times l), m0..m2 (receiver weights),
// s (directional: q' = p + s d; point: l, q' = L + l (p - L)), then, with a dilation delta,
// e0..e2 in [0, 2 delta] (q' = q + e - delta).
struct PairProgram {
    Lp lp;
    int vars;
    explicit PairProgram(int n) : lp(n), vars(n) {}
};

PairProgram makePair(const Tri& t, const Tri& r, const LightQ& L, const Q& delta, bool reach) {
    const bool dil = delta > 0;
    PairProgram P(dil ? 10 : 7);
    const int n = P.vars;
    auto row = [&]() { return std::vector<Q>(size_t(n), Q(0)); };
    if (L.directional) {
        std::vector<Q> a = row();
        a[0] = a[1] = a[2] = 1;
        P.lp.add(a, Lp::Relation::Equal, 1);
    } else {
        std::vector<Q> a = row();  // sum w = l
        a[0] = a[1] = a[2] = 1;
        a[6] = -1;
        P.lp.add(a, Lp::Relation::Equal, 0);
    }
    {
        std::vector<Q> a = row();
        a[3] = a[4] = a[5] = 1;
        P.lp.add(a, Lp::Relation::Equal, 1);
    }
    for (int k = 0; k < 3; ++k) {
        // Directional: sum m b + e - delta - sum w a - s d = 0.
        // Point:       sum m b + e - delta - sum w a + l L = L  (q' - L = sum w (a - L)).
        std::vector<Q> a = row();
        for (int j = 0; j < 3; ++j) a[size_t(3 + j)] = r.v[j][k];
        for (int i = 0; i < 3; ++i) a[size_t(i)] = -t.v[i][k];
        a[6] = L.directional ? Q(-L.d[k]) : Q(L.L[k]);
        if (dil) a[size_t(7 + k)] = 1;
        P.lp.add(a, Lp::Relation::Equal, (L.directional ? Q(0) : L.L[k]) + delta);
        if (dil) {
            std::vector<Q> e = row();
            e[size_t(7 + k)] = 1;
            P.lp.add(e, Lp::Relation::LessEqual, 2 * delta);
        }
    }
    if (!L.directional && reach) {
        // p within range (its box): |sum w a_k - l L_k| <= R l; q within range: |q_k - L_k| <= R.
        for (int k = 0; k < 3; ++k) {
            std::vector<Q> a = row(), b = row(), c = row();
            for (int i = 0; i < 3; ++i) a[size_t(i)] = b[size_t(i)] = t.v[i][k];
            a[6] = -L.L[k] - L.range;
            b[6] = -L.L[k] + L.range;
            P.lp.add(a, Lp::Relation::LessEqual, 0);
            P.lp.add(b, Lp::Relation::GreaterEqual, 0);
            for (int j = 0; j < 3; ++j) c[size_t(3 + j)] = r.v[j][k];
            P.lp.add(c, Lp::Relation::LessEqual, L.L[k] + L.range);
            P.lp.add(c, Lp::Relation::GreaterEqual, L.L[k] - L.range);
        }
        if (L.spot) {
            // Inside the cone's half-space (half-angle <= 90 degrees): (x - L) . axis >= 0.
            std::vector<Q> a = row(), c = row();
            for (int i = 0; i < 3; ++i) a[size_t(i)] = dot(t.v[i], L.d);
            a[6] = -dot(L.L, L.d);
            P.lp.add(a, Lp::Relation::GreaterEqual, 0);
            for (int j = 0; j < 3; ++j) c[size_t(3 + j)] = dot(r.v[j], L.d);
            P.lp.add(c, Lp::Relation::GreaterEqual, dot(L.L, L.d));
        }
    }
    return P;
}

std::vector<Q> unitObjective(int n, int k) {
    std::vector<Q> c(size_t(n), Q(0));
    c[size_t(k)] = 1;
    return c;
}

// Exact: does the open segment from the light to p (directional: the open ray from p
// against the light's direction) meet triangle o (closed; a triangle with repeated
// vertices is its segment or point)?
bool meets(const Tri& o, const QVec& p, const LightQ& L) {
    // Cheap exact box test first.
    for (int k = 0; k < 3; ++k) {
        Q lo = o.v[0][k], hi = o.v[0][k];
        for (int i = 1; i < 3; ++i) {
            lo = std::min(lo, o.v[i][k]);
            hi = std::max(hi, o.v[i][k]);
        }
        if (L.directional) {
            // Ray p - u d, u > 0.
            const Q& dk = L.d[k];
            if (dk == 0) {
                if (p[k] < lo || p[k] > hi) return false;
            } else if (dk > 0) {
                if (lo >= p[k]) return false;  // the ray goes to smaller values (strictly)
            } else {
                if (hi <= p[k]) return false;
            }
        } else {
            const Q a = std::min(p[k], L.L[k]), b = std::max(p[k], L.L[k]);
            if (hi < a || lo > b) return false;
        }
    }
    // x = sum lambda o_i = p - u d (u > 0), or L + w (p - L) with w in (0, 1).
    Lp lp(4);
    std::vector<Q> a(4, Q(0));
    a[0] = a[1] = a[2] = 1;
    lp.add(a, Lp::Relation::Equal, 1);
    const QVec pl = p - L.L;
    for (int k = 0; k < 3; ++k) {
        std::vector<Q> b(4, Q(0));
        for (int i = 0; i < 3; ++i) b[size_t(i)] = o.v[i][k];
        if (L.directional) {
            b[3] = L.d[k];
            lp.add(b, Lp::Relation::Equal, p[k]);
        } else {
            b[3] = -pl[k];
            lp.add(b, Lp::Relation::Equal, L.L[k]);
        }
    }
    ++refCounters().lps;
    if (L.directional) {
        if (lp.maximise(unitObjective(4, 3)) != Lp::Outcome::Optimal) return false;
        return lp.value() > 0;
    }
    std::vector<Q> c(4, Q(0));
    c[3] = 1;
    lp.add(c, Lp::Relation::LessEqual, 1);
    if (lp.maximise(unitObjective(4, 3)) != Lp::Outcome::Optimal) return false;
    const Q hi = lp.value();
    std::vector<Q> neg(4, Q(0));
    neg[3] = -1;
    if (lp.maximise(neg) != Lp::Outcome::Optimal) return false;
    const Q lo = -lp.value();
    return hi > 0 && lo < 1;
}

struct Context {
    const RefScene& scene;
    std::vector<Tri> tris;
    std::vector<const Tri*> terrain;
};

// Not deeper than the tolerance under any terrain triangle over q (the terrain itself is
// exempt). Stricter than "the lowest surface decides" where terrains overlap.
bool aboveTerrain(const Context& c, const QVec& q) {
    const Q tol(c.scene.terrainTolerance);
    for (const Tri* g : c.terrain) {
        // The closed xz-triangle holds (q.x, q.z)?
        auto orient = [&](const QVec& a, const QVec& b) -> Q { return (b.x - a.x) * (q.z - a.z) - (b.z - a.z) * (q.x - a.x); };
        const Q o0 = orient(g->v[0], g->v[1]), o1 = orient(g->v[1], g->v[2]), o2 = orient(g->v[2], g->v[0]);
        const bool inside = (o0 >= 0 && o1 >= 0 && o2 >= 0) || (o0 <= 0 && o1 <= 0 && o2 <= 0);
        if (!inside || g->n.y == 0) continue;
        // Plane height at (q.x, q.z): n . (x - v0) = 0.
        const Q h = g->v[0].y - (g->n.x * (q.x - g->v[0].x) + g->n.z * (q.z - g->v[0].z)) / g->n.y;
        if (q.y < h - tol) return false;
    }
    return true;
}

// Checks the witness (p on caster t, q on receiver r) exactly against every condition.
bool isWitness(const Context& c, const LightQ& L, const Tri& r, const QVec& p, const QVec& q, std::string& why) {
    ++refCounters().witnessTries;
    if (!L.directional && dot(p - L.L, p - L.L) == 0) return false;
    if (!inReach(p, L) || !inReach(q, L)) return false;
    if (!r.src->twoSided && facing(r, L) <= 0) return false;
    // Depth: q beyond p on p's ray by more than an upper bound of the bias.
    const QVec ray = L.directional ? L.d : q - L.L;
    Q beta = L.bias;
    if (L.slopeBias > 0) {
        const std::optional<Q> t2 = tanSquared(r.n, ray);
        if (!t2) return false;
        beta += L.slopeBias * sqrtUpper(*t2);
    }
    const QVec pq = q - p;
    if (L.directional) {
        // q - p = s d with s > 0: depth difference s |d|.
        const Q s = dot(pq, L.d) / L.dSq;
        const QVec off = pq - s * L.d;
        if (off.x != 0 || off.y != 0 || off.z != 0 || !(s > 0)) return false;
        if (!(s * s * L.dSq > beta * beta)) return false;
    } else {
        const QVec pl = p - L.L, ql = q - L.L;
        const Q l = dot(ql, pl) / dot(pl, pl);
        const QVec off = ql - l * pl;
        if (off.x != 0 || off.y != 0 || off.z != 0 || !(l > 1)) return false;
        if (!((l - 1) * (l - 1) * dot(pl, pl) > beta * beta)) return false;
    }
    if (!r.src->terrain && !aboveTerrain(c, q)) return false;
    for (const Tri& o : c.tris) {
        if (!o.src->blocksLight) continue;
        if (meets(o, p, L)) return false;
    }
    why = "witness p (" + std::to_string(p.x.get_d()) + " " + std::to_string(p.y.get_d()) + " " + std::to_string(p.z.get_d()) +
          ") q (" + std::to_string(q.x.get_d()) + " " + std::to_string(q.y.get_d()) + " " + std::to_string(q.z.get_d()) +
          ") on object " + std::to_string(r.src->object) + " group " + std::to_string(r.src->group);
    return true;
}

// p and q of a solution of the (undilated) pair program.
void pointsOf(const std::vector<Q>& x, const Tri& t, const Tri& r, const LightQ& L, QVec& p, QVec& q) {
    p = QVec(Q(0), Q(0), Q(0));
    q = p;
    for (int i = 0; i < 3; ++i) p = p + x[size_t(i)] * t.v[i];
    if (!L.directional) {
        const Q l = x[6];
        p = (Q(1) / l) * p;
    }
    for (int j = 0; j < 3; ++j) q = q + x[size_t(3 + j)] * r.v[j];
}

// Looks for a witness among points of the pairs with s (or l) at least `floor`: vertices
// that maximise each weight, and their average (a point inside the pairs' set, away from
// the edges where a touching occluder blocks).
bool searchWitness(const Context& c, const LightQ& L, const Tri& t, const Tri& r, const std::vector<Q>& best, const Q& floor,
                   RefAnswer& out) {
    std::vector<std::vector<Q>> sols = {best};
    for (int k = 0; k < 6; ++k) {
        PairProgram P = makePair(t, r, L, Q(0), true);
        std::vector<Q> a(size_t(P.vars), Q(0));
        a[6] = 1;
        P.lp.add(a, Lp::Relation::GreaterEqual, floor);
        ++refCounters().lps;
        if (P.lp.maximise(unitObjective(P.vars, k)) == Lp::Outcome::Optimal) sols.push_back(P.lp.solution());
    }
    std::vector<Q> mean(best.size(), Q(0));
    for (const auto& s : sols)
        for (size_t i = 0; i < s.size(); ++i) mean[i] += s[i];
    for (Q& v : mean) v /= Q(long(sols.size()));
    sols.insert(sols.begin(), mean);
    for (const auto& s : sols) {
        QVec p, q;
        if (!L.directional && !(s[6] > 0)) continue;
        pointsOf(s, t, r, L, p, q);
        std::string why;
        if (isWitness(c, L, r, p, q, why)) {
            out.verdict = RefVerdict::One;
            out.why = why;
            out.p = toDouble(p);
            out.q = toDouble(q);
            return true;
        }
    }
    return false;
}

// Two exact projections of the pair test that need no program: the depth along d, and the
// two directions across it (directional lights only). True when no pair of t and r (r
// widened by `delta`) can have s above `thr`.
bool prefilterExcludes(const Tri& t, const Tri& r, const LightQ& L, const Q& delta, const Q& thr) {
    if (!L.directional) return false;
    const QVec& d = L.d;
    auto range = [](const Tri& x, const QVec& axis, Q& lo, Q& hi) {
        lo = hi = dot(x.v[0], axis);
        for (int i = 1; i < 3; ++i) {
            const Q v = dot(x.v[i], axis);
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        }
    };
    Q tlo, thi, rlo, rhi;
    range(t, d, tlo, thi);
    range(r, d, rlo, rhi);
    // (q' - p) . d = s |d|^2, q' = q + e with |e_k| <= delta.
    if (rhi + delta * abs1(d) - tlo <= thr * L.dSq) return true;
    // Across: (q' - p) . u = 0 for every u normal to d.
    int k = 0;
    for (int i = 1; i < 3; ++i)
        if (abs(d[i]) < abs(d[k])) k = i;
    QVec e(Q(0), Q(0), Q(0));
    e[k] = 1;
    const QVec u = cross(d, e), v = cross(d, u);
    for (const QVec* axis : {&u, &v}) {
        range(t, *axis, tlo, thi);
        range(r, *axis, rlo, rhi);
        const Q grow = delta * abs1(*axis);
        if (rhi + grow < tlo || rlo - grow > thi) return true;
    }
    return false;
}

}  // namespace

RefCounters& refCounters() {
    static RefCounters c;
    return c;
}

const char* refVerdictName(RefVerdict v) {
    switch (v) {
        case RefVerdict::One: return "1";
        case RefVerdict::Zero: return "0";
        default: return "unsure";
    }
}

RefScene referenceScene(const BakeWindow& w) {
    RefScene s;
    s.lights = w.lsLights;
    s.terrainTolerance = w.terrainTolerance;
    for (size_t k = 0; k < w.objects.size(); ++k) {
        const WindowObject& o = w.objects[k];
        s.castsShadow.push_back(o.castsShadow);
        const Mesh& m = *o.mesh;
        const RowTransform& t = o.lsTransform;
        // Mirrored when the placement's linear part has a negative determinant (computed
        // here exactly, not taken from the window).
        const QVec r0(t.rows[0]), r1(t.rows[1]), r2(t.rows[2]);
        const bool mirrored = dot(r0, cross(r1, r2)) < 0;
        const bool terrain = o.kind == ChunkObject::Kind::Terrain;
        s.hasTerrain |= terrain;
        for (size_t i = 0; i < m.triangles.size(); ++i) {
            RefTriangle rt;
            rt.v = o.lsTriangle(i);
            rt.object = uint32_t(k);
            rt.group = m.triangleGroup[i];
            const PrimitiveGroup& g = m.groups[rt.group];
            rt.blocksLight = o.castsShadow && !g.alphaTested;
            rt.twoSided = g.alphaTested || g.doubleSided;
            rt.mirrored = !terrain && mirrored;
            rt.terrain = terrain;
            s.triangles.push_back(rt);
        }
    }
    return s;
}

RefAnswer referenceDecision(const RefScene& scene, uint32_t object, uint32_t group, size_t light, const RefOptions& options) {
    RefAnswer out;
    if (!scene.castsShadow[object]) {
        out.verdict = RefVerdict::Zero;
        out.why = "the object casts no shadow (never drawn into the shadow map)";
        return out;
    }
    Context c{scene, {}, {}};
    c.tris.reserve(scene.triangles.size());
    for (const RefTriangle& rt : scene.triangles) {
        Tri t;
        for (int i = 0; i < 3; ++i) t.v[i] = QVec(rt.v[size_t(i)]);
        t.n = cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
        t.repeated = rt.v[0] == rt.v[1] || rt.v[1] == rt.v[2] || rt.v[0] == rt.v[2];
        t.src = &rt;
        c.tris.push_back(std::move(t));
    }
    for (const Tri& t : c.tris)
        if (t.src->terrain && !t.repeated) c.terrain.push_back(&t);
    const LightQ L = lightOf(scene.lights[light]);
    const Q delta = L.filterRadius + L.normalBias;
    const bool canProve = options.proveZero && !(!L.directional && L.filterRadius > 0);
    const bool canWitness = options.searchWitness && !(L.normalBias > 0);
    bool unsure = !canProve;
    if (!canProve) out.why = "a point light with a filter radius: no linear superset";
    bool anyCaster = false;
    for (const Tri& t : c.tris) {
        if (t.src->object != object || t.src->group != group || t.repeated) continue;
        anyCaster = true;
        // Point lights: |p - L| <= Dmax over the caster, so l > 1 + bias / Dmax for a pair.
        Q dHi = 0;
        if (!L.directional)
            for (int i = 0; i < 3; ++i) dHi = std::max(dHi, sqrtUpper(dot(t.v[i] - L.L, t.v[i] - L.L)));
        for (const Tri& r : c.tris) {
            if (r.repeated) continue;
            if (!r.src->twoSided && facing(r, L) <= 0) continue;
            ++refCounters().pairs;
            // The least s (or l) a pair must exceed: a lower bound of the bias.
            Q betaLo = L.bias;
            if (L.directional && L.slopeBias > 0) {
                const std::optional<Q> t2 = tanSquared(r.n, L.d);
                if (t2) betaLo += L.slopeBias * sqrtLower(*t2);
            }
            Q thr0;
            if (L.directional) thr0 = betaLo / L.dLenHi;
            else thr0 = dHi > 0 ? Q(1) + betaLo / dHi : Q(1);
            if (prefilterExcludes(t, r, L, canProve ? delta : Q(0), thr0)) {
                ++refCounters().prefiltered;
                continue;
            }
            // The dilated program for the proof, the plain one for a witness.
            std::optional<Q> provedBelow;  // s* of the dilated program when it decided
            bool excluded = false;
            if (canProve) {
                PairProgram P = makePair(t, r, L, delta, true);
                ++refCounters().lps;
                const Lp::Outcome o = P.lp.maximise(unitObjective(P.vars, 6));
                if (o == Lp::Outcome::Infeasible || (o == Lp::Outcome::Optimal && P.lp.value() <= thr0)) excluded = true;
                else if (o == Lp::Outcome::Unbounded && out.why.empty()) out.why = "the light touches a caster triangle";
            }
            if (excluded) continue;
            unsure = true;
            if (!canWitness) continue;
            PairProgram W = makePair(t, r, L, Q(0), true);
            ++refCounters().lps;
            if (W.lp.maximise(unitObjective(W.vars, 6)) != Lp::Outcome::Optimal) continue;
            const Q best = W.lp.value();
            if (!(best > thr0)) continue;
            const std::vector<Q> bestX = W.lp.solution();
            if (searchWitness(c, L, t, r, bestX, (best + thr0) / 2, out)) return out;
        }
    }
    if (!anyCaster) {
        out.verdict = RefVerdict::Zero;
        out.why = "no triangle of three distinct vertices";
        return out;
    }
    if (!unsure) {
        out.verdict = RefVerdict::Zero;
        out.why = "no receiver pair deeper than the bias (linear superset)";
        return out;
    }
    out.verdict = RefVerdict::Unsure;
    if (out.why.empty()) out.why = "a pair the superset cannot exclude, and no witness found";
    return out;
}

}  // namespace shadowcull::reference
