#include "geometry/box_tree.h"

#include "core/median_split.h"

namespace shadowcull::geometry {

BoxTree::BoxTree(const std::vector<Aabb>& boxes) {
    // The splits (core/median_split.h) over the items with a box; the shape (and so every
    // query's order) does not depend on the threads.
    std::vector<uint32_t> order;
    order.reserve(boxes.size());
    std::vector<glm::dvec3> centres(boxes.size());
    for (uint32_t k = 0; k < boxes.size(); ++k) {
        if (boxes[k].empty()) continue;  // left out
        order.push_back(k);
        centres[k] = 0.5 * (boxes[k].min + boxes[k].max);
    }
    if (order.empty()) return;
    const std::vector<SplitNode> split = medianSplit(order, centres, kLeafSize);
    items_.resize(order.size());
    for (size_t k = 0; k < order.size(); ++k) items_[k] = {boxes[order[k]], order[k]};
    // Boxes bottom up (children after parents in `split`).
    nodes_.resize(split.size());
    for (size_t k = split.size(); k-- > 0;) {
        const SplitNode& s = split[k];
        Node& n = nodes_[k];
        if (s.left < 0) {
            n.first = s.begin;
            n.count = s.end - s.begin;
            for (uint32_t i = s.begin; i < s.end; ++i) n.box.extend(items_[i].box);
        } else {
            n.first = uint32_t(s.left);
            n.count = 0;
            n.box = nodes_[n.first].box;
            n.box.extend(nodes_[n.first + 1].box);
        }
    }
}

}  // namespace shadowcull::geometry
