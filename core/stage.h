// The stage interface: a stage looks at a bake window and the chunk's verdict table and
// turns some undecided bits into kept (with a witness) or culled (with a proof). Stages
// run cheap to expensive; each skips bits already decided.
#pragma once

#include <cstdint>
#include <string>
#include <unordered_set>
#include <vector>

#include "core/verdict.h"
#include "core/window.h"
#include "util/status.h"

namespace shadowcull {

struct StageStats {
    double seconds = 0.0;
    uint64_t bitsExamined = 0;  // undecided (group, light) bits the stage looked at
    uint64_t raysCast = 0;
    uint64_t exactTests = 0;  // exact (CGAL) receiver tests
    uint64_t gpuPasses = 0;   // render passes over a light view's targets (GPU stages)
    double gpuSeconds = 0.0;  // GL_TIME_ELAPSED of the GPU stages' passes, where gpuTimed
    bool gpuTimed = false;    // the driver has timer queries (not every stage uses the GPU)
    uint64_t provedKept = 0;
    uint64_t provedCulled = 0;
    void add(const StageStats& o) {
        seconds += o.seconds;
        bitsExamined += o.bitsExamined;
        raysCast += o.raysCast;
        exactTests += o.exactTests;
        gpuPasses += o.gpuPasses;
        gpuSeconds += o.gpuSeconds;
        gpuTimed |= o.gpuTimed;
        provedKept += o.provedKept;
        provedCulled += o.provedCulled;
    }
};

class Stage {
public:
    virtual ~Stage() = default;
    virtual const char* name() const = 0;
    // Errors from the stage's library (Embree, CGAL, GL) come back as ErrorKind::Internal;
    // the table then holds only the decisions made before the failure.
    virtual Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) = 0;
    // The bake is about to free these meshes (it loads chunks as windows need them and drops
    // them after: io/space_source.h). A cache keyed by a mesh's address must forget them
    // now, since a mesh loaded later may get the same address.
    virtual void forgetMeshes(const std::unordered_set<const Mesh*>& meshes) { (void)meshes; }
};

// Sets up the verdict table of the window's centre chunk: one row per model/terrain element
// (skipped ones get no groups), all undecided.
ChunkVerdicts makeChunkVerdicts(const Space& space, const BakeWindow& window);

// The first, cheapest stage (core): decides what the input alone settles, exactly.
//  - castsShadow false: culled (the engine never renders it into a shadow map).
//  - a group with no triangle of non-zero extent (every triangle repeats a vertex): culled.
//  - a point or spot light whose range sphere or cone cannot reach any point of the
//    group's bounding box: culled (condition 3 needs p within range and cone).
// Distances are compared with a margin far above double rounding, so only clear cases
// are culled; everything else is left undecided.
class ReachStage : public Stage {
public:
    // `lightsReach` false: only the input checks (castsShadow, no area), as the original
    // GPU method honoured them; it decides range and cone itself.
    explicit ReachStage(bool lightsReach = true) : lightsReach_(lightsReach) {}
    const char* name() const override { return "reach"; }
    Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) override;

private:
    bool lightsReach_ = true;
};

// Lights that can reach any undecided group of the chunk: the others need no rays.
std::vector<bool> lightsWithUndecided(const ChunkVerdicts& verdicts);

}  // namespace shadowcull
