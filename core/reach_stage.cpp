// ReachStage: the bits the input alone decides (see core/stage.h).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include <glm/geometric.hpp>

#include "core/light_reach.h"
#include "core/stage.h"
#include "util/format.h"
#include "util/stop_request.h"

namespace shadowcull {

ChunkVerdicts makeChunkVerdicts(const Space& space, const BakeWindow& window) {
    ChunkVerdicts cv;
    cv.coord = window.centre;
    cv.path = window.centrePath;
    cv.lightCount = int(space.settings.lights.size());
    auto it = space.chunks.find(window.centre);
    if (it == space.chunks.end()) return cv;
    std::unordered_map<const ChunkObject*, int> loaded;  // centre objects in the window
    for (size_t k = 0; k < window.objects.size(); ++k)
        if (window.objects[k].centre) loaded[window.objects[k].source] = int(k);
    for (const ChunkObject& o : it->second.objects) {
        ObjectVerdicts ov;
        ov.elementIndex = o.elementIndex;
        ov.terrain = o.kind == ChunkObject::Kind::Terrain;
        ov.uuid = o.uuid;
        auto found = loaded.find(&o);
        if (found != loaded.end()) ov.windowObject = found->second;
        if (ov.windowObject >= 0) {
            ov.groupCount = int(window.objects[size_t(ov.windowObject)].mesh->groups.size());
            ov.decisions.resize(size_t(ov.groupCount) * size_t(cv.lightCount));
            const WindowObject& wo = window.objects[size_t(ov.windowObject)];
            ov.wsGroupBounds.assign(size_t(ov.groupCount), {glm::dvec3(1e300), glm::dvec3(-1e300)});
            // Per unique mesh, not per triangle (core/mesh_index.h).
            ov.groupTriangles = vertexIndex(*wo.mesh).groupTriangles;
            for (int g = 0; g < ov.groupCount; ++g) {
                // The window-local box moved to the world: bit for bit the box of each vertex
                // moved (adding a constant rounds monotonically, so it keeps the extremes).
                const Aabb ls = lsGroupBounds(wo, uint32_t(g), false);
                if (!ls.empty()) ov.wsGroupBounds[size_t(g)] = {ls.min + window.wsOrigin, ls.max + window.wsOrigin};
            }
        }
        cv.objects.push_back(std::move(ov));
    }
    return cv;
}

std::vector<bool> lightsWithUndecided(const ChunkVerdicts& verdicts) {
    std::vector<bool> any(size_t(verdicts.lightCount), false);
    for (const ObjectVerdicts& ov : verdicts.objects)
        for (size_t k = 0; k < ov.decisions.size(); ++k)
            if (ov.decisions[k].verdict == Verdict::Undecided) any[k % size_t(verdicts.lightCount)] = true;
    return any;
}

Status ReachStage::run(const BakeWindow& window, ChunkVerdicts& cv, StageStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    // One "beyond the range" reason per light, shared by every bit it decides (most bits of
    // a large world are decided here; their reason costs no memory of its own).
    std::vector<std::shared_ptr<const Evidence>> beyondRange(window.lsLights.size());
    for (size_t l = 0; l < beyondRange.size(); ++l)
        beyondRange[l] = std::make_shared<const Evidence>(
            Evidence{"the group lies beyond the light's range (" + formatNumber(window.lsLights[l].range) + " m)", {}, {}});
    for (size_t oi = 0; oi < cv.objects.size(); ++oi) {
        // A chunk of 50,000 objects takes seconds here: a signal stops it (the bits left
        // undecided are never written).
        if (oi % 1024 == 0)
            if (Status s = stopStatus(); !s) return s;
        ObjectVerdicts& ov = cv.objects[oi];
        if (ov.windowObject < 0) continue;
        const WindowObject& wo = window.objects[size_t(ov.windowObject)];
        // Window-local bounds of each group's triangles that have extent (from the mesh's
        // vertex trees: a few leaves, not every triangle).
        std::vector<Aabb> groupBounds(size_t(ov.groupCount));
        for (int g = 0; g < ov.groupCount; ++g) groupBounds[size_t(g)] = lsGroupBounds(wo, uint32_t(g), true);
        const bool castsShadow = wo.source->castsShadow;
        for (int g = 0; g < ov.groupCount; ++g) {
            for (int l = 0; l < cv.lightCount; ++l) {
                Decision& d = cv.at(oi, g, l);
                if (d.verdict != Verdict::Undecided) continue;
                ++stats.bitsExamined;
                const Light& L = window.lsLights[size_t(l)];
                const Aabb& gb = groupBounds[size_t(g)];
                if (!castsShadow) {
                    decide(d, Verdict::Culled, "input", reasons::kCastsShadowFalse);
                } else if (gb.empty()) {
                    decide(d, Verdict::Culled, "input", "the group has no triangle with three distinct vertices");
                } else if (!lightsReach_) {
                    continue;
                } else if (boxBeyondRange(L, gb)) {
                    decide(d, Verdict::Culled, name(), beyondRange[size_t(l)]);
                } else if (boxOutsideCone(L, gb)) {
                    decide(d, Verdict::Culled, name(), "the group lies outside the light's cone");
                } else {
                    continue;
                }
                ++stats.provedCulled;
            }
        }
    }
    stats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Status::ok();
}

}  // namespace shadowcull
