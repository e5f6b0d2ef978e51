// An independent exact reference for the bake's bits, for tests (issue 34): written from
// ../shared/spec/semantics.md alone, in exact rational arithmetic (GMP), sharing no code
// with geometry/, raycast/ or gpu/ (only core/'s scene types, to read the triangles and
// lights of a window). Small scenes only: it is brute force.
//
// For one (group, light) it answers
//   One    a witness, constructed and checked exactly: a point p on the group whose open
//          segment to the light (a directional light: the ray from p against its
//          direction) meets no opaque triangle at all, and a point q on a receiver on p's
//          ray, deeper than p by more than an upper bound of the bias, facing the light or
//          two-sided, within range and cone, not deeper than the tolerance under any
//          terrain triangle over it. Stricter than the spec wherever it is unclear (a ray
//          touching an opaque edge counts as blocked), so a One is a true 1.
//   Zero   for every caster triangle of the group and every receiver triangle that the
//          exact facing rule leaves, a linear program over the pairs (p on the caster, q on
//          the receiver, q on p's ray) finds no pair deeper than a lower bound of the
//          bias. A superset of the spec's pairs: occluders are ignored (p may be shaded),
//          the terrain rule is ignored (a buried receiver counts), range and cone are
//          relaxed to boxes and half-spaces, filterRadius and normalBias widen the receiver
//          by a cube (which holds the ball). So a Zero is a true 0.
//   Unsure otherwise (and for what the method cannot bound linearly: a point light with a
//          filter radius, a point light touching its caster).
// Witnesses are not searched with a normal bias (the lookup point q + b n has an
// irrational n): such bits are Zero or Unsure.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "core/scene.h"
#include "core/window.h"

namespace shadowcull::reference {

struct RefTriangle {
    std::array<glm::dvec3, 3> v;  // window-local, as the window places it
    uint32_t object = 0, group = 0;
    bool blocksLight = true;  // opaque: its object casts shadows and its group is not alpha-tested
    bool twoSided = false;
    bool mirrored = false;  // its placement mirrors: the front is the clockwise side
    bool terrain = false;
};

struct RefScene {
    std::vector<RefTriangle> triangles;  // every triangle of the window, repeated vertices too
    std::vector<bool> castsShadow;       // per object
    std::vector<Light> lights;           // window-local
    double terrainTolerance = 0.01;
    bool hasTerrain = false;
};

// Every triangle and light of the window (reads core's types only).
RefScene referenceScene(const BakeWindow& window);

enum class RefVerdict { One, Zero, Unsure };
const char* refVerdictName(RefVerdict v);

struct RefAnswer {
    RefVerdict verdict = RefVerdict::Unsure;
    std::string why;
    glm::dvec3 p{0.0}, q{0.0};  // One: the witness (rounded to double, for messages)
};

struct RefOptions {
    bool searchWitness = true;  // false: only try to prove Zero
    bool proveZero = true;      // false: only search a witness
};

// The reference's decision for (window object `object`, group, light).
RefAnswer referenceDecision(const RefScene& scene, uint32_t object, uint32_t group, size_t light, const RefOptions& options = {});

// Counters of the work done (for the test's report).
struct RefCounters {
    uint64_t pairs = 0, prefiltered = 0, lps = 0, witnessTries = 0;
};
RefCounters& refCounters();

}  // namespace shadowcull::reference
