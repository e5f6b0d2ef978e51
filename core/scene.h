// The scene model: what space.xml, chunk files, .model and .terrain files say, in the
// units and conventions of ../shared/spec/scene-format.md (metres, Y up, right-handed,
// row-vector transforms relative to the chunk origin).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/mesh.h"
#include "util/status.h"

namespace shadowcull {

enum class LightType { Directional, Point, Spot };

const char* lightTypeName(LightType type);

// A light as written in space.xml. Positions are world coordinates (metres); directions
// are unit vectors along which light travels. Light i (0-based) owns bit i of every mask.
struct Light {
    std::string name;
    LightType type = LightType::Directional;
    // Coordinates: world in SpaceSettings::lights, window-local in BakeWindow::lsLights.
    glm::dvec3 direction{0.0, -1.0, 0.0};  // directional, spot; normalised on read
    glm::dvec3 position{0.0};              // point, spot; metres
    double range = 0.0;                      // metres; point, spot (> 0)
    double coneHalfAngleDeg = 0.0;           // spot: half-angle in degrees, (0, 90]
    double bias = 0.0;                       // metres
    double slopeBias = 0.0;                  // metres at 45 degrees; times tan(theta)
    double filterRadius = 0.0;               // metres; > 0 when the engine filters
    // Metres: the engine looks a receiver's shadow up at q + normalBias * n (n its unit front
    // normal; either normal for a two-sided surface), semantics.md condition 5.
    double normalBias = 0.0;
    int line = 0;                            // line of <light> in space.xml
};

// Neighbour counts: left = -x, right = +x, bottom = -z, top = +z (in chunks).
struct Neighbours {
    int left = 1, right = 1, bottom = 1, top = 1;
};

struct SpaceSettings {
    std::string spaceDir;      // the space directory
    std::string resourceRoot;  // resource paths in chunk files are relative to it
    double chunkSize = 100.0;  // metres
    Neighbours neighbours;
    double terrainTolerance = 0.01;  // metres (default when space.xml is silent)
    std::vector<Light> lights;       // file order; at most 32
};

constexpr int kMaxLights = 32;

struct ChunkCoord {
    int32_t x = 0, z = 0;
    bool operator<(const ChunkCoord& o) const { return x != o.x ? x < o.x : z < o.z; }
    bool operator==(const ChunkCoord& o) const { return x == o.x && z == o.z; }
};

// "XXXXZZZZo.chunk" with 16-bit two's-complement hex (either case). Returns nothing for any
// other name.
std::optional<ChunkCoord> parseChunkName(const std::string& fileName);
std::string chunkFileName(ChunkCoord c);  // lowercase hex
// A chunk named on the command line: "XXXXZZZZo", "XXXXZZZZo.chunk", or a path to one.
std::optional<ChunkCoord> parseChunkArgument(const std::string& argument);

// Row-vector affine transform: p' = p.x*rows[0] + p.y*rows[1] + p.z*rows[2] + rows[3].
struct RowTransform {
    std::array<glm::dvec3, 4> rows{glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1),
                                   glm::dvec3(0, 0, 0)};
    glm::dvec3 apply(const glm::dvec3& p) const { return p.x * rows[0] + p.y * rows[1] + p.z * rows[2] + rows[3]; }
    glm::dvec3 applyLinear(const glm::dvec3& v) const { return v.x * rows[0] + v.y * rows[1] + v.z * rows[2]; }
    double determinant() const;
    // Why the 3x3 part cannot be used, or "" when it can: its rows are (nearly) linearly
    // dependent or not finite (|det| <= 1e-9 times the product of the row lengths,
    // independent of the overall scale), or its inverse has an entry above
    // limits::kMaxInverseEntry (an axis too short for the float copies Embree and GL use).
    std::string singularReason() const;
    bool isSingular() const { return !singularReason().empty(); }
};

// A 16-bit heightmap over one chunk square (spec: sample (i, j) at chunk-local
// x = i*S/(N-1), z = j*S/(N-1); two triangles per cell split from (i,j) to (i+1,j+1)).
struct Heightfield {
    int n = 0;                    // samples per side, >= 2
    double size = 0.0;            // chunk size S, metres
    std::vector<double> heights;  // n*n, row-major: heights[j*n + i], metres
    std::vector<std::string> sourceFiles;  // the .terrain and its PNG
    double at(int i, int j) const { return heights[size_t(j) * size_t(n) + size_t(i)]; }
    // Chunk-local coordinate of sample column (or row) i: (i S) / (N - 1), so sample 0 lies at
    // 0 and sample N - 1 at exactly S, on the next chunk's sample 0 once placed (S / (N - 1)
    // first, then times i, left it an ulp short for S = 100, N = 98: a gap at the seam). The
    // last is S itself: (N - 1) S rounds when S is not whole (9 x 7.3 / 9 is an ulp above 7.3).
    double sampleAt(int i) const { return i == n - 1 ? size : double(i) * size / double(n - 1); }
    // The cell (0 .. N - 2) of the mesh holding chunk-local coordinate v (clamped to the
    // square), decided by the sample positions themselves, and the fraction across it in
    // [0, 1] (0 at sampleAt(cell), exactly).
    int cellOf(double v, double& fraction) const;
    // Height of the triangulated surface at chunk-local (x, z), clamped to the square.
    double heightAt(double x, double z) const;
    // Triangles of the surface, chunk-local, front faces up (counter-clockwise from above).
    Mesh toMesh() const;
};

// One <model> or <terrain> child of a chunk's root element.
struct ChunkObject {
    enum class Kind { Model, Terrain };
    Kind kind = Kind::Model;
    int elementIndex = 0;  // among the root's model/terrain children, document order
    int line = 0;          // line of the element in the chunk file
    std::string resource;  // as written (relative to the resource root)
    std::string uuid;      // models; may be empty
    RowTransform transform;  // chunk-local placement (identity for terrain)
    bool castsShadow = true;
    // Set when the object could not be used (bad transform, missing or bad resource):
    // it is then neither occluder nor receiver, and its <shadow> is left untouched.
    bool skipped = false;
    std::string skipReason;
    std::shared_ptr<const Mesh> mesh;              // models, when loaded
    std::shared_ptr<const Heightfield> heightfield;  // terrain, when loaded
    // The box of the vertices its triangles use under the transform's linear part alone
    // (core/window.cpp, placeObject): made by the first window that places the object, and
    // valid while it lives (its mesh and transform are never changed). Empty when that box
    // has a zero coordinate (whose sign the windows' own loop decides).
    mutable std::optional<std::pair<glm::dvec3, glm::dvec3>> linearBox;
    mutable bool linearBoxMade = false;
};

struct ChunkFile {
    std::string path;
    ChunkCoord coord;
    // Hash of the bytes the objects were read from: the bake writes the file only while it
    // still holds exactly these bytes (an edit made during the bake is never overwritten).
    uint64_t contentHash = 0;
    // Hash of the document apart from its objects' <shadow> elements (the bake's output):
    // elements, attributes, text and comments in order, text trimmed and whitespace between
    // tags left out, since rewriting a mask inserts or removes lines and indentation. Equal
    // before and after any bake wrote masks into the file, so shards baked in place one
    // after another still hash the same inputs (cli/resume.cpp's spaceInputHash).
    uint64_t contentWithoutShadowsHash = 0;
    std::vector<ChunkObject> objects;
};

// A warning about input the bake went on without (file, line, what was done).
struct Diagnostic {
    std::string file;
    int line = 0;
    std::string message;  // what is wrong and what the tool did, e.g. "...; object skipped"
    std::string what() const { return file + (line > 0 ? ":" + std::to_string(line) : "") + ": " + message; }
};

struct Space {
    SpaceSettings settings;
    std::map<ChunkCoord, ChunkFile> chunks;
    std::vector<Diagnostic> diagnostics;  // objects skipped, files ignored
    // Every file the space was read from (space.xml, chunk files, resources and the files
    // they name), sorted: outputs must never replace one of them.
    std::vector<std::string> inputFiles() const;
};

}  // namespace shadowcull
