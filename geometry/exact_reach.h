// The geometry stage's exact test of one receiver against one caster triangle's frustum,
// with the normal bias and the terrain rule on the part the shadow reaches.
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"
#include "geometry/exact_frustum.h"
#include "geometry/receiver_rules.h"

namespace shadowcull::geometry {

// The exact test of one receiver against one caster triangle's frustum: whether the shadow
// reaches more than beta behind the caster at a point where the receiver looks its shadow
// up, and the terrain rule on the part it reaches. Without a normal bias the lookup points
// are the receiver itself. With one (semantics.md, condition 5) they are the receiver moved
// by normalBias along its front normal, and against it for a two-sided receiver: each moved
// triangle is tested against the frustum dilated by filterRadius plus a bound on the move's
// rounding (normalOffsetError, at most `slack_` metres), or, where that bound is larger,
// the receiver itself against the frustum dilated by filterRadius + normalBias (every
// lookup point lies within normalBias of it: a superset). Frusta are built on first use.
class ExactReach {
public:
    ExactReach(const BakeWindow& w, const Triangle& caster, const LightGeometry& lg, const Light& L, double margin,
               const OccluderSource* occluders);

    // True when the shadow reaches the receiver: `part` is the box of the reached part of
    // the lookup surface, `at` a point of the receiver itself whose lookup is reached.
    bool reaches(const Receiver& r, double beta, std::array<glm::dvec3, 2>& part, glm::dvec3& at);

private:
    ExactFrustum& frustum(std::optional<ExactFrustum>& f, double dilation) {
        if (!f) f.emplace(caster_, lg_, dilation);
        return *f;
    }

    // `surface` is the receiver's lookup surface: the receiver moved by `offset` (window-
    // local metres, as computed). The terrain rule applies to the receiver's own points:
    // exactly when there is no offset; with one, by the box of the reached part moved back
    // (grown by the slack), against the lowest ground (a superset: the exact clip against
    // the ground triangles is skipped).
    bool reachesSurface(ExactFrustum& f, const Receiver& r, const Triangle& surface, double beta, const glm::dvec3& offset,
                        std::array<glm::dvec3, 2>& part, glm::dvec3& at);

    const BakeWindow& w_;
    const Triangle& caster_;
    const LightGeometry& lg_;
    const Light& L_;  // as the scene gives it (not dilated)
    double margin_;
    const OccluderSource* occluders_;
    double slack_;  // metres: the largest move rounding tested on the moved receiver
    // Built on the first receiver that passes the broad phase and the rules: most caster
    // triangles of a dense mesh never need one.
    std::optional<ExactFrustum> plain_, moved_, broad_;
    std::vector<Triangle> ground_;         // terrain under a reached part (the terrain rule)
    std::vector<GroundOpening> openings_;  // squares with none under it
};

}  // namespace shadowcull::geometry
