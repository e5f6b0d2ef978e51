// The GPU confirmation's surfaces for one light: an object's occluder sheets and receiver
// triangles (confirm_stage.cpp, points 3 and 4), found from the triangles that can reach
// the examined pixels alone (SelectionTree selects them) instead of from every triangle of the
// object.
//
// A sheet is a connected component of the WHOLE mesh's triangles of one class (one facing
// towards the light), joined across edges shared by exactly two of them running the edge
// in opposite directions. It is found by walking from the selected triangles across such
// edges, so it is the same component the whole mesh gives (its extent beyond the selection
// is walked too: the component decides which edges are cracks). Of a sheet, only the
// selected triangles and the crack edges of selected triangles are listed: any other
// triangle or crack lies within a triangle whose every piece misses the examined pixels in
// every view, so the pieces drawn are exactly those the whole classification gave
// (tests/gpu_test.cpp, TreeSelectionChangesNothing).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"

namespace shadowcull::gpu {

struct MeshEdges;  // gpu/conservative.h

struct TriRef {
    uint32_t object, triangle;
};

// A connected opaque sheet of one object: triangles facing the same way (so the same
// orientation on screen), joined across edges shared by exactly two of them.
struct Sheet {
    std::vector<TriRef> triangles;  // the selected ones, ascending
    std::vector<TriRef> cracks;     // (object, edge index), ascending
    uint32_t firstTriangle = 0;     // the smallest mesh triangle of the whole component (orders the sheets)
};

// One object's part for one light: its occluder sheets and receiver triangles.
struct ObjectSurfaces {
    std::vector<Sheet> sheets;       // ordered by firstTriangle (as a whole-mesh pass lists them)
    std::vector<TriRef> receivers;   // selected triangles that may receive, ascending
};

// What a light asks of a surface.
struct SurfaceLight {
    const Light* light = nullptr;  // window-local
    bool anyReceiver = false;      // receivers unbounded: none are listed
};

// The sheets and receivers of window object k among its `selected` triangles (ascending mesh
// triangle indices with three distinct vertices), with `edges` the mesh's adjacency over all
// such triangles.
ObjectSurfaces objectSurfaces(const BakeWindow& w, uint32_t k, const SurfaceLight& sl, const MeshEdges& edges,
                              const std::vector<uint32_t>& selected);

}  // namespace shadowcull::gpu
