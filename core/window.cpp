#include "core/window.h"

#include <algorithm>
#include <cmath>

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

std::optional<double> BakeWindow::lsTerrainMinOver(double x0, double z0, double x1, double z1) const {
    if (terrainObjects.empty()) return std::nullopt;
    // Chunk squares are aligned with the window origin (a chunk corner).
    const int cx0 = int(std::floor(x0 / chunkSize)), cx1 = int(std::floor(x1 / chunkSize));
    const int cz0 = int(std::floor(z0 / chunkSize)), cz1 = int(std::floor(z1 / chunkSize));
    if (cx1 - cx0 > 64 || cz1 - cz0 > 64) return std::nullopt;
    std::optional<double> lowest;
    for (int cx = cx0; cx <= cx1; ++cx) {
        for (int cz = cz0; cz <= cz1; ++cz) {
            bool covered = false;
            for (size_t k : terrainObjects) {
                const WindowObject& o = objects[k];
                if (o.lsTerrainOrigin.x != cx * chunkSize || o.lsTerrainOrigin.z != cz * chunkSize) continue;
                covered = true;
                const Heightfield& hf = *o.heightfield;
                const double cell = hf.size / double(hf.n - 1);
                auto index = [&](double v, double origin, bool up) {
                    double f = (v - origin) / cell;
                    int i = up ? int(std::ceil(f)) : int(std::floor(f));
                    return std::clamp(i, 0, hf.n - 1);
                };
                const int i0 = index(x0, o.lsTerrainOrigin.x, false), i1 = index(x1, o.lsTerrainOrigin.x, true);
                const int j0 = index(z0, o.lsTerrainOrigin.z, false), j1 = index(z1, o.lsTerrainOrigin.z, true);
                for (int j = j0; j <= j1; ++j)
                    for (int i = i0; i <= i1; ++i) {
                        const double h = hf.at(i, j) + o.lsTerrainOrigin.y;
                        if (!lowest || h < *lowest) lowest = h;
                    }
            }
            if (!covered) return std::nullopt;
        }
    }
    return lowest;
}

namespace {

std::string objectLabel(const ChunkFile& cf, const ChunkObject& o) {
    std::string name = chunkFileName(cf.coord);
    if (o.kind == ChunkObject::Kind::Terrain) return name + " terrain #" + std::to_string(o.elementIndex);
    std::string s = name + " model #" + std::to_string(o.elementIndex);
    if (!o.uuid.empty()) s += " (" + o.uuid + ")";
    return s;
}

}  // namespace

BakeWindow buildWindow(const Space& space, ChunkCoord centre,
                       TerrainMeshes& terrainMeshes) {
    const SpaceSettings& S = space.settings;
    BakeWindow w;
    w.centre = centre;
    w.chunkSize = S.chunkSize;
    w.terrainTolerance = S.terrainTolerance;
    auto cit = space.chunks.find(centre);
    if (cit != space.chunks.end()) w.centrePath = cit->second.path;

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
            } else if (o.mesh) {
                for (const glm::dvec3& p : o.mesh->positions) {
                    double y = o.transform.apply(p).y;
                    yMin = std::min(yMin, y);
                    yMax = std::max(yMax, y);
                }
            }
        }
    }
    const double oy = yMin <= yMax ? std::round(0.5 * (yMin + yMax)) : 0.0;
    w.wsOrigin = glm::dvec3(double(centre.x) * S.chunkSize, oy, double(centre.z) * S.chunkSize);

    for (int dx = -S.neighbours.left; dx <= S.neighbours.right; ++dx) {
        for (int dz = -S.neighbours.bottom; dz <= S.neighbours.top; ++dz) {
            ChunkCoord c{centre.x + dx, centre.z + dz};
            auto it = space.chunks.find(c);
            if (it == space.chunks.end()) continue;
            const ChunkFile& cf = it->second;
            // Chunk origin relative to the window origin: whole chunks, exact in double.
            const glm::dvec3 lsChunk(double(dx) * S.chunkSize, -oy, double(dz) * S.chunkSize);
            for (const ChunkObject& o : cf.objects) {
                if (o.skipped) {
                    ++w.skippedObjects;
                    continue;
                }
                WindowObject wo;
                wo.kind = o.kind;
                wo.source = &o;
                wo.chunk = c;
                wo.centre = dx == 0 && dz == 0;
                wo.label = objectLabel(cf, o);
                if (o.kind == ChunkObject::Kind::Terrain) {
                    std::shared_ptr<const Mesh>& tm = terrainMeshes[o.heightfield.get()];
                    if (!tm) tm = std::make_shared<const Mesh>(o.heightfield->toMesh());
                    wo.mesh = tm.get();
                    wo.heightfield = o.heightfield.get();
                    wo.lsTerrainOrigin = lsChunk;
                    wo.lsTransform.rows[3] = lsChunk;
                    w.hasTerrain = true;
                    w.terrainObjects.push_back(w.objects.size());
                } else {
                    wo.mesh = o.mesh.get();
                    wo.lsTransform = o.transform;
                    // Translation: chunk-local + chunk offset, both relative to the window.
                    wo.lsTransform.rows[3] = o.transform.rows[3] + lsChunk;
                    wo.flipsWinding = o.transform.determinant() < 0;
                    for (const PrimitiveGroup& g : wo.mesh->groups) w.hasAlphaTested |= g.alphaTested;
                }
                // Every vertex a triangle uses, mapped once (a dense mesh's vertices are shared
                // by ~6 triangles): the same box as mapping each triangle's corners.
                std::vector<char> used(wo.mesh->positions.size(), 0);
                for (const auto& tri : wo.mesh->triangles)
                    for (uint32_t v : tri) used[v] = 1;
                for (size_t v = 0; v < used.size(); ++v)
                    if (used[v]) wo.lsBounds.extend(wo.lsTransform.apply(wo.mesh->positions[v]));
                if (!wo.lsBounds.empty()) {
                    w.lsBounds.extend(wo.lsBounds);
                    if (wo.centre) w.lsCentreBounds.extend(wo.lsBounds);
                }
                w.objects.push_back(std::move(wo));
            }
        }
    }
    for (Light L : S.lights) {
        L.position -= w.wsOrigin;  // window-local
        w.lsLights.push_back(L);
    }
    return w;
}

}  // namespace shadowcull
