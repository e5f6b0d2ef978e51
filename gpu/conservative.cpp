#include "gpu/conservative.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/clip_polygon.h"
#include "core/rounding.h"

namespace shadowcull::gpu {

namespace {

bool lexLess(const glm::dvec3& a, const glm::dvec3& b) {
    if (a.x != b.x) return a.x < b.x;
    if (a.y != b.y) return a.y < b.y;
    return a.z < b.z;
}

// Sutherland-Hodgman against f(v) >= 0 (core/clip_polygon.h); the crossing point is
// computed from the lexicographically lesser endpoint, so two triangles sharing an edge get
// the same point.
template <class F>
int clipPolygon(const glm::dvec3* in, int n, glm::dvec3* out, F f) {
    int m = 0;
    shadowcull::clipPolygon(
        in, size_t(n), f, closedSide,
        [](const glm::dvec3& c, const glm::dvec3& d, double fc, double fd) {
            const bool cFirst = lexLess(c, d);
            const glm::dvec3& p = cFirst ? c : d;
            const glm::dvec3& q = cFirst ? d : c;
            const double fp = cFirst ? fc : fd, fq = cFirst ? fd : fc;
            return p + (q - p) * (fp / (fp - fq));
        },
        [&](const glm::dvec3& p) { out[m++] = p; });
    return m;
}

double segmentDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
    const glm::dvec3 ab = b - a;
    const double l2 = glm::dot(ab, ab);
    double t = l2 > 0 ? glm::dot(p - a, ab) / l2 : 0.0;
    t = std::clamp(t, 0.0, 1.0);
    return glm::length(p - (a + ab * t));
}

}  // namespace

double pointTriangleDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    double d = std::min({segmentDistance(p, a, b), segmentDistance(p, b, c), segmentDistance(p, c, a)});
    const glm::dvec3 n = glm::cross(b - a, c - a);
    const double nn = glm::dot(n, n);
    if (nn > 0) {
        const double h = glm::dot(p - a, n);
        const glm::dvec3 q = p - n * (h / nn);
        if (glm::dot(glm::cross(b - a, q - a), n) >= 0 && glm::dot(glm::cross(c - b, q - b), n) >= 0 &&
            glm::dot(glm::cross(a - c, q - c), n) >= 0)
            d = std::min(d, std::abs(h) / std::sqrt(nn));
    }
    return d;
}

PieceBuilder::PieceBuilder(const LightView& view, double nearZ)
    : view_(view), nearZ_(nearZ), guard_(2 * view.t) {}

void PieceBuilder::triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, float dilatePx,
                            uint32_t id, std::vector<RasterPiece>& out) const {
    glm::dvec3 poly[16] = {view_.toView(a), view_.toView(b), view_.toView(c)};
    int n = 3;
    if (view_.perspective) {
        glm::dvec3 tmp[16];
        const double g = guard_, nz = nearZ_;
        n = clipPolygon(poly, n, tmp, [&](const glm::dvec3& v) { return v.z - nz; });
        n = clipPolygon(tmp, n, poly, [&](const glm::dvec3& v) { return g * v.z - v.x; });
        n = clipPolygon(poly, n, tmp, [&](const glm::dvec3& v) { return g * v.z + v.x; });
        n = clipPolygon(tmp, n, poly, [&](const glm::dvec3& v) { return g * v.z - v.y; });
        n = clipPolygon(poly, n, tmp, [&](const glm::dvec3& v) { return g * v.z + v.y; });
        std::copy(tmp, tmp + n, poly);
    }
    for (int k = 1; k + 1 < n; ++k) {
        const glm::dvec3 tri[3] = {poly[0], poly[k], poly[k + 1]};
        emit(tri, dilatePx, 0.0f, id, out);
    }
}

void PieceBuilder::segment(const glm::dvec3& a, const glm::dvec3& b, std::vector<RasterPiece>& out) const {
    glm::dvec3 p = view_.toView(a), q = view_.toView(b);
    if (view_.perspective) {
        if (lexLess(q, p)) std::swap(p, q);
        const double g = guard_, nz = nearZ_;
        auto clip = [&](auto f) {
            const double fp = f(p), fq = f(q);
            if (fp < 0 && fq < 0) return false;
            if (fp < 0) p = p + (q - p) * (fp / (fp - fq));
            else if (fq < 0) q = p + (q - p) * (fp / (fp - fq));
            return true;
        };
        if (!clip([&](const glm::dvec3& v) { return v.z - nz; })) return;
        if (!clip([&](const glm::dvec3& v) { return g * v.z - v.x; })) return;
        if (!clip([&](const glm::dvec3& v) { return g * v.z + v.x; })) return;
        if (!clip([&](const glm::dvec3& v) { return g * v.z - v.y; })) return;
        if (!clip([&](const glm::dvec3& v) { return g * v.z + v.y; })) return;
    }
    const glm::dvec3 seg[3] = {p, q, q};
    emit(seg, 0.0f, 1.0f, 0, out);
}

bool PieceBuilder::hullBounds(const glm::dvec3* pts, size_t n, double bounds[4]) const {
    // Projection is affine (orthographic) or, for points beyond the near plane, projective
    // with z > 0: either maps the hull of the points onto the hull of their images, and
    // clipping only takes parts of it.
    bounds[0] = bounds[1] = 1e300;
    bounds[2] = bounds[3] = -1e300;
    for (size_t k = 0; k < n; ++k) {
        const glm::dvec3 v = view_.toView(pts[k]);
        if (view_.perspective && !(v.z >= nearZ_)) return false;
        const glm::dvec2 p = view_.viewToPixel(v);
        bounds[0] = std::min(bounds[0], p.x), bounds[1] = std::min(bounds[1], p.y);
        bounds[2] = std::max(bounds[2], p.x), bounds[3] = std::max(bounds[3], p.y);
    }
    return n > 0;
}

bool PieceBuilder::clipsAway(const glm::dvec3* pts, size_t n) const {
    if (!view_.perspective || n == 0) return false;
    // The clip functions of triangle() at each point's view coordinates (LightView::toView),
    // each certainly negative in exact arithmetic (core/rounding.h) for the piece to go.
    bool out[5] = {true, true, true, true, true};
    const Bounded g = exactly(guard_), nz = exactly(nearZ_);
    for (size_t k = 0; k < n; ++k) {
        const Bounded3 d = difference(pts[k], view_.eye);
        const Bounded x = dot(d, exactly(view_.U)), y = dot(d, exactly(view_.V)), z = dot(d, exactly(view_.W));
        const Bounded f[5] = {z - nz, g * z - x, g * z + x, g * z - y, g * z + y};
        for (int c = 0; c < 5; ++c) out[c] = out[c] && certainSign(f[c]) < 0;
    }
    return out[0] || out[1] || out[2] || out[3] || out[4];
}

namespace {

// The cover of a segment or a thin triangle (whose pushed-out triangle is no smaller than
// its box): the rectangle along its longest edge around it, widened by h (L-infinity) on
// every side. A point q within h (L-infinity) of a point p of the piece has
// |(q - p) . u| <= h (|ux| + |uy|) along any unit u, so it lies in the piece's extent
// along the edge direction u and along its normal, each widened by that much: the
// rectangle holds every pixel centre the box would. A long diagonal crack segment's box
// is about its length squared / 2 pixels, this rectangle about 3 times its length. False
// (and nothing written) when it is not smaller than the box.
bool orientedCover(const glm::dvec2 P[3], double h, double boxArea, float cover[8]) {
    int longest = -1;
    double len2 = 0;
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 e = P[(k + 1) % 3] - P[k];
        if (glm::dot(e, e) > len2) len2 = glm::dot(e, e), longest = k;
    }
    if (longest < 0) return false;
    const glm::dvec2 u = (P[(longest + 1) % 3] - P[longest]) / std::sqrt(len2), n(-u.y, u.x);
    double t0 = 1e300, t1 = -1e300, s0 = 1e300, s1 = -1e300;
    for (int k = 0; k < 3; ++k) {
        const double t = glm::dot(u, P[k]), sv = glm::dot(n, P[k]);
        t0 = std::min(t0, t), t1 = std::max(t1, t), s0 = std::min(s0, sv), s1 = std::max(s1, sv);
    }
    const double e = h * (std::abs(u.x) + std::abs(u.y));  // the same along n (u turned by 90 degrees)
    t0 -= e, t1 += e, s0 -= e, s1 += e;
    const double area = (t1 - t0) * (s1 - s0);
    if (!(std::isfinite(area) && area < 0.8 * boxArea)) return false;
    const double ts[4][2] = {{t0, s0}, {t1, s0}, {t0, s1}, {t1, s1}};  // strip order, as the box's
    for (int k = 0; k < 4; ++k) {
        const glm::dvec2 c = u * ts[k][0] + n * ts[k][1];
        cover[2 * k] = float(c.x), cover[2 * k + 1] = float(c.y);
    }
    return true;
}

}  // namespace

void PieceBuilder::emit(const glm::dvec3* v, float dilatePx, float kind, uint32_t id,
                        std::vector<RasterPiece>& out) const {
    glm::dvec2 P[3];
    double s[3], z[3];
    for (int k = 0; k < 3; ++k) {
        P[k] = view_.viewToPixel(v[k]);
        z[k] = v[k].z;
        s[k] = view_.perspective ? 1.0 / v[k].z : v[k].z;
    }
    const double W = view_.width, H = view_.height;
    // Cull what cannot reach a pixel of the view.
    const double reach = 0.5 + double(dilatePx) + 1.0;
    const double minX = std::min({P[0].x, P[1].x, P[2].x}), maxX = std::max({P[0].x, P[1].x, P[2].x});
    const double minY = std::min({P[0].y, P[1].y, P[2].y}), maxY = std::max({P[0].y, P[1].y, P[2].y});
    if (maxX < -reach || maxY < -reach || minX > W + reach || minY > H + reach) return;

    RasterPiece r{};
    r.box[0] = float(minX), r.box[1] = float(minY), r.box[2] = float(maxX), r.box[3] = float(maxY);
    for (int k = 0; k < 3; ++k) {
        const glm::dvec2 e = P[(k + 1) % 3] - P[k];
        const double len = glm::length(e);
        if (!(len > 0)) continue;  // n = 0, lo = hi = 0: no constraint, never "inside"
        const glm::dvec2 n(-e.y / len, e.x / len);
        const double tEdge = glm::dot(n, P[k]), tOpp = glm::dot(n, P[(k + 2) % 3]);
        r.edge[k][0] = float(n.x);
        r.edge[k][1] = float(n.y);
        r.edge[k][2] = float(std::min(tEdge, tOpp));
        r.edge[k][3] = float(std::max(tEdge, tOpp));
    }
    r.plane[0] = float(P[0].x), r.plane[1] = float(P[0].y), r.plane[2] = float(s[0]);
    r.plane2[1] = float(std::min({z[0], z[1], z[2]}));
    r.plane2[2] = float(std::max({z[0], z[1], z[2]}));
    r.misc[0] = dilatePx;
    // Float coordinates are within ~6e-8 relative of these; the shader's arithmetic adds a
    // few more ulps. The margin is far above both.
    const double maxAbs = std::max({std::abs(minX), std::abs(maxX), std::abs(minY), std::abs(maxY)});
    r.misc[1] = float(1e-3 + 1e-6 * (maxAbs + std::max(W, H)));
    r.misc[2] = kind;
    r.id = id;
    const glm::dvec2 d1 = P[1] - P[0], d2 = P[2] - P[0], d3 = P[2] - P[1];
    const double det = d1.x * d2.y - d1.y * d2.x;
    const double maxLen2 = std::max({glm::dot(d1, d1), glm::dot(d2, d2), glm::dot(d3, d3)});
    // The shape drawn: every pixel centre within h (L-infinity) of the piece must be in it.
    // 0.01 px more than the fragment shader's widest test, against float rounding.
    const double h = 0.5 + double(dilatePx) + double(r.misc[1]) + 0.01;
    const double boxArea = (maxX - minX + 2 * h) * (maxY - minY + 2 * h);
    bool triangleCover = false;
    if (kind == 0.0f && maxLen2 > 0 && std::abs(det) > 1e-6 * maxLen2) {
        // Edge k's line pushed outwards by h (|nx| + |ny|) (the square's support along its
        // unit outward normal n); vertex k of the cover is where lines k-1 and k meet.
        const double orient = det > 0 ? 1.0 : -1.0;
        glm::dvec2 n[3];
        double c[3];
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 e = P[(k + 1) % 3] - P[k];
            n[k] = glm::dvec2(e.y, -e.x) * (orient / glm::length(e));
            c[k] = glm::dot(n[k], P[k]) + h * (std::abs(n[k].x) + std::abs(n[k].y));
        }
        glm::dvec2 V[3];
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 &a = n[(k + 2) % 3], &b = n[k];
            const double ca = c[(k + 2) % 3], cb = c[k], dd = a.x * b.y - a.y * b.x;
            V[k] = glm::dvec2((ca * b.y - cb * a.y) / dd, (a.x * cb - b.x * ca) / dd);
        }
        const double triArea =
            0.5 * std::abs((V[1].x - V[0].x) * (V[2].y - V[0].y) - (V[1].y - V[0].y) * (V[2].x - V[0].x));
        if (std::isfinite(triArea) && triArea < 0.8 * boxArea) {
            triangleCover = true;
            const glm::dvec2 corners[4] = {V[0], V[1], V[2], V[2]};
            for (int k = 0; k < 4; ++k) r.cover[2 * k] = float(corners[k].x), r.cover[2 * k + 1] = float(corners[k].y);
        }
    }
    if (!triangleCover && !orientedCover(P, h, boxArea, r.cover)) {
        const double x0 = minX - h, y0 = minY - h, x1 = maxX + h, y1 = maxY + h;
        const double corners[8] = {x0, y0, x1, y0, x0, y1, x1, y1};
        for (int k = 0; k < 8; ++k) r.cover[k] = float(corners[k]);
    }
    // The plane is used only where it is well conditioned (smallest angle not tiny);
    // otherwise the shader keeps to the vertices' depth range, which is always sound.
    if (kind == 0.0f && maxLen2 > 0 && std::abs(det) > 1e-6 * maxLen2) {
        const double ds1 = s[1] - s[0], ds2 = s[2] - s[0];
        const double a = (ds1 * d2.y - ds2 * d1.y) / det, b = (d1.x * ds2 - d2.x * ds1) / det;
        if (std::isfinite(float(a)) && std::isfinite(float(b))) {
            r.plane[3] = float(a);
            r.plane2[0] = float(b);
            r.plane2[3] = 1.0f;
        }
    }
    out.push_back(r);
}

MeshEdges::MeshEdges(const Mesh& mesh, const std::vector<uint32_t>& triangles) {
    struct Directed {
        glm::dvec3 lo, hi;
        uint32_t vlo, vhi;
        uint32_t triangle;
        uint8_t k;
        bool forward;
    };
    std::vector<Directed> all;
    all.reserve(triangles.size() * 3);
    for (uint32_t t : triangles) {
        const auto& tri = mesh.triangles[t];
        for (uint8_t k = 0; k < 3; ++k) {
            const uint32_t i = tri[k], j = tri[(k + 1) % 3];
            const glm::dvec3& p = mesh.positions[i];
            const glm::dvec3& q = mesh.positions[j];
            const bool fwd = lexLess(p, q);
            all.push_back({fwd ? p : q, fwd ? q : p, fwd ? i : j, fwd ? j : i, t, k, fwd});
        }
    }
    auto less = [](const Directed& a, const Directed& b) {
        if (lexLess(a.lo, b.lo)) return true;
        if (lexLess(b.lo, a.lo)) return false;
        return lexLess(a.hi, b.hi);
    };
    std::sort(all.begin(), all.end(), less);
    edgeOf.assign(mesh.triangles.size() * 3, UINT32_MAX);
    for (size_t i = 0; i < all.size();) {
        size_t j = i;
        while (j < all.size() && !less(all[i], all[j]) && !less(all[j], all[i])) ++j;
        const uint32_t e = uint32_t(ends.size());
        ends.push_back({all[i].vlo, all[i].vhi});
        start.push_back(uint32_t(uses.size()));
        for (size_t k = i; k < j; ++k) {
            uses.push_back({all[k].triangle, all[k].forward});
            edgeOf[3 * size_t(all[k].triangle) + all[k].k] = e;
        }
        i = j;
    }
    start.push_back(uint32_t(uses.size()));
}

}  // namespace shadowcull::gpu
