// Receiver-side targets for witness rays: points on the receivers that can lie
// in a large caster's shadow, aimed at from the light. A caster's own samples (rays from
// the light through points on it, group_samples.h) are spread over the whole caster; a
// 4,096 m² terrain chunk's few real witnesses (a ridge shading a valley, a rock behind a
// crest) are then needles the samples miss. Aiming through the receivers instead samples
// where the shadow lands: the first opaque hit along such a line is on the caster (p) when
// the receiver point is in its shadow, and the receiver behind is q.
//
// These are only targets: every line is verified by the raycast stage's witness test
// (raycast_stage.cpp, Tracer::tryRay), exactly as for the caster's own samples, so a poor
// target costs rays, never a verdict.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "core/window.h"
#include "raycast/group_samples.h"

namespace shadowcull::raycast {

// Whether a group is a large continuous caster: a terrain, or a group whose own area
// samples leave gaps of at least `minSpacing` metres (sqrt(placed area / areaSamples)),
// i.e. whose bounds dwarf the sample spacing (building shells, cliff meshes, ledges).
bool isLargeCaster(const WindowObject& object, uint32_t group, int areaSamples, double minSpacing);

// Up to `budget` window-local points on the receivers of the window that may lie in the
// shadow of (object, group) under `light`, in an order where every prefix is spread over
// them (the search stops at the first witness). A receiver triangle is sampled when it
// faces the light (or is two-sided), its projection along the light's rays overlaps the
// caster's and it reaches deeper than the caster's nearest point plus the bias. Points go
// to objects by the square root of their projected area (a 1 m rock in a terrain's shadow
// column gets a few, where its share by area would be a few in a thousand) and within an
// object by projected area; those deeper than the terrain tolerance under the terrain
// (non-terrain receivers: the terrain rule) are left out. Every other point lies in the
// terrain band of models that cross the ground (the 1 cm under the surface the rule lets
// receive), on their triangles facing the light, when there are such: only where the
// light grazes the ground enough that a band point can be more than the bias behind the
// surface (sin of the angle under 2 tolerance / bias). The caster's own triangles count as receivers (a ridge
// of a terrain shading its own valley). Deterministic: same window, same points.
// `samples` gives the models' points (their own witness samples, placed).
std::vector<glm::dvec3> receiverTargets(const BakeWindow& window, uint32_t object, uint32_t group, const Light& light,
                                        int budget, GroupSampleCache& samples);

}  // namespace shadowcull::raycast
