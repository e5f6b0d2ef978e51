// Whether a caster triangle's shadow, under a directional light, runs wholly inside the
// ground: a proof, cheaper than the broad phase, that no receiver can be met. A terrain
// triangle's column goes straight into the hill it lies on; under a high sun, and under a
// low one wherever the slopes beyond it do not fall away faster than the light, every point
// of it more than the bias behind the caster lies deeper than the terrain tolerance under
// the terrain, where the terrain rule lets no model receive and no terrain surface lies
// (semantics.md, conditions 2 and 3). The broad phase meets there the buried halves and
// back faces of the rocks under the caster, triangle by triangle (79 % of the geometry
// stage's time on world R went to such probes, docs/performance.md); this test looks at
// the terrain triangles under the column instead.
//
// Per terrain triangle g the column can cross (boxes), the question is a small linear
// program: is there a point x = p + s d, p on the caster, s >= bias, over g's cell, at most
// the tolerance under g's plane? Eliminating s (Fourier-Motzkin: s's bounds from the caster's
// edges, pairwise) leaves half-planes over the cell's x-z plane, whose intersection is
// empty exactly when no such x exists; it is found by clipping (Sutherland-Hodgman). The
// coefficients carry their rounding bounds (core/rounding.h's Bounded) and every half-plane
// is relaxed by them and by the stage's margin, so an empty clip proves the exact region
// empty. A cheap bound per cell (the caster's highest vertex over g's plane, s at its least)
// settles the cells far from the caster first.
//
// H.-W. Kuhn, "Solvability and consistency for linear equations and inequalities", Amer.
// Math. Monthly 63(4), 1956 (Fourier-Motzkin elimination); I. E. Sutherland, G. W. Hodgman,
// "Reentrant Polygon Clipping", CACM 17(1), 1974; N. Max, "Horizon mapping: shadows for
// bump-mapped surfaces", The Visual Computer 4(2), 1988 (a heightfield's self-shadow).
#pragma once

#include <glm/vec3.hpp>

#include "core/window.h"
#include "geometry/exact_frustum.h"

namespace shadowcull::geometry {

// True only when no point of the column {p + s d / |d| : p on `lsCaster`, s > bias} (`d`:
// the directional light's direction; window-local metres) that lies inside `lsLimits` (the
// loaded window) is within the terrain tolerance under the terrain of the window, nor
// beside it: every such point lies over loaded terrain, deeper than the tolerance (plus
// `margin`, metres, the stage's slack for the placement's rounding) under the lowest
// terrain surface there. No receiver can then be reached: the terrain rule excludes
// every model point there, and every terrain surface lies above. False: not proved (a
// point light, a light from below, a caster or terrain cell too steep to bound, a column
// leaving the terrain, or some point near the ground).
bool columnUnderTerrain(const BakeWindow& w, const Triangle& lsCaster, const glm::dvec3& direction, double bias,
                        const Aabb& lsLimits, double margin);

}  // namespace shadowcull::geometry
