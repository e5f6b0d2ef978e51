// `shadowcull preview`: the camera's view of a bake window lit by one light, shadowed the
// way an engine shadows it (a depth map from the light, the light's bias and slope bias,
// PCF), rendered twice: once with every caster the engine draws (castsShadow true) and once
// with only the casters whose bit is 1. The two frames, their difference and the cost of
// each shadow pass (draw calls, triangles, GPU time) are what a user needs to trust the
// masks: docs/semantics.md ("Why the frames agree") says when the frames must be identical.
//
// Shadow maps (docs/semantics.md for the sampling model):
//   directional - one orthographic view over the whole window (gpu/light_view.h), texels
//                 square in metres when the window's projection is square;
//   spot        - one perspective view over the cone (cones up to kMaxSingleViewSpotDeg),
//                 else a cube;
//   point       - a cube map: six perspective faces, texels addressed across faces.
// Depths are linear: directional along the light's direction, point and spot the distance
// from the light (as the spec's depth(p)). The shadow test of a receiver point q against a
// texel holding depth D is `D + bias + slopeBias * tan(theta) < depth(q)` (shadowed),
// theta the angle between the light ray and q's normal: the spec's condition 2, in float.
// PCF of radius R averages the (2R+1)^2 tests around q's texel.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/verdict.h"
#include "core/window.h"
#include "util/status.h"

namespace shadowcull::gpu {

struct PreviewRequest {
    int light = 0;                 // 0-based
    int shadowResolution = 2048;   // texels per side of each shadow-map view
    int pcfRadius = -1;            // texels; < 0: defaultPcfRadius
    // Camera eye and target, world coordinates; nothing: looking at the chunk from above.
    std::optional<glm::dvec3> wsEye, wsTarget;
    int width = 640, height = 480;  // of each frame
    double fovYDeg = 60.0;
    int timingRepeats = 5;          // each shadow pass is drawn this often, alternating; medians
    size_t maxListed = 20;          // differing pixels listed in the report
};

// One shadow pass (every view of the light's depth map), as an engine would issue it.
struct ShadowPassTiming {
    uint64_t drawCalls = 0;  // one per (object, primitive group) per view it is drawn into
    uint64_t triangles = 0;  // triangles submitted, over every view
    uint64_t casters = 0;    // (object, group) pairs drawn
    double gpuMs = -1;       // median GL_TIME_ELAPSED; < 0 where the device has no timer query
    double cpuMs = 0;        // median wall time of submit + glFinish
};

// How a pixel whose shadow differs between the frames is explained (gpu/preview_pixels.h).
enum class PixelClass {
    FalseCull,    // a witness shows there: the bake culled a shadow the engine draws
    OwnSurface,   // on the culled caster's own surface, no witness: its acne, not a shadow
    Band,         // on another surface, no witness: the texel-edge band of the sampling
};
const char* pixelClassName(PixelClass c);

// A pixel whose shadow test differs between the frames, with what explains it.
struct DifferingPixel {
    int x = 0, y = 0;                // in the frame, row 0 at the top
    glm::dvec3 wsReceiver{0.0};      // the receiver point q seen there (world)
    std::string receiver;            // its object label and group
    std::string caster;              // the culled caster of the witness, else the one nearest
                                     // the light at the first differing texel
    std::string casterProof;         // the stage and reason that culled it
    double footprint = 0;            // metres: farthest texel-centre ray sampled, laterally from q
    bool covered = false;            // footprint <= the light's filterRadius
    PixelClass cls = PixelClass::Band;
    bool exactWitness = false;       // the exact light ray through q' is a witness (wsP on it)
    glm::dvec3 wsP{0.0};             // world: the culled caster's lit point, when exactWitness
};

// A culled caster whose shadow the frames show missing: the bake's false cull.
struct FalseCullCaster {
    std::string caster;  // object label and group
    std::string proof;   // the stage and reason that culled it
    uint64_t pixels = 0; // false-cull pixels attributed to it
};

struct PreviewReport {
    int pcfRadius = 0;
    bool pcfDefaulted = false;
    double texelSize = 0;          // metres: directional, the texel's larger side; point/spot, at range
    double worstFootprint = 0;     // metres: (R + 1/2) texel diagonals, at the worst receiver
    int views = 0;                 // shadow-map views (1 or 6)
    glm::dvec3 wsEye{0.0}, wsTarget{0.0};
    uint64_t receiverPixels = 0;   // pixels showing a surface that receives the light
    uint64_t coveredPixels = 0;    // of those, where the footprint fits within filterRadius
    uint64_t differingPixels = 0;  // receiving pixels whose PCF result differs
    uint64_t differingCovered = 0; // of those, where the footprint fits (each a false cull)
    // The differing pixels by class (they sum to differingPixels; gpu/preview_pixels.h).
    // "Own": the surface of the culled caster that differs there; "kept": any other surface.
    uint64_t differingOnKeptSurfaces = 0;  // false culls: a culled caster's shadow missing
                                           // on another surface (the gate: must be 0)
    uint64_t falseCullsOnOwnSurfaces = 0;  // false culls: a culled caster's self-shadow
                                           // missing (must be 0 as well)
    uint64_t differingOnOwnSurfaces = 0;   // a culled caster's own acne, no witness
    uint64_t differingInBand = 0;          // another surface, the texel-edge band, no witness
    std::vector<FalseCullCaster> falseCulls;  // most pixels first
    uint64_t culledCasters = 0;    // casters drawn in the first frame and not the second
    ShadowPassTiming all, kept;
    std::vector<DifferingPixel> listed;  // false culls first
    std::string device;            // the GL renderer
    int pictureWidth = 0, pictureHeight = 0;
    uint64_t falseCullPixels() const { return differingOnKeptSurfaces + falseCullsOnOwnSurfaces; }
};

// The largest PCF radius R (texels) with (R + 1/2) * texelDiagonal <= filterRadius, i.e.
// half a texel's diagonal plus the kernel's reach within the filter; 0 when none fits.
int defaultPcfRadius(double filterRadius, double texelDiagonal);

// Renders both frames and writes the picture (all | kept | difference, labelled) as an
// 8-bit RGB PNG. Errors: BadInput for a light or size out of range, a camera whose eye is its
// target; Internal when no GL context can be made; Io when the file cannot be written.
Expected<PreviewReport> renderShadowPreview(const BakeWindow& window, const ChunkVerdicts& verdicts,
                                            const PreviewRequest& request, const std::string& pngPath);

}  // namespace shadowcull::gpu
