// Median splits: the one builder behind every BoxTree (core/box_tree.h).
//
// A range of more than `leafSize` items is halved at its median (count / 2, the lower half
// left) along the longest side of the box of its items' centres (ties: x, then y). Balanced,
// so that queries' stacks stay shallow (depth about log2(n / leafSize) + 1). The items are
// sorted by a key array of their centres (32 bytes each, moved by nth_element), not by
// indices into the callers' own records: building the trees of a 180,000-triangle mesh
// was a large part of a dense world's first window.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

namespace shadowcull {

struct SplitNode {
    uint32_t begin = 0, end = 0;  // its items: order[begin, end)
    int32_t left = -1;            // inner: the left child's index (the right one's is left + 1); leaf: -1
};

// An item and the centre it is split by.
struct SplitEntry {
    glm::dvec3 centre;
    uint32_t item;
};

// Which side of a split items with equal centres (along its axis) go to.
enum class SplitTies {
    AsFound,  // as nth_element leaves them: depends on the items' order before the split
    ByItem,   // the smaller item first: the halves depend only on the set of entries
};

// Permutes `entries` leaf by leaf and returns the nodes, as below (for callers that have
// no array of centres by item: one array fewer, the size of a dense mesh's triangles).
// With `orderLeaf` below `leafSize`, a leaf's items are further ordered as the splits down
// to leaves of `orderLeaf` would order them, without nodes: the items' order (and so the
// order of every walk over them) is that of the finer tree, with the nodes of the coarser.
std::vector<SplitNode> medianSplit(std::vector<SplitEntry>& entries, uint32_t leafSize, uint32_t orderLeaf = 0,
                                   SplitTies ties = SplitTies::AsFound);

// Permutes `order` (item indices; centres[item] is the item's centre) leaf by leaf and
// returns the nodes: the root first, every child after its parent (a pass from the last
// node back computes children before parents), siblings side by side.
// Node indices, order and shape depend only on the input (not on threads: large subtrees
// are built in parallel, each into slots counted out in advance).
std::vector<SplitNode> medianSplit(std::vector<uint32_t>& order, const std::vector<glm::dvec3>& centres, uint32_t leafSize);

}  // namespace shadowcull
