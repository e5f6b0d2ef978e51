// Which chunks a bake window holds. Receivers are every surface of the space
// (../shared/spec/semantics.md): a shadow that leaves the `neighbours` rectangle around the
// baked chunk still lands, and the engine draws it. So the analytic bake's window is the
// baked chunk and every chunk that holds a receiver its shadows can reach or an occluder
// between it and a light, found on the scan's summaries (each chunk's world-space box)
// before any of them is loaded:
//
//  - a directional light: the centre chunk's box swept along the light's direction (its
//    shadow column, widened by the light's filterRadius and normalBias) meets the chunk's
//    box. The column runs on until it has passed every box of the space (below the lowest
//    surface for a downward light), so a chunk it misses holds no receiver anywhere.
//    Swept the other way (towards the light), the box meets every chunk holding an
//    occluder between the centre chunk and the light.
//  - a point or spot light: every chunk whose box lies within the light's range (and, for
//    a spot light, meets its cone): q and p both lie there (condition 3), and so does
//    every occluder between them and the light.
//
// The window is a function of the centre chunk and the space alone: `neighbours` neither
// limits it nor adds to it, so a bake gives the same bits whatever `neighbours` says (it is
// a window for work in the original tool, not for the answer: scene-format.md). Chunks of
// the rectangle that no column meets can hold neither a receiver nor an occluder.
// Conservative: a chunk is left out only when its box is farther from the column than a
// margin far above the rounding of the test (1 mm plus 1e-9 of the coordinates), so every
// receiver a shadow reaches is loaded. `--method gpu` (the original tool's method) keeps the
// rectangle: there `neighbours` keeps its old meaning.
#pragma once

#include <algorithm>
#include <map>
#include <vector>

#include "core/scene.h"
#include "core/window.h"

namespace shadowcull {

// One chunk file as the scan read it (io/space_source.h fills them).
struct ChunkEntry {
    std::string path;
    uint64_t contentHash = 0;  // of the bytes the scan read (ChunkFile::contentHash)
    uint64_t contentWithoutShadowsHash = 0;  // the same bytes without the bake's output (ChunkFile)
    size_t usableObjects = 0;  // objects not skipped
    // Hash of what the stages read of it (bake --resume, shards): every object's element,
    // kind, resource, uuid, flags and placement, and its mesh's or heightfield's content.
    uint64_t objectsHash = 0;
    // World-space box of every usable object's triangles (conservative: from the resources'
    // vertex boxes, placed with a margin); empty when none. Planning windows (core/
    // window_plan.h) needs only this of the chunks a window does not hold.
    Aabb wsBounds;
    uint64_t triangles = 0;  // of the usable objects' meshes and terrains (placements counted each)
};

// How far one light's shadows took a window beyond the `neighbours` rectangle.
struct LightReach {
    size_t chunksBeyond = 0;  // chunks loaded for this light outside the rectangle
    int ringsBeyond = 0;      // the farthest of them, in chunk rings past the rectangle
    std::vector<ChunkCoord> beyond;  // one window's: those chunks, in grid order (not summed)
};

struct WindowPlan {
    std::vector<ChunkCoord> chunks;  // grid order (ChunkCoord's), each once, the centre included
    // How far the shadows and occluders took the window past the `neighbours` rectangle
    // (what a window of the original tool would have missed), per light in light order.
    std::vector<LightReach> lights;
    size_t chunksBeyond = 0;         // chunks outside the rectangle, any light
};

// A bake's windows together (the summary's "shadows beyond the window" line).
struct ReachTotals {
    size_t windows = 0;
    size_t chunks = 0;                        // chunks the windows held, summed
    size_t chunksBeyond = 0;                  // of those, outside the rectangle (any light)
    std::vector<LightReach> lights;           // per light: chunks summed, rings the most
    std::vector<size_t> windowsBeyond;        // per light: windows it took past the rectangle
    void add(const WindowPlan& plan) {
        ++windows;
        chunks += plan.chunks.size();
        chunksBeyond += plan.chunksBeyond;
        if (lights.size() < plan.lights.size()) lights.resize(plan.lights.size()), windowsBeyond.resize(plan.lights.size());
        for (size_t i = 0; i < plan.lights.size(); ++i) {
            lights[i].chunksBeyond += plan.lights[i].chunksBeyond;
            lights[i].ringsBeyond = std::max(lights[i].ringsBeyond, plan.lights[i].ringsBeyond);
            windowsBeyond[i] += plan.lights[i].chunksBeyond ? 1 : 0;
        }
    }
};

// What planning a window needs to know of the whole space besides the chunks near it: a
// shard given a plan (shadowcull plan) holds the summaries of only the chunks its windows
// reach, and plans its windows with the whole space's bounds, as a full scan would.
struct SpaceBounds {
    Aabb wsSpace;          // every chunk's box (metres, world space)
    double overhang = 0;   // how far (metres, x or z) any chunk's box leaves its square
    bool operator==(const SpaceBounds& o) const {
        return wsSpace.min == o.wsSpace.min && wsSpace.max == o.wsSpace.max && overhang == o.overhang;
    }
};
SpaceBounds spaceBoundsOf(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks);

class WindowPlanner {
public:
    // `wholeSpace` false: every window is the `neighbours` rectangle (the original method).
    // `chunks`: the scan's summaries (SpaceSource::chunks()); they must outlive the planner.
    WindowPlanner(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks, bool wholeSpace);
    // The same with the whole space's bounds given: `chunks` may then be only those the
    // windows planned reach (and their rectangles), and plan() says what it would say on
    // every chunk of the space.
    WindowPlanner(const SpaceSettings& settings, const std::map<ChunkCoord, ChunkEntry>& chunks, bool wholeSpace,
                  const SpaceBounds& bounds);
    WindowPlan plan(ChunkCoord centre) const;
    bool wholeSpace() const { return wholeSpace_; }

private:
    // Chunks of the space whose boxes may meet the box `wsQuery` (over their squares,
    // widened by the largest overhang): the candidates an exact test then looks at.
    template <class Visit>
    void forChunksNear(const Aabb& wsQuery, const Visit& visit) const;
    void addDirectional(const Light& L, const Aabb& wsCentre, const glm::dvec3& towards, std::vector<ChunkCoord>& out) const;
    void addLocal(const Light& L, std::vector<ChunkCoord>& out) const;

    const SpaceSettings& settings_;
    const std::map<ChunkCoord, ChunkEntry>& chunks_;
    bool wholeSpace_ = true;
    Aabb wsSpace_;          // every chunk's box (SpaceBounds)
    double overhang_ = 0;   // how far (metres, x or z) any chunk's box leaves its square
    int gx0_ = 0, gx1_ = -1, gz0_ = 0, gz1_ = -1;  // the grid's extent, chunk coordinates
};

}  // namespace shadowcull
