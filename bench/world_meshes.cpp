// The meshes of the benchmark worlds (world_parts.h): trees, rocks, buildings and props
// of the forest worlds, and the scanned rocks and sheets of the dense and real-map-like
// worlds. Every mesh is closed and counter-clockwise outward unless it is alpha-tested.

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "bench/world_parts.h"

namespace shadowcull::bench::worldgen {

// Scale, then turn about +Y by `yawDegrees`, then move to `at`. Matrix entries rounded to
// 1e-6 (a valid affine map either way; it keeps the chunk files short).
Affine placed(const glm::dvec3& at, double yawDegrees, const glm::dvec3& scale) {
    Affine a = Affine::scaling(scale).then(Affine::rotationY(yawDegrees));
    for (glm::dvec3* r : {&a.row0, &a.row1, &a.row2}) *r = glm::dvec3(round6(r->x), round6(r->y), round6(r->z));
    a.row3 = glm::dvec3(mm(at.x), mm(at.y), mm(at.z));
    return a;
}

namespace {

// Copies `src`'s triangles into group `group` of `dst` (MeshSpec::append would add src's
// groups as new ones; here many parts share one material).
void mergeInto(MeshSpec& dst, const MeshSpec& src, int group) {
    const int base = int(dst.positions.size());
    for (const glm::dvec3& p : src.positions) dst.addVertex(p);
    for (const auto& t : src.triangles) dst.addTriangle(base + t[0], base + t[1], base + t[2], group);
}

// Closed n-sided prism about +Y (a truncated cone when r1 < r0, a cone when r1 == 0),
// from y0 (radius r0) to y1 (radius r1), faces outward.
void addPrism(MeshSpec& m, int group, int n, double r0, double r1, double y0, double y1, double phase = 0.0) {
    const glm::dvec3 inside(0, 0.5 * (y0 + y1), 0);
    std::vector<glm::dvec3> bottom, top;
    for (int k = 0; k < n; ++k) {
        const double a = phase + 2 * kPi * k / n;
        bottom.push_back({round6(r0 * std::cos(a)), y0, round6(r0 * std::sin(a))});
        top.push_back({round6(r1 * std::cos(a)), y1, round6(r1 * std::sin(a))});
    }
    for (int k = 0; k < n; ++k) {
        const int k1 = (k + 1) % n;
        if (r1 > 0)
            m.addFace({bottom[size_t(k)], bottom[size_t(k1)], top[size_t(k1)], top[size_t(k)]}, group, inside);
        else
            m.addFace({bottom[size_t(k)], bottom[size_t(k1)], glm::dvec3(0, y1, 0)}, group, inside);
    }
    m.addFace(bottom, group, inside);
    if (r1 > 0) m.addFace(top, group, inside);
}

void addBox(MeshSpec& m, int group, const glm::dvec3& lo, const glm::dvec3& hi) {
    mergeInto(m, MeshSpec::box(lo, hi), group);
}

// A flat card (alpha-tested, so two-sided; the winding does not matter): corners
// c +- u*w/2 +- v*h/2.
void addCard(MeshSpec& m, int group, const glm::dvec3& c, const glm::dvec3& u, const glm::dvec3& v, double w, double h) {
    const glm::dvec3 n = glm::normalize(glm::cross(u, v));
    auto r = [](const glm::dvec3& p) { return glm::dvec3(round6(p.x), round6(p.y), round6(p.z)); };
    m.addFace({r(c - u * (w / 2) - v * (h / 2)), r(c + u * (w / 2) - v * (h / 2)), r(c + u * (w / 2) + v * (h / 2)),
               r(c - u * (w / 2) + v * (h / 2))},
              group, c - n * 0.1);
}

}  // namespace

glm::dvec3 randomUnit(DeterministicRng& rng) {
    for (;;) {
        const glm::dvec3 v(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        const double l = glm::length(v);
        if (l > 0.1 && l <= 1.0) return v / l;
    }
}

// ---------------------------------------------------------------------------------------
// Meshes (model-local metres, origin on the ground at the object's foot)

// Conifer: a tapered hexagonal trunk (opaque "bark", sunk 0.5 m) and tiers of needle cards
// sloping down from the trunk (alpha-tested "needles"), two crossed cards on top.
MeshSpec pineTree(double height, int tiers, int cardsPerTier) {
    MeshSpec m;
    const int bark = m.addGroup(GroupSpec::named("bark"));
    const int needles = m.addGroup(GroupSpec::named("needles", true));
    addPrism(m, bark, 6, 0.22, 0.07, -0.5, 0.9 * height);
    for (int t = 0; t < tiers; ++t) {
        const double f = double(t) / tiers;
        const double y = height * (0.22 + 0.68 * f);
        const double R = 0.5 + 2.4 * (1 - f);
        for (int k = 0; k < cardsPerTier; ++k) {
            const double a = 2 * kPi * (k + 0.5 * (t % 2)) / cardsPerTier;
            const glm::dvec3 d(std::cos(a), 0, std::sin(a)), p(-std::sin(a), 0, std::cos(a));
            const glm::dvec3 inner = d * 0.15 + glm::dvec3(0, y + 0.9, 0), outer = d * R + glm::dvec3(0, y - 0.4, 0);
            const double wi = 0.25, wo = 0.45 * R + 0.3;
            m.addFace({inner - p * wi, outer - p * wo, outer + p * wo, inner + p * wi}, needles, inner + glm::dvec3(0, -1, 0));
        }
    }
    const glm::dvec3 top(0, 0.92 * height, 0);
    addCard(m, needles, top, {1, 0, 0}, {0, 1, 0}, 1.0, 0.16 * height);
    addCard(m, needles, top, {0, 0, 1}, {0, 1, 0}, 1.0, 0.16 * height);
    return m;
}

// Broadleaf: an octagonal trunk (opaque) and a cloud of randomly turned leaf cards in an
// ellipsoid around the crown (alpha-tested).
MeshSpec broadleafTree(uint64_t seed, double trunkHeight, double crownRadius, int cards) {
    DeterministicRng rng(seed);
    MeshSpec m;
    const int bark = m.addGroup(GroupSpec::named("bark"));
    const int leaves = m.addGroup(GroupSpec::named("leaves", true));
    addPrism(m, bark, 8, 0.32, 0.18, -0.5, trunkHeight + 0.8 * crownRadius);
    const glm::dvec3 crown(0, trunkHeight + 0.8 * crownRadius, 0);
    for (int k = 0; k < cards; ++k) {
        glm::dvec3 off;
        do off = glm::dvec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        while (glm::dot(off, off) > 1.0);
        const glm::dvec3 c = crown + glm::dvec3(off.x * crownRadius, off.y * 0.75 * crownRadius, off.z * crownRadius);
        const glm::dvec3 u = randomUnit(rng);
        glm::dvec3 v = glm::cross(u, randomUnit(rng));
        if (glm::length(v) < 1e-3) v = glm::cross(u, glm::dvec3(0, 1, 0.3));
        v = glm::normalize(v);
        const double s = rng.uniform(1.4, 2.4);
        addCard(m, leaves, c, u, v, s, s);
    }
    return m;
}

// Bush: a stem (opaque) and leaf cards around it (alpha-tested).
MeshSpec bush(uint64_t seed) {
    DeterministicRng rng(seed);
    MeshSpec m;
    const int stems = m.addGroup(GroupSpec::named("stems"));
    const int leaves = m.addGroup(GroupSpec::named("bushleaves", true));
    addPrism(m, stems, 5, 0.07, 0.03, -0.2, 0.9);
    for (int k = 0; k < 14; ++k) {
        const double a = 2 * kPi * k / 14;
        const glm::dvec3 c(0.6 * std::cos(a), rng.uniform(0.4, 1.2), 0.6 * std::sin(a));
        addCard(m, leaves, c, glm::normalize(glm::dvec3(-std::sin(a), 0, std::cos(a))),
                glm::normalize(glm::dvec3(0.3 * std::cos(a), 1, 0.3 * std::sin(a))), 1.1, 0.9);
    }
    return m;
}

// A lumpy closed solid: an octahedron subdivided `levels` times, each vertex pushed to
// radius * [1 - jitter, 1 + jitter] along its own ray (which keeps faces outward), then
// squashed in y. Origin at the centre.
MeshSpec lumpySolid(uint64_t seed, double radius, double jitter, double squash, int levels, const std::string& material) {
    std::vector<glm::dvec3> v = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    std::vector<std::array<int, 3>> faces;
    for (int x : {0, 1})
        for (int y : {2, 3})
            for (int z : {4, 5}) {
                const glm::dvec3 a = v[size_t(x)], b = v[size_t(y)], c = v[size_t(z)];
                faces.push_back(glm::dot(a, glm::cross(b, c)) > 0 ? std::array<int, 3>{x, y, z} : std::array<int, 3>{x, z, y});
            }
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<int, int>, int> middle;
        auto mid = [&](int a, int b) {
            const std::pair<int, int> key{std::min(a, b), std::max(a, b)};
            auto it = middle.find(key);
            if (it != middle.end()) return it->second;
            v.push_back(glm::normalize((v[size_t(a)] + v[size_t(b)]) * 0.5));
            return middle[key] = int(v.size()) - 1;
        };
        std::vector<std::array<int, 3>> finer;
        for (const auto& f : faces) {
            const int ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
            finer.insert(finer.end(), {{f[0], ab, ca}, {ab, f[1], bc}, {ca, bc, f[2]}, {ab, bc, ca}});
        }
        faces = finer;
    }
    DeterministicRng rng(seed);
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named(material));
    for (const glm::dvec3& p : v) {
        const double r = radius * rng.uniform(1.0 - jitter, 1.0 + jitter);
        m.addVertex(glm::dvec3(round6(p.x * r), round6(p.y * r * squash), round6(p.z * r)));
    }
    for (const auto& f : faces) m.addTriangle(f[0], f[1], f[2], g);
    return m;
}

// A closed gable roof over [-w/2, w/2] x [-d/2, d/2] from y0 to the ridge (along z) at y1,
// with an overhang.
void addGableRoof(MeshSpec& m, int group, double w, double d, double y0, double y1, double overhang) {
    const double hw = w / 2 + overhang, hd = d / 2 + overhang;
    const glm::dvec3 a{-hw, y0, -hd}, b{hw, y0, -hd}, c{hw, y0, hd}, e{-hw, y0, hd};
    const glm::dvec3 r0{0, y1, -hd}, r1{0, y1, hd}, inside{0, 0.5 * (y0 + y1), 0};
    m.addFace({a, b, c, e}, group, inside);
    m.addFace({a, e, r1, r0}, group, inside);
    m.addFace({b, r0, r1, c}, group, inside);
    m.addFace({a, r0, b}, group, inside);
    m.addFace({e, c, r1}, group, inside);
}

// Closed house: walls (a box with a foundation `foundation` m deep) and a gable roof.
MeshSpec house(double w, double d, double wallHeight, double ridge, double foundation) {
    MeshSpec m;
    const int walls = m.addGroup(GroupSpec::named("walls"));
    const int roof = m.addGroup(GroupSpec::named("roof"));
    addBox(m, walls, {-w / 2, -foundation, -d / 2}, {w / 2, wallHeight, d / 2});
    addGableRoof(m, roof, w, d, wallHeight, ridge, 0.5);
    return m;
}

// Hall with an interior: a floor slab on a 4 m foundation, four 0.4 m walls with a door
// opening (3 m x 3.5 m) in the front (-z) wall, and a closed gable roof. Props stand
// inside (kHallInterior).
constexpr double kHallW = 12, kHallD = 16, kHallH = 6, kHallT = 0.4;
MeshSpec hall() {
    MeshSpec m;
    const int walls = m.addGroup(GroupSpec::named("walls"));
    const int roof = m.addGroup(GroupSpec::named("roof"));
    const double w = kHallW / 2, d = kHallD / 2, H = kHallH, t = kHallT, door = 1.5, doorH = 3.5;
    addBox(m, walls, {-w, -4, -d}, {w, 0.2, d});              // floor slab and foundation
    addBox(m, walls, {-w, 0.2, d - t}, {w, H, d});            // back
    addBox(m, walls, {-w, 0.2, -d}, {-w + t, H, d - t});      // left
    addBox(m, walls, {w - t, 0.2, -d}, {w, H, d - t});        // right
    addBox(m, walls, {-w + t, 0.2, -d}, {-door, H, -d + t});  // front, left of the door
    addBox(m, walls, {door, 0.2, -d}, {w - t, H, -d + t});    // front, right of the door
    addBox(m, walls, {-door, doorH, -d}, {door, H, -d + t});  // lintel
    addGableRoof(m, roof, kHallW, kHallD, H, H + 4, 0.6);
    return m;
}

// Hall-local spots for props inside (on the floor at y = 0.2).
const std::array<glm::dvec3, 4> kHallInterior = {{{-3.5, 0.2, 4.5}, {3.5, 0.2, 5.0}, {0.0, 0.2, 1.0}, {-3.0, 0.2, -3.0}}};

// Round tower: an octagonal shaft (walls) and a conical roof.
MeshSpec tower() {
    MeshSpec m;
    const int walls = m.addGroup(GroupSpec::named("walls"));
    const int roof = m.addGroup(GroupSpec::named("roof"));
    addPrism(m, walls, 8, 3.0, 2.7, -3, 16, kPi / 8);
    addPrism(m, roof, 8, 3.6, 0.0, 16, 21.5, kPi / 8);
    return m;
}

MeshSpec fence() {
    MeshSpec m;
    const int wood = m.addGroup(GroupSpec::named("fencewood"));
    addBox(m, wood, {-2.0, -0.3, -0.06}, {-1.88, 1.2, 0.06});
    addBox(m, wood, {1.88, -0.3, -0.06}, {2.0, 1.2, 0.06});
    addBox(m, wood, {-1.88, 0.35, -0.03}, {1.88, 0.47, 0.03});
    addBox(m, wood, {-1.88, 0.85, -0.03}, {1.88, 0.97, 0.03});
    return m;
}

MeshSpec lampPost() {
    MeshSpec m;
    const int metal = m.addGroup(GroupSpec::named("metal"));
    const int glass = m.addGroup(GroupSpec::named("glass"));
    addPrism(m, metal, 6, 0.08, 0.06, -0.3, 4.4);
    addBox(m, glass, {-0.22, 4.4, -0.22}, {0.22, 4.9, 0.22});
    return m;
}

MeshSpec table() {
    MeshSpec m;
    const int wood = m.addGroup(GroupSpec::named("tablewood"));
    addBox(m, wood, {-0.9, 0.72, -0.5}, {0.9, 0.78, 0.5});
    for (double x : {-0.8, 0.74})
        for (double z : {-0.42, 0.36}) addBox(m, wood, {x, 0, z}, {x + 0.06, 0.72, z + 0.06});
    return m;
}

MeshSpec grassPatch() {
    MeshSpec m;
    const int grass = m.addGroup(GroupSpec::named("grass", true));
    for (int k = 0; k < 3; ++k) {
        const double a = kPi * k / 3;
        addCard(m, grass, {0, 0.35, 0}, {std::cos(a), 0, std::sin(a)}, {0, 1, 0}, 1.2, 0.8);
    }
    return m;
}

MeshSpec balloon() {
    MeshSpec m = lumpySolid(44, 4.0, 0.0, 1.15, 2, "silk");
    const int wicker = m.addGroup(GroupSpec::named("wicker"));
    addBox(m, wicker, {-0.7, -7.0, -0.7}, {0.7, -5.8, 0.7});
    return m;
}

MeshSpec barrel() {
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named("staves"));
    addPrism(m, g, 10, 0.35, 0.35, 0, 1.0);
    return m;
}

MeshSpec drone() {
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named("body"));
    addBox(m, g, {-0.3, -0.1, -0.3}, {0.3, 0.1, 0.3});
    for (int k = 0; k < 4; ++k) {
        const double x = k % 2 ? 0.45 : -0.45, z = k / 2 ? 0.45 : -0.45;
        addBox(m, g, {x - 0.15, 0.1, z - 0.15}, {x + 0.15, 0.13, z + 0.15});
    }
    return m;
}

// ---------------------------------------------------------------------------------------
// Dense scanned meshes (D, D2k) and the real-map-like world's rocks (R)

namespace {


// A geodesic sphere on the octahedron at frequency n: 8 n^2 triangles, 4 n^2 + 2 vertices.
// Vertex (a, b, c), integers with |a| + |b| + |c| = n, has direction (a, b, c) / |(a, b, c)|;
// every triangle is wound counter-clockwise seen from outside, decided exactly on the
// integer points (det > 0: the origin lies behind it).
struct GeoSphere {
    std::vector<glm::dvec3> dirs;
    std::vector<std::array<int, 3>> tris;
};

GeoSphere geoSphere(int n) {
    GeoSphere s;
    std::map<std::array<int, 3>, int> index;
    std::vector<std::array<long long, 3>> ip;
    auto vertex = [&](int a, int b, int c) {
        const std::array<int, 3> key{a, b, c};
        auto it = index.find(key);
        if (it != index.end()) return it->second;
        s.dirs.push_back(glm::normalize(glm::dvec3(a, b, c)));
        ip.push_back({a, b, c});
        return index[key] = int(s.dirs.size()) - 1;
    };
    auto add = [&](int a, int b, int c) {
        const auto &A = ip[size_t(a)], &B = ip[size_t(b)], &C = ip[size_t(c)];
        const long long det = A[0] * (B[1] * C[2] - B[2] * C[1]) - A[1] * (B[0] * C[2] - B[2] * C[0]) +
                              A[2] * (B[0] * C[1] - B[1] * C[0]);
        if (det > 0) s.tris.push_back({a, b, c});
        else s.tris.push_back({a, c, b});
    };
    for (int sx : {1, -1})
        for (int sy : {1, -1})
            for (int sz : {1, -1}) {
                auto P = [&](int i, int j) { return vertex(sx * i, sy * j, sz * (n - i - j)); };
                for (int i = 0; i < n; ++i)
                    for (int j = 0; j < n - i; ++j) {
                        add(P(i, j), P(i + 1, j), P(i, j + 1));
                        if (i + j < n - 1) add(P(i + 1, j), P(i + 1, j + 1), P(i, j + 1));
                    }
            }
    return s;
}

// A ridged wave: 1 - 2 |sin(.)| in [-1, 1], a sharp crest where the sine crosses zero.
double ridge(double x) { return 1.0 - 2.0 * std::abs(std::sin(x)); }

}  // namespace

RockShape::RockShape(uint64_t seed, double radius0, const glm::dvec3& axes0, double amplitude, int octaves)
    : radius(radius0), axes(axes0) {
    DeterministicRng rng(mix64(seed ^ 0x5CA7ull));
    for (int o = 0; o < octaves; ++o)
        for (int k = 0; k < 4; ++k)
            waves.push_back({randomUnit(rng), 3.0 * std::pow(2.0, o) * rng.uniform(0.8, 1.25),
                             amplitude * std::pow(0.55, o) * rng.uniform(0.7, 1.0), rng.uniform(0, 2 * kPi)});
}

double RockShape::radiusAlong(const glm::dvec3& u) const {
    double f = 1.0;
    for (const Wave& w : waves) f += w.amp * ridge(w.freq * glm::dot(u, w.dir) + w.phase);
    return radius * std::max(f, 0.35);
}

// A closed jagged rock: the geodesic sphere of frequency n, each vertex at the shape's
// radius times (1 +- a quarter of an edge's angle) along its own direction, then stretched
// by the axes. A positive radius along each vertex's own direction and a positive diagonal
// stretch keep det(a, b, c) > 0 for every triangle: counter-clockwise seen from outside,
// non-degenerate, a closed star-shaped surface. Checked on the rounded positions.
MeshSpec scannedRock(const RockShape& shape, int n, uint64_t seed, const std::string& material) {
    const GeoSphere sphere = geoSphere(n);
    DeterministicRng rng(mix64(seed ^ 0x7E77ull));
    const double jitter = 0.25 * (kPi / 2) / n;
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named(material));
    m.positions.reserve(sphere.dirs.size());
    for (const glm::dvec3& u : sphere.dirs) {
        const glm::dvec3 p = shape.axes * (shape.radiusAlong(u) * rng.uniform(1.0 - jitter, 1.0 + jitter) * u);
        m.addVertex({round6(p.x), round6(p.y), round6(p.z)});
    }
    m.triangles.reserve(sphere.tris.size());
    m.triangleGroup.reserve(sphere.tris.size());
    for (const auto& t : sphere.tris) {
        const glm::dvec3 &a = m.positions[size_t(t[0])], &b = m.positions[size_t(t[1])], &c = m.positions[size_t(t[2])];
        const glm::dvec3 nrm = glm::cross(b - a, c - a);
        if (!(glm::dot(nrm, a) > 0) || !(glm::length(nrm) > 1e-12))
            throw std::logic_error("world: a scanned rock triangle is degenerate or inward (" + material + ")");
        m.addTriangle(t[0], t[1], t[2], g);
    }
    return m;
}

// An open jagged sheet (a scanned outcrop of bedrock): a heightfield over w x d metres
// (centred on the origin) of n x n quads, a dome `height` m high plus octaves of ridged
// waves (wavelengths 6 m down to 0.19 m) and a per-vertex jitter of a quarter cell; the
// quads split along alternating diagonals. Every triangle faces up (counter-clockwise
// seen from above) and is non-degenerate; checked.
MeshSpec scannedSheet(uint64_t seed, double w, double d, double height, int n, const std::string& material) {
    DeterministicRng rng(mix64(seed ^ 0x5EE7ull));
    struct Wave {
        double c, s, freq, amp, phase;
    };
    std::vector<Wave> waves;
    for (int o = 0; o < 6; ++o)
        for (int k = 0; k < 3; ++k) {
            const double t = rng.uniform(0, 2 * kPi);
            waves.push_back({std::cos(t), std::sin(t), 2 * kPi / (6.0 * std::pow(0.5, o)) * rng.uniform(0.8, 1.25),
                             0.3 * std::pow(0.55, o) * rng.uniform(0.7, 1.0), rng.uniform(0, 2 * kPi)});
        }
    const double cell = std::min(w, d) / n, jitter = 0.25 * cell;
    MeshSpec m;
    const int g = m.addGroup(GroupSpec::named(material));
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const double x = -w / 2 + w * i / n, z = -d / 2 + d * j / n;
            const double r2 = (2 * x / w) * (2 * x / w) + (2 * z / d) * (2 * z / d);
            double h = height * std::exp(-2.0 * r2);
            for (const Wave& wv : waves) h += wv.amp * ridge(wv.freq * (x * wv.c + z * wv.s) + wv.phase);
            h += rng.uniform(-jitter, jitter);
            m.addVertex({round6(x), round6(h), round6(z)});
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, e = c + 1;
            const std::array<std::array<int, 3>, 2> tris =
                (i + j) % 2 == 0 ? std::array<std::array<int, 3>, 2>{{{a, c, b}, {b, c, e}}}
                                 : std::array<std::array<int, 3>, 2>{{{a, c, e}, {a, e, b}}};
            for (const auto& t : tris) {
                const glm::dvec3 &p = m.positions[size_t(t[0])], &q = m.positions[size_t(t[1])], &r = m.positions[size_t(t[2])];
                const glm::dvec3 nrm = glm::cross(q - p, r - p);
                if (!(nrm.y > 0) || !(glm::length(nrm) > 1e-12))
                    throw std::logic_error("world: a scanned sheet triangle is degenerate or faces down (" + material + ")");
                m.addTriangle(t[0], t[1], t[2], g);
            }
        }
    return m;
}

}  // namespace shadowcull::bench::worldgen
