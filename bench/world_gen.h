// Benchmark worlds: a chunked game world of any size, generated deterministically from a
// seed, in the scene format (../shared/spec/scene-format.md), for bench/bake_bench.
//
// Per chunk (100 m): hilly terrain (33 x 33 samples), a forest of alpha-tested trees
// (opaque trunk group + alpha-tested canopy group, five variants), rocks (four irregular
// closed meshes, a third of them partly buried), buildings (walls + roof groups; halls
// with an open door and props inside), props (crates, barrels, fences, lamp posts), grass
// cards with castsShadow false, and a few floating or hidden objects (drones, balloons
// hundreds of metres up, chests buried under the terrain). Lights: three directional (a
// low sun 10 degrees above the horizon with bias 0.05, a high sun, a moon) and point/spot
// lights scattered over the world (total <= 32, the format's limit).
//
// Few unique meshes (22), many placements: every model resource is written once and
// placed by transform (instancing), as in a real game world.
//
// Deterministic: SplitMix64 (testing::DeterministicRng) seeded per chunk from the world
// seed and the chunk's grid position, our own formulas for every distribution, no
// std::random_device or std distributions; the same spec writes the same bytes.
//
// Two more kinds of world (issue 13), on 64 m chunks with terrain at 17 x 17 samples:
// - Dense (D): a few unique scanned-rock-like meshes of 50k-180k triangles (three closed
//   jagged solids and one open jagged sheet), instanced 10-18 times per chunk, resting,
//   half-buried or nearly buried in the terrain; a slanted sun and one point light. D2k:
//   the same placements (same seed, same transforms) of the same shapes tessellated with
//   about 2k triangles each.
// - Real-map-like (R): rolling hills and many small rocks (a few hundred triangles each,
//   six unique), most of them half-buried, and 2-8 trees per chunk, under a low sun (17
//   degrees) and a high one (75 degrees, issue 19).
#pragma once

#include <cstdint>
#include <map>
#include <string>

namespace shadowcull::bench {

// What a world holds (see the top of this file).
enum class WorldKind {
    Forest,   // S, M, L (issue 6)
    Dense,    // D, D2k (issue 13)
    RealMap,  // R (issue 13)
};

struct WorldSpec {
    std::string name = "custom";  // for reports and cache directory names
    WorldKind kind = WorldKind::Forest;
    int chunksX = 3, chunksZ = 3;  // grid size; chunks gx in [-chunksX/2, chunksX - chunksX/2)
    uint64_t seed = 1;
    double objectsPerChunk = 280.0;  // models per chunk (terrain not counted)
    double chunkSize = 100.0;        // metres
    int terrainSamples = 33;         // N x N heightmap per chunk
    int localLights = 20;            // point + spot lights over the whole world (plus 3 directional)
    int neighbours = 1;              // chunks loaded on each side of the baked one
    // Dense worlds: 0 for the dense meshes (51k-180k triangles), else every unique mesh
    // tessellated with about this many triangles (D2k: 2048), placements unchanged.
    int meshTriangles = 0;
    // Real-map-like worlds: the low sun's elevation (degrees above the horizon). R: 17; R10:
    // 10, the evening sun whose shadows run several chunks (issue 33).
    double lowSunDegrees = 17.0;
};

// The benchmark sizes of issue 6. Same density everywhere (280 models per chunk), so that
// per-chunk figures compare across sizes.
WorldSpec worldS();  // 3 x 3 chunks, ~2.5k models
WorldSpec worldM();  // 10 x 10 chunks, ~28k models
WorldSpec worldL();  // 30 x 30 chunks, ~250k models
WorldSpec worldXL();  // 100 x 100 chunks, ~2.8 M models (issue 16: memory follows the window)
// Issue 13.
WorldSpec worldD();    // 6 x 6 chunks of 64 m, dense meshes (51k-180k triangles), ~500 placements
WorldSpec worldD2k();  // D with every mesh at 2,048 triangles (same placements)
WorldSpec worldR();    // 20 x 20 chunks of 64 m, ~48k small rocks, trees, a low and a high sun
WorldSpec worldR10();  // R with its low sun 10 degrees up (issue 33: shadows several chunks long)
// "S", "M", "L", "D", "D2k", "R", "R10" (case-insensitive); false for anything else.
bool worldByName(const std::string& name, WorldSpec& out);

// A hash of every field of the spec and of the generator's version: the cache key of a
// written world (a changed generator or spec never reuses an old directory).
uint64_t specHash(const WorldSpec& spec);
std::string specHashHex(const WorldSpec& spec);

struct WorldStats {
    int chunks = 0;
    uint64_t models = 0;                       // placed models
    std::map<std::string, uint64_t> byKind;    // "tree", "rock", "building", ... -> placements
    int uniqueMeshes = 0;                      // model resources written (each once)
    uint64_t uniqueMeshTriangles = 0;          // triangles over the unique meshes
    uint64_t placedTriangles = 0;              // sum over placements, terrain included
    uint64_t terrainTriangles = 0;
    int lights = 0, directionalLights = 0, pointLights = 0, spotLights = 0;
    uint64_t bytesOnDisk = 0;                  // every file written
    uint64_t files = 0;
    double buildSeconds = 0;                   // describing the world
    double writeSeconds = 0;                   // writing the files
};

// Writes the world into `dir` (created; must not exist or be empty) and returns what it
// holds. Throws std::runtime_error (I/O) or std::invalid_argument (a bad spec: more than
// 32 lights, a grid beyond 16-bit chunk names, ...).
WorldStats writeWorld(const WorldSpec& spec, const std::string& dir);

}  // namespace shadowcull::bench
