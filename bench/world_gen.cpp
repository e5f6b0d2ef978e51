// Benchmark worlds (see world_gen.h). The world is described through testing::SpaceBuilder
// (meshes written once as OBJ+MTL, placements as chunk-relative transforms, terrain as
// 16-bit PNG heightmaps), which stays fast enough at 250k placements (seconds, a few
// hundred MB); transforms are rounded to 1e-6 and positions to a millimetre so that chunk
// files stay small (~400 bytes per model).

#include "bench/world_gen.h"

#include <algorithm>
#include <array>
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
    double fPhase = 0, fCos = 1, fSin = 0;
    explicit Landscape(uint64_t seed) {
        DeterministicRng rng(mix64(seed ^ 0x7E44A1Bull));
        const std::array<double, 5> a = {10.0, 5.0, 2.0, 0.6, 0.25}, wl = {520, 230, 90, 38, 17};
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
    // Metres, within [-6, 30] (stored between -20 and 45).
    double height(double x, double z) const {
        double h = 12.0;
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

bool worldByName(const std::string& name, WorldSpec& out) {
    if (name == "S" || name == "s") out = worldS();
    else if (name == "M" || name == "m") out = worldM();
    else if (name == "L" || name == "l") out = worldL();
    else return false;
    return true;
}

uint64_t specHash(const WorldSpec& s) {
    std::ostringstream o;
    o << "v" << kGeneratorVersion << "|" << s.name << "|" << s.chunksX << "x" << s.chunksZ << "|" << s.seed << "|"
      << testing::formatNumber(s.objectsPerChunk) << "|" << testing::formatNumber(s.chunkSize) << "|" << s.terrainSamples
      << "|" << s.localLights << "|" << s.neighbours;
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
            std::vector<Disc> taken;
            // A free spot in the chunk (`margin` from its edges), `clear` from what is taken;
            // after 40 tries it takes the last one anyway (dense forests).
            auto spot = [&](double clear, double margin) {
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
                return std::pair<double, double>{x, z};
            };
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
                    taken.push_back({x, z, 1});
                } else {
                    std::tie(x, z) = spot(1.5, 1);
                }
                place("prop", name, placed({x, groundRange(x, z, 0.5).first, z}, rng.uniform(0, 360)));
                ++placedHere;
            }
            // Grass cards: castsShadow false (decided by the input; still occluders and receivers).
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
