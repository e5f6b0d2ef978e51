// Embree scenes of bake windows, shared by the raycast stage and the bench's bare-Embree
// loops (so both trace the same scene): one prototype scene per mesh, built once and kept
// for the whole bake, placed in each window by instances; terrain as plain triangles.
// The geometry ID of a window object is its index in BakeWindow::objects (an instance's
// in hit.instID[0], a terrain's in hit.geomID). Internal to raycast/ and bench/: it
// exposes Embree types.
#pragma once

#include <unordered_map>

#include <embree3/rtcore.h>

#include "core/window.h"

namespace shadowcull::raycast {

class EmbreeScenes {
public:
    explicit EmbreeScenes(RTCDevice device) : device_(device) {}
    ~EmbreeScenes();
    EmbreeScenes(const EmbreeScenes&) = delete;
    EmbreeScenes& operator=(const EmbreeScenes&) = delete;

    // The committed scene of the window; the caller releases it (rtcReleaseScene).
    RTCScene buildWindow(const BakeWindow& window);

private:
    RTCScene prototype(const Mesh* mesh);
    RTCDevice device_;
    std::unordered_map<const Mesh*, RTCScene> prototypes_;
};

// The index in BakeWindow::objects of the object a hit lies on.
inline uint32_t hitObject(unsigned instID, unsigned geomID) {
    return instID != RTC_INVALID_GEOMETRY_ID ? instID : geomID;
}

// The context for finding p: rejects hits on alpha-tested groups (light passes them),
// except on the group whose witness is sought (its own alpha-tested triangles are p).
// Install with ctx.filter = &skipAlphaTested only when the window has alpha-tested groups.
struct AlphaSkip {
    RTCIntersectContext ctx;  // first member: Embree passes &ctx back to the filter
    const BakeWindow* window = nullptr;
    uint32_t object = 0, group = 0;
};
void skipAlphaTested(const RTCFilterFunctionNArguments* args);

// Denormals in ray traversal cost ~100x per operation; the geometry never needs them. Call
// in every thread (task) that traces rays.
void enableFlushToZero();

}  // namespace shadowcull::raycast
