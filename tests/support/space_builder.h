// Writes complete spaces (directories) in the scene format of shared/spec/scene-format.md,
// for acceptance tests (known-answer scenes), metamorphic tests (the same world moved by
// 100 km, lifted by 5 km or turned a quarter about Y), the kill test (many chunks) and the
// bundled sample space (tools/make_sample_space.cpp).
//
// Everything is described in WORLD coordinates (metres, Y up, right-handed). The builder
// only turns that description into files at write time: it picks each model's chunk from
// its world position, makes its transform chunk-relative, quantises terrain heights into a
// 16-bit PNG and, when asked, moves the whole world first (WorldTransform).
//
// It depends on no other project code on purpose: the project's readers are tested
// against files that simply follow the spec.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace shadowcull::testing {

// ---------------------------------------------------------------------------------------
// Transforms

// A row-vector affine map, as chunk files write it: a local point p maps to
// p.x*row0 + p.y*row1 + p.z*row2 + row3 (metres).
struct Affine {
    glm::dvec3 row0{1, 0, 0}, row1{0, 1, 0}, row2{0, 0, 1};  // linear part (rotation, scale)
    glm::dvec3 row3{0, 0, 0};                                // translation, metres

    static Affine translation(const glm::dvec3& t);
    static Affine scaling(const glm::dvec3& s);
    // Right-handed turn about +Y: +90 degrees takes +x to -z and +z to +x. Multiples of 90
    // degrees are exact (no cos(pi/2) residue).
    static Affine rotationY(double degrees);

    // This map followed by `next` (row-vector form: R' = R*Rn, t' = t*Rn + tn).
    Affine then(const Affine& next) const;
    glm::dvec3 apply(const glm::dvec3& p) const { return p.x * row0 + p.y * row1 + p.z * row2 + row3; }
    glm::dvec3 applyLinear(const glm::dvec3& v) const { return v.x * row0 + v.y * row1 + v.z * row2; }
};

// A move of the whole world, applied at write time: first `quarterTurnsY` right-handed
// quarter turns about +Y (one turn: x' = z, z' = -x), then `translation` (metres).
// translation.x and .z must be whole multiples of the chunk size (100 km = 1000 chunks of
// 100 m), so that chunk squares map onto chunk squares; write() throws otherwise.
// translation.y is free (terrain min/max heights shift with it).
struct WorldTransform {
    int quarterTurnsY = 0;
    glm::dvec3 translation{0.0};

    static WorldTransform identity() { return {}; }
    static WorldTransform turned(int quarterTurns) { return {quarterTurns, glm::dvec3(0.0)}; }
    static WorldTransform moved(const glm::dvec3& t) { return {0, t}; }

    int turns() const { return ((quarterTurnsY % 4) + 4) % 4; }  // 0..3
    Affine affine() const;
    glm::dvec3 apply(const glm::dvec3& p) const { return affine().apply(p); }
    glm::dvec3 applyToDirection(const glm::dvec3& d) const { return affine().applyLinear(d); }
};

// ---------------------------------------------------------------------------------------
// Chunk grid and small helpers

struct ChunkId {
    int gx = 0, gz = 0;
    bool operator<(const ChunkId& o) const { return gx != o.gx ? gx < o.gx : gz < o.gz; }
    bool operator==(const ChunkId& o) const { return gx == o.gx && gz == o.gz; }
};

// "XXXXZZZZ": 16-bit two's-complement lowercase hex (-1 -> "ffff", -2 -> "fffe").
// Throws std::out_of_range outside -32768..32767.
std::string chunkBaseName(int gx, int gz);
// "XXXXZZZZo.chunk" (outdoor chunk file name).
std::string chunkName(int gx, int gz);
// The chunk whose square [gx*S, (gx+1)*S) x [gz*S, (gz+1)*S) holds world (x, z).
ChunkId chunkContaining(double x, double z, double chunkSize);
// The chunk that the square of `c` becomes under `wt` (throws when wt is not chunk-aligned).
ChunkId mapChunk(ChunkId c, const WorldTransform& wt, double chunkSize);

// Heights <-> 16-bit samples (sample 0 = minHeight, 65535 = maxHeight), the way the
// .terrain format defines them. quantiseHeight rounds to nearest and throws
// std::range_error for heights outside [minHeight, maxHeight] or non-finite ones.
uint16_t quantiseHeight(double h, double minHeight, double maxHeight);
double dequantiseHeight(uint16_t sample, double minHeight, double maxHeight);

// Shortest decimal text that reads back to the same double ("0.3", "100", "-1e-07").
std::string formatNumber(double v);
// A readable fixed UUID in the chunk-file style: fixedUuid(0xA1) = "00000000-00000000-00000000-000000A1".
std::string fixedUuid(uint32_t n);

// A small deterministic generator (SplitMix64). std distributions are not portable across
// standard libraries, so sample spaces use these formulas instead.
class DeterministicRng {
public:
    explicit DeterministicRng(uint64_t seed) : state_(seed) {}
    uint64_t next();
    double uniform(double lo, double hi);  // [lo, hi)
    int below(int n);                      // 0..n-1
private:
    uint64_t state_;
};

// ---------------------------------------------------------------------------------------
// Meshes

// One primitive group: in OBJ one material (`usemtl`), numbered in order of first use.
struct GroupSpec {
    std::string material;                     // MTL material name; empty: "group<i>" when one is needed
    bool alphaTested = false;                 // MTL `map_d` (an alpha texture is written too)
    std::optional<bool> alphaTestOverride;    // .model <primitiveGroup alphaTest="...">
    std::optional<bool> doubleSidedOverride;  // .model <primitiveGroup doubleSided="...">

    static GroupSpec named(std::string material, bool alphaTested = false);
};

// A triangle mesh in model-local coordinates (metres). Triangles are counter-clockwise
// seen from their front. Every group must have at least one triangle (OBJ groups exist
// only through use); material names must be unique within a mesh.
struct MeshSpec {
    std::vector<glm::dvec3> positions;
    std::vector<std::array<int, 3>> triangles;  // indices into positions
    std::vector<int> triangleGroup;             // per triangle: index into groups
    std::vector<GroupSpec> groups;

    int addGroup(const GroupSpec& g);
    int addVertex(const glm::dvec3& p);
    void addTriangle(int a, int b, int c, int group);
    // A convex planar polygon, fan-triangulated, wound so that its front faces away from
    // `inside` (a point behind the face, e.g. the solid's centre).
    void addFace(const std::vector<glm::dvec3>& polygon, int group, const glm::dvec3& inside);
    // Appends `other` with its groups renumbered after this mesh's groups.
    MeshSpec& append(const MeshSpec& other);
    // Merges vertices with bit-identical positions (makes shared edges topological).
    MeshSpec welded() const;

    // Closed axis-aligned box, faces outward (one group).
    static MeshSpec box(const glm::dvec3& min, const glm::dvec3& max, const GroupSpec& g = {});
    // Box without its top (+y) face: an open mesh.
    static MeshSpec openBox(const glm::dvec3& min, const glm::dvec3& max, const GroupSpec& g = {});
    // One-sided quad a-b-c-d; its front is the side from which the corners run counter-clockwise.
    static MeshSpec quad(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d,
                         const GroupSpec& g = {});
    // Thin closed box along +x from x = 0 to `length`, cross-section `thickness` square
    // centred on the x axis (metres).
    static MeshSpec rod(double length, double thickness, const GroupSpec& g = {});
    // Two closed cubes of side `size` welded along one edge (x = y = size): a non-manifold
    // edge with four faces.
    static MeshSpec edgeSharingCubes(double size, const GroupSpec& g = {});
    // An open sheet of n x n quads of `cell` metres over x, z in [0, n cell], heights
    // alternating between 0 and `zig` metres (a scanned surface; 0: flat), fronts up.
    static MeshSpec jaggedSheet(int n, double cell, double zig, const GroupSpec& g = {});
    // Adds the quad a-b-c-d (two triangles, front where the corners run counter-clockwise).
    void addQuad(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d, int group);
};

// ---------------------------------------------------------------------------------------
// Lights and settings

enum class LightKind { Directional, Point, Spot };

struct LightSpec {
    std::string name;
    LightKind kind = LightKind::Directional;
    glm::dvec3 direction{0, -1, 0};  // the way light travels (directional, spot); any length
    glm::dvec3 position{0.0};        // world, metres (point, spot)
    double range = 0.0;              // metres (point, spot)
    double coneAngle = 0.0;          // half-angle, degrees (spot)
    double bias = 0.0;               // metres
    double slopeBias = 0.0;          // metres at 45 degrees
    double filterRadius = 0.0;       // metres
    double normalBias = 0.0;         // metres (written only when > 0)

    static LightSpec directional(std::string name, const glm::dvec3& direction);
    static LightSpec point(std::string name, const glm::dvec3& position, double range);
    static LightSpec spot(std::string name, const glm::dvec3& position, const glm::dvec3& direction, double range,
                          double coneAngleDegrees);
    LightSpec& withBias(double b, double slope = 0.0) { bias = b; slopeBias = slope; return *this; }
    LightSpec& withFilterRadius(double r) { filterRadius = r; return *this; }
    LightSpec& withNormalBias(double b) { normalBias = b; return *this; }
};

// Chunks loaded on each side of the baked one: left = -x, right = +x, bottom = -z, top = +z.
// Written as <neighbours> n </neighbours> when all four agree, as attributes otherwise.
struct NeighbourSpec {
    int left = 1, right = 1, top = 1, bottom = 1;
    static NeighbourSpec all(int n) { return {n, n, n, n}; }
};

struct SpaceOptions {
    double chunkSize = 100.0;  // metres
    NeighbourSpec neighbours;
    double terrainTolerance = 0.01;  // metres
    std::string resourceRoot;        // empty: the space directory; else a directory relative to it
};

using HeightFunction = std::function<double(double worldX, double worldZ)>;  // metres

// Where an object ends up in a written space: its chunk file and its index among that
// chunk root's <model>/<terrain> children (document order).
struct ObjectLocation {
    ChunkId chunk;
    std::string chunkFile;  // e.g. "03e80000o.chunk"
    int elementIndex = 0;
};

// The true mask of one primitive group under semantics.md. `key` is a model's uuid or
// SpaceBuilder::terrainKey(); terrain has only group 0.
struct KnownAnswer {
    std::string key;
    int group = 0;
    uint32_t mask = 0;
    std::string why;
};

// ---------------------------------------------------------------------------------------
// The builder

class SpaceBuilder {
public:
    explicit SpaceBuilder(SpaceOptions options = {});

    SpaceOptions& options() { return options_; }
    const SpaceOptions& options() const { return options_; }

    // Registers a mesh resource `name` (no '/'), written as models/<name>.obj (+ .mtl when
    // it has materials) and, when `viaModelFile` or any group has an override, also
    // models/<name>.model, which placements then name. Returns the resource path.
    std::string addMesh(const std::string& name, const MeshSpec& mesh, bool viaModelFile = false);
    // An extra file under the resource root (e.g. a glTF for a placement to name).
    void addFile(const std::string& relativePath, const std::string& contents);

    // Places a model at world transform `world`. `resource` is a registered mesh name, or a
    // resource path (contains '/') used verbatim. Empty `uuid`: a deterministic one is made
    // from a counter. castsShadow is written only when given. Returns the uuid.
    std::string addModel(const std::string& resource, const Affine& world, std::string uuid = {},
                         std::optional<bool> castsShadow = std::nullopt);
    // Terrain of chunk (gx, gz): N x N samples of height(worldX, worldZ), quantised between
    // minHeight and maxHeight (metres). Row j is chunk-local z = j*S/(N-1), column i is x = i*S/(N-1).
    void addTerrain(int gx, int gz, int samples, HeightFunction height, double minHeight, double maxHeight);
    // Flat terrain at exactly `height` (minHeight = height, every sample 0).
    void addFlatTerrain(int gx, int gz, double height, int samples = 2);
    // Makes chunk (gx, gz) exist even when nothing is placed in it.
    void addChunk(int gx, int gz);
    // Raw XML (comments, unknown elements) written first inside chunk (gx, gz)'s root, for
    // preservation tests. Must not contain <model> or <terrain> elements.
    void addChunkXml(int gx, int gz, const std::string& xml);
    // Appends a light; returns its number (1-based, as in "light i owns bit i-1").
    int addLight(const LightSpec& light);

    // Records a known answer (see KnownAnswer); scenes below fill these in.
    void expect(const std::string& key, int group, uint32_t mask, std::string why);
    const std::vector<KnownAnswer>& expectations() const { return expectations_; }

    // Height of the written (quantised, triangulated) terrain surface at world (x, z), as
    // a reader will see it; nullopt where there is no terrain. For resting objects on it.
    std::optional<double> terrainHeightAt(double x, double z) const;

    // "terrain:XXXXZZZZ" with the chunk name BEFORE any WorldTransform.
    static std::string terrainKey(int gx, int gz);
    // For every placed model (by uuid) and terrain (by terrainKey) its location when
    // written under `wt`: compare verdicts of "the same object" across moved copies.
    std::map<std::string, ObjectLocation> locateObjects(const WorldTransform& wt = {}) const;
    // The chunk files write(dir, wt) creates, sorted by (gx, gz).
    std::vector<std::string> chunkFiles(const WorldTransform& wt = {}) const;

    // Writes the whole space into `dir` (created; must not exist or be empty) with the
    // world moved by `wt`. Throws, naming the problem: std::invalid_argument for a wt that
    // is not chunk-aligned, std::out_of_range for a chunk beyond 16-bit names,
    // std::range_error for a height outside its terrain's range, std::runtime_error for
    // I/O (and a non-empty `dir`). Nothing is written when the description is bad.
    //
    // Exactness: quarter turns permute coordinates exactly and chunk-aligned translations
    // keep chunk-local x/z offsets bit-identical (they are computed before the move).
    // Terrain samples are re-sampled from the height function at the original sample
    // positions, so quantised codes are an exact permutation. One caveat comes from the
    // format: cells split along the (i,j)-(i+1,j+1) diagonal, and an odd number of quarter
    // turns flips that diagonal, so the triangulated surface is congruent only where every
    // cell is planar (flat or uniformly sloped terrain). Half turns are always congruent.
    void write(const std::string& dir, const WorldTransform& wt = {}) const;

private:
    struct Mesh {
        std::string name;
        MeshSpec spec;
        bool viaModelFile = false;
        std::string resourcePath() const;
    };
    struct Placement {
        std::string resource, uuid;
        Affine world;
        std::optional<bool> castsShadow;
    };
    struct Terrain {
        ChunkId chunk;
        int samples = 2;
        HeightFunction height;
        double minHeight = 0, maxHeight = 1;
        uint16_t code(int i, int j, double chunkSize) const;    // sample (column i, row j), untransformed
        std::vector<uint16_t> codes(double chunkSize) const;  // row-major [j*N + i], untransformed
    };
    struct ChunkLayout {
        std::vector<std::string> xml;
        std::vector<std::pair<const Placement*, Affine>> models;  // chunk-local transforms
        const Terrain* terrain = nullptr;
    };
    std::map<ChunkId, ChunkLayout> layout(const WorldTransform& wt) const;
    void writeMesh(const std::string& resDir, const Mesh& m) const;
    std::string spaceXml(const WorldTransform& wt) const;

    SpaceOptions options_;
    std::vector<Mesh> meshes_;
    std::vector<std::pair<std::string, std::string>> files_;
    std::vector<Placement> placements_;
    std::vector<Terrain> terrains_;
    std::map<ChunkId, size_t> terrainIndex_;  // chunk -> index into terrains_
    std::vector<ChunkId> forcedChunks_;
    std::vector<std::pair<ChunkId, std::string>> chunkXml_;
    std::vector<LightSpec> lights_;
    std::vector<KnownAnswer> expectations_;
    std::set<std::string> uuids_;
    uint32_t uuidCounter_ = 0;
};

// ---------------------------------------------------------------------------------------
// Known-answer scenes (true masks per semantics.md; each scene also records them with
// expect()). Unless said otherwise: one chunk (0, 0) of 100 m, neighbours 1, models' uuids
// are fixedUuid(1), fixedUuid(2), ... in the order listed.

// (1) Flat terrain at y = 0 over chunk (0,0); a 1 m cube resting on it at (50,0,50); sun
// (0.3,-1,0.2), bias 0.05. Cube: mask 1 (its shadow lands on the terrain). Terrain: 0.
SpaceBuilder cubeOnTerrain();
// (2) No terrain; 1 m cubes at (40,20,50) and (50,20,50), 10 m apart; sun (0.05,-1,0.02).
// Nothing lies below them and a convex one-sided cube cannot shadow itself: both 0.
// (A raycast-only bake finds no witness and leaves them undecided, written 1.)
SpaceBuilder twoFloatingCubes();
// (3) Flat terrain at 0; light 1 "lamp" point at (20,5,20) range 10; light 2 "torch" spot
// at (20,8,20) straight down, range 20, cone 30. Cube A (22..23, 0..1, 20..21): mask 3.
// Cube B (80..81, 0..1, 80..81): out of both ranges, mask 0. Cube C (26..27, 0..1, 20..21):
// in the lamp's range, outside the torch's cone (every point is > 36 degrees off axis): mask 1.
SpaceBuilder rangeAndCone();
// (4) Flat terrain at 0; a 2 m x 5 mm x 5 mm rod along x centred 2 m above it at
// (50..52, 2, 50); sun (0.3,-1,0.2). Rod: mask 1 (thin, but its shadow lands). Terrain: 0.
SpaceBuilder thinRod();
// (5) Flat terrain at 0; one model, two groups: group 0 a cube at (40..41, 0..1, 50..51),
// group 1 a cube at (46..47, 0..1, 50..51). Light 1 "lamp" point at (48,3,50.5) range 5
// reaches group 1 only (group 0 is >= 7.28 m away); light 2 "sun" (0.3,-1,0.2) reaches both.
// Group 0: mask 2, group 1: mask 3 (the model's <shadow> is 3). Terrain: 0.
SpaceBuilder twoLightsMasks();
// (6) An n x n grid of chunks (gx, gz in 0..n-1) of 100 m, each with gentle terrain (N = 9)
// and three cubes resting on it, under a tilted sun. For the kill test; no known answers.
SpaceBuilder manyChunks(int n);
// (7) Flat terrain at 0; a 1 m cube at (50..51, 0..1, 50..51) under a 20 m x 20 m x 0.2 m
// roof slab at y = 3..3.2; sun (0.3,-1,0.2). Opaque roof: cube 0 (no lit point; needs an
// occlusion proof), roof 1. Alpha-tested roof (.model alphaTest override): light passes it,
// cube 1, roof 1. A roof with castsShadow false: the engine never draws it into the shadow
// map, so light passes it too (semantics.md condition 1): cube 1; the roof itself is never a
// caster: 0. Terrain: 0.
enum class Roof { Opaque, AlphaTested, CastsNoShadow };
SpaceBuilder hiddenUnderRoof(Roof roof);
// (7b) No terrain; a 1 m cube floating at (50..51, 2..3, 50..51) over a 20 m x 20 m x 0.2 m
// floor slab at y = 0..0.2 (40..60) whose model has castsShadow false; sun (0.3,-1,0.2).
// The floor casts nothing (0) but still receives: the cube's shadow falls on it (1).
SpaceBuilder cubeOverNonCastingFloor();
// (7c) No terrain; a 1 m cube floating at (50..51, 2..3, 50..51), sun (1,-1,0) with the given
// normal bias, and a one-sided wall facing -x at x = 54.02 (y 0..1.5, z 49..52). The cube's
// shadow on the wall's plane ends 2 cm below the wall: with normal bias 0 nothing receives
// it (0). A normal bias of 0.1 m looks the wall's shadow up 0.1 m in front of it, where the
// shadow reaches 8 cm up: the cube's shadow shows on the wall's foot (1). The wall: 0.
SpaceBuilder cubeBesideWall(double normalBias);
// (7d) Long shadows (issue 33: receivers are every surface of the space, not the window's).
// Chunks of 100 m along x, neighbours 1, sun_low (1,-0.18,0) (10.2 degrees up, bias 0.05).
// Chunk 0: a plateau (0..50, 0..46, 0..100) and at its edge a tower (50..52, 46..60, 49..51);
// ground quads at y = 0 over chunks 1 and 2, then, by `ending`: ground over chunk 3 (the
// tower's shadow lands there: 1); chunk 3 empty and ground over chunk 4, which the shadow
// passes below (0); nothing (the space ends at x = 300: 0). The plateau's shadow lands on
// chunk 2 (1). A window of the neighbours alone holds none of it.
enum class LongShadow { LandsThreeChunksAway, FallsInAGap, LeavesTheSpace };
SpaceBuilder longShadowOverChunks(LongShadow ending);
// (7e) A point lamp at (50,30,50) of range 250 over a 1 m cube at (80..81, 24.5..25.5,
// 49.5..50.5); chunk 1 empty, ground over chunk 2 at y = 0: the cube's shadow lands there,
// two chunks over, within range (1).
SpaceBuilder lampTwoChunksOver();
// (8) Flat terrain at 0; a 1 m cube at (26..27, 0..1, 20..21) beside light 1 "lamp", point
// at (20,5,20) with the given range: from range 10 on its shadow lands on the terrain (a
// witness); with range 5 (the cube is >= 7.2 m away) it is out of reach. No expectations.
SpaceBuilder cubeBesideLamp(double range);

// One group in two parts, in mesh coordinates around a lamp at (0, 5, 0) of range 10: a
// 1 m face 7 m away along +x turned to the lamp, and a 1 m patch 20 m away (beyond range)
// facing up (issue 13: a group the range sphere cuts).
MeshSpec faceAndFarPatch();

}  // namespace shadowcull::testing
