// The analysis: which pixels differ between the frame with every caster and the frame
// with the kept ones, and why each one does.
//
// A pixel differs (beyond TOLERANCE) only where some shadow-map texel holds a culled
// caster in the "all" frame. Its surface (object-ID pass) is either
//  - a primitive culled for this light: its own shadow-map depth is missing in the "kept"
//    frame, so its self-shadowing (acne at the engine's bias) differs: reported, not gated;
//  - a kept primitive (or one that casts no shadow): the gate. The exact test decides:
//    from the pixel's world point q (position pass), moved to q' = q + normalBias * n as
//    the engine looks it up (normal pass), a ray toward the light finds every shadow
//    caster on the way. Walking from the light end, the first surface is lit; alpha-tested
//    ones let light through, so the walk goes on past them and stops at the first opaque
//    one. If a caster culled for this light is met lit with
//        depth(q') - depth(p) > bias + slopeBias * tan(theta)
//    the bake culled a shadow the engine draws there: a FALSE CULL (the tool's definition,
//    semantics.md conditions 1, 2 and 5). Otherwise the engine's texel near q saw the
//    culled caster but q's exact ray does not: the texel-edge BAND, a sampling artifact
//    within a texel of a silhouette, counted apart.
//  - a surface that receives nothing from this light by the tool's condition 3 (facing
//    away, beyond range or outside the cone) is counted as NOT_RECEIVING (three's lighting
//    makes such pixels equal in both frames, so this should stay 0).
// Culled surfaces get the same exact test (a receiver is any surface, culled casters
// included): a culled caster that shadows another culled surface is a false cull too.

import * as THREE from 'three';
import { culledFor } from './masks.js';

export const TOLERANCE = 2; // 8-bit levels per channel; both frames run the same shader
export const SELF_HIT = 2e-3; // metres: a ray meeting its own primitive nearer is its start

export const SAME = 0;
export const CULLED_SURFACE = 1;
export const FALSE_CULL = 2;
export const BAND = 3;
export const NOT_RECEIVING = 4;

// Double-sided stand-ins of the shadow casters for the exact rays: the shadow map holds
// both faces (frameMaterial's shadowSide), so the rays must meet both too.
export function makeOccluders(records) {
  return makeProxies(records.filter((r) => r.castsShadow));
}

// Double-sided stand-ins of the given primitives, each knowing its record.
export function makeProxies(records) {
  const material = new THREE.MeshBasicMaterial({ side: THREE.DoubleSide });
  return records.map((r) => {
    r.mesh.updateWorldMatrix(true, false);
    const proxy = new THREE.Mesh(r.mesh.geometry, material);
    proxy.matrixAutoUpdate = false;
    proxy.matrixWorld.copy(r.mesh.matrixWorld);
    proxy.userData.record = r;
    return proxy;
  });
}

// The light as the exact test sees it (world metres).
function lightGeometry(light) {
  const { entry, position, direction } = light.userData.shadowcull;
  const cosCone = entry.type === 'spot' ? Math.cos((entry.coneAngle * Math.PI) / 180) : -1;
  return {
    entry,
    toLight(q, out) {
      return entry.type === 'directional' ? out.copy(direction).negate() : out.copy(position).sub(q).normalize();
    },
    reach(q) {
      return entry.type === 'directional' ? Infinity : position.distanceTo(q);
    },
    // Condition 3 of the tool (facing, range, cone), at q itself.
    receives(q, n, twoSided, toLight) {
      const facing = n.dot(toLight);
      if (!(facing > 0) && !(twoSided && facing < 0)) return false;
      if (entry.type === 'directional') return true;
      if (position.distanceTo(q) > entry.range) return false;
      if (entry.type === 'spot') return -toLight.dot(direction) >= cosCone;
      return true;
    },
  };
}

// Lateral ray origins for a light with filterRadius r > 0 (condition 4: q may lie within r
// of the lit point's ray): the point itself, and rings at r/2 and r around it, across the ray.
function lateralOrigins(q, toLight, r) {
  if (!(r > 0)) return [q];
  const a = new THREE.Vector3(1, 0, 0);
  if (Math.abs(toLight.x) > 0.9) a.set(0, 1, 0);
  const u = a.cross(toLight).normalize();
  const v = new THREE.Vector3().crossVectors(toLight, u);
  const origins = [q];
  for (const radius of [r / 2, r])
    for (let k = 0; k < 8; k++) {
      const phi = (k * Math.PI) / 4;
      origins.push(q.clone().addScaledVector(u, radius * Math.cos(phi)).addScaledVector(v, radius * Math.sin(phi)));
    }
  return origins;
}

// The exact test for one pixel: the culled record whose lit point shadows q', or null.
function falseCullAt(q, n, surface, light, lightIndex, occluders, geo) {
  const { entry } = geo;
  const lookup = q.clone().addScaledVector(n, entry.normalBias || 0); // q' (condition 5)
  const toLight = geo.toLight(lookup, new THREE.Vector3());
  const cos = Math.min(1, Math.abs(n.dot(toLight)));
  const tanTheta = cos > 1e-6 ? Math.sqrt(1 - cos * cos) / cos : 1e6;
  const beta = (entry.bias || 0) + (entry.slopeBias || 0) * tanTheta;
  const raycaster = new THREE.Raycaster();
  for (const origin of lateralOrigins(lookup, toLight, entry.filterRadius || 0)) {
    raycaster.set(origin, toLight);
    raycaster.near = 1e-5;
    raycaster.far = geo.reach(origin);
    const hits = raycaster.intersectObjects(occluders, false);
    for (let k = hits.length - 1; k >= 0; k--) {
      const record = hits[k].object.userData.record;
      const gap = hits[k].distance; // depth(q') - depth(p): the ray runs along the light's
      if (record === surface && gap < SELF_HIT) continue;
      if (culledFor(record, lightIndex) && gap > beta) return { record, gap, beta };
      if (!record.alphaTested) break; // opaque: nothing nearer q is lit
    }
  }
  return null;
}

// Compares the two frames of one camera. Returns the counts, the false-culling records
// with their pixel counts, and a class per pixel for the picture.
export function compareFrames({ all, kept, analysis, light, lightIndex, recordsById, occluders }) {
  const { ids, position, normal } = analysis;
  const geo = lightGeometry(light);
  const classes = new Uint8Array(ids.length);
  const result = {
    compared: 0,
    differing: 0,
    culledSurface: 0, // differing pixels on the surfaces of culled primitives (acne)
    keptSurface: 0, // differing pixels on kept surfaces (the gate)
    falseCull: 0, // differing pixels, on any surface, where a culled caster's shadow is missing
    falseCullOnKept: 0, // of those, on kept surfaces (the brief's gate; falseCull is stricter)
    band: 0, // kept-surface pixels within a texel of a silhouette (no false cull)
    notReceiving: 0, // kept-surface pixels the light does not reach by the tool's rules
    falseCulls: new Map(), // culprit label -> { pixels, maxGap }
  };
  const q = new THREE.Vector3();
  const n = new THREE.Vector3();
  const toLight = new THREE.Vector3();
  for (let k = 0; k < ids.length; k++) {
    if (ids[k] === 0) continue;
    result.compared++;
    const o = 4 * k;
    const differs =
      Math.abs(all[o] - kept[o]) > TOLERANCE || Math.abs(all[o + 1] - kept[o + 1]) > TOLERANCE || Math.abs(all[o + 2] - kept[o + 2]) > TOLERANCE;
    if (!differs) continue;
    result.differing++;
    const surface = recordsById.get(ids[k]);
    q.set(position[o], position[o + 1], position[o + 2]);
    n.set(normal[o], normal[o + 1], normal[o + 2]).normalize();
    const onCulled = culledFor(surface, lightIndex);
    if (onCulled) result.culledSurface++;
    else result.keptSurface++;
    const receives = geo.receives(q, n, surface.twoSided, geo.toLight(q, toLight));
    const found = receives ? falseCullAt(q, n, surface, light, lightIndex, occluders, geo) : null;
    if (found) {
      classes[k] = FALSE_CULL;
      result.falseCull++;
      if (!onCulled) result.falseCullOnKept++;
      const entry = result.falseCulls.get(found.record.label) || { pixels: 0, maxGap: 0, node: found.record.node };
      entry.pixels++;
      entry.maxGap = Math.max(entry.maxGap, found.gap - found.beta);
      result.falseCulls.set(found.record.label, entry);
    } else if (onCulled) {
      classes[k] = CULLED_SURFACE;
    } else if (!receives) {
      classes[k] = NOT_RECEIVING;
      result.notReceiving++;
    } else {
      classes[k] = BAND;
      result.band++;
    }
  }
  return { result, classes };
}
