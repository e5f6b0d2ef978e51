// Benchmark worlds (see world_gen.h). The world is described through testing::SpaceBuilder
// (meshes written once as OBJ+MTL, placements as chunk-relative transforms, terrain as
// 16-bit PNG heightmaps), which stays fast enough at 250k placements (seconds, a few
// hundred MB); transforms are rounded to 1e-6 and positions to a millimetre so that chunk
// files stay small (~400 bytes per model).

#include "bench/world_gen.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <vector>

#include <glm/geometric.hpp>

#include "tests/support/space_builder.h"

namespace shadowcull::bench {

using testing::Affine;
using testing::DeterministicRng;
using testing::GroupSpec;
using testing::LightSpec;
using testing::MeshSpec;
using testing::SpaceBuilder;
using testing::SpaceOptions;
namespace fs = std::filesystem;

namespace {

// Bump when the generator's output changes: cached worlds are keyed by it.
constexpr uint64_t kGeneratorVersion = 3;
// The same for the issue-13 worlds (D, D2k, R) alone, so that S, M and L stay cached.
constexpr uint64_t kIssue13GeneratorVersion = 1;
// R alone (2: trees and a high sun, issue 19), so that D and D2k stay cached.
constexpr uint64_t kRealMapGeneratorVersion = 2;
constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------
// Seeds and small helpers

uint64_t mix64(uint64_t z) {  // SplitMix64 finaliser
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

uint64_t chunkSeed(uint64_t seed, int gx, int gz, uint64_t stream) {
    return mix64(mix64(mix64(seed ^ 0xC0FFEEull) + uint64_t(uint32_t(gx))) + (uint64_t(uint32_t(gz)) << 20) + stream);
}

double round6(double v) { return std::round(v * 1e6) / 1e6; }
double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

// Scale, then turn about +Y by `yawDegrees`, then move to `at`. Matrix entries rounded to
// 1e-6 (a valid affine map either way; it keeps the chunk files short).
Affine placed(const glm::dvec3& at, double yawDegrees, const glm::dvec3& scale = glm::dvec3(1.0)) {
    Affine a = Affine::scaling(scale).then(Affine::rotationY(yawDegrees));
    for (glm::dvec3* r : {&a.row0, &a.row1, &a.row2}) *r = glm::dvec3(round6(r->x), round6(r->y), round6(r->z));
    a.row3 = glm::dvec3(mm(at.x), mm(at.y), mm(at.z));
    return a;
}

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
// Terrain and the forest density field (world metres)

struct Landscape {
    std::array<double, 5> amp{}, freq{}, cosT{}, sinT{}, phase{};
    double fPhase = 0, fCos = 1, fSin = 0, base = 12.0;
    // S, M, L: hills between -6 and 30 m.
    explicit Landscape(uint64_t seed) : Landscape(seed, {10.0, 5.0, 2.0, 0.6, 0.25}, {520, 230, 90, 38, 17}, 12.0) {}
    // Five waves of amplitude a[k] (metres) and wavelength wl[k] about `base0` (the same
    // draws from the seed whatever the waves).
    Landscape(uint64_t seed, const std::array<double, 5>& a, const std::array<double, 5>& wl, double base0) : base(base0) {
        DeterministicRng rng(mix64(seed ^ 0x7E44A1Bull));
        for (size_t k = 0; k < 5; ++k) {
            const double t = rng.uniform(0, 2 * kPi);
            amp[k] = a[k];
            freq[k] = 2 * kPi / wl[k];
            cosT[k] = std::cos(t);
            sinT[k] = std::sin(t);
            phase[k] = rng.uniform(0, 2 * kPi);
        }
        fPhase = rng.uniform(0, 2 * kPi);
        const double t = rng.uniform(0, 2 * kPi);
        fCos = std::cos(t);
        fSin = std::sin(t);
    }
    // Metres, within base +- reach() (S, M, L: [-6, 30], stored between -20 and 45).
    double reach() const { return amp[0] + amp[1] + amp[2] + amp[3] + amp[4]; }
    double height(double x, double z) const {
        double h = base;
        for (size_t k = 0; k < 5; ++k) h += amp[k] * std::sin(freq[k] * (x * cosT[k] + z * sinT[k]) + phase[k]);
        return h;
    }
    // 0 (open land, villages) .. 1 (deep forest), varying over ~700 m.
    double forest(double x, double z) const {
        const double u = x * fCos + z * fSin, v = -x * fSin + z * fCos;
        const double s = std::sin(2 * kPi * u / 700 + fPhase) * std::cos(2 * kPi * v / 900 + 0.5 * fPhase);
        return std::clamp(0.5 + 0.6 * s, 0.0, 1.0);
    }
};
constexpr double kMinHeight = -20, kMaxHeight = 45;

struct Disc {
    double x, z, r;
};

uint64_t directorySize(const fs::path& dir, uint64_t& files) {
    uint64_t bytes = 0;
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) {
            bytes += e.file_size();
            ++files;
        }
    return bytes;
}

// ---------------------------------------------------------------------------------------
// Issue 13: dense scanned meshes (D, D2k) and a real-map-like world (R)

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

// The surface of a scanned rock: its radius along each direction, `radius` times 1 plus
// octaves of ridged waves (4 random directions per octave, frequency doubling, amplitude
// 0.55x per octave: from broad lumps to crests a few centimetres apart), then stretched by
// positive `axes`. A function of the direction only, so that every tessellation samples
// the same shape.
struct RockShape {
    struct Wave {
        glm::dvec3 dir;
        double freq, amp, phase;
    };
    double radius = 1;
    glm::dvec3 axes{1.0};
    std::vector<Wave> waves;

    RockShape(uint64_t seed, double radius0, const glm::dvec3& axes0, double amplitude, int octaves)
        : radius(radius0), axes(axes0) {
        DeterministicRng rng(mix64(seed ^ 0x5CA7ull));
        for (int o = 0; o < octaves; ++o)
            for (int k = 0; k < 4; ++k)
                waves.push_back({randomUnit(rng), 3.0 * std::pow(2.0, o) * rng.uniform(0.8, 1.25),
                                 amplitude * std::pow(0.55, o) * rng.uniform(0.7, 1.0), rng.uniform(0, 2 * kPi)});
    }
    double radiusAlong(const glm::dvec3& u) const {
        double f = 1.0;
        for (const Wave& w : waves) f += w.amp * ridge(w.freq * glm::dot(u, w.dir) + w.phase);
        return radius * std::max(f, 0.35);
    }
    // Half the nominal height (the placement's unit for burying it; ridges add ~15 %).
    double halfHeight() const { return radius * axes.y; }
    double footprint() const { return radius * std::max(axes.x, axes.z); }
};

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

// Chunk-local spots for the issue-13 worlds: `clear` metres from what is taken and
// `margin` from the chunk's edges; after 40 tries the last one anyway.
struct SpotPicker {
    DeterministicRng& rng;
    double cx, cz, S;
    std::vector<Disc> taken;
    std::pair<double, double> operator()(double clear, double margin) {
        double x = 0, z = 0;
        for (int attempt = 0; attempt < 40; ++attempt) {
            x = cx + rng.uniform(margin, S - margin);
            z = cz + rng.uniform(margin, S - margin);
            bool ok = true;
            for (const Disc& d : taken)
                if ((x - d.x) * (x - d.x) + (z - d.z) * (z - d.z) < (d.r + clear) * (d.r + clear)) {
                    ok = false;
                    break;
                }
            if (ok) break;
        }
        taken.push_back({x, z, clear});
        return {x, z};
    }
};

// Dense (D, D2k) and real-map-like (R) worlds; see world_gen.h.
WorldStats writeIssue13World(const WorldSpec& spec, const std::string& dir) {
    const auto t0 = std::chrono::steady_clock::now();
    WorldStats st;
    const bool dense = spec.kind == WorldKind::Dense;
    const double S = spec.chunkSize;
    SpaceOptions opt;
    opt.chunkSize = S;
    opt.neighbours = testing::NeighbourSpec::all(spec.neighbours);
    SpaceBuilder b(opt);

    std::map<std::string, uint64_t> triangles;
    auto mesh = [&](const std::string& name, const MeshSpec& m) {
        b.addMesh(name, m);
        triangles[name] = m.triangles.size();
        st.uniqueMeshTriangles += m.triangles.size();
        ++st.uniqueMeshes;
    };

    // Terrain: rolling hills, no wave shorter than 30 m (17 x 17 samples: 4 m apart).
    const Landscape land = dense ? Landscape(spec.seed, {6.0, 3.0, 1.2, 0.4, 0.0}, {400, 180, 70, 30, 17}, 8.0)
                                 : Landscape(spec.seed, {9.0, 4.5, 1.8, 0.5, 0.0}, {600, 260, 110, 45, 17}, 10.0);
    const double hLo = std::floor(land.base - land.reach() - 4), hHi = std::ceil(land.base + land.reach() + 4);
    const int gx0 = -(spec.chunksX / 2), gz0 = -(spec.chunksZ / 2);
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j)
            b.addTerrain(gx0 + i, gz0 + j, spec.terrainSamples, [&land](double x, double z) { return land.height(x, z); },
                         hLo, hHi);
    st.chunks = spec.chunksX * spec.chunksZ;
    st.terrainTriangles = 2ull * uint64_t(spec.terrainSamples - 1) * uint64_t(spec.terrainSamples - 1) * uint64_t(st.chunks);
    st.placedTriangles = st.terrainTriangles;
    auto ground = [&](double x, double z) { return *b.terrainHeightAt(x, z); };
    auto lowestGround = [&](double x, double z, double r) {
        double lo = ground(x, z);
        for (int q = 0; q < 8; ++q) {
            const double a = q * 0.25 * kPi;
            lo = std::min(lo, ground(x + r * std::cos(a), z + r * std::sin(a)));
        }
        return lo;
    };
    auto place = [&](const std::string& kind, const std::string& meshName, const Affine& a) {
        b.addModel(meshName, a);
        ++st.byKind[kind];
        ++st.models;
        st.placedTriangles += triangles.at(meshName);
    };
    auto dirFrom = [](double elevationDeg, double azimuthDeg) {
        const double e = elevationDeg * kPi / 180, a = azimuthDeg * kPi / 180;
        return glm::dvec3(round6(std::cos(e) * std::cos(a)), round6(-std::sin(e)), round6(std::cos(e) * std::sin(a)));
    };
    DeterministicRng lightRng(mix64(spec.seed ^ 0x11647ull));
    const double k = spec.objectsPerChunk;

    if (dense) {
        // Three closed scanned rocks and one open sheet; the shapes do not depend on the
        // tessellation (D2k: ~2k triangles each, the same surfaces sampled coarser).
        struct Rock {
            const char* name;
            RockShape shape;
            int n;  // geodesic frequency of the dense mesh: 8 n^2 triangles
        };
        const std::array<Rock, 3> rocks = {{{"scan_boulder", RockShape(1301, 2.6, {1.15, 0.7, 1.0}, 0.1, 6), 150},
                                            {"scan_rock", RockShape(1302, 1.8, {1.0, 0.8, 0.85}, 0.12, 6), 112},
                                            {"scan_stone", RockShape(1303, 1.1, {1.2, 0.6, 0.9}, 0.12, 6), 80}}};
        const double ledgeW = 14, ledgeD = 10, ledgeH = 1.6;
        const int coarseRock = std::max(1, int(std::lround(std::sqrt(spec.meshTriangles / 8.0))));
        const int coarseSheet = std::max(1, int(std::lround(std::sqrt(spec.meshTriangles / 2.0))));
        for (size_t r = 0; r < rocks.size(); ++r)
            mesh(rocks[r].name, scannedRock(rocks[r].shape, spec.meshTriangles > 0 ? coarseRock : rocks[r].n, 1301 + r, "stone"));
        mesh("scan_ledge", scannedSheet(1304, ledgeW, ledgeD, ledgeH, spec.meshTriangles > 0 ? coarseSheet : 160, "bedrock"));

        // A slanted sun with a small bias, and one lamp near the centre.
        b.addLight(LightSpec::directional("sun", {0.4, -1.0, 0.3}).withBias(0.03));
        {
            const double x = mm(lightRng.uniform(-20, 20)), z = mm(lightRng.uniform(-20, 20));
            b.addLight(LightSpec::point("lamp", {x, mm(ground(x, z) + 5.0), z}, 40.0));
        }
        st.directionalLights = 1;
        st.pointLights = 1;

        for (int i = 0; i < spec.chunksX; ++i)
            for (int j = 0; j < spec.chunksZ; ++j) {
                const int gx = gx0 + i, gz = gz0 + j;
                DeterministicRng rng(chunkSeed(spec.seed, gx, gz, 13));
                SpotPicker spot{rng, gx * S, gz * S, S, {}};
                const int n = int(std::lround(k * rng.uniform(0.7, 1.3)));
                for (int q = 0; q < n; ++q) {
                    const int type = rng.below(20);
                    const double s = rng.uniform(0.75, 1.3);
                    const glm::dvec3 scale(s * rng.uniform(0.9, 1.1), s * rng.uniform(0.9, 1.1), s * rng.uniform(0.9, 1.1));
                    const double yaw = std::round(rng.uniform(0, 360));
                    if (type >= 17) {  // the ledge, its rim under the ground and its dome out
                        const double half = 0.5 * std::max(ledgeW, ledgeD) * s;
                        const auto [x, z] = spot(half, std::min(half, S / 4));
                        const double y = lowestGround(x, z, 0.45 * std::min(ledgeW, ledgeD) * s) - rng.uniform(0.3, 0.9);
                        place("sheet", "scan_ledge", placed({x, y, z}, yaw, scale));
                        continue;
                    }
                    const Rock& rock = rocks[type < 4 ? 0 : type < 11 ? 1 : 2];
                    const double foot = rock.shape.footprint() * s, hh = rock.shape.halfHeight() * scale.y;
                    const auto [x, z] = spot(foot, std::min(foot, S / 4));
                    // Resting (sunk 15 %), half-buried (40-60 % of its height) or nearly
                    // buried (80-105 %: a scanned top showing, or nothing).
                    const int burial = rng.below(20);
                    const double sink = burial < 7 ? 0.3 * hh : burial < 16 ? rng.uniform(0.8, 1.2) * hh : rng.uniform(1.6, 2.1) * hh;
                    place("rock", rock.name, placed({x, lowestGround(x, z, 0.6 * foot) + hh - sink, z}, yaw, scale));
                }
            }
    } else {
        // Six small rocks, 200-392 triangles.
        std::vector<RockShape> shapes;
        const std::array<glm::dvec3, 6> axes = {{{1.1, 0.6, 0.9}, {1.0, 0.75, 1.0}, {1.25, 0.5, 0.8},
                                                 {0.9, 0.85, 0.9}, {1.2, 0.65, 1.0}, {1.0, 0.45, 1.1}}};
        const std::array<int, 6> freq = {5, 6, 7, 5, 6, 7};
        std::vector<std::string> names;
        for (size_t r = 0; r < 6; ++r) {
            shapes.emplace_back(1401 + r, 1.0, axes[r], 0.12, 4);
            names.push_back(std::string("stone_") + char('a' + r));
            mesh(names.back(), scannedRock(shapes.back(), freq[r], 1401 + r, "stone"));
        }
        b.addLight(LightSpec::directional("sun_low", dirFrom(spec.lowSunDegrees, 35)).withBias(0.05));
        // Issue 19: the real map's case, a sun 75 degrees high, beside the low one.
        b.addLight(LightSpec::directional("sun_high", dirFrom(75, 200)).withBias(0.05));
        st.directionalLights = 2;
        // Issue 19: trees among the rocks (alpha-tested crowns), a few per chunk.
        mesh("pine_a", pineTree(11.0, 5, 7));
        mesh("oak_a", broadleafTree(101, 3.5, 3.2, 36));

        for (int i = 0; i < spec.chunksX; ++i)
            for (int j = 0; j < spec.chunksZ; ++j) {
                const int gx = gx0 + i, gz = gz0 + j;
                DeterministicRng rng(chunkSeed(spec.seed, gx, gz, 17));
                const double cx = gx * S, cz = gz * S;
                SpotPicker spot{rng, cx, cz, S, {}};
                // Rock fields and open grassland: 0.4x to 1.6x the mean density.
                const double density = 0.4 + 1.2 * land.forest(cx + S / 2, cz + S / 2);
                const int n = int(std::floor(k * density + rng.uniform(0, 1)));
                for (int q = 0; q < n; ++q) {
                    const size_t type = size_t(rng.below(6));
                    const double s = std::exp(rng.uniform(std::log(0.3), std::log(2.2)));
                    const glm::dvec3 scale(s * rng.uniform(0.85, 1.15), s * rng.uniform(0.85, 1.15), s * rng.uniform(0.85, 1.15));
                    const double foot = shapes[type].footprint() * s, hh = shapes[type].halfHeight() * scale.y;
                    const auto [x, z] = spot(0.8 * foot, 0.5);
                    // Most half-buried (35-60 % of the height), some resting, a few nearly buried.
                    const int burial = rng.below(10);
                    const double sink = burial < 6   ? rng.uniform(0.7, 1.2) * hh
                                        : burial < 9 ? rng.uniform(0.2, 0.4) * hh
                                                     : rng.uniform(1.4, 1.9) * hh;
                    place("rock", names[type],
                          placed({x, lowestGround(x, z, 0.6 * foot) + hh - sink, z}, rng.uniform(0, 360), scale));
                }
                // Trees from their own stream, after the rocks (which keep their places).
                DeterministicRng treeRng(chunkSeed(spec.seed, gx, gz, 19));
                SpotPicker treeSpot{treeRng, cx, cz, S, spot.taken};  // clear of the rocks
                const int nTrees = 2 + int(treeRng.below(7));
                for (int t = 0; t < nTrees; ++t) {
                    const bool pine = treeRng.uniform(0, 1) < 0.5;
                    const auto [x, z] = treeSpot(2.0, 0.5);
                    place("tree", pine ? "pine_a" : "oak_a",
                          placed({x, ground(x, z), z}, treeRng.uniform(0, 360), glm::dvec3(treeRng.uniform(0.8, 1.2))));
                }
            }
    }
    st.lights = st.directionalLights + st.pointLights + st.spotLights;
    const auto t1 = std::chrono::steady_clock::now();
    st.buildSeconds = std::chrono::duration<double>(t1 - t0).count();
    b.write(dir);
    st.writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    st.bytesOnDisk = directorySize(dir, st.files);
    return st;
}

}  // namespace

// ---------------------------------------------------------------------------------------

WorldSpec worldS() {
    WorldSpec s;
    s.name = "S";
    s.chunksX = s.chunksZ = 3;
    s.seed = 0x5C0FFEE5ull;
    return s;
}

WorldSpec worldM() {
    WorldSpec s = worldS();
    s.name = "M";
    s.chunksX = s.chunksZ = 10;
    return s;
}

WorldSpec worldL() {
    WorldSpec s = worldS();
    s.name = "L";
    s.chunksX = s.chunksZ = 30;
    return s;
}

// Issue 16: generated like L, 100 x 100 chunks of 100 m (10 km x 10 km), for memory that
// follows the window: baked in part (--max-chunks), read whole.
WorldSpec worldXL() {
    WorldSpec s = worldS();
    s.name = "XL";
    s.chunksX = s.chunksZ = 100;
    return s;
}

// Issue 13: dense scanned meshes on 6 x 6 chunks of 64 m, 14 placements per chunk on
// average (10-18), terrain at 17 x 17 samples; a sun and one point light.
WorldSpec worldD() {
    WorldSpec s;
    s.name = "D";
    s.kind = WorldKind::Dense;
    s.chunksX = s.chunksZ = 6;
    s.seed = 0xD3175Eull;
    s.objectsPerChunk = 14;
    s.chunkSize = 64;
    s.terrainSamples = 17;
    s.localLights = 1;
    return s;
}

// D with every unique mesh at 2,048 triangles: the same seed, so the same placements.
WorldSpec worldD2k() {
    WorldSpec s = worldD();
    s.name = "D2k";
    s.meshTriangles = 2000;
    return s;
}

// Real-map-like: 20 x 20 chunks of 64 m, terrain at 17 x 17 samples, ~120 small rocks per
// chunk (48 to 192 with the local density), a low sun.
WorldSpec worldR() {
    WorldSpec s;
    s.name = "R";
    s.kind = WorldKind::RealMap;
    s.chunksX = s.chunksZ = 20;
    s.seed = 0x8EA1A4ull;
    s.objectsPerChunk = 120;
    s.chunkSize = 64;
    s.terrainSamples = 17;
    s.localLights = 0;
    return s;
}

// R's placements under an evening sun 10 degrees up: the same seed, so the same content.
WorldSpec worldR10() {
    WorldSpec s = worldR();
    s.name = "R10";
    s.lowSunDegrees = 10;
    return s;
}

bool worldByName(const std::string& name, WorldSpec& out) {
    std::string n;
    for (char c : name) n += char(std::toupper(static_cast<unsigned char>(c)));
    if (n == "S") out = worldS();
    else if (n == "M") out = worldM();
    else if (n == "L") out = worldL();
    else if (n == "XL") out = worldXL();
    else if (n == "D") out = worldD();
    else if (n == "D2K") out = worldD2k();
    else if (n == "R") out = worldR();
    else if (n == "R10") out = worldR10();
    else return false;
    return true;
}

uint64_t specHash(const WorldSpec& s) {
    std::ostringstream o;
    o << "v" << kGeneratorVersion << "|" << s.name << "|" << s.chunksX << "x" << s.chunksZ << "|" << s.seed << "|"
      << testing::formatNumber(s.objectsPerChunk) << "|" << testing::formatNumber(s.chunkSize) << "|" << s.terrainSamples
      << "|" << s.localLights << "|" << s.neighbours;
    // Fields added with issue 13: only in the other kinds' keys, so that the cached S, M and
    // L worlds stay valid (their output did not change).
    if (s.kind != WorldKind::Forest) o << "|kind" << int(s.kind) << "|" << s.meshTriangles << "|i13v" << kIssue13GeneratorVersion;
    if (s.kind == WorldKind::RealMap) o << "|r" << kRealMapGeneratorVersion;
    if (s.kind == WorldKind::RealMap && s.lowSunDegrees != 17.0) o << "|sun" << testing::formatNumber(s.lowSunDegrees);
    uint64_t h = 0xcbf29ce484222325ull;  // FNV-1a
    for (unsigned char c : o.str()) {
        h ^= c;
        h *= 0x100000001b3ull;
    }
    return h;
}

std::string specHashHex(const WorldSpec& s) {
    char buf[20];
    std::snprintf(buf, sizeof buf, "%016llx", (unsigned long long)specHash(s));
    return buf;
}

WorldStats writeWorld(const WorldSpec& spec, const std::string& dir) {
    if (spec.chunksX < 1 || spec.chunksZ < 1 || spec.chunksX > 60000 || spec.chunksZ > 60000)
        throw std::invalid_argument("world: bad grid size");
    if (spec.localLights < 0 || spec.localLights + 3 > 32)
        throw std::invalid_argument("world: at most 29 point/spot lights (32 lights in all)");
    if (!(spec.objectsPerChunk >= 0) || !(spec.chunkSize > 0) || spec.terrainSamples < 2)
        throw std::invalid_argument("world: bad density, chunk size or terrain samples");
    if (spec.kind != WorldKind::Forest) return writeIssue13World(spec, dir);
    const auto t0 = std::chrono::steady_clock::now();
    WorldStats st;
    const double S = spec.chunkSize;
    const double k = spec.objectsPerChunk / 280.0;  // content scales with the density
    SpaceOptions opt;
    opt.chunkSize = S;
    opt.neighbours = testing::NeighbourSpec::all(spec.neighbours);
    SpaceBuilder b(opt);

    // Meshes: written once, placed many times.
    std::map<std::string, uint64_t> triangles;
    auto mesh = [&](const std::string& name, const MeshSpec& m) {
        b.addMesh(name, m);
        triangles[name] = m.triangles.size();
        st.uniqueMeshTriangles += m.triangles.size();
        ++st.uniqueMeshes;
    };
    mesh("pine_a", pineTree(11.0, 5, 7));
    mesh("pine_b", pineTree(15.0, 7, 8));
    mesh("oak_a", broadleafTree(101, 3.5, 3.2, 36));
    mesh("oak_b", broadleafTree(202, 4.5, 4.2, 52));
    mesh("bush", bush(303));
    mesh("rock_a", lumpySolid(11, 1.0, 0.25, 0.7, 2, "stone"));
    mesh("rock_b", lumpySolid(22, 1.0, 0.30, 0.55, 2, "stone"));
    mesh("rock_c", lumpySolid(33, 1.0, 0.20, 0.9, 3, "stone"));
    mesh("rock_d", lumpySolid(44, 1.0, 0.15, 0.35, 3, "stone"));
    mesh("house_small", house(6, 8, 4, 6.5, 3));
    mesh("house_long", house(8, 18, 5, 8, 4));
    mesh("hall", hall());
    mesh("tower", tower());
    mesh("crate", MeshSpec::box({-0.5, 0, -0.5}, {0.5, 1, 0.5}, GroupSpec::named("planks")));
    mesh("barrel", barrel());
    mesh("fence", fence());
    mesh("lamp_post", lampPost());
    mesh("table", table());
    mesh("grass", grassPatch());
    mesh("drone", drone());
    mesh("balloon", balloon());
    mesh("chest", MeshSpec::box({-0.5, 0, -0.3}, {0.5, 0.6, 0.3}, GroupSpec::named("iron")));

    const Landscape land(spec.seed);
    const int gx0 = -(spec.chunksX / 2), gz0 = -(spec.chunksZ / 2);
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j)
            b.addTerrain(gx0 + i, gz0 + j, spec.terrainSamples, [&land](double x, double z) { return land.height(x, z); },
                         kMinHeight, kMaxHeight);
    const uint64_t terrainTris = 2ull * uint64_t(spec.terrainSamples - 1) * uint64_t(spec.terrainSamples - 1);
    st.chunks = spec.chunksX * spec.chunksZ;
    st.terrainTriangles = terrainTris * uint64_t(st.chunks);
    st.placedTriangles = st.terrainTriangles;

    // The written (quantised, triangulated) surface, as the tool will read it.
    auto ground = [&](double x, double z) { return *b.terrainHeightAt(x, z); };
    // Lowest and highest ground under a disc (centre and 8 points on the rim).
    auto groundRange = [&](double x, double z, double r) {
        double lo = ground(x, z), hi = lo;
        for (int q = 0; q < 8; ++q) {
            const double a = q * 0.25 * kPi;
            const double h = ground(x + r * std::cos(a), z + r * std::sin(a));
            lo = std::min(lo, h);
            hi = std::max(hi, h);
        }
        return std::pair<double, double>{lo, hi};
    };
    auto place = [&](const std::string& kind, const std::string& meshName, const Affine& a,
                     std::optional<bool> castsShadow = std::nullopt) {
        b.addModel(meshName, a, {}, castsShadow);
        ++st.byKind[kind];
        ++st.models;
        st.placedTriangles += triangles.at(meshName);
    };

    // Lights: three directional (azimuths from the seed), then point/spot lights.
    {
        DeterministicRng rng(mix64(spec.seed ^ 0x11647ull));
        auto dirFrom = [](double elevationDeg, double azimuthDeg) {
            const double e = elevationDeg * kPi / 180, a = azimuthDeg * kPi / 180;
            return glm::dvec3(round6(std::cos(e) * std::cos(a)), round6(-std::sin(e)), round6(std::cos(e) * std::sin(a)));
        };
        const double az = std::round(rng.uniform(0, 360));
        b.addLight(LightSpec::directional("sun_low", dirFrom(10, az)).withBias(0.05));
        b.addLight(LightSpec::directional("sun_high", dirFrom(55, az + 70)).withBias(0.05, 0.02));
        b.addLight(LightSpec::directional("moon", dirFrom(32, az + 190)).withBias(0.1).withFilterRadius(0.05));
        st.directionalLights = 3;
        const double x0 = gx0 * S, z0 = gz0 * S, x1 = x0 + spec.chunksX * S, z1 = z0 + spec.chunksZ * S;
        for (int l = 0; l < spec.localLights; ++l) {
            const double x = mm(rng.uniform(x0 + 5, x1 - 5)), z = mm(rng.uniform(z0 + 5, z1 - 5));
            const glm::dvec3 at(x, mm(ground(x, z) + rng.uniform(3, 9)), z);
            // Most lights are small (lamps, torches); some are large (floodlights, fires).
            const double range = std::round(rng.below(10) < 7 ? rng.uniform(12, 30) : rng.uniform(50, 110));
            if (rng.below(10) < 6) {
                b.addLight(LightSpec::point("lamp_" + std::to_string(l), at, range));
                ++st.pointLights;
            } else {
                const glm::dvec3 d(round6(rng.uniform(-0.5, 0.5)), -1.0, round6(rng.uniform(-0.5, 0.5)));
                b.addLight(LightSpec::spot("spot_" + std::to_string(l), at, d, range, std::round(rng.uniform(20, 55))));
                ++st.spotLights;
            }
        }
        st.lights = st.directionalLights + st.pointLights + st.spotLights;
    }

    // Content, chunk by chunk, each from its own seed (the same chunk gets the same content
    // whatever the grid size).
    const std::array<const char*, 4> rocks = {"rock_a", "rock_b", "rock_c", "rock_d"};
    const std::array<double, 4> rockHalfHeight = {0.8, 0.65, 1.0, 0.38};  // per unit scale, jitter included
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j) {
            const int gx = gx0 + i, gz = gz0 + j;
            DeterministicRng rng(chunkSeed(spec.seed, gx, gz, 1));
            const double cx = gx * S, cz = gz * S;
            const double forest = land.forest(cx + S / 2, cz + S / 2);
            // A free spot in the chunk (`margin` from its edges), `clear` from what is taken;
            // after 40 tries it takes the last one anyway (dense forests).
            SpotPicker spot{rng, cx, cz, S, {}};
            const int total = int(std::lround(spec.objectsPerChunk));
            int placedHere = 0;
            auto count = [&](double expected) { return int(std::floor(expected + rng.uniform(0, 1))); };

            // Buildings: more in open land, fewer in deep forest; on the highest ground
            // under them (foundations reach 3-4 m down).
            const int buildings = count(k * (1.0 + 4.0 * (1.0 - forest)));
            std::vector<Affine> halls;
            std::vector<Disc> buildingSpots;
            for (int n = 0; n < buildings; ++n) {
                const int type = rng.below(20);
                const char* name = type < 8 ? "house_small" : type < 13 ? "house_long" : type < 17 ? "hall" : "tower";
                const double radius = type < 8 ? 5.5 : type < 17 ? 10.5 : 4.0;
                const auto [x, z] = spot(radius + 2, radius + 1);
                const double hi = groundRange(x, z, radius * 0.8).second;
                const Affine a = placed({x, hi, z}, std::round(rng.uniform(0, 360)));
                place("building", name, a);
                buildingSpots.push_back({x, z, radius});
                if (type >= 13 && type < 17) halls.push_back(a);
                ++placedHere;
            }
            // Props inside the halls: lit at most through the door.
            for (const Affine& h : halls) {
                const std::array<const char*, 4> inside = {"crate", "table", "barrel", "crate"};
                for (size_t p = 0; p < kHallInterior.size(); ++p) {
                    place("interior", inside[p], placed(h.apply(kHallInterior[p]), std::round(rng.uniform(0, 90))));
                    ++placedHere;
                }
            }
            // Floating and hidden objects.
            if (rng.below(2) == 0) {  // a drone 15-40 m up: its shadow lands on the ground
                const auto [x, z] = spot(0.5, 2);
                place("floating", "drone", placed({x, ground(x, z) + rng.uniform(15, 40), z}, rng.uniform(0, 360)));
                ++placedHere;
            }
            if (rng.below(10) == 0) {  // a balloon 300-800 m up: its shadow mostly leaves the window
                const auto [x, z] = spot(1, 5);
                place("floating", "balloon", placed({x, ground(x, z) + rng.uniform(300, 800), z}, 0));
                ++placedHere;
            }
            if (rng.below(2) == 0) {  // a chest 1.5 m under the terrain: no lit point
                const auto [x, z] = spot(1, 3);
                place("hidden", "chest", placed({x, groundRange(x, z, 0.7).first - 2.1, z}, rng.uniform(0, 360)));
                ++placedHere;
            }
            // Rocks: a third buried 30-60% of their height, the rest sunk a little.
            const int nRocks = count(k * 40);
            for (int n = 0; n < nRocks; ++n) {
                const double s = rng.uniform(0.4, 2.6);
                const auto [x, z] = spot(s, 1);
                const int type = rng.below(4);
                const glm::dvec3 scale(s * rng.uniform(0.8, 1.2), s * rng.uniform(0.8, 1.2), s * rng.uniform(0.8, 1.2));
                const double halfHeight = scale.y * rockHalfHeight[size_t(type)];
                const double sink = (rng.below(3) == 0 ? rng.uniform(0.6, 1.2) : 0.3) * halfHeight;
                const double y = groundRange(x, z, 0.7 * s).first + halfHeight - sink;
                place("rock", rocks[size_t(type)], placed({x, y, z}, rng.uniform(0, 360), scale));
                ++placedHere;
            }
            // Props, near buildings when there are any.
            const int nProps = count(k * 16);
            for (int n = 0; n < nProps; ++n) {
                const int type = rng.below(8);
                const char* name = type < 3 ? "crate" : type < 5 ? "barrel" : type < 7 ? "fence" : "lamp_post";
                double x, z;
                if (!buildingSpots.empty() && rng.below(3) != 0) {
                    const Disc& d = buildingSpots[size_t(rng.below(int(buildingSpots.size())))];
                    const double a = rng.uniform(0, 2 * kPi), r = d.r + rng.uniform(1.5, 6);
                    x = std::clamp(d.x + r * std::cos(a), cx + 0.5, cx + S - 0.5);
                    z = std::clamp(d.z + r * std::sin(a), cz + 0.5, cz + S - 0.5);
                    spot.taken.push_back({x, z, 1});
                } else {
                    std::tie(x, z) = spot(1.5, 1);
                }
                place("prop", name, placed({x, groundRange(x, z, 0.5).first, z}, rng.uniform(0, 360)));
                ++placedHere;
            }
            // Grass cards: castsShadow false (decided by the input; they block no light and still
            // receive, semantics.md condition 1).
            const int nGrass = count(k * 20);
            for (int n = 0; n < nGrass; ++n) {
                const double x = cx + rng.uniform(0.5, S - 0.5), z = cz + rng.uniform(0.5, S - 0.5);
                place("grass", "grass", placed({x, ground(x, z) - 0.05, z}, rng.uniform(0, 360)), false);
                ++placedHere;
            }
            // Trees fill the rest: conifers in deep forest, broadleaves and bushes elsewhere.
            const int nTrees = std::max(0, total - placedHere);
            for (int n = 0; n < nTrees; ++n) {
                const bool conifer = rng.uniform(0, 1) < 0.25 + 0.5 * forest;
                const int variant = rng.below(10);
                const char* name = conifer ? (variant < 6 ? "pine_a" : "pine_b")
                                           : (variant < 4 ? "oak_a" : variant < 7 ? "oak_b" : "bush");
                const auto [x, z] = spot(name[0] == 'b' ? 1.0 : 2.0, 0.5);
                const double s = rng.uniform(0.8, 1.25);
                place("tree", name, placed({x, ground(x, z), z}, rng.uniform(0, 360), glm::dvec3(s)));
            }
        }
    const auto t1 = std::chrono::steady_clock::now();
    st.buildSeconds = std::chrono::duration<double>(t1 - t0).count();
    b.write(dir);
    st.writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    st.bytesOnDisk = directorySize(dir, st.files);
    return st;
}

}  // namespace shadowcull::bench
