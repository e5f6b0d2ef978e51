// The tool's light parameters in three.js's units (README.md, "Mapping the parameters").
//
// The tool: q is shadowed by p when depth(q) > depth(p) + bias (metres along the light ray;
// directional: along the light's direction, point and spot: distance from the light).
// three.js (r187, shadowmap_pars_fragment): `shadowCoord.z += shadowBias`, then lit when
// shadowCoord.z <= stored depth, so q is shadowed when z(q) + shadowBias > z(p): a
// *negative* shadow.bias of -b pushes the shadow back by b depth-buffer units. z is the
// shadow camera's [0, 1] window depth, which is
//   orthographic (DirectionalLight):  (d - near) / (far - near)          linear in d;
//   perspective (SpotLight, and each cube face of a PointLight, whose lookup recomputes
//   the face's perspective depth from max(|x|, |y|, |z|) of the light-to-point vector):
//                                     far (d - near) / (d (far - near))   with d the view
//                                     depth along the camera axis, not the distance.
// Pure functions: no three.js import, so the README's numbers can be checked in node.

// Directional: depth is linear, so the mapping is exact.
export function directionalShadowBias(biasMetres, near, far) {
  return -biasMetres / (far - near);
}

// Perspective depth window(d) = far (d - near) / (d (far - near)) is concave in d: a fixed
// window offset is worth more metres the farther from the light. The bias returned is the
// window offset of `axialBias` metres at the far plane, the least it is worth anywhere in
// [near, far]: so three.js shadows every q the tool's bias shadows (at least the shadows the
// bake assumed), and near the light a little more (acne a culled caster's own surface may
// show, counted apart). axialBias is the tool's bias along the light ray times the smallest
// cosine between that ray and the camera axis (see perspectiveAxialBias): view depth, not
// distance, is what the map stores.
export function perspectiveShadowBias(axialBias, near, far) {
  if (!(axialBias > 0)) return 0;
  const b = Math.min(axialBias, far - near); // a bias beyond the range is the whole range
  return -(near * b) / ((far - near) * (far - b));
}

// The view-depth share of a bias of `biasMetres` along the ray, for the worst ray the map
// holds: a spot light's cone edge (cos of the half-angle), a cube face's corner (1/sqrt(3)).
export function perspectiveAxialBias(biasMetres, type, coneAngleDeg) {
  if (type === 'spot') return biasMetres * Math.cos((coneAngleDeg * Math.PI) / 180);
  if (type === 'point') return biasMetres / Math.sqrt(3);
  throw new Error(`no perspective map for a ${type} light`);
}

// Depth-buffer window depth of view depth d (perspective), for the checks in the README.
export function perspectiveWindowDepth(d, near, far) {
  return (far * (d - near)) / (d * (far - near));
}

// PCF radius (three.js: shadow.radius, in texels of the map) for the tool's filterRadius
// (metres at the receiver). three's PCF takes 5 Vogel-disk taps within `radius` texels, each
// a hardware 2x2 compare that reaches one more texel: radius + 1.5 texels (a texel's
// half-diagonal included) must stay within filterRadius, so that every texel three reads is
// one whose centre ray passes within filterRadius of q (the tool's condition 4).
// filterRadius 0 means the basic, unfiltered map (one texel, the nearest).
export function pcfRadiusTexels(filterRadius, texelMetres) {
  if (!(filterRadius > 0)) return 0;
  return Math.max(0, filterRadius / texelMetres - 1.5);
}
