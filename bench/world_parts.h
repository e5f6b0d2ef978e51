// Internals of the benchmark worlds (world_gen.h), shared by world_gen.cpp (the forest
// worlds S, M, L, the specs and their hash), world_dense.cpp (D, D2k and R) and
// world_meshes.cpp (the meshes every kind of world places).
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "bench/world_gen.h"
#include "tests/support/space_builder.h"

namespace shadowcull::bench::worldgen {

using testing::Affine;
using testing::DeterministicRng;
using testing::GroupSpec;
using testing::LightSpec;
using testing::MeshSpec;
using testing::SpaceBuilder;
using testing::SpaceOptions;

constexpr double kPi = 3.14159265358979323846;

// ---------------------------------------------------------------------------------------
// Seeds and small helpers

inline uint64_t mix64(uint64_t z) {  // SplitMix64 finaliser
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

inline uint64_t chunkSeed(uint64_t seed, int gx, int gz, uint64_t stream) {
    return mix64(mix64(mix64(seed ^ 0xC0FFEEull) + uint64_t(uint32_t(gx))) + (uint64_t(uint32_t(gz)) << 20) + stream);
}

inline double round6(double v) { return std::round(v * 1e6) / 1e6; }
inline double mm(double v) { return std::round(v * 1000.0) / 1000.0; }

// Scale, then turn about +Y by `yawDegrees`, then move to `at`. Matrix entries rounded to
// 1e-6 (a valid affine map either way; it keeps the chunk files short).
Affine placed(const glm::dvec3& at, double yawDegrees, const glm::dvec3& scale = glm::dvec3(1.0));

// A uniformly random unit vector.
glm::dvec3 randomUnit(DeterministicRng& rng);

// A directional light's direction from its elevation above the horizon and its azimuth
// (degrees), rounded to 1e-6.
glm::dvec3 sunDirection(double elevationDeg, double azimuthDeg);

// ---------------------------------------------------------------------------------------
// Meshes (world_meshes.cpp; model-local metres, origin on the ground at the object's foot)

MeshSpec pineTree(double height, int tiers, int cardsPerTier);
MeshSpec broadleafTree(uint64_t seed, double trunkHeight, double crownRadius, int cards);
MeshSpec bush(uint64_t seed);
MeshSpec lumpySolid(uint64_t seed, double radius, double jitter, double squash, int levels, const std::string& material);
MeshSpec house(double w, double d, double wallHeight, double ridge, double foundation);
MeshSpec hall();
// Where hall() holds its props (model-local): lit at most through the door.
extern const std::array<glm::dvec3, 4> kHallInterior;
MeshSpec tower();
MeshSpec fence();
MeshSpec lampPost();
MeshSpec table();
MeshSpec grassPatch();
MeshSpec balloon();
MeshSpec barrel();
MeshSpec drone();

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

    RockShape(uint64_t seed, double radius0, const glm::dvec3& axes0, double amplitude, int octaves);
    double radiusAlong(const glm::dvec3& u) const;
    // Half the nominal height (the placement's unit for burying it; ridges add ~15 %).
    double halfHeight() const { return radius * axes.y; }
    double footprint() const { return radius * std::max(axes.x, axes.z); }
};

// A closed jagged rock of 8 n^2 triangles on `shape` (world_meshes.cpp).
MeshSpec scannedRock(const RockShape& shape, int n, uint64_t seed, const std::string& material);
// An open jagged sheet of 2 n^2 triangles, w x d metres, its dome `height` high.
MeshSpec scannedSheet(uint64_t seed, double w, double d, double height, int n, const std::string& material);

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

// Chunk-local spots for the dense and real-map-like worlds: `clear` metres from what is
// taken and `margin` from the chunk's edges; after 40 tries the last one anyway.
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

// ---------------------------------------------------------------------------------------
// A world being described: the space builder, what the world holds so far and the
// triangles of each mesh (world_gen.cpp).

struct WorldWriter {
    explicit WorldWriter(const WorldSpec& spec);

    const WorldSpec& spec;
    std::chrono::steady_clock::time_point start;
    WorldStats st;
    SpaceBuilder b;
    std::map<std::string, uint64_t> triangles;  // per mesh
    int gx0, gz0;                               // the grid's first chunk

    // Writes mesh `name` once (placed many times).
    void mesh(const std::string& name, const MeshSpec& m);
    // Places mesh `meshName`, counted as `kind`.
    void place(const std::string& kind, const std::string& meshName, const Affine& a,
               std::optional<bool> castsShadow = std::nullopt);
    // Every chunk's terrain from `land`, stored between `minHeight` and `maxHeight`.
    void addTerrain(const Landscape& land, double minHeight, double maxHeight);
    // The written (quantised, triangulated) surface, as the tool will read it.
    double ground(double x, double z) const;
    // Lowest and highest ground under a disc (centre and 8 points on the rim).
    std::pair<double, double> groundRange(double x, double z, double r) const;
    // Writes the world into `dir`; what it holds, with the times and the bytes written.
    WorldStats write(const std::string& dir);
};

// Dense (D, D2k) and real-map-like (R) worlds (world_dense.cpp); see world_gen.h.
WorldStats writeDenseWorld(const WorldSpec& spec, const std::string& dir);
WorldStats writeRealMapWorld(const WorldSpec& spec, const std::string& dir);

}  // namespace shadowcull::bench::worldgen
