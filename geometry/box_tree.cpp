#include "geometry/box_tree.h"

#include <algorithm>
#include <atomic>

#include <tbb/task_group.h>

namespace shadowcull::geometry {

namespace {

// Subtrees with fewer items are built on the calling thread.
constexpr uint32_t kParallelBelow = 1u << 14;

}  // namespace

BoxTree::BoxTree(const std::vector<Aabb>& boxes) {
    items_.reserve(boxes.size());
    for (uint32_t k = 0; k < boxes.size(); ++k)
        if (!boxes[k].empty()) items_.push_back({boxes[k], k});
    if (items_.empty()) return;
    // Only nodes of more than kLeafSize items are split, into halves of at least 2, so a
    // leaf holds at least 2 items (or all of them): at most n/2 + 1 leaves, n + 1 nodes.
    // Children's slots are taken from an atomic counter, so large subtrees can be built in
    // parallel; the shape (and so every query's order) does not depend on the threads.
    nodes_.resize(items_.size() + 1);
    std::atomic<uint32_t> used{1};
    struct Builder {
        BoxTree& t;
        std::atomic<uint32_t>& used;
        void build(uint32_t node, uint32_t first, uint32_t count, tbb::task_group* group) {
            Aabb box, centres;
            for (uint32_t i = first; i < first + count; ++i) {
                box.extend(t.items_[i].box);
                centres.extend(0.5 * (t.items_[i].box.min + t.items_[i].box.max));
            }
            Node& n = t.nodes_[node];
            n.box = box;
            n.items = count;
            n.begin = first;
            if (count <= kLeafSize) {
                n.first = first;
                n.count = count;
                return;
            }
            int axis = 0;
            const glm::dvec3 extent = centres.max - centres.min;
            if (extent.y > extent[axis]) axis = 1;
            if (extent.z > extent[axis]) axis = 2;
            const uint32_t half = count / 2;
            auto begin = t.items_.begin() + first;
            std::nth_element(begin, begin + half, begin + count, [axis](const Item& p, const Item& q) {
                return p.box.min[axis] + p.box.max[axis] < q.box.min[axis] + q.box.max[axis];
            });
            const uint32_t left = used.fetch_add(2);
            n.first = left;
            n.count = 0;
            if (group && count >= kParallelBelow) {
                group->run([this, left, first, half, count, group] { build(left + 1, first + half, count - half, group); });
                build(left, first, half, group);
            } else {
                build(left, first, half, group);
                build(left + 1, first + half, count - half, group);
            }
        }
    };
    Builder b{*this, used};
    if (items_.size() >= kParallelBelow) {
        tbb::task_group group;
        b.build(0, 0, uint32_t(items_.size()), &group);
        group.wait();
    } else {
        b.build(0, 0, uint32_t(items_.size()), nullptr);
    }
    nodes_.resize(used.load());
}

const BoxTree& MeshTreeCache::tree(const Mesh& mesh) {
    Entry* e = nullptr;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        std::unique_ptr<Entry>& slot = entries_[&mesh];
        if (!slot) slot = std::make_unique<Entry>();
        e = slot.get();
    }
    std::call_once(e->once, [&] {
        std::vector<Aabb> boxes(mesh.triangles.size());
        for (size_t t = 0; t < mesh.triangles.size(); ++t) {
            const auto& i = mesh.triangles[t];
            const glm::dvec3 &a = mesh.positions[i[0]], &b = mesh.positions[i[1]], &c = mesh.positions[i[2]];
            if (hasRepeatedVertex(a, b, c)) continue;  // left out: never a receiver
            boxes[t].extend(a);
            boxes[t].extend(b);
            boxes[t].extend(c);
        }
        e->tree = BoxTree(boxes);
    });
    return e->tree;
}

void MeshTreeCache::keepOnly(const std::unordered_set<const Mesh*>& meshes) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end();)
        it = meshes.count(it->first) ? std::next(it) : entries_.erase(it);
}

void MeshTreeCache::forget(const std::unordered_set<const Mesh*>& meshes) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Mesh* m : meshes) entries_.erase(m);
}

size_t MeshTreeCache::size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return entries_.size();
}

}  // namespace shadowcull::geometry
