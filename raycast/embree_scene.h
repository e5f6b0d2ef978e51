// Embree scenes of bake windows, shared by the raycast stage and the bench's bare-Embree
// loops (so both trace the same scene): one prototype scene per mesh (models) and per
// heightfield (terrain), built once and kept for the whole bake, placed in each window by
// instances. Moving the window to the next chunk rebuilds only the window's top-level
// trees over its instances (about 2 ms for 2,500 instances); every mesh's own tree stays.
// The instance ID of a window object is its index in BakeWindow::objects
// (hit.instID[0]). Internal to raycast/ and bench/: it
// exposes Embree types.
#pragma once

#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <embree3/rtcore.h>

#include "core/window.h"

namespace shadowcull::raycast {

// A window's two scenes. `all`: every triangle, for closest hits (p with the transparency
// filter, the receivers behind it without). `opaque`: the triangles that block light, for
// occlusion tests (no filter needed, so Embree's packet kernels run unhindered): the
// instances without their alpha-tested triangles, and without the objects that cast no
// shadow (WindowObject::castsShadow). The same scene twice when everything in the window
// blocks light. A closest hit in `opaque` names the triangle by its index among the
// mesh's opaque ones: meshTriangle maps it back. Move-only; releases both.
class WindowScene {
public:
    // Per window object: the mesh triangle of each of its triangles in `opaque`, in order;
    // null where those are all of the mesh's (no alpha-tested group).
    using TriangleMap = std::shared_ptr<const std::vector<uint32_t>>;

    WindowScene() = default;
    WindowScene(RTCScene all, RTCScene opaque, std::vector<TriangleMap> opaqueTriangles = {})
        : all_(all), opaque_(opaque), opaqueTriangles_(std::move(opaqueTriangles)) {}
    ~WindowScene() { reset(); }
    WindowScene(WindowScene&& o) noexcept
        : all_(o.all_), opaque_(o.opaque_), opaqueTriangles_(std::move(o.opaqueTriangles_)) {
        o.all_ = o.opaque_ = nullptr;
    }
    WindowScene& operator=(WindowScene&& o) noexcept {
        if (this != &o) {
            reset();
            all_ = o.all_;
            opaque_ = o.opaque_;
            opaqueTriangles_ = std::move(o.opaqueTriangles_);
            o.all_ = o.opaque_ = nullptr;
        }
        return *this;
    }
    // The mesh triangle of object `object`'s triangle `prim` in `opaque`.
    uint32_t meshTriangle(uint32_t object, uint32_t prim) const {
        const TriangleMap* map = object < opaqueTriangles_.size() ? &opaqueTriangles_[object] : nullptr;
        return map && *map ? (**map)[prim] : prim;
    }
    WindowScene(const WindowScene&) = delete;
    WindowScene& operator=(const WindowScene&) = delete;
    RTCScene all() const { return all_; }
    RTCScene opaque() const { return opaque_; }
    void reset() {
        if (opaque_ && opaque_ != all_) rtcReleaseScene(opaque_);
        if (all_) rtcReleaseScene(all_);
        all_ = opaque_ = nullptr;
        opaqueTriangles_.clear();
    }

private:
    RTCScene all_ = nullptr, opaque_ = nullptr;
    std::vector<TriangleMap> opaqueTriangles_;
};

class EmbreeScenes {
public:
    explicit EmbreeScenes(RTCDevice device) : device_(device) {}
    ~EmbreeScenes();
    EmbreeScenes(const EmbreeScenes&) = delete;
    EmbreeScenes& operator=(const EmbreeScenes&) = delete;

    // The committed scenes of the window: its missing prototypes built in parallel, then
    // its two top-level trees side by side. Prototypes of meshes the window does not hold
    // are released (those of the previous window that it left behind). Not reentrant.
    WindowScene buildWindow(const BakeWindow& window);
    size_t prototypeCount() const { return prototypes_.size(); }
    // Rays traced in the scenes since the last call (the raycast stage, after each search):
    // what tells when a compact prototype has cost its rays more than its build saved.
    void noteRays(uint64_t rays) { rays_ += rays; }
    // Whether the mesh's prototype is built compact now (tests, the bench).
    bool isCompact(const Mesh* mesh) const {
        auto it = prototypes_.find(mesh);
        return it != prototypes_.end() && it->second.compact;
    }

    // Dense prototypes are built compact (Embree's RTC_SCENE_FLAG_COMPACT: the leaves hold
    // vertex indices, not copies): on a 180,000-triangle scan the build is about 40 % faster
    // and 27 bytes a triangle smaller, each closest-hit ray through it about 17 % slower. A
    // dense mesh's build is most of a first window's ray tracing, and a bake of a few
    // windows traces far fewer rays through it than its triangles; a long bake traces more,
    // so once the rays traced since the build reach kFullAfterRays per triangle (as if each
    // went through it: the extra time then bounded by about twice the build time saved),
    // the prototype is built again in full, for the rest of the bake. Verdicts and evidence
    // do not depend on it (the same triangles, the same robust intersection).
    static constexpr size_t kCompactFrom = size_t(1) << 16;  // triangles
    static constexpr uint64_t kFullAfterRays = 8;            // per triangle
    // Releases the prototypes of `meshes` (about to be freed).
    void forget(const std::unordered_set<const Mesh*>& meshes);

private:
    // A mesh's scenes, in mesh coordinates less `offset` (terrain: its rounded middle
    // height, so that a lifted terrain gives the same floats; models: zero). `opaque`:
    // without the alpha-tested triangles (== `all` when there are none; nullptr when
    // every triangle is alpha-tested). `opaqueTriangles`: the mesh triangles of
    // `opaque`'s, when it is not `all`.
    struct Prototype {
        RTCScene all = nullptr, opaque = nullptr;
        WindowScene::TriangleMap opaqueTriangles;
        glm::dvec3 offset{0.0};
        bool compact = false;
        uint64_t raysAtBuild = 0;  // rays_ when it was built
    };
    Prototype buildPrototype(const Mesh* mesh, bool terrain) const;
    // A prototype for every mesh of the window that has none.
    void buildPrototypes(const BakeWindow& w);
    void release(Prototype& proto);
    RTCScene placeAll(const BakeWindow& w, bool opaque) const;
    RTCDevice device_;
    std::unordered_map<const Mesh*, Prototype> prototypes_;
    uint64_t rays_ = 0;                     // noteRays, summed
    std::unordered_set<const Mesh*> full_;  // meshes whose compact prototype was replaced
};

// The index in BakeWindow::objects of the object a hit lies on.
inline uint32_t hitObject(unsigned instID, unsigned geomID) {
    return instID != RTC_INVALID_GEOMETRY_ID ? instID : geomID;
}

// The context for finding p: rejects hits on surfaces that let light pass (alpha-tested
// groups, objects that cast no shadow: WindowObject::blocksLight), except on the group
// whose witness is sought (its own alpha-tested triangles are p). Install with
// ctx.filter = &skipTransparent only when the window has such surfaces
// (needsTransparencyFilter).
struct TransparentSkip {
    RTCIntersectContext ctx;  // first member: Embree passes &ctx back to the filter
    const BakeWindow* window = nullptr;
    uint32_t object = 0, group = 0;
};
void skipTransparent(const RTCFilterFunctionNArguments* args);
inline bool needsTransparencyFilter(const BakeWindow& w) { return w.hasAlphaTested || w.hasNonCasters; }

}  // namespace shadowcull::raycast
