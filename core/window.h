// A bake window: the centre chunk being baked plus the chunks loaded around it (the
// `neighbours` rectangle and what its shadows reach: core/window_plan.h), in one
// window-local frame (metres, double). The frame's origin is the centre chunk's origin
// (gx*S, oy, gz*S), oy being the rounded middle height of the centre chunk's content,
// so a space moved by whole chunks (e.g. 100 km) or lifted (e.g. 5 km) gives the
// same window-local numbers and so the same verdicts.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "core/rounding.h"
#include "core/scene.h"

namespace shadowcull {

struct Aabb {
    glm::dvec3 min{1e300}, max{-1e300};
    void extend(const glm::dvec3& p) { min = glm::min(min, p); max = glm::max(max, p); }
    void extend(const Aabb& b) { min = glm::min(min, b.min); max = glm::max(max, b.max); }
    bool empty() const { return min.x > max.x; }
    // Corner k takes x from max when bit 0 of k is set, y when bit 1 is, z when bit 2 is.
    std::array<glm::dvec3, 8> corners() const {
        std::array<glm::dvec3, 8> c;
        for (int k = 0; k < 8; ++k) c[size_t(k)] = {k & 1 ? max.x : min.x, k & 2 ? max.y : min.y, k & 4 ? max.z : min.z};
        return c;
    }
};

// Where the ray origin + t dir (t >= 0) enters the box: 0 when it starts inside; infinity
// when it misses the box (which rounding can do for a ray along the boundary). Slab test.
inline double rayBoxEntry(const Aabb& box, const glm::dvec3& origin, const glm::dvec3& dir) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        if (dir[a] == 0.0) {
            if (origin[a] < box.min[a] || origin[a] > box.max[a]) return t1;
            continue;
        }
        double ta = (box.min[a] - origin[a]) / dir[a], tb = (box.max[a] - origin[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : std::numeric_limits<double>::infinity();
}

// The corners of a box in mesh coordinates mapped by `lsFromMesh` (in corners() order).
inline std::array<glm::dvec3, 8> placedCorners(const Aabb& msBox, const RowTransform& lsFromMesh) {
    std::array<glm::dvec3, 8> c = msBox.corners();
    for (glm::dvec3& p : c) p = lsFromMesh.apply(p);
    return c;
}

// The box of the mesh-coordinate box `msBox` placed by `lsFromMesh`, from its centre and
// half extent (|A| e): a third of the cost of mapping the eight corners. Widened by
// kPlacementRounding (core/rounding.h) of the coordinates' magnitude, the rounding of either
// way, so it holds every corner placed exactly and as placedCorners computes it (conservative).
inline Aabb placedBounds(const Aabb& msBox, const RowTransform& lsFromMesh) {
    const glm::dvec3 c = 0.5 * (msBox.min + msBox.max), e = 0.5 * (msBox.max - msBox.min);
    glm::dvec3 centre = lsFromMesh.rows[3], half(0.0), magnitude = glm::abs(lsFromMesh.rows[3]);
    for (size_t k = 0; k < 3; ++k) {
        const glm::dvec3 a = glm::abs(lsFromMesh.rows[k]);
        centre += c[int(k)] * lsFromMesh.rows[k];
        half += e[int(k)] * a;
        magnitude += std::abs(c[int(k)]) * a;
    }
    const glm::dvec3 pad = half + kPlacementRounding * (magnitude + half) + 1e-300;
    return Aabb{centre - pad, centre + pad};
}

// One loaded model or terrain of the window.
struct WindowObject {
    ChunkObject::Kind kind = ChunkObject::Kind::Model;
    const ChunkObject* source = nullptr;  // the chunk file's object
    ChunkCoord chunk;
    bool centre = false;              // in the chunk being baked (gets verdicts)
    const Mesh* mesh = nullptr;       // model-local (terrain: chunk-local) triangles
    RowTransform lsTransform;         // mesh coordinates -> window-local
    bool flipsWinding = false;        // lsTransform mirrors: fronts are the other side
    // False for a model with castsShadow false: the engine never draws it into a shadow map,
    // so it blocks no light (semantics.md, condition 1) and is never a caster; it still
    // receives. Every stage's "p is lit" and "hidden by others" leaves it out.
    bool castsShadow = true;
    const Heightfield* heightfield = nullptr;  // terrain only
    glm::dvec3 lsTerrainOrigin{0.0};           // terrain only: its chunk origin, window-local
    Aabb lsBounds;                    // window-local bounds of all triangles
    std::string label;                // "0000ffffo.chunk model #2 (uuid)" for reports

    // Whether the group's triangles block light: opaque (not alpha-tested) groups of objects
    // that cast shadows. Everything else lets light pass (semantics.md, condition 1).
    bool blocksLight(uint32_t group) const { return castsShadow && !mesh->groups[group].alphaTested; }

    // Mesh triangle `t` placed in the window: lsTransform applied to its three vertices
    // (the very doubles every stage tests).
    std::array<glm::dvec3, 3> lsTriangle(size_t t) const {
        const auto& i = mesh->triangles[t];
        return {lsTransform.apply(mesh->positions[i[0]]), lsTransform.apply(mesh->positions[i[1]]),
                lsTransform.apply(mesh->positions[i[2]])};
    }
};

// A window-local chunk square [x0,x1] x [z0,z1] (metres) with no terrain loaded: points
// over it are under no terrain, so the terrain rule does not hold there.
struct GroundOpening {
    double x0, z0, x1, z1;
};

struct BakeWindow {
    ChunkCoord centre;
    std::string centrePath;
    glm::dvec3 wsOrigin{0.0};         // world position of the window-local origin
    double chunkSize = 100.0;
    double terrainTolerance = 0.01;
    std::vector<WindowObject> objects;
    std::vector<Light> lsLights;      // positions window-local, directions unchanged
    Aabb lsBounds;                    // every loaded triangle
    Aabb lsCentreBounds;              // the centre chunk's triangles
    bool hasAlphaTested = false;      // any alpha-tested group loaded: the alpha rule applies
    bool hasTerrain = false;          // any terrain loaded: the terrain rule applies
    bool hasNonCasters = false;       // any object with castsShadow false loaded: light passes it
    int skippedObjects = 0;           // objects of the window that could not be loaded
    std::vector<size_t> terrainObjects;  // indices into `objects` of the terrains

    // Lowest terrain surface over window-local (x, z), or nothing where no terrain lies.
    // (The lowest, so that a receiver is only discounted when it is under every terrain.)
    std::optional<double> lsTerrainHeight(double x, double z) const;
    // The lowest point of the terrain surface (the triangulated heightfield, of every
    // terrain there) over the window-local rectangle [x0,x1] x [z0,z1], or nothing when
    // part of the rectangle has no terrain. Computed in double from the rectangle's corners
    // and the cells' diagonals: within rounding (~1e-15 relative) of the true minimum, so a
    // caller deciding "is this under the terrain" subtracts a margin above that. (It was the
    // lowest sample of every cell touched: on a slope, a cell's relief too low.)
    std::optional<double> lsTerrainMinOver(double x0, double z0, double x1, double z1) const;
    // The highest point of the terrain surfaces (of every terrain there, not only the lowest
    // at each point) over the rectangle, or nothing when part of it has no terrain; within
    // rounding of the true maximum, as above.
    std::optional<double> lsTerrainMaxOver(double x0, double z0, double x1, double z1) const;
    // Appends to `out` the window-local terrain triangles (as the terrains' meshes place
    // them, so the very triangles the stages test as receivers) of every cell that meets
    // the rectangle [x0,x1] x [z0,z1], one cell more on each side against rounding, of
    // every terrain there. False when part of the rectangle has no terrain (`out` is then
    // incomplete and must not be used).
    bool lsTerrainTrianglesOver(double x0, double z0, double x1, double z1,
                                std::vector<std::array<glm::dvec3, 3>>& out) const;
    // The same, leaving out only triangles whose box lies wholly beside the x-z extent of
    // `keep` (y ignored; a cell at a time, where the terrain is placed by a translation):
    // what a caller skipping those by their boxes keeps, in the same order, at the cost of
    // the cells it keeps.
    bool lsTerrainTrianglesOver(double x0, double z0, double x1, double z1, const Aabb& keep,
                                std::vector<std::array<glm::dvec3, 3>>& out) const;
    // As lsTerrainTrianglesOver, but a chunk square the rectangle meets that has no
    // terrain loaded (the world's edge, a chunk without terrain) is appended to
    // `openings` instead of failing: no terrain rule holds over it. False only when the
    // rectangle spans more than a few squares, or when `openings` is null and one is open.
    bool lsGroundOver(double x0, double z0, double x1, double z1, std::vector<std::array<glm::dvec3, 3>>& out,
                      std::vector<GroundOpening>* openings) const;
    // The meshes the window holds (what a stage's per-mesh cache keeps as the window slides).
    std::unordered_set<const Mesh*> meshes() const {
        std::unordered_set<const Mesh*> m;
        for (const WindowObject& o : objects) m.insert(o.mesh);
        return m;
    }
};

// The window-local box of the object's placed vertices of one group's triangles (withArea:
// of its triangles with three distinct vertices), bit for bit the box a loop over those
// triangles' corners with Aabb::extend gives, at the cost of a few leaves of the mesh's
// vertex trees (core/mesh_index.h). Empty when the group has no such triangle.
Aabb lsGroupBounds(const WindowObject& object, uint32_t group, bool withArea);
// The same by the loop over the triangles (the reference; the fallback of the above).
Aabb lsGroupBoundsByLoop(const WindowObject& object, uint32_t group, bool withArea);

// Terrain meshes made from heightfields, kept across windows (a bake makes each once).
using TerrainMeshes = std::unordered_map<const Heightfield*, std::shared_ptr<const Mesh>>;

// Builds the window around `centre` of the chunks `chunks` (those of them `space` holds),
// in that order (a plan's grid order: core/window_plan.h). Terrain meshes are made once per
// heightfield and kept in `terrainMeshes` (owned by the caller, reused across windows).
// Once a stop is requested (util/stop_request.h) it returns an incomplete window: the
// caller checks stopStatus() before using it.
BakeWindow buildWindow(const Space& space, ChunkCoord centre, const std::vector<ChunkCoord>& chunks,
                       TerrainMeshes& terrainMeshes);
// The window of the `neighbours` rectangle around `centre` (the original method's window).
BakeWindow buildWindow(const Space& space, ChunkCoord centre, TerrainMeshes& terrainMeshes);

// Exact test for a triangle with no area in the sense used everywhere in the project:
// two of its vertices are the same point. (Collinear but distinct vertices are kept: a
// renderer may still rasterise them, so no verdict of 0 may rest on skipping them.)
inline bool hasRepeatedVertex(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    return a == b || b == c || a == c;
}
// The same test on triangle `t` of the mesh (mesh coordinates).
inline bool hasRepeatedVertex(const Mesh& mesh, size_t t) {
    const auto& i = mesh.triangles[t];
    return hasRepeatedVertex(mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]);
}

}  // namespace shadowcull
