// three.js lights from extras.shadowcull.lights: placed by their glTF node (or, for a light
// without one, the tool's --sun, by the exported direction), with shadow cameras that cover
// the scene and the bake's bias, normalBias and filterRadius mapped to three's units.

import * as THREE from 'three';
import {
  directionalShadowBias,
  pcfRadiusTexels,
  perspectiveAxialBias,
  perspectiveShadowBias,
} from './bias_mapping.js';

// Brightness: not the file's (glTF intensities are photometric and the check wants lit and
// shadowed areas far apart in 8-bit colour). Decay 0, and hard edges (below): a local light
// is as bright at its range and its cone's edge as anywhere, so a missing shadow shows at
// full contrast wherever the bake's rules say a surface receives light.
const INTENSITY = 1.9;
const SPOT_PENUMBRA = 0;

// three's point and spot lights fade smoothly to nothing at `distance` (a window on the
// last part of the range) and across the penumbra: differences there would fall below any
// pixel tolerance. The check's engine instead lights every point within range and cone
// fully and nothing beyond: the bake's condition 3 exactly. Patched into the shader chunk
// before any program is compiled.
export function useHardLightEdges() {
  const chunk = THREE.ShaderChunk.lights_pars_begin;
  if (chunk.includes('step( lightDistance, cutoffDistance )')) return; // done already
  const window = 'distanceFalloff *= pow2( saturate( 1.0 - pow4( lightDistance / cutoffDistance ) ) );';
  const cone = 'return smoothstep( coneCosine, penumbraCosine, angleCosine );';
  if (!chunk.includes(window) || !chunk.includes(cone)) throw new Error('three.js lights_pars_begin changed: check useHardLightEdges');
  THREE.ShaderChunk.lights_pars_begin = chunk
    .replace(window, 'distanceFalloff *= step( lightDistance, cutoffDistance );')
    .replace(cone, 'return step( coneCosine, angleCosine );');
}

export const DEFAULT_SHADOW_SETTINGS = {
  directionalMapSize: 4096, // texels per side, over the scene's bounding sphere
  spotMapSize: 2048,
  pointMapSize: 1024, // per cube face
  near: 0.05, // metres: perspective maps' near plane (casters nearer the light are clipped)
};

// World position and the way light travels, from the light's node (-Z of its world
// transform, as KHR_lights_punctual says) or from the exported direction (node null).
export function lightFrame(entry, nodeObjects) {
  if (entry.node === null) {
    return { position: null, direction: new THREE.Vector3(...entry.direction).normalize() };
  }
  const object = nodeObjects.get(entry.node);
  if (!object) throw new Error(`light '${entry.name}': node ${entry.node} is not in the scene`);
  object.updateWorldMatrix(true, false);
  const position = new THREE.Vector3().setFromMatrixPosition(object.matrixWorld);
  const direction = new THREE.Vector3(0, 0, -1).transformDirection(object.matrixWorld);
  return { position, direction };
}

// A three.js light for one entry, shadow on, alone in the scene when added. `bounds`: the
// scene's world box (the shadow camera must hold every caster and receiver).
export function makeLight(entry, nodeObjects, bounds, settings = DEFAULT_SHADOW_SETTINGS) {
  const { position, direction } = lightFrame(entry, nodeObjects);
  const sphere = bounds.getBoundingSphere(new THREE.Sphere());
  let light;
  let texelMetres;
  if (entry.type === 'directional') {
    light = new THREE.DirectionalLight(0xffffff, INTENSITY);
    // An orthographic box around the scene's bounding sphere, looking along the light.
    const margin = 1 + 0.01 * sphere.radius;
    const reach = sphere.radius + margin;
    light.position.copy(sphere.center).addScaledVector(direction, -reach);
    light.target.position.copy(sphere.center);
    const cam = light.shadow.camera;
    Object.assign(cam, { left: -reach, right: reach, top: reach, bottom: -reach, near: 0, far: 2 * reach });
    cam.updateProjectionMatrix();
    light.shadow.mapSize.set(settings.directionalMapSize, settings.directionalMapSize);
    light.shadow.bias = directionalShadowBias(entry.bias, cam.near, cam.far);
    texelMetres = (2 * reach) / settings.directionalMapSize;
  } else if (entry.type === 'point') {
    light = new THREE.PointLight(0xffffff, INTENSITY, entry.range, 0);
    light.position.copy(position);
    light.shadow.camera.near = settings.near;
    light.shadow.camera.far = entry.range; // three also sets far = distance each frame
    light.shadow.camera.updateProjectionMatrix();
    light.shadow.mapSize.set(settings.pointMapSize, settings.pointMapSize);
    light.shadow.bias = perspectiveShadowBias(perspectiveAxialBias(entry.bias, 'point'), settings.near, entry.range);
    texelMetres = (2 * entry.range) / settings.pointMapSize; // a face's texel at the range, on its axis
  } else {
    const angle = (entry.coneAngle * Math.PI) / 180;
    light = new THREE.SpotLight(0xffffff, INTENSITY, entry.range, angle, SPOT_PENUMBRA, 0);
    light.position.copy(position);
    light.target.position.copy(position).add(direction);
    light.shadow.camera.near = settings.near;
    light.shadow.mapSize.set(settings.spotMapSize, settings.spotMapSize);
    light.shadow.bias = perspectiveShadowBias(perspectiveAxialBias(entry.bias, 'spot', entry.coneAngle), settings.near, entry.range);
    texelMetres = (2 * entry.range * Math.tan(Math.min(angle, 1.55))) / settings.spotMapSize;
  }
  light.name = entry.name;
  light.castShadow = true;
  // Engine-style normal offset: three moves the lookup point along the receiver's world
  // normal by normalBias world units (shadowmap_vertex), the tool's condition 5: direct.
  light.shadow.normalBias = entry.normalBias || 0;
  light.shadow.radius = pcfRadiusTexels(entry.filterRadius || 0, texelMetres);
  light.userData.shadowcull = {
    entry,
    position,
    direction,
    texelMetres,
    shadowMapType: entry.filterRadius > 0 ? THREE.PCFShadowMap : THREE.BasicShadowMap,
  };
  return light;
}
