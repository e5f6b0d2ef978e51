// A mesh's triangles in a box hierarchy, mesh coordinates (see mesh_tree.h).
#include "gpu/mesh_tree.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "core/mesh.h"

namespace shadowcull::gpu {

namespace {

// Box padding, relative to the mesh's size (largest |coordinate| plus extent): far above
// the rounding of the vertices' placement (~1e-16 relative), far below anything a pixel
// test can tell (the hull tests keep a pixel and more to spare).
constexpr double kPad = 1e-9;

}  // namespace

MeshTree::MeshTree(const Mesh& mesh) {
    const auto& P = mesh.positions;
    Aabb all;
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        const auto& tri = mesh.triangles[t];
        if (hasRepeatedVertex(P[tri[0]], P[tri[1]], P[tri[2]])) continue;
        triangles_.push_back(uint32_t(t));
        for (uint32_t v : tri) all.extend(P[v]);
    }
    if (triangles_.empty()) return;
    const glm::dvec3 mag = glm::max(glm::abs(all.min), glm::abs(all.max));
    const double pad = kPad * (std::max({mag.x, mag.y, mag.z}) + std::max({all.max.x - all.min.x, all.max.y - all.min.y,
                                                                              all.max.z - all.min.z}));
    std::vector<glm::dvec3> centre(mesh.triangles.size());
    for (uint32_t t : triangles_) {
        const auto& tri = mesh.triangles[t];
        centre[t] = (P[tri[0]] + P[tri[1]] + P[tri[2]]) / 3.0;
    }
    order_ = triangles_;
    nodes_.reserve(2 * (triangles_.size() / kLeafSize + 1));
    // Median splits along the longest axis of the centres: depth ~log2(n / kLeafSize).
    struct Job {
        uint32_t node, first, count;
    };
    std::vector<Job> jobs;
    nodes_.emplace_back();
    jobs.push_back({0, 0, uint32_t(order_.size())});
    while (!jobs.empty()) {
        const Job j = jobs.back();
        jobs.pop_back();
        Aabb box, centres;
        for (uint32_t i = j.first; i < j.first + j.count; ++i) {
            const auto& tri = mesh.triangles[order_[i]];
            for (uint32_t v : tri) box.extend(P[v]);
            centres.extend(centre[order_[i]]);
        }
        nodes_[j.node].box = {box.min - glm::dvec3(pad), box.max + glm::dvec3(pad)};
        if (j.count <= kLeafSize) {
            nodes_[j.node].first = j.first;
            nodes_[j.node].count = j.count;
            continue;
        }
        const glm::dvec3 size = centres.max - centres.min;
        const int axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
        const uint32_t half = j.count / 2;
        auto begin = order_.begin() + j.first;
        std::nth_element(begin, begin + half, begin + j.count, [&](uint32_t a, uint32_t b) {
            return centre[a][axis] < centre[b][axis] || (centre[a][axis] == centre[b][axis] && a < b);
        });
        const uint32_t left = uint32_t(nodes_.size());
        nodes_.emplace_back();
        const uint32_t right = uint32_t(nodes_.size());
        nodes_.emplace_back();
        nodes_[j.node].first = left;
        nodes_[j.node].right = right;
        jobs.push_back({right, j.first + half, j.count - half});
        jobs.push_back({left, j.first, half});
    }
}

}  // namespace shadowcull::gpu
