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

#include "bench/world_parts.h"

namespace shadowcull::bench {

using namespace worldgen;
namespace fs = std::filesystem;

namespace {

// Bump when the generator's output changes: cached worlds are keyed by it.
constexpr uint64_t kGeneratorVersion = 3;
// The same for the dense and real-map-like worlds (D, D2k, R) alone, so that S, M and L
// stay cached.
constexpr uint64_t kDenseGeneratorVersion = 1;
// R alone (2: trees and a high sun), so that D and D2k stay cached.
constexpr uint64_t kRealMapGeneratorVersion = 2;

uint64_t directorySize(const fs::path& dir, uint64_t& files) {
    uint64_t bytes = 0;
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) {
            bytes += e.file_size();
            ++files;
        }
    return bytes;
}

SpaceOptions spaceOptions(const WorldSpec& spec) {
    SpaceOptions opt;
    opt.chunkSize = spec.chunkSize;
    opt.neighbours = testing::NeighbourSpec::all(spec.neighbours);
    return opt;
}

}  // namespace

// ---------------------------------------------------------------------------------------

namespace worldgen {

glm::dvec3 sunDirection(double elevationDeg, double azimuthDeg) {
    const double e = elevationDeg * kPi / 180, a = azimuthDeg * kPi / 180;
    return glm::dvec3(round6(std::cos(e) * std::cos(a)), round6(-std::sin(e)), round6(std::cos(e) * std::sin(a)));
}

WorldWriter::WorldWriter(const WorldSpec& s)
    : spec(s), start(std::chrono::steady_clock::now()), b(spaceOptions(s)), gx0(-(s.chunksX / 2)), gz0(-(s.chunksZ / 2)) {}

void WorldWriter::mesh(const std::string& name, const MeshSpec& m) {
    b.addMesh(name, m);
    triangles[name] = m.triangles.size();
    st.uniqueMeshTriangles += m.triangles.size();
    ++st.uniqueMeshes;
}

void WorldWriter::place(const std::string& kind, const std::string& meshName, const Affine& a, std::optional<bool> castsShadow) {
    b.addModel(meshName, a, {}, castsShadow);
    ++st.byKind[kind];
    ++st.models;
    st.placedTriangles += triangles.at(meshName);
}

void WorldWriter::addTerrain(const Landscape& land, double minHeight, double maxHeight) {
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j)
            b.addTerrain(gx0 + i, gz0 + j, spec.terrainSamples, [&land](double x, double z) { return land.height(x, z); },
                         minHeight, maxHeight);
    const uint64_t terrainTris = 2ull * uint64_t(spec.terrainSamples - 1) * uint64_t(spec.terrainSamples - 1);
    st.chunks = spec.chunksX * spec.chunksZ;
    st.terrainTriangles = terrainTris * uint64_t(st.chunks);
    st.placedTriangles = st.terrainTriangles;
}

double WorldWriter::ground(double x, double z) const { return *b.terrainHeightAt(x, z); }

std::pair<double, double> WorldWriter::groundRange(double x, double z, double r) const {
    double lo = ground(x, z), hi = lo;
    for (int q = 0; q < 8; ++q) {
        const double a = q * 0.25 * kPi;
        const double h = ground(x + r * std::cos(a), z + r * std::sin(a));
        lo = std::min(lo, h);
        hi = std::max(hi, h);
    }
    return {lo, hi};
}

WorldStats WorldWriter::write(const std::string& dir) {
    st.lights = st.directionalLights + st.pointLights + st.spotLights;
    const auto t1 = std::chrono::steady_clock::now();
    st.buildSeconds = std::chrono::duration<double>(t1 - start).count();
    b.write(dir);
    st.writeSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
    st.bytesOnDisk = directorySize(dir, st.files);
    return st;
}

}  // namespace worldgen

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
    if (s.kind != WorldKind::Forest) o << "|kind" << int(s.kind) << "|" << s.meshTriangles << "|i13v" << kDenseGeneratorVersion;
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

// ---------------------------------------------------------------------------------------
// The forest worlds (S, M, L)

namespace {

// Meshes: written once, placed many times.
void addForestMeshes(WorldWriter& w) {
    w.mesh("pine_a", pineTree(11.0, 5, 7));
    w.mesh("pine_b", pineTree(15.0, 7, 8));
    w.mesh("oak_a", broadleafTree(101, 3.5, 3.2, 36));
    w.mesh("oak_b", broadleafTree(202, 4.5, 4.2, 52));
    w.mesh("bush", bush(303));
    w.mesh("rock_a", lumpySolid(11, 1.0, 0.25, 0.7, 2, "stone"));
    w.mesh("rock_b", lumpySolid(22, 1.0, 0.30, 0.55, 2, "stone"));
    w.mesh("rock_c", lumpySolid(33, 1.0, 0.20, 0.9, 3, "stone"));
    w.mesh("rock_d", lumpySolid(44, 1.0, 0.15, 0.35, 3, "stone"));
    w.mesh("house_small", house(6, 8, 4, 6.5, 3));
    w.mesh("house_long", house(8, 18, 5, 8, 4));
    w.mesh("hall", hall());
    w.mesh("tower", tower());
    w.mesh("crate", MeshSpec::box({-0.5, 0, -0.5}, {0.5, 1, 0.5}, GroupSpec::named("planks")));
    w.mesh("barrel", barrel());
    w.mesh("fence", fence());
    w.mesh("lamp_post", lampPost());
    w.mesh("table", table());
    w.mesh("grass", grassPatch());
    w.mesh("drone", drone());
    w.mesh("balloon", balloon());
    w.mesh("chest", MeshSpec::box({-0.5, 0, -0.3}, {0.5, 0.6, 0.3}, GroupSpec::named("iron")));
}

// Three directional lights (azimuths from the seed), then point/spot lights.
void addForestLights(WorldWriter& w) {
    const WorldSpec& spec = w.spec;
    const double S = spec.chunkSize;
    DeterministicRng rng(mix64(spec.seed ^ 0x11647ull));
    const double az = std::round(rng.uniform(0, 360));
    w.b.addLight(LightSpec::directional("sun_low", sunDirection(10, az)).withBias(0.05));
    w.b.addLight(LightSpec::directional("sun_high", sunDirection(55, az + 70)).withBias(0.05, 0.02));
    w.b.addLight(LightSpec::directional("moon", sunDirection(32, az + 190)).withBias(0.1).withFilterRadius(0.05));
    w.st.directionalLights = 3;
    const double x0 = w.gx0 * S, z0 = w.gz0 * S, x1 = x0 + spec.chunksX * S, z1 = z0 + spec.chunksZ * S;
    for (int l = 0; l < spec.localLights; ++l) {
        const double x = mm(rng.uniform(x0 + 5, x1 - 5)), z = mm(rng.uniform(z0 + 5, z1 - 5));
        const glm::dvec3 at(x, mm(w.ground(x, z) + rng.uniform(3, 9)), z);
        // Most lights are small (lamps, torches); some are large (floodlights, fires).
        const double range = std::round(rng.below(10) < 7 ? rng.uniform(12, 30) : rng.uniform(50, 110));
        if (rng.below(10) < 6) {
            w.b.addLight(LightSpec::point("lamp_" + std::to_string(l), at, range));
            ++w.st.pointLights;
        } else {
            const glm::dvec3 d(round6(rng.uniform(-0.5, 0.5)), -1.0, round6(rng.uniform(-0.5, 0.5)));
            w.b.addLight(LightSpec::spot("spot_" + std::to_string(l), at, d, range, std::round(rng.uniform(20, 55))));
            ++w.st.spotLights;
        }
    }
    w.st.lights = w.st.directionalLights + w.st.pointLights + w.st.spotLights;
}

// One chunk's content, from its own seed (the same chunk gets the same content whatever
// the grid size), in this order: buildings, the props inside halls, floating and hidden
// objects, rocks, props, grass, and trees filling the rest.
struct ForestChunk {
    ForestChunk(WorldWriter& writer, const Landscape& land, int gx, int gz)
        : w(writer), S(writer.spec.chunkSize), k(writer.spec.objectsPerChunk / 280.0),
          rng(chunkSeed(writer.spec.seed, gx, gz, 1)), cx(gx * S), cz(gz * S), forest(land.forest(cx + S / 2, cz + S / 2)),
          spot{rng, cx, cz, S, {}} {}

    WorldWriter& w;
    const double S;
    const double k;  // content scales with the density
    DeterministicRng rng;
    const double cx, cz;
    const double forest;
    // A free spot in the chunk (`margin` from its edges), `clear` from what is taken;
    // after 40 tries it takes the last one anyway (dense forests).
    SpotPicker spot;
    int placedHere = 0;
    std::vector<Affine> halls;
    std::vector<Disc> buildingSpots;

    int count(double expected) { return int(std::floor(expected + rng.uniform(0, 1))); }
    void place(const std::string& kind, const std::string& meshName, const Affine& a,
               std::optional<bool> castsShadow = std::nullopt) {
        w.place(kind, meshName, a, castsShadow);
        ++placedHere;
    }

    // Buildings: more in open land, fewer in deep forest; on the highest ground under them
    // (foundations reach 3-4 m down).
    void buildings() {
        const int n = count(k * (1.0 + 4.0 * (1.0 - forest)));
        for (int q = 0; q < n; ++q) {
            const int type = rng.below(20);
            const char* name = type < 8 ? "house_small" : type < 13 ? "house_long" : type < 17 ? "hall" : "tower";
            const double radius = type < 8 ? 5.5 : type < 17 ? 10.5 : 4.0;
            const auto [x, z] = spot(radius + 2, radius + 1);
            const double hi = w.groundRange(x, z, radius * 0.8).second;
            const Affine a = placed({x, hi, z}, std::round(rng.uniform(0, 360)));
            place("building", name, a);
            buildingSpots.push_back({x, z, radius});
            if (type >= 13 && type < 17) halls.push_back(a);
        }
        // Props inside the halls: lit at most through the door.
        for (const Affine& h : halls) {
            const std::array<const char*, 4> inside = {"crate", "table", "barrel", "crate"};
            for (size_t p = 0; p < kHallInterior.size(); ++p)
                place("interior", inside[p], placed(h.apply(kHallInterior[p]), std::round(rng.uniform(0, 90))));
        }
    }

    // Floating and hidden objects.
    void oddities() {
        if (rng.below(2) == 0) {  // a drone 15-40 m up: its shadow lands on the ground
            const auto [x, z] = spot(0.5, 2);
            place("floating", "drone", placed({x, w.ground(x, z) + rng.uniform(15, 40), z}, rng.uniform(0, 360)));
        }
        if (rng.below(10) == 0) {  // a balloon 300-800 m up: its shadow mostly leaves the window
            const auto [x, z] = spot(1, 5);
            place("floating", "balloon", placed({x, w.ground(x, z) + rng.uniform(300, 800), z}, 0));
        }
        if (rng.below(2) == 0) {  // a chest 1.5 m under the terrain: no lit point
            const auto [x, z] = spot(1, 3);
            place("hidden", "chest", placed({x, w.groundRange(x, z, 0.7).first - 2.1, z}, rng.uniform(0, 360)));
        }
    }

    // Rocks: a third buried 30-60% of their height, the rest sunk a little.
    void rocks() {
        const std::array<const char*, 4> names = {"rock_a", "rock_b", "rock_c", "rock_d"};
        const std::array<double, 4> rockHalfHeight = {0.8, 0.65, 1.0, 0.38};  // per unit scale, jitter included
        const int n = count(k * 40);
        for (int q = 0; q < n; ++q) {
            const double s = rng.uniform(0.4, 2.6);
            const auto [x, z] = spot(s, 1);
            const int type = rng.below(4);
            const glm::dvec3 scale(s * rng.uniform(0.8, 1.2), s * rng.uniform(0.8, 1.2), s * rng.uniform(0.8, 1.2));
            const double halfHeight = scale.y * rockHalfHeight[size_t(type)];
            const double sink = (rng.below(3) == 0 ? rng.uniform(0.6, 1.2) : 0.3) * halfHeight;
            const double y = w.groundRange(x, z, 0.7 * s).first + halfHeight - sink;
            place("rock", names[size_t(type)], placed({x, y, z}, rng.uniform(0, 360), scale));
        }
    }

    // Props, near buildings when there are any.
    void props() {
        const int n = count(k * 16);
        for (int q = 0; q < n; ++q) {
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
            place("prop", name, placed({x, w.groundRange(x, z, 0.5).first, z}, rng.uniform(0, 360)));
        }
    }

    // Grass cards: castsShadow false (decided by the input; they block no light and still
    // receive, semantics.md condition 1).
    void grass() {
        const int n = count(k * 20);
        for (int q = 0; q < n; ++q) {
            const double x = cx + rng.uniform(0.5, S - 0.5), z = cz + rng.uniform(0.5, S - 0.5);
            place("grass", "grass", placed({x, w.ground(x, z) - 0.05, z}, rng.uniform(0, 360)), false);
        }
    }

    // Trees fill the rest, up to the chunk's models: conifers in deep forest, broadleaves
    // and bushes elsewhere.
    void trees() {
        const int n = std::max(0, int(std::lround(w.spec.objectsPerChunk)) - placedHere);
        for (int q = 0; q < n; ++q) {
            const bool conifer = rng.uniform(0, 1) < 0.25 + 0.5 * forest;
            const int variant = rng.below(10);
            const char* name = conifer ? (variant < 6 ? "pine_a" : "pine_b")
                                       : (variant < 4 ? "oak_a" : variant < 7 ? "oak_b" : "bush");
            const auto [x, z] = spot(name[0] == 'b' ? 1.0 : 2.0, 0.5);
            const double s = rng.uniform(0.8, 1.25);
            place("tree", name, placed({x, w.ground(x, z), z}, rng.uniform(0, 360), glm::dvec3(s)));
        }
    }
};

}  // namespace

WorldStats writeWorld(const WorldSpec& spec, const std::string& dir) {
    if (spec.chunksX < 1 || spec.chunksZ < 1 || spec.chunksX > 60000 || spec.chunksZ > 60000)
        throw std::invalid_argument("world: bad grid size");
    if (spec.localLights < 0 || spec.localLights + 3 > 32)
        throw std::invalid_argument("world: at most 29 point/spot lights (32 lights in all)");
    if (!(spec.objectsPerChunk >= 0) || !(spec.chunkSize > 0) || spec.terrainSamples < 2)
        throw std::invalid_argument("world: bad density, chunk size or terrain samples");
    if (spec.kind == WorldKind::Dense) return writeDenseWorld(spec, dir);
    if (spec.kind == WorldKind::RealMap) return writeRealMapWorld(spec, dir);
    WorldWriter w(spec);
    addForestMeshes(w);
    const Landscape land(spec.seed);
    w.addTerrain(land, kMinHeight, kMaxHeight);
    addForestLights(w);
    for (int i = 0; i < spec.chunksX; ++i)
        for (int j = 0; j < spec.chunksZ; ++j) {
            ForestChunk chunk(w, land, w.gx0 + i, w.gz0 + j);
            chunk.buildings();
            chunk.oddities();
            chunk.rocks();
            chunk.props();
            chunk.grass();
            chunk.trees();
        }
    return w.write(dir);
}

}  // namespace shadowcull::bench
