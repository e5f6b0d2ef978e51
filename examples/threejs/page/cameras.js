// Cameras around a world box (the part of the scene a light can light): a few views from
// different sides and heights, so a shadow hidden behind an object in one view shows in
// another.

import * as THREE from 'three';

const REGION_RAYS = 4096; // rays from a point or spot light to find what it lights

// Directions spread evenly over the spherical cap within `halfAngle` of `axis` (the whole
// sphere for pi): a Fibonacci spiral.
function capDirections(axis, halfAngle, count) {
  const q = new THREE.Quaternion().setFromUnitVectors(new THREE.Vector3(0, 0, 1), axis);
  const cosMin = Math.cos(halfAngle);
  const golden = Math.PI * (3 - Math.sqrt(5));
  const out = [];
  for (let k = 0; k < count; k++) {
    const z = 1 - ((k + 0.5) / count) * (1 - cosMin);
    const r = Math.sqrt(Math.max(0, 1 - z * z));
    out.push(new THREE.Vector3(r * Math.cos(k * golden), r * Math.sin(k * golden), z).applyQuaternion(q));
  }
  return out;
}

// The world box a light lights (what its cameras frame): the whole scene for a directional
// light; for a point or spot light the first surfaces its rays meet within range (and
// cone), found by casting REGION_RAYS rays at `surfaces` (double-sided stand-ins of every
// primitive). Empty when it lights nothing.
export function litRegion(light, bounds, surfaces) {
  const { entry, position, direction } = light.userData.shadowcull;
  if (entry.type === 'directional') return bounds.clone();
  const halfAngle = entry.type === 'spot' ? (entry.coneAngle * Math.PI) / 180 : Math.PI;
  const axis = entry.type === 'spot' ? direction : new THREE.Vector3(0, -1, 0);
  const raycaster = new THREE.Raycaster();
  raycaster.far = entry.range;
  const region = new THREE.Box3();
  for (const d of capDirections(axis, halfAngle, REGION_RAYS)) {
    raycaster.set(position, d);
    const hit = raycaster.intersectObjects(surfaces, false)[0];
    if (hit) region.expandByPoint(hit.point);
  }
  if (!region.isEmpty()) region.expandByScalar(0.05 * region.getSize(new THREE.Vector3()).length() + 0.1);
  return region;
}

// [azimuth, elevation] in degrees: high and oblique, from the other side, low (walls and
// the sides of things), and from above (every shadow on the ground, none hidden behind
// its caster).
const VIEWS = [
  [35, 38],
  [160, 55],
  [285, 22],
  [0, 88],
];

// Narrows the angle of view until the box's corners just fit (with a small margin): the
// bounding sphere leaves a flat scene small in the frame. Perspective projection scales
// with tan(fov / 2) at a fixed position, so one step is exact.
function fitToBox(camera, box) {
  let extent = 0;
  const p = new THREE.Vector3();
  for (let k = 0; k < 8; k++) {
    p.set(k & 1 ? box.max.x : box.min.x, k & 2 ? box.max.y : box.min.y, k & 4 ? box.max.z : box.min.z).project(camera);
    extent = Math.max(extent, Math.abs(p.x), Math.abs(p.y));
  }
  const half = Math.atan(Math.tan((camera.fov * Math.PI) / 360) * extent * 1.04);
  camera.fov = (360 * half) / Math.PI;
  camera.updateProjectionMatrix();
}

export function camerasFor(region, width, height, count = VIEWS.length) {
  if (count > VIEWS.length) throw new Error(`at most ${VIEWS.length} cameras`);
  const sphere = region.getBoundingSphere(new THREE.Sphere());
  const radius = Math.max(sphere.radius, 0.5);
  const fov = 45;
  // Far enough that the sphere fits the narrower of the two angles of view.
  const halfAngle = Math.min(fov / 2, (Math.atan(Math.tan(((fov / 2) * Math.PI) / 180) * (width / height)) * 180) / Math.PI);
  const distance = (radius / Math.sin((halfAngle * Math.PI) / 180)) * 1.02;
  return VIEWS.slice(0, count).map(([az, el], k) => {
    const a = (az * Math.PI) / 180;
    const e = (el * Math.PI) / 180;
    const camera = new THREE.PerspectiveCamera(fov, width / height, Math.max(0.01, distance - 2 * radius), distance + 2 * radius);
    camera.position.set(
      sphere.center.x + distance * Math.cos(e) * Math.sin(a),
      sphere.center.y + distance * Math.sin(e),
      sphere.center.z + distance * Math.cos(e) * Math.cos(a)
    );
    camera.lookAt(sphere.center);
    camera.updateMatrixWorld();
    fitToBox(camera, region);
    camera.name = `camera ${k + 1} (azimuth ${az}, elevation ${el})`;
    return camera;
  });
}
