// Rendering: the two shadowed frames (all casters, kept casters) read back from the
// canvas, the analysis passes read back from render targets, and the shadow pass's draw
// calls counted.

import * as THREE from 'three';
import { LAYER_ALL_CASTERS, layerOfLight } from './masks.js';
import { PASS_ID, PASS_NORMAL, PASS_POSITION, useAnalysisMaterials, useFrameMaterials } from './materials.js';

const FRAME_BACKGROUND = 0x1c2026;

export function createRenderer(width, height) {
  // No antialiasing: one sample per pixel, at the pixel centre, in every pass, so the
  // frames and the analysis passes see the same surface point.
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(width, height, false);
  renderer.shadowMap.enabled = true;
  renderer.shadowMap.type = THREE.BasicShadowMap;
  renderer.toneMapping = THREE.NoToneMapping;
  const drawCalls = countShadowDrawCalls(renderer);
  const targets = {
    id: new THREE.WebGLRenderTarget(width, height, { type: THREE.UnsignedByteType }),
    float: new THREE.WebGLRenderTarget(width, height, { type: THREE.FloatType }),
  };
  for (const t of Object.values(targets)) {
    t.texture.minFilter = t.texture.magFilter = THREE.NearestFilter;
    t.texture.generateMipmaps = false;
  }
  return { renderer, width, height, targets, drawCalls };
}

// Wraps the shadow pass: the draw calls it issues (renderer.info counts every draw; the
// difference around shadowMap.render is the shadow pass's alone), summed since reset().
function countShadowDrawCalls(renderer) {
  const counter = { calls: 0, reset() { this.calls = 0; } };
  const render = renderer.shadowMap.render.bind(renderer.shadowMap);
  renderer.shadowMap.render = (lights, scene, camera) => {
    const before = renderer.info.render.calls;
    render(lights, scene, camera);
    counter.calls += renderer.info.render.calls - before;
  };
  return counter;
}

// One shadowed frame: `which` is 'all' (the shadow camera sees every caster) or 'kept'
// (light i's layer only). Returns { rgba (canvas pixels, bottom row first), shadowDrawCalls }.
export function renderFrame(ctx, scene, camera, light, lightIndex, which, records) {
  const { renderer, width, height, drawCalls } = ctx;
  const type = light.userData.shadowcull.shadowMapType;
  if (renderer.shadowMap.type !== type) renderer.shadowMap.type = type;
  light.shadow.camera.layers.set(which === 'all' ? LAYER_ALL_CASTERS : layerOfLight(lightIndex));
  useFrameMaterials(records);
  renderer.shadowMap.autoUpdate = true;
  drawCalls.reset();
  renderer.setRenderTarget(null);
  renderer.setClearColor(FRAME_BACKGROUND, 1);
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const rgba = new Uint8Array(width * height * 4);
  gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, rgba);
  return { rgba, shadowDrawCalls: drawCalls.calls };
}

// The analysis passes for one camera: ids (Uint32Array, record id per pixel, 0 none),
// position and normal (Float32Array, xyzw per pixel, world metres / unit). Bottom row first.
export function renderAnalysis(ctx, scene, camera, records) {
  const { renderer, width, height, targets } = ctx;
  renderer.shadowMap.autoUpdate = false; // no light or shadow takes part here
  const read = (mode, target, array) => {
    useAnalysisMaterials(records, mode);
    renderer.setRenderTarget(target);
    renderer.setClearColor(0x000000, 0);
    renderer.clear();
    renderer.render(scene, camera);
    renderer.readRenderTargetPixels(target, 0, 0, width, height, array);
    return array;
  };
  const idBytes = read(PASS_ID, targets.id, new Uint8Array(width * height * 4));
  const position = read(PASS_POSITION, targets.float, new Float32Array(width * height * 4));
  const normal = read(PASS_NORMAL, targets.float, new Float32Array(width * height * 4));
  renderer.setRenderTarget(null);
  useFrameMaterials(records);
  const ids = new Uint32Array(width * height);
  for (let k = 0; k < ids.length; k++) ids[k] = (idBytes[4 * k] << 16) | (idBytes[4 * k + 1] << 8) | idBytes[4 * k + 2];
  return { ids, position, normal };
}
