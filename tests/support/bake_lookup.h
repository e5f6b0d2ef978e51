// Shared by the end-to-end tests: the known-answer scenes by name, and finding the
// decision of "the same object" (by its builder location) in a bake result.
#pragma once

#include <functional>
#include <vector>

#include "cli/pipeline.h"
#include "tests/support/space_builder.h"

namespace shadowcull::testing {

struct NamedScene {
    const char* name;
    std::function<SpaceBuilder()> make;
};

// The builder's known-answer scenes (space_builder.h), each with its expectations.
inline const std::vector<NamedScene>& knownAnswerScenes() {
    static const std::vector<NamedScene> s = {
        {"cubeOnTerrain", cubeOnTerrain},
        {"twoFloatingCubes", twoFloatingCubes},
        {"rangeAndCone", rangeAndCone},
        {"thinRod", thinRod},
        {"twoLightsMasks", twoLightsMasks},
        {"hiddenUnderOpaqueRoof", [] { return hiddenUnderRoof(Roof::Opaque); }},
        {"hiddenUnderAlphaRoof", [] { return hiddenUnderRoof(Roof::AlphaTested); }},
        {"underNonCastingRoof", [] { return hiddenUnderRoof(Roof::CastsNoShadow); }},
        {"cubeOverNonCastingFloor", cubeOverNonCastingFloor},
        {"cubeBesideWall", [] { return cubeBesideWall(0.0); }},
        {"cubeBesideWallNormalBias", [] { return cubeBesideWall(0.1); }},
        {"longShadowLandsThreeChunksAway", [] { return longShadowOverChunks(LongShadow::LandsThreeChunksAway); }},
        {"longShadowFallsInAGap", [] { return longShadowOverChunks(LongShadow::FallsInAGap); }},
        {"longShadowLeavesTheSpace", [] { return longShadowOverChunks(LongShadow::LeavesTheSpace); }},
        {"lampTwoChunksOver", lampTwoChunksOver},
    };
    return s;
}

// The decision for (object at `loc`, group, light), or nullptr when there is none.
inline const Decision* findDecision(const cli::BakeResult& r, const ObjectLocation& loc, int group, int light) {
    for (const ChunkVerdicts& cv : r.chunks) {
        if (chunkFileName(cv.coord) != loc.chunkFile) continue;
        for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
            const ObjectVerdicts& ov = cv.objects[oi];
            if (ov.elementIndex != loc.elementIndex) continue;
            if (group >= ov.groupCount || light >= cv.lightCount) return nullptr;
            return &cv.at(oi, group, light);
        }
    }
    return nullptr;
}

}  // namespace shadowcull::testing
