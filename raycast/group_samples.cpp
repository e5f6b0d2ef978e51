#include "raycast/group_samples.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "core/mesh_index.h"

namespace shadowcull::raycast {

double radicalInverse2(uint32_t i) {
    i = (i << 16) | (i >> 16);
    i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
    i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
    i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
    i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
    return double(i) * (1.0 / 4294967296.0);
}

namespace {

struct Tri {
    glm::dvec3 a, b, c;
};

Tri triOf(const Mesh& mesh, uint32_t t) {
    const auto& i = mesh.triangles[t];
    return Tri{mesh.positions[i[0]], mesh.positions[i[1]], mesh.positions[i[2]]};
}

// The points of sampleMeshGroup on the mesh's triangles `tris` (indices, in mesh order,
// none repeating a vertex), whatever chose them. Indices, not copies: a dense group's
// triangles copied were 72 bytes each (13 MB for a 180,000-triangle rock).
std::vector<glm::dvec3> samplePoints(const Mesh& mesh, const std::vector<uint32_t>& tris, int areaSamples,
                                     int maxFeatureSamples) {
    std::vector<double> cumulative;  // cumulative area
    cumulative.reserve(tris.size());
    double total = 0.0;
    for (uint32_t i : tris) {
        const Tri tri = triOf(mesh, i);
        total += 0.5 * glm::length(glm::cross(tri.b - tri.a, tri.c - tri.a));
        cumulative.push_back(total);
    }
    std::vector<glm::dvec3> out;
    if (tris.empty()) return out;
    out.reserve(size_t(areaSamples) + size_t(maxFeatureSamples));

    if (total > 0.0) {
        const double offset = 0.5 / double(std::max(1, areaSamples));
        for (int s = 0; s < areaSamples; ++s) {
            double u = radicalInverse2(uint32_t(s)) + offset;
            u = (u - std::floor(u)) * total;
            size_t k = size_t(std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin());
            k = std::min(k, tris.size() - 1);
            const double before = k ? cumulative[k - 1] : 0.0;
            const double area = cumulative[k] - before;
            // First coordinate: where u falls inside this triangle's share (stratified);
            // second: a golden-ratio sequence (well spread, deterministic).
            const double v1 = area > 0 ? std::clamp((u - before) / area, 0.0, 1.0) : 0.5;
            const double g = double(s) * 0.6180339887498949 + 0.5;
            const double v2 = g - std::floor(g);
            const double r = std::sqrt(v1);
            const Tri t = triOf(mesh, tris[k]);
            out.push_back((1 - r) * t.a + r * (1 - v2) * t.b + r * v2 * t.c);
        }
    }
    // Features: vertices and edge midpoints, nudged into the triangle.
    constexpr double e = 1e-3;
    int features = 0;
    for (uint32_t i : tris) {
        if (features >= maxFeatureSamples) break;
        const Tri t = triOf(mesh, i);
        const glm::dvec3 pts[6] = {
            (1 - 2 * e) * t.a + e * t.b + e * t.c,
            e * t.a + (1 - 2 * e) * t.b + e * t.c,
            e * t.a + e * t.b + (1 - 2 * e) * t.c,
            (0.5 - e / 2) * (t.a + t.b) + e * t.c,
            (0.5 - e / 2) * (t.b + t.c) + e * t.a,
            (0.5 - e / 2) * (t.c + t.a) + e * t.b,
        };
        for (const glm::dvec3& p : pts) {
            if (features++ >= maxFeatureSamples) break;
            out.push_back(p);
        }
    }
    return out;
}

// Triangle `t` of the mesh has three distinct vertices (else no area, no samples).
bool sampled(const Mesh& mesh, uint32_t t) { return !hasRepeatedVertex(mesh, t); }

}  // namespace

std::vector<glm::dvec3> sampleMeshGroup(const Mesh& mesh, uint32_t group, int areaSamples, int maxFeatureSamples) {
    std::vector<uint32_t> tris;
    for (uint32_t t = 0; t < mesh.triangles.size(); ++t)
        if (mesh.triangleGroup[t] == group && sampled(mesh, t)) tris.push_back(t);
    return samplePoints(mesh, tris, areaSamples, maxFeatureSamples);
}

namespace {

std::vector<glm::dvec3> place(const WindowObject& object, std::vector<glm::dvec3> points) {
    for (glm::dvec3& p : points) p = object.lsTransform.apply(p);
    return points;
}

}  // namespace

void placeSamples(const WindowObject& object, const std::vector<glm::dvec3>& msPoints, size_t count,
                  std::vector<glm::dvec3>& placed) {
    count = std::min(count, msPoints.size());
    if (placed.size() >= count) return;
    placed.reserve(msPoints.size());  // the rest, if asked, without moving the prefix twice
    for (size_t k = placed.size(); k < count; ++k) placed.push_back(object.lsTransform.apply(msPoints[k]));
}

std::vector<glm::dvec3> sampleGroup(const WindowObject& object, uint32_t group, int areaSamples, int maxFeatureSamples) {
    return place(object, sampleMeshGroup(*object.mesh, group, areaSamples, maxFeatureSamples));
}

std::vector<glm::dvec3> sampleGroupWithinReach(const WindowObject& object, uint32_t group, const Light& light, int areaSamples,
                                               int maxFeatureSamples) {
    if (light.type == LightType::Directional) return {};
    const Mesh& mesh = *object.mesh;
    std::vector<uint32_t> chosen;
    vertexIndex(mesh).triangles.visit(
        // A node by its placed bounds (core/window.h: every placed corner, rounding
        // included), so that no triangle a vertex's own rounding puts within reach is cut.
        [&](const glm::dvec3& lo, const glm::dvec3& hi) { return !boxOutOfReach(light, placedBounds(Aabb{lo, hi}, object.lsTransform)); },
        [&](uint32_t t) {
            if (mesh.triangleGroup[t] != group) return;
            Aabb placed;
            for (int c = 0; c < 3; ++c) placed.extend(object.lsTransform.apply(mesh.positions[mesh.triangles[t][c]]));
            if (!boxOutOfReach(light, placed)) chosen.push_back(t);
        });
    std::sort(chosen.begin(), chosen.end());  // mesh order: the same points whatever the tree
    chosen.erase(std::remove_if(chosen.begin(), chosen.end(), [&](uint32_t t) { return !sampled(mesh, t); }), chosen.end());
    return place(object, samplePoints(mesh, chosen, areaSamples, maxFeatureSamples));
}

const std::vector<glm::dvec3>& GroupSampleCache::meshPoints(const Mesh& mesh, uint32_t group) {
    const auto key = std::make_pair(&mesh, group);
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (auto it = local_.find(key); it != local_.end()) return it->second;
    }
    // Sampled without the lock (a large mesh's group takes milliseconds, and every other
    // search would wait for it); a thread that sampled the same group meanwhile wins, with
    // the same points (sampleMeshGroup is deterministic).
    std::vector<glm::dvec3> points = sampleMeshGroup(mesh, group, area_, features_);
    std::lock_guard<std::mutex> lock(mutex_);
    return local_.emplace(key, std::move(points)).first->second;  // std::map nodes stay put; never changed again
}

std::vector<glm::dvec3> GroupSampleCache::placed(const WindowObject& object, uint32_t group) {
    return place(object, meshPoints(*object.mesh, group));
}

void GroupSampleCache::forget(const std::unordered_set<const Mesh*>& meshes) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = local_.begin(); it != local_.end();) it = meshes.count(it->first.first) ? local_.erase(it) : std::next(it);
}

size_t GroupSampleCache::meshGroups() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return local_.size();
}

}  // namespace shadowcull::raycast
