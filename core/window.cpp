#include "core/window.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_for_each.h>

#include "util/stop_request.h"

namespace shadowcull {

std::optional<double> BakeWindow::lsTerrainHeight(double x, double z) const {
    std::optional<double> lowest;
    for (size_t k : terrainObjects) {
        const WindowObject& o = objects[k];
        const double lx = x - o.lsTerrainOrigin.x, lz = z - o.lsTerrainOrigin.z;
        if (lx < 0 || lz < 0 || lx > chunkSize || lz > chunkSize) continue;
        const double h = o.heightfield->heightAt(lx, lz) + o.lsTerrainOrigin.y;
        if (!lowest || h < *lowest) lowest = h;
    }
    return lowest;
}

namespace {

// The lowest point of cell (i, j)'s triangulated surface over the part [u0,u1] x [v0,v1]
// of the cell (cell-local fractions in [0, 1]). The surface is two planes split along
// u = v (Heightfield::toMesh): (i,j)-(i,j+1)-(i+1,j+1) where v >= u, (i,j)-(i+1,j+1)-(i+1,j)
// where u >= v; over each half a plane is lowest at a corner of that half's polygon: the
// rectangle's corners in it and where the diagonal crosses the rectangle's sides.
// With `highest`: the highest point instead (a plane is highest at a corner of the polygon too).
double cellSurfaceMin(const Heightfield& hf, int i, int j, double u0, double v0, double u1, double v1, bool highest = false) {
    const double h00 = hf.at(i, j), h10 = hf.at(i + 1, j), h01 = hf.at(i, j + 1), h11 = hf.at(i + 1, j + 1);
    auto height = [&](double u, double v) {
        return v >= u ? h00 + u * (h11 - h01) + v * (h01 - h00) : h00 + u * (h10 - h00) + v * (h11 - h10);
    };
    const auto pick = [&](std::initializer_list<double> h) { return highest ? std::max(h) : std::min(h); };
    double lowest = pick({height(u0, v0), height(u1, v0), height(u0, v1), height(u1, v1)});
    // The diagonal u = v meets the rectangle where [u0,u1] and [v0,v1] overlap.
    const double lo = std::max(u0, v0), hi = std::min(u1, v1);
    if (lo <= hi) lowest = pick({lowest, height(lo, lo), height(hi, hi)});
    return lowest;
}

// Calls visit(terrain) for every terrain over each chunk square the rectangle
// [x0,x1] x [z0,z1] meets, and open(square) for each of those squares that has none
// (it returns false to stop: the result is then false); false also when the rectangle
// spans more than `maxSquares` squares a side.
template <class Visit, class Open>
bool forTerrainsOver(const BakeWindow& w, double x0, double z0, double x1, double z1, int maxSquares, const Visit& visit,
                     const Open& open) {
    if (w.terrainObjects.empty() || !(x0 <= x1 && z0 <= z1)) return false;
    // Chunk squares are aligned with the window origin (a chunk corner).
    const int cx0 = int(std::floor(x0 / w.chunkSize)), cx1 = int(std::floor(x1 / w.chunkSize));
    const int cz0 = int(std::floor(z0 / w.chunkSize)), cz1 = int(std::floor(z1 / w.chunkSize));
    if (cx1 - cx0 > maxSquares || cz1 - cz0 > maxSquares) return false;
    for (int cx = cx0; cx <= cx1; ++cx)
        for (int cz = cz0; cz <= cz1; ++cz) {
            bool covered = false;
            for (size_t k : w.terrainObjects) {
                const WindowObject& o = w.objects[k];
                if (o.lsTerrainOrigin.x != cx * w.chunkSize || o.lsTerrainOrigin.z != cz * w.chunkSize) continue;
                covered = true;
                visit(o);
            }
            if (!covered && !open(GroundOpening{cx * w.chunkSize, cz * w.chunkSize, (cx + 1) * w.chunkSize, (cz + 1) * w.chunkSize}))
                return false;
        }
    return true;
}

template <class Visit>
bool forTerrainsOver(const BakeWindow& w, double x0, double z0, double x1, double z1, int maxSquares, const Visit& visit) {
    return forTerrainsOver(w, x0, z0, x1, z1, maxSquares, visit, [](const GroundOpening&) { return false; });
}

// lsTerrainMinOver, or with `highest` lsTerrainMaxOver.
std::optional<double> terrainExtremeOver(const BakeWindow& w, double x0, double z0, double x1, double z1, bool highest) {
    std::optional<double> lowest;
    const bool covered = forTerrainsOver(w, x0, z0, x1, z1, 64, [&](const WindowObject& o) {
        const Heightfield& hf = *o.heightfield;
        // The rectangle's corners in this terrain's cells (Heightfield::cellOf: the mesh's
        // own sample positions), clamped to its square.
        double f0 = 0, f1 = 0, g0 = 0, g1 = 0;
        const int i0 = hf.cellOf(x0 - o.lsTerrainOrigin.x, f0), i1 = hf.cellOf(x1 - o.lsTerrainOrigin.x, f1);
        const int j0 = hf.cellOf(z0 - o.lsTerrainOrigin.z, g0), j1 = hf.cellOf(z1 - o.lsTerrainOrigin.z, g1);
        for (int j = j0; j <= j1; ++j)
            for (int i = i0; i <= i1; ++i) {
                const double u0 = i == i0 ? f0 : 0.0, u1 = i == i1 ? f1 : 1.0;
                const double v0 = j == j0 ? g0 : 0.0, v1 = j == j1 ? g1 : 1.0;
                const double h = cellSurfaceMin(hf, i, j, u0, v0, u1, v1, highest) + o.lsTerrainOrigin.y;
                if (!lowest || (highest ? h > *lowest : h < *lowest)) lowest = h;
            }
    });
    return covered ? lowest : std::nullopt;
}

}  // namespace

std::optional<double> BakeWindow::lsTerrainMinOver(double x0, double z0, double x1, double z1) const {
    return terrainExtremeOver(*this, x0, z0, x1, z1, false);
}

std::optional<double> BakeWindow::lsTerrainMaxOver(double x0, double z0, double x1, double z1) const {
    return terrainExtremeOver(*this, x0, z0, x1, z1, true);
}

namespace {

// The terrain triangles of lsGroundOver's rectangle, of every terrain there (see window.h),
// leaving out with `keep` cells whose triangles lie wholly outside its x-z extent.
bool groundOver(const BakeWindow& w, double x0, double z0, double x1, double z1, const Aabb* keep,
                std::vector<std::array<glm::dvec3, 3>>& out, std::vector<GroundOpening>* openings) {
    // A part spanning more than a few chunks: not worth it (the caller keeps the receiver).
    return forTerrainsOver(
        w, x0, z0, x1, z1, 4,
        [&](const WindowObject& o) {
            const Heightfield& hf = *o.heightfield;
            const int cells = hf.n - 1;
            // The cell holding v (as the mesh places its samples), widened by `slack` cells.
            auto index = [&](double v, double origin, int slack) {
                double fraction = 0;
                return std::clamp(hf.cellOf(v - origin, fraction) + slack, 0, cells - 1);
            };
            const int i0 = index(x0, o.lsTerrainOrigin.x, -1), i1 = index(x1, o.lsTerrainOrigin.x, 1);
            const int j0 = index(z0, o.lsTerrainOrigin.z, -1), j1 = index(z1, o.lsTerrainOrigin.z, 1);
            // With `keep`, where the placement only moves the mesh (a terrain's: rows 0-2 the
            // identity), the placed x of column i's vertices is the same in every row (the
            // other terms are zeros) and increases with i; likewise z by row. A cell lying
            // wholly beside `keep` holds two triangles whose boxes do too.
            const RowTransform& t = o.lsTransform;
            const bool moved = keep && t.rows[0] == glm::dvec3(1, 0, 0) && t.rows[1] == glm::dvec3(0, 1, 0) &&
                               t.rows[2] == glm::dvec3(0, 0, 1);
            thread_local std::vector<double> columnX, rowZ;  // placed x of columns i0 .. i1 + 1, z of rows
            if (moved) {
                auto placed = [&](int i, int j) {
                    return t.apply(o.mesh->positions[size_t(j) * size_t(hf.n) + size_t(i)]);
                };
                columnX.clear(), rowZ.clear();
                for (int i = i0; i <= i1 + 1; ++i) columnX.push_back(placed(i, j0).x);
                for (int j = j0; j <= j1 + 1; ++j) rowZ.push_back(placed(i0, j).z);
            }
            for (int j = j0; j <= j1; ++j) {
                if (moved && (rowZ[size_t(j + 1 - j0)] < keep->min.z || rowZ[size_t(j - j0)] > keep->max.z)) continue;
                for (int i = i0; i <= i1; ++i) {
                    if (moved && (columnX[size_t(i + 1 - i0)] < keep->min.x || columnX[size_t(i - i0)] > keep->max.x))
                        continue;
                    for (int half = 0; half < 2; ++half) {
                        // Heightfield::toMesh: cell (i, j) holds triangles 2 (j cells + i) and the next.
                        out.push_back(o.lsTriangle(2 * (size_t(j) * size_t(cells) + size_t(i)) + size_t(half)));
                    }
                }
            }
        },
        [&](const GroundOpening& g) {
            if (!openings) return false;
            openings->push_back(g);
            return true;
        });
}

}  // namespace

bool BakeWindow::lsGroundOver(double x0, double z0, double x1, double z1, std::vector<std::array<glm::dvec3, 3>>& out,
                              std::vector<GroundOpening>* openings) const {
    return groundOver(*this, x0, z0, x1, z1, nullptr, out, openings);
}

bool BakeWindow::lsTerrainTrianglesOver(double x0, double z0, double x1, double z1,
                                        std::vector<std::array<glm::dvec3, 3>>& out) const {
    return groundOver(*this, x0, z0, x1, z1, nullptr, out, nullptr);
}

bool BakeWindow::lsTerrainTrianglesOver(double x0, double z0, double x1, double z1, const Aabb& keep,
                                        std::vector<std::array<glm::dvec3, 3>>& out) const {
    return groundOver(*this, x0, z0, x1, z1, &keep, out, nullptr);
}

Aabb lsGroupBoundsByLoop(const WindowObject& o, uint32_t group, bool withArea) {
    Aabb box;
    const Mesh& m = *o.mesh;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        if (m.triangleGroup[t] != group) continue;
        const auto& tri = m.triangles[t];
        const glm::dvec3 &a = m.positions[tri[0]], &b = m.positions[tri[1]], &c = m.positions[tri[2]];
        if (withArea && hasRepeatedVertex(a, b, c)) continue;
        box.extend(o.lsTransform.apply(a));
        box.extend(o.lsTransform.apply(b));
        box.extend(o.lsTransform.apply(c));
    }
    return box;
}

Aabb lsGroupBounds(const WindowObject& o, uint32_t group, bool withArea) {
    const MeshVertexIndex& index = vertexIndex(*o.mesh);
    if (group >= index.group.size()) return {};
    const VertexTree& tree = *(withArea ? index.groupWithArea : index.group)[group];
    if (tree.empty()) return {};
    if (auto box = placedBox(tree, o.mesh->positions, o.lsTransform)) return Aabb{box->first, box->second};
    return lsGroupBoundsByLoop(o, group, withArea);  // a zero coordinate: its sign is the loop's
}

namespace {

// The window-local box of every vertex a triangle of the object uses, by the loop over the
// vertices in index order (the reference; the fallback of placedBox).
Aabb lsUsedBoundsByLoop(const WindowObject& wo) {
    Aabb box;
    std::vector<char> used(wo.mesh->positions.size(), 0);
    for (const auto& tri : wo.mesh->triangles)
        for (uint32_t v : tri) used[v] = 1;
    for (size_t v = 0; v < used.size(); ++v)
        if (used[v]) box.extend(wo.lsTransform.apply(wo.mesh->positions[v]));
    return box;
}

std::string objectLabel(const ChunkFile& cf, const ChunkObject& o) {
    std::string name = chunkFileName(cf.coord);
    if (o.kind == ChunkObject::Kind::Terrain) return name + " terrain #" + std::to_string(o.elementIndex);
    std::string s = name + " model #" + std::to_string(o.elementIndex);
    if (!o.uuid.empty()) s += " (" + o.uuid + ")";
    return s;
}

}  // namespace

BakeWindow buildWindow(const Space& space, ChunkCoord centre, TerrainMeshes& terrainMeshes) {
    const Neighbours& n = space.settings.neighbours;
    std::vector<ChunkCoord> chunks;
    for (int dx = -n.left; dx <= n.right; ++dx)
        for (int dz = -n.bottom; dz <= n.top; ++dz) chunks.push_back({centre.x + dx, centre.z + dz});
    return buildWindow(space, centre, chunks, terrainMeshes);
}

namespace {

// One object of a window's chunks, before it is placed: its chunk file, the chunk's origin
// relative to the window origin, and (terrain) its mesh.
struct ObjectSlot {
    const ChunkFile* file = nullptr;
    ChunkCoord chunk;
    const ChunkObject* object = nullptr;
    bool centre = false;
    glm::dvec3 lsChunk{0.0};
    const Mesh* terrainMesh = nullptr;
};

// The objects of `chunks` in order, skipped ones included. Terrain meshes are made here,
// one thread (terrainMeshes is shared by the windows).
std::vector<ObjectSlot> objectSlots(const Space& space, ChunkCoord centre, const std::vector<ChunkCoord>& chunks, double oy,
                                    TerrainMeshes& terrainMeshes) {
    std::vector<ObjectSlot> slots;
    size_t count = 0;
    for (ChunkCoord c : chunks)
        if (auto it = space.chunks.find(c); it != space.chunks.end()) count += it->second.objects.size();
    slots.reserve(count);
    for (ChunkCoord c : chunks) {
        auto it = space.chunks.find(c);
        if (it == space.chunks.end()) continue;
        const int dx = c.x - centre.x, dz = c.z - centre.z;
        // Chunk origin relative to the window origin: whole chunks, exact in double.
        const glm::dvec3 lsChunk(double(dx) * space.settings.chunkSize, -oy, double(dz) * space.settings.chunkSize);
        for (const ChunkObject& o : it->second.objects) {
            ObjectSlot slot{&it->second, c, &o, dx == 0 && dz == 0, lsChunk, nullptr};
            if (!o.skipped && o.kind == ChunkObject::Kind::Terrain) {
                std::shared_ptr<const Mesh>& tm = terrainMeshes[o.heightfield.get()];
                if (!tm) tm = std::make_shared<const Mesh>(o.heightfield->toMesh());
                slot.terrainMesh = tm.get();
            }
            slots.push_back(slot);
        }
    }
    return slots;
}

// The window-local box of every vertex a triangle of `wo` uses: the box of mapping each
// triangle's corners. Its coordinates are extremes over the vertices of fl(L(v) + t), L the
// transform's linear part as RowTransform::apply computes it and t the window's translation
// added last; rounding a sum with the same t is monotone, so they are fl(extreme of L(v) +
// t): the object's box under L alone (made once, ChunkObject::linearBox) moved by t, bit
// for bit what the mesh's vertex tree gives per window (core/mesh_index.h, placedBox). A
// zero coordinate, whose sign the loop over the vertices decides, takes that loop.
Aabb lsObjectBounds(const ChunkObject& o, const WindowObject& wo) {
    const VertexTree& used = *vertexIndex(*wo.mesh).used;
    if (used.empty()) return {};
    if (!o.linearBoxMade) {
        RowTransform linear = wo.lsTransform;
        linear.rows[3] = glm::dvec3(0.0);
        o.linearBox = placedBox(used, wo.mesh->positions, linear);
        o.linearBoxMade = true;
    }
    if (o.linearBox) {
        const glm::dvec3& t = wo.lsTransform.rows[3];
        const Aabb moved{o.linearBox->first + t, o.linearBox->second + t};
        bool zero = false;
        for (int a = 0; a < 3; ++a) zero = zero || moved.min[a] == 0.0 || moved.max[a] == 0.0;
        if (!zero) return moved;
    }
    if (auto box = placedBox(used, wo.mesh->positions, wo.lsTransform)) return Aabb{box->first, box->second};
    return lsUsedBoundsByLoop(wo);  // a zero coordinate: its sign is the loop's
}

// The window object of a slot (not skipped): its mesh placed by the chunk's offset, and its
// box, from the mesh's vertex tree: the box of every vertex a triangle uses (the same box
// as mapping each triangle's corners), a few leaves per placement, bit for bit the loop's
// box (core/mesh_index.h).
WindowObject placeObject(const ObjectSlot& slot) {
    const ChunkObject& o = *slot.object;
    WindowObject wo;
    wo.kind = o.kind;
    wo.source = &o;
    wo.chunk = slot.chunk;
    wo.centre = slot.centre;
    wo.label = objectLabel(*slot.file, o);
    wo.castsShadow = o.castsShadow;
    if (o.kind == ChunkObject::Kind::Terrain) {
        wo.mesh = slot.terrainMesh;
        wo.heightfield = o.heightfield.get();
        wo.lsTerrainOrigin = slot.lsChunk;
        wo.lsTransform.rows[3] = slot.lsChunk;
    } else {
        wo.mesh = o.mesh.get();
        wo.lsTransform = o.transform;
        // Translation: chunk-local + chunk offset, both relative to the window.
        wo.lsTransform.rows[3] = o.transform.rows[3] + slot.lsChunk;
        wo.flipsWinding = o.transform.determinant() < 0;
    }
    wo.lsBounds = lsObjectBounds(o, wo);
    return wo;
}

}  // namespace

BakeWindow buildWindow(const Space& space, ChunkCoord centre, const std::vector<ChunkCoord>& chunks,
                       TerrainMeshes& terrainMeshes) {
    const SpaceSettings& S = space.settings;
    BakeWindow w;
    w.centre = centre;
    w.chunkSize = S.chunkSize;
    w.terrainTolerance = S.terrainTolerance;
    auto cit = space.chunks.find(centre);
    if (cit != space.chunks.end()) w.centrePath = cit->second.path;

    // The window's meshes' indexes, those not built yet built in parallel: a dense mesh's
    // (a 180,000-triangle scan's trees) are most of its first window's own work, and the
    // loops below would build them one after the other.
    {
        std::unordered_set<const Mesh*> seen;
        std::vector<const Mesh*> meshes;
        for (ChunkCoord c : chunks) {
            auto it = space.chunks.find(c);
            if (it == space.chunks.end()) continue;
            for (const ChunkObject& o : it->second.objects)
                if (!o.skipped && o.mesh && seen.insert(o.mesh.get()).second) meshes.push_back(o.mesh.get());
        }
        tbb::parallel_for_each(meshes.begin(), meshes.end(), [](const Mesh* m) { vertexIndex(*m); });
    }

    // Vertical origin: middle of the centre chunk's world-space heights, rounded to a whole
    // metre so that lifting the space by whole metres shifts it exactly.
    double yMin = 1e300, yMax = -1e300;
    if (cit != space.chunks.end()) {
        for (const ChunkObject& o : cit->second.objects) {
            if (o.skipped) continue;
            if (o.heightfield) {
                auto [lo, hi] = std::minmax_element(o.heightfield->heights.begin(), o.heightfield->heights.end());
                yMin = std::min(yMin, *lo);
                yMax = std::max(yMax, *hi);
            } else if (o.mesh && !o.mesh->positions.empty()) {
                // The extremes of y over every vertex, from the mesh's vertex tree: the loop's
                // values exactly (core/mesh_index.h). A zero extreme: the loop, whose order
                // decides which zero it keeps.
                const VertexTree& all = *vertexIndex(*o.mesh).positions;
                const std::vector<glm::dvec3>& ps = o.mesh->positions;
                const double hi = all.maximum(
                    [&](const glm::dvec3& a, const glm::dvec3& b) { return placedCoordinateUpper(o.transform, 1, 1.0, a, b); },
                    [&](uint32_t v) { return o.transform.apply(ps[v]).y; });
                const double lo = -all.maximum(
                    [&](const glm::dvec3& a, const glm::dvec3& b) { return placedCoordinateUpper(o.transform, 1, -1.0, a, b); },
                    [&](uint32_t v) { return -o.transform.apply(ps[v]).y; });
                if (lo != 0.0 && hi != 0.0) {
                    yMin = std::min(yMin, lo);
                    yMax = std::max(yMax, hi);
                } else {
                    for (const glm::dvec3& p : ps) {
                        const double y = o.transform.apply(p).y;
                        yMin = std::min(yMin, y);
                        yMax = std::max(yMax, y);
                    }
                }
            }
        }
    }
    const double oy = yMin <= yMax ? std::round(0.5 * (yMin + yMax)) : 0.0;
    w.wsOrigin = glm::dvec3(double(centre.x) * S.chunkSize, oy, double(centre.z) * S.chunkSize);

    // The window's objects in chunk order, each placed on its own (in parallel: a
    // whole-space window holds thousands, each with its box from its mesh's tree), then
    // joined in that order.
    const std::vector<ObjectSlot> slots = objectSlots(space, centre, chunks, oy, terrainMeshes);
    std::vector<WindowObject> placed(slots.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, slots.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        // A window of 200,000 objects takes seconds: a stop request leaves it incomplete,
        // for the caller to notice (see window.h).
        if (stopRequested()) return;
        for (size_t k = r.begin(); k < r.end(); ++k)
            if (!slots[k].object->skipped) placed[k] = placeObject(slots[k]);
    });
    if (stopRequested()) return w;
    w.objects.reserve(slots.size());
    for (size_t k = 0; k < slots.size(); ++k) {
        if (slots[k].object->skipped) {
            ++w.skippedObjects;
            continue;
        }
        WindowObject& wo = placed[k];
        w.hasNonCasters |= !wo.castsShadow;
        if (wo.kind == ChunkObject::Kind::Terrain) {
            w.hasTerrain = true;
            w.terrainObjects.push_back(w.objects.size());
        } else {
            for (const PrimitiveGroup& g : wo.mesh->groups) w.hasAlphaTested |= g.alphaTested;
        }
        if (!wo.lsBounds.empty()) {
            w.lsBounds.extend(wo.lsBounds);
            if (wo.centre) w.lsCentreBounds.extend(wo.lsBounds);
        }
        w.objects.push_back(std::move(wo));
    }
    for (Light L : S.lights) {
        L.position -= w.wsOrigin;  // window-local
        w.lsLights.push_back(L);
    }
    return w;
}

}  // namespace shadowcull
