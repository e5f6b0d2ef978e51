// The frame check, step by step: load the exported scene, apply the masks as an engine
// would, then per light and camera render the frame with every caster and the frame with
// the kept ones, and explain every pixel where they differ (classify.js).

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { camerasFor, litRegion } from './cameras.js';
import { compareFrames, makeOccluders, makeProxies } from './classify.js';
import { DEFAULT_SHADOW_SETTINGS, makeLight, useHardLightEdges } from './lights.js';
import { applyMasks, culledFor, readLightEntries } from './masks.js';
import { assignMaterials, withFlatNormals } from './materials.js';
import { composePicture } from './picture.js';
import { createRenderer, renderAnalysis, renderFrame } from './passes.js';

const AMBIENT = 0.9; // so that shadowed areas are not black: shapes stay readable

export const DEFAULT_OPTIONS = {
  scene: '/scene.glb',
  width: 600,
  height: 400,
  cameras: 4,
  ...DEFAULT_SHADOW_SETTINGS,
};

async function loadScene(url) {
  const gltf = await new GLTFLoader().loadAsync(url);
  // The file's own lights (KHR_lights_punctual, made by GLTFLoader) go dark: the check
  // makes one light at a time from extras.shadowcull.lights, with the bake's parameters.
  // They stay in the tree: a light node's object is the light itself when the node holds
  // nothing else, and its children and world transform are still needed.
  gltf.scene.traverse((o) => {
    if (!o.isLight) return;
    o.intensity = 0;
    o.castShadow = false;
  });
  gltf.scene.updateMatrixWorld(true);
  return gltf;
}

// glTF node index -> the three.js object GLTFLoader made for it.
function nodeObjects(gltf) {
  const map = new Map();
  gltf.scene.traverse((o) => {
    const a = gltf.parser.associations.get(o);
    if (a && a.nodes !== undefined && !map.has(a.nodes)) map.set(a.nodes, o);
  });
  return map;
}

function sceneBounds(records) {
  const box = new THREE.Box3();
  for (const { mesh } of records) box.expandByObject(mesh);
  return box;
}

// What a light's report says before any frame: its parameters and three.js's values.
function describeLight(light, lightIndex, records) {
  const { entry, texelMetres, shadowMapType } = light.userData.shadowcull;
  return {
    light: lightIndex,
    name: entry.name,
    type: entry.type,
    node: entry.node,
    parameters: {
      bias: entry.bias,
      slopeBias: entry.slopeBias,
      filterRadius: entry.filterRadius,
      normalBias: entry.normalBias,
      threeShadowBias: light.shadow.bias,
      threeNormalBias: light.shadow.normalBias,
      threeRadius: light.shadow.radius,
      texelMetres,
      shadowMap: shadowMapType === THREE.BasicShadowMap ? 'basic' : 'pcf',
    },
    culledCasters: records.filter((r) => culledFor(r, lightIndex)).map((r) => r.label),
    drawCalls: { all: 0, kept: 0 },
    cameras: [],
    falseCulls: [],
  };
}

// One camera: both frames, the analysis passes, and every differing pixel explained.
function checkCamera(ctx, scene, camera, light, lightIndex, records, occluders) {
  const all = renderFrame(ctx, scene, camera, light, lightIndex, 'all', records);
  const kept = renderFrame(ctx, scene, camera, light, lightIndex, 'kept', records);
  const analysis = renderAnalysis(ctx, scene, camera, records);
  const recordsById = new Map(records.map((r) => [r.id, r]));
  const { result, classes } = compareFrames({ all: all.rgba, kept: kept.rgba, analysis, light, lightIndex, recordsById, occluders });
  const { falseCulls, ...counts } = result;
  return {
    counts: { camera: camera.name, ...counts },
    falseCulls,
    drawCalls: { all: all.shadowDrawCalls, kept: kept.shadowDrawCalls },
    row: {
      all: all.rgba,
      kept: kept.rgba,
      classes,
      caption: `${camera.name}: ${counts.compared} px compared; ${counts.differing} differ: ${counts.culledSurface} on culled casters, ${counts.keptSurface} on kept surfaces; false cull ${counts.falseCull}, band ${counts.band}`,
    },
  };
}

// Adds one camera's false culls (label -> { pixels, maxGap, node }) to the light's list.
function addCulprits(culprits, falseCulls, records, lightName) {
  for (const [label, f] of falseCulls) {
    const record = records.find((r) => r.label === label);
    const sum = culprits.get(label) || { node: f.node, nodeName: record.nodeName, primitive: label, light: lightName, pixels: 0, maxGapMetres: 0 };
    sum.pixels += f.pixels;
    sum.maxGapMetres = Math.max(sum.maxGapMetres, f.maxGap);
    culprits.set(label, sum);
  }
}

// One light, alone in the scene: its cameras, counts, culprits and picture.
function checkLight(ctx, scene, records, occluders, surfaces, light, lightIndex, bounds, options) {
  const { entry } = light.userData.shadowcull;
  scene.add(light);
  if (light.target) scene.add(light.target);
  const report = describeLight(light, lightIndex, records);
  const region = litRegion(light, bounds, surfaces);
  // A light that reaches nothing still has a shadow pass to count: one view, not judged.
  const cameras = region.isEmpty() ? [] : camerasFor(region, ctx.width, ctx.height, options.cameras);
  const rows = [];
  const culprits = new Map();
  for (const camera of cameras) {
    const c = checkCamera(ctx, scene, camera, light, lightIndex, records, occluders);
    report.drawCalls = c.drawCalls; // the shadow cameras do not depend on the view
    report.cameras.push(c.counts);
    rows.push(c.row);
    addCulprits(culprits, c.falseCulls, records, entry.name);
  }
  if (cameras.length === 0) {
    const anyView = new THREE.PerspectiveCamera();
    report.drawCalls = {
      all: renderFrame(ctx, scene, anyView, light, lightIndex, 'all', records).shadowDrawCalls,
      kept: renderFrame(ctx, scene, anyView, light, lightIndex, 'kept', records).shadowDrawCalls,
    };
  }
  report.falseCulls = [...culprits.values()];
  const title = `light ${lightIndex} '${entry.name}' (${entry.type}): shadow-pass draw calls ${report.drawCalls.all} all, ${report.drawCalls.kept} kept; bias ${entry.bias} m -> three ${light.shadow.bias.toExponential(3)}, normalBias ${entry.normalBias} m`;
  report.picture = rows.length ? composePicture(title, rows, ctx.width, ctx.height) : null;
  scene.remove(light);
  if (light.target) scene.remove(light.target);
  light.dispose();
  return report;
}

// The whole check. Returns { scene, primitives, lights: [per-light report] }.
export async function runFrameCheck(userOptions = {}) {
  const options = { ...DEFAULT_OPTIONS, ...userOptions };
  useHardLightEdges();
  const gltf = await loadScene(options.scene);
  const entries = readLightEntries(gltf.parser.json);
  const records = applyMasks(gltf, entries.length);
  withFlatNormals(records);
  assignMaterials(records);
  const scene = new THREE.Scene();
  scene.add(gltf.scene);
  scene.add(new THREE.AmbientLight(0xffffff, AMBIENT));
  scene.updateMatrixWorld(true);
  const bounds = sceneBounds(records);
  const occluders = makeOccluders(records);
  const surfaces = makeProxies(records);
  const objects = nodeObjects(gltf);
  const ctx = createRenderer(options.width, options.height);
  const lights = entries.map((entry, i) => {
    const light = makeLight(entry, objects, bounds, options);
    return checkLight(ctx, scene, records, occluders, surfaces, light, i, bounds, options);
  });
  ctx.renderer.dispose();
  return {
    scene: options.scene,
    bounds: { min: bounds.min.toArray(), max: bounds.max.toArray() },
    primitives: records.map((r) => ({ label: r.label, node: r.node, mask: r.mask, hasMask: r.hasMask, castsShadow: r.castsShadow })),
    lights,
  };
}
