// The dense worlds (D, D2k: a few scanned-rock-like meshes of 50k-180k triangles) and the
// real-map-like world (R: many small rocks and a few trees); see world_gen.h.

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "bench/world_parts.h"

namespace shadowcull::bench::worldgen {

namespace {

// One of the dense worlds' closed rocks.
struct Rock {
    const char* name;
    RockShape shape;
    int n;  // geodesic frequency of the dense mesh: 8 n^2 triangles
};

// The dense worlds' ledge: an open sheet, w x d metres, its dome h high.
constexpr double kLedgeW = 14, kLedgeD = 10, kLedgeH = 1.6;

// Rolling hills, no wave shorter than 30 m (17 x 17 samples: 4 m apart).
Landscape denseLand(const WorldSpec& spec, bool dense) {
    return dense ? Landscape(spec.seed, {6.0, 3.0, 1.2, 0.4, 0.0}, {400, 180, 70, 30, 17}, 8.0)
                 : Landscape(spec.seed, {9.0, 4.5, 1.8, 0.5, 0.0}, {600, 260, 110, 45, 17}, 10.0);
}

// The terrain of both kinds, stored 4 m beyond the hills' reach.
Landscape addDenseTerrain(WorldWriter& w, bool dense) {
    const Landscape land = denseLand(w.spec, dense);
    const double hLo = std::floor(land.base - land.reach() - 4), hHi = std::ceil(land.base + land.reach() + 4);
    w.addTerrain(land, hLo, hHi);
    return land;
}

// The lowest ground under a disc (centre and 8 points on the rim).
double lowestGround(const WorldWriter& w, double x, double z, double r) { return w.groundRange(x, z, r).first; }

// One chunk of a dense world: 10-18 placements (at the mean density), rocks resting,
// half-buried or nearly buried, and ledges.
void placeDenseChunk(WorldWriter& w, const std::array<Rock, 3>& rocks, int gx, int gz) {
    const double S = w.spec.chunkSize, k = w.spec.objectsPerChunk;
    DeterministicRng rng(chunkSeed(w.spec.seed, gx, gz, 13));
    SpotPicker spot{rng, gx * S, gz * S, S, {}};
    const int n = int(std::lround(k * rng.uniform(0.7, 1.3)));
    for (int q = 0; q < n; ++q) {
        const int type = rng.below(20);
        const double s = rng.uniform(0.75, 1.3);
        const glm::dvec3 scale(s * rng.uniform(0.9, 1.1), s * rng.uniform(0.9, 1.1), s * rng.uniform(0.9, 1.1));
        const double yaw = std::round(rng.uniform(0, 360));
        if (type >= 17) {  // the ledge, its rim under the ground and its dome out
            const double half = 0.5 * std::max(kLedgeW, kLedgeD) * s;
            const auto [x, z] = spot(half, std::min(half, S / 4));
            const double y = lowestGround(w, x, z, 0.45 * std::min(kLedgeW, kLedgeD) * s) - rng.uniform(0.3, 0.9);
            w.place("sheet", "scan_ledge", placed({x, y, z}, yaw, scale));
            continue;
        }
        const Rock& rock = rocks[type < 4 ? 0 : type < 11 ? 1 : 2];
        const double foot = rock.shape.footprint() * s, hh = rock.shape.halfHeight() * scale.y;
        const auto [x, z] = spot(foot, std::min(foot, S / 4));
        // Resting (sunk 15 %), half-buried (40-60 % of its height) or nearly
        // buried (80-105 %: a scanned top showing, or nothing).
        const int burial = rng.below(20);
        const double sink = burial < 7 ? 0.3 * hh : burial < 16 ? rng.uniform(0.8, 1.2) * hh : rng.uniform(1.6, 2.1) * hh;
        w.place("rock", rock.name, placed({x, lowestGround(w, x, z, 0.6 * foot) + hh - sink, z}, yaw, scale));
    }
}

// One chunk of the real-map-like world: rocks at the local density (0.4x to 1.6x the
// mean: rock fields and open grassland), then 2-8 trees clear of them.
void placeRealMapChunk(WorldWriter& w, const Landscape& land, const std::vector<RockShape>& shapes,
                       const std::vector<std::string>& names, int gx, int gz) {
    const double S = w.spec.chunkSize, k = w.spec.objectsPerChunk;
    DeterministicRng rng(chunkSeed(w.spec.seed, gx, gz, 17));
    const double cx = gx * S, cz = gz * S;
    SpotPicker spot{rng, cx, cz, S, {}};
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
        w.place("rock", names[type], placed({x, lowestGround(w, x, z, 0.6 * foot) + hh - sink, z}, rng.uniform(0, 360), scale));
    }
    // Trees from their own stream, after the rocks (which keep their places).
    DeterministicRng treeRng(chunkSeed(w.spec.seed, gx, gz, 19));
    SpotPicker treeSpot{treeRng, cx, cz, S, spot.taken};  // clear of the rocks
    const int nTrees = 2 + int(treeRng.below(7));
    for (int t = 0; t < nTrees; ++t) {
        const bool pine = treeRng.uniform(0, 1) < 0.5;
        const auto [x, z] = treeSpot(2.0, 0.5);
        w.place("tree", pine ? "pine_a" : "oak_a",
                placed({x, w.ground(x, z), z}, treeRng.uniform(0, 360), glm::dvec3(treeRng.uniform(0.8, 1.2))));
    }
}

}  // namespace

WorldStats writeDenseWorld(const WorldSpec& spec, const std::string& dir) {
    WorldWriter w(spec);
    addDenseTerrain(w, true);
    DeterministicRng lightRng(mix64(spec.seed ^ 0x11647ull));
    // Three closed scanned rocks and one open sheet; the shapes do not depend on the
    // tessellation (D2k: ~2k triangles each, the same surfaces sampled coarser).
    const std::array<Rock, 3> rocks = {{{"scan_boulder", RockShape(1301, 2.6, {1.15, 0.7, 1.0}, 0.1, 6), 150},
                                        {"scan_rock", RockShape(1302, 1.8, {1.0, 0.8, 0.85}, 0.12, 6), 112},
                                        {"scan_stone", RockShape(1303, 1.1, {1.2, 0.6, 0.9}, 0.12, 6), 80}}};
    const int coarseRock = std::max(1, int(std::lround(std::sqrt(spec.meshTriangles / 8.0))));
    const int coarseSheet = std::max(1, int(std::lround(std::sqrt(spec.meshTriangles / 2.0))));
    for (size_t r = 0; r < rocks.size(); ++r)
        w.mesh(rocks[r].name, scannedRock(rocks[r].shape, spec.meshTriangles > 0 ? coarseRock : rocks[r].n, 1301 + r, "stone"));
    w.mesh("scan_ledge", scannedSheet(1304, kLedgeW, kLedgeD, kLedgeH, spec.meshTriangles > 0 ? coarseSheet : 160, "bedrock"));

    // A slanted sun with a small bias, and one lamp near the centre.
    w.b.addLight(LightSpec::directional("sun", {0.4, -1.0, 0.3}).withBias(0.03));
    {
        const double x = mm(lightRng.uniform(-20, 20)), z = mm(lightRng.uniform(-20, 20));
        w.b.addLight(LightSpec::point("lamp", {x, mm(w.ground(x, z) + 5.0), z}, 40.0));
    }
    w.st.directionalLights = 1;
    w.st.pointLights = 1;

    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j) placeDenseChunk(w, rocks, w.gx0 + i, w.gz0 + j);
    return w.write(dir);
}

WorldStats writeRealMapWorld(const WorldSpec& spec, const std::string& dir) {
    WorldWriter w(spec);
    const Landscape land = addDenseTerrain(w, false);
    // Six small rocks, 200-392 triangles.
    std::vector<RockShape> shapes;
    const std::array<glm::dvec3, 6> axes = {{{1.1, 0.6, 0.9}, {1.0, 0.75, 1.0}, {1.25, 0.5, 0.8},
                                             {0.9, 0.85, 0.9}, {1.2, 0.65, 1.0}, {1.0, 0.45, 1.1}}};
    const std::array<int, 6> freq = {5, 6, 7, 5, 6, 7};
    std::vector<std::string> names;
    for (size_t r = 0; r < 6; ++r) {
        shapes.emplace_back(1401 + r, 1.0, axes[r], 0.12, 4);
        names.push_back(std::string("stone_") + char('a' + r));
        w.mesh(names.back(), scannedRock(shapes.back(), freq[r], 1401 + r, "stone"));
    }
    // A low sun, and the real map's other case beside it: a sun 75 degrees high.
    w.b.addLight(LightSpec::directional("sun_low", sunDirection(spec.lowSunDegrees, 35)).withBias(0.05));
    w.b.addLight(LightSpec::directional("sun_high", sunDirection(75, 200)).withBias(0.05));
    w.st.directionalLights = 2;
    // Trees among the rocks (alpha-tested crowns), a few per chunk.
    w.mesh("pine_a", pineTree(11.0, 5, 7));
    w.mesh("oak_a", broadleafTree(101, 3.5, 3.2, 36));

    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j) placeRealMapChunk(w, land, shapes, names, w.gx0 + i, w.gz0 + j);
    return w.write(dir);
}

}  // namespace shadowcull::bench::worldgen
