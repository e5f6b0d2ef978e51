// geometry/: proves "nothing can receive" exactly (semantics.md, the second way a shadow
// is meaningless: it falls on nothing). For each undecided (group, light), the group's
// shadow volume (union of its triangles' exact frusta, exact_frustum.h) is tested against
// every loaded receiver triangle that survives the receiver rules; no receiver at all
// proves 0. Otherwise the bit stays undecided.
//
// Shadow volumes: F. C. Crow, "Shadow Algorithms for Computer Graphics", SIGGRAPH 1977.
#pragma once

#include <array>
#include <vector>

#include <glm/vec3.hpp>

#include "core/stage.h"
#include "geometry/broad_phase.h"

namespace shadowcull::geometry {

struct GeometryOptions {
    // Test mode: also examine bits the raycast stage kept, and fail with an internal error
    // if a bit with a witness would be proved 0 (the two stages must never disagree).
    bool crossCheckWitnesses = false;
    // Test mode: the reference the fast path must equal. Every receiver of the window goes
    // to the exact test (no light-space hierarchy, no world grid, no double filters).
    bool exhaustive = false;
    // Receiver meshes of at least this many triangles have their tree's nodes tested against
    // the terrain (pruning subtrees wholly buried, and those whose part not buried lies in
    // front of the caster); smaller ones only at their leaves, whose rules are cached and
    // cost less. Tests lower it to run the node rules on small meshes.
    size_t nodeTerrainRuleFrom = 1024;
};

// A lower bound of the bias the light `L` gives the receiver triangle `tri` (window-local
// metres): beta = bias + slopeBias tan(theta) for a directional light, theta the angle
// between its direction and the triangle's normal (exact for the double inputs), the bias
// alone for point and spot lights (semantics.md). Never above the exact beta; never below
// the bias. Where the slope term cannot be bounded usefully (a needle too thin for double,
// a receiver within 1e-6 of edge-on to the light) it is left out.
double biasLowerBound(const Light& L, const std::array<glm::dvec3, 3>& tri);

class GeometryStage : public Stage {
public:
    explicit GeometryStage(GeometryOptions options = {}) : options_(options) {}
    const char* name() const override { return "geometry"; }
    // Decides nothing for a window with skipped objects: an object that could not be
    // loaded might have been a receiver.
    Status run(const BakeWindow& window, ChunkVerdicts& verdicts, StageStats& stats) override;

    // The bits of the last window left undecided, each with a point (window-local) of the
    // candidate receiver its shadow volume reaches (above the ground where the terrain rule
    // applies): where a witness ray may be aimed (cli/pipeline.cpp does). Sorted.
    struct Candidate {
        size_t object = 0;  // index into ChunkVerdicts::objects
        int group = 0, light = 0;
        glm::dvec3 lsPoint{0.0};  // a point of the receiver the shadow volume reaches
        // The receiver it lies on: window object and mesh triangle (where a normal bias moves
        // the lookup point off the surface, the witness rays test that triangle's moved copy).
        uint32_t receiverObject = 0, receiverTriangle = 0;
    };
    const std::vector<Candidate>& candidates() const { return candidates_; }

private:
    GeometryOptions options_;
    std::vector<Candidate> candidates_;
};

}  // namespace shadowcull::geometry
