// The GPU confirmation's triangle tree (gpu/selection_tree.h).
#include "gpu/selection_tree.h"

#include <algorithm>
#include <cmath>

#include <glm/common.hpp>

#include "core/median_split.h"
#include "core/mesh.h"

namespace shadowcull::gpu {

namespace {

// Box padding, relative to the mesh's size (largest |coordinate| plus extent): far above
// the rounding of the vertices' placement (~1e-16 relative), far below anything a pixel
// test can tell (the hull tests keep a pixel and more to spare).
constexpr double kPad = 1e-9;

}  // namespace

SelectionTree::SelectionTree(const Mesh& mesh) {
    const auto& P = mesh.positions;
    Aabb all;
    std::vector<SplitEntry> entries;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& tri = mesh.triangles[t];
        if (hasRepeatedVertex(P[tri[0]], P[tri[1]], P[tri[2]])) continue;
        triangles_.push_back(uint32_t(t));
        for (uint32_t v : tri) all.extend(P[v]);
        // Split by the centroid; equal centres by triangle index (the halves do not depend
        // on the order nth_element met them in).
        entries.push_back({(P[tri[0]] + P[tri[1]] + P[tri[2]]) / 3.0, uint32_t(t)});
    }
    if (triangles_.empty()) return;
    const glm::dvec3 mag = glm::max(glm::abs(all.min), glm::abs(all.max));
    pad_ = kPad * (std::max({mag.x, mag.y, mag.z}) + std::max({all.max.x - all.min.x, all.max.y - all.min.y,
                                                                all.max.z - all.min.z}));
    const std::vector<SplitNode> split = medianSplit(entries, kLeafSize, 0, SplitTies::ByItem);
    std::vector<uint32_t> order(entries.size());
    for (size_t k = 0; k < entries.size(); ++k) order[k] = entries[k].item;
    tree_ = BoxTree<>(std::move(order), split, [&](uint32_t t, glm::dvec3& lo, glm::dvec3& hi) {
        for (uint32_t v : mesh.triangles[t]) {
            lo = glm::min(lo, P[v]);
            hi = glm::max(hi, P[v]);
        }
    });
}

}  // namespace shadowcull::gpu
