// Whether a pixel where `shadowcull preview`'s two frames differ shows a shadow the bake had
// to keep: the exact light ray through the pixel's receiver point, walked in double on the
// CPU (no GL), as semantics.md defines a witness. A pixel's frames can differ for two
// reasons (docs/semantics.md, "Why the frames agree"):
//  - a false cull: a culled caster is first on the light's own ray to the receiver's lookup
//    point q' and q' lies more than the bias behind it (a witness: the bit was a true 1);
//  - the texel-edge band: the shadow map samples texel-centre rays, which pass up to one
//    footprint beside q', and such a ray meets a culled caster that q's own ray does not
//    (or meets it within the bias): the engine's sampling, not a missing shadow.
// This tells them apart for one pixel. It errs on the side of "band": a hit must lie inside
// the caster's triangle and the depth gap must exceed the bias by a margin far above double
// rounding, so a reported false cull is a witness.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"

namespace shadowcull::gpu {

// A witness found on a receiver point's light ray.
struct RayWitness {
    uint32_t object = 0;  // index into BakeWindow::objects: the culled caster
    uint32_t group = 0;
    glm::dvec3 lsP{0.0};  // window-local: the lit point on the caster
    double gap = 0;       // metres: depth(q') - depth(p), more than the bias
};

class ExactLightRays {
public:
    // `culled[k]`: per window object, one flag per primitive group: the bake culled
    // (object k, group g) for light L (only the centre chunk's casters can be culled).
    ExactLightRays(const BakeWindow& w, const Light& L, std::vector<std::vector<uint8_t>> culled);

    // The receiver point q (window-local, on window object `receiverObject`'s receiving
    // surface with unit front normal `nFront`, the normal the engine offsets along) and the
    // light's bias at q (`beta`: bias + slopeBias tan(theta), metres). Returns the culled
    // caster whose lit point the ray from the light to q' = q + normalBias * nFront meets
    // first with q' more than beta behind it, or nothing (no witness on this ray: the band,
    // or no difference at all). q must also receive by condition 3 (range, cone, terrain).
    std::optional<RayWitness> culledCasterShadowing(uint32_t receiverObject, const glm::dvec3& q,
                                                    const glm::dvec3& nFront, double beta) const;

private:
    struct Hit {
        double t;
        uint32_t object, triangle;
        bool inside;  // barycentrics above a relative 1e-9: a certain crossing
    };
    // Every triangle the segment origin + s * dir, s in (0, tEnd), crosses or touches (within
    // a relative 1e-9 of its edges: such a touch still blocks light), nearest first.
    std::vector<Hit> hitsAlong(const glm::dvec3& origin, const glm::dvec3& dir, double tEnd) const;

    const BakeWindow& w_;
    const Light& L_;
    std::vector<std::vector<uint8_t>> culled_;
    double margin_;    // metres: far above the double rounding of depths in the window
    double backDist_;  // directional lights: ray origins this far before q'
};

}  // namespace shadowcull::gpu
