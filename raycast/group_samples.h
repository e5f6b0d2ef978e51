// Sample points on a primitive group, aimed at by witness rays.
#pragma once

#include <map>
#include <mutex>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"

namespace shadowcull::raycast {

// Van der Corput radical inverse in base 2: 0, 1/2, 1/4, 3/4, ... (each prefix of length
// 2^k is one point per stratum of width 2^-k).
double radicalInverse2(uint32_t i);

// Points on the group's triangles (mesh coordinates), in an order where every prefix is
// spread over the group: first `areaSamples` points distributed by area (stratified along
// the cumulative area with a van der Corput sequence, so small triangles such as a 5 mm
// rod still get their share), then every triangle's vertices and edge midpoints nudged
// 0.1% into the triangle (so a ray aimed there hits this triangle, not the neighbour or
// the silhouette), up to `maxFeatureSamples`. Triangles that repeat a vertex get none.
// Deterministic: the same group gives the same points. The area is measured in mesh
// coordinates, so every placement of a mesh gets the same points (spread by placed area as
// long as the placement scales uniformly).
std::vector<glm::dvec3> sampleMeshGroup(const Mesh& mesh, uint32_t group, int areaSamples, int maxFeatureSamples);

// The same points placed in the window (window-local, metres).
std::vector<glm::dvec3> sampleGroup(const WindowObject& object, uint32_t group, int areaSamples, int maxFeatureSamples);

// Appends to `placed` the points of `msPoints` (a mesh's, as sampleMeshGroup gives them)
// from placed.size() up to `count` (all when fewer), placed in the window as sampleGroup
// places them: a search that stops at its first witness, most often in the first packet,
// places only what it traces.
void placeSamples(const WindowObject& object, const std::vector<glm::dvec3>& msPoints, size_t count,
                  std::vector<glm::dvec3>& placed);

// Point and spot lights: the points sampleMeshGroup gives, on the group's triangles that
// have a point within the light's range and cone (their placed boxes against the reach
// tests of core/light_reach.h), placed in the window. p lies within reach (semantics.md):
// when a range sphere cuts a large group, most of the whole group's points lie beyond it
// and aim at nothing. Empty for a directional light or when no triangle is within reach.
// Deterministic, as sampleMeshGroup (the triangles are taken in mesh order).
std::vector<glm::dvec3> sampleGroupWithinReach(const WindowObject& object, uint32_t group, const Light& light, int areaSamples,
                                               int maxFeatureSamples);

// sampleMeshGroup once per (mesh, group) for a whole bake: placements of a mesh share
// their points, and only the placement is computed per window. Keyed by the mesh's
// address, so one cache serves one loaded space. Thread-safe.
class GroupSampleCache {
public:
    GroupSampleCache(int areaSamples, int maxFeatureSamples) : area_(areaSamples), features_(maxFeatureSamples) {}
    // The object's group's points, window-local.
    std::vector<glm::dvec3> placed(const WindowObject& object, uint32_t group);
    // The (mesh, group)'s points in mesh coordinates (a reference that stays valid as long
    // as the cache: a caller placing only a prefix of them).
    const std::vector<glm::dvec3>& meshPoints(const Mesh& mesh, uint32_t group);
    size_t meshGroups() const;
    // Drops the points of `meshes` (about to be freed: a later mesh may get the address).
    void forget(const std::unordered_set<const Mesh*>& meshes);

private:
    int area_, features_;
    mutable std::mutex mutex_;
    std::map<std::pair<const Mesh*, uint32_t>, std::vector<glm::dvec3>> local_;  // nodes never move
};

}  // namespace shadowcull::raycast
