// Sample points on a primitive group, aimed at by witness rays.
#pragma once

#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"

namespace shadowcull::raycast {

// Points on the group's triangles (window-local, metres), in an order where every prefix is
// spread over the group: first `areaSamples` points distributed by area (stratified along
// the cumulative area with a van der Corput sequence, so small triangles such as a 5 mm
// rod still get their share), then every triangle's vertices and edge midpoints nudged
// 0.1% into the triangle (so a ray aimed there hits this triangle, not the neighbour or
// the silhouette), up to `maxFeatureSamples`. Triangles that repeat a vertex get none.
// Deterministic: the same group gives the same points.
std::vector<glm::dvec3> sampleGroup(const WindowObject& object, uint32_t group, int areaSamples, int maxFeatureSamples);

}  // namespace shadowcull::raycast
