// Median splits (core/median_split.h).

#include "core/median_split.h"

#include <algorithm>
#include <limits>
#include <unordered_map>

#include <glm/common.hpp>
#include <tbb/task_group.h>

namespace shadowcull {

namespace {

// Subtrees with fewer items are built on the calling thread.
constexpr uint32_t kParallelFrom = 1u << 14;

using Entry = SplitEntry;

class Splitter {
public:
    Splitter(std::vector<Entry>& entries, std::vector<SplitNode>& nodes, uint32_t leafSize, uint32_t orderLeaf, SplitTies ties)
        : entries_(entries), nodes_(nodes), leafSize_(leafSize), orderLeaf_(std::max(orderLeaf, 1u)), ties_(ties) {}

    // Nodes of a subtree over `count` items (1 for a leaf): what the slots are counted by.
    uint32_t subtreeNodes(uint32_t count) {
        if (count <= leafSize_) return 1;
        // At most two distinct counts per level: a few entries, computed before any thread
        // starts (the root's call fills the table for every count below it).
        const auto it = memo_.find(count);
        if (it != memo_.end()) return it->second;
        const uint32_t n = 1 + subtreeNodes(count / 2) + subtreeNodes(count - count / 2);
        memo_.emplace(count, n);
        return n;
    }

    // Builds node `node` over entries [begin, end), its children at slots childSlot and
    // childSlot + 1, their descendants after them.
    void build(uint32_t node, uint32_t begin, uint32_t end, uint32_t childSlot, tbb::task_group* group) {
        SplitNode& n = nodes_[node];
        n.begin = begin;
        n.end = end;
        const uint32_t count = end - begin;
        if (count <= leafSize_) {
            orderWithin(begin, end);
            return;
        }
        const uint32_t mid = split(begin, end);
        n.left = int32_t(childSlot);
        const uint32_t left = childSlot, right = childSlot + 1;
        const uint32_t leftSlot = childSlot + 2;
        const uint32_t rightSlot = leftSlot + lookup(mid - begin) - 1;
        if (group && count >= kParallelFrom) {
            group->run([=] { build(right, mid, end, rightSlot, group); });
            build(left, begin, mid, leftSlot, group);
        } else {
            build(left, begin, mid, leftSlot, group);
            build(right, mid, end, rightSlot, group);
        }
    }

private:
    // Orders a leaf's items as the splits down to leaves of orderLeaf would.
    void orderWithin(uint32_t begin, uint32_t end) {
        if (end - begin <= orderLeaf_) return;
        const uint32_t mid = split(begin, end);
        orderWithin(begin, mid);
        orderWithin(mid, end);
    }

    // Halves [begin, end) at its median along the longest side of its centres' box;
    // returns where the right half starts.
    uint32_t split(uint32_t begin, uint32_t end) {
        glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
        for (uint32_t k = begin; k < end; ++k) {
            lo = glm::min(lo, entries_[k].centre);
            hi = glm::max(hi, entries_[k].centre);
        }
        const glm::dvec3 side = hi - lo;
        const int axis = side.x >= side.y && side.x >= side.z ? 0 : side.y >= side.z ? 1 : 2;
        const uint32_t mid = begin + (end - begin) / 2;
        const auto first = entries_.begin() + begin, nth = entries_.begin() + mid, last = entries_.begin() + end;
        if (ties_ == SplitTies::ByItem)
            std::nth_element(first, nth, last, [axis](const Entry& a, const Entry& b) {
                return a.centre[axis] < b.centre[axis] || (a.centre[axis] == b.centre[axis] && a.item < b.item);
            });
        else
            std::nth_element(first, nth, last, [axis](const Entry& a, const Entry& b) { return a.centre[axis] < b.centre[axis]; });
        return mid;
    }

    // subtreeNodes() once the table is filled: read-only, safe from any thread.
    uint32_t lookup(uint32_t count) const { return count <= leafSize_ ? 1 : memo_.at(count); }

    std::vector<Entry>& entries_;
    std::vector<SplitNode>& nodes_;
    const uint32_t leafSize_;
    const uint32_t orderLeaf_;  // leaves' items are ordered down to ranges of this many
    const SplitTies ties_;
    std::unordered_map<uint32_t, uint32_t> memo_;
};

}  // namespace

std::vector<SplitNode> medianSplit(std::vector<SplitEntry>& entries, uint32_t leafSize, uint32_t orderLeaf, SplitTies ties) {
    std::vector<SplitNode> nodes;
    if (entries.empty()) return nodes;
    leafSize = std::max(leafSize, 1u);
    Splitter s(entries, nodes, leafSize, orderLeaf == 0 ? leafSize : std::min(orderLeaf, leafSize), ties);
    nodes.resize(s.subtreeNodes(uint32_t(entries.size())));
    if (entries.size() >= kParallelFrom) {
        tbb::task_group group;
        s.build(0, 0, uint32_t(entries.size()), 1, &group);
        group.wait();
    } else {
        s.build(0, 0, uint32_t(entries.size()), 1, nullptr);
    }
    return nodes;
}

std::vector<SplitNode> medianSplit(std::vector<uint32_t>& order, const std::vector<glm::dvec3>& centres, uint32_t leafSize) {
    std::vector<SplitEntry> entries(order.size());
    for (size_t k = 0; k < order.size(); ++k) entries[k] = {centres[order[k]], order[k]};
    std::vector<SplitNode> nodes = medianSplit(entries, leafSize);
    for (size_t k = 0; k < order.size(); ++k) order[k] = entries[k].item;
    return nodes;
}

}  // namespace shadowcull
