#!/usr/bin/env node
// Writes a glTF scene with many casters the bake should cull, and some it must keep:
//
//   node gen_scene.mjs OUT.glb [--columns N]
//
// Import it with the sun from -Z, 60 degrees up (light travelling +Z and down), and a bias:
//   shadowcull import OUT.glb SPACE --sun 0,60 --bias 0.05
//
// Metres, Y up; a ground 64 m deep (z in [-32, 32]) and wide enough for N columns
// (default 5) 12 m apart:
//   row A, z = -24: OnGround_k       cubes on the ground: kept for the sun
//   row B, z =  -8: Roof_k           7 m slabs at y 4..4.4, over
//                   UnderRoof_k      cubes hidden from every light: culled
//                   (column 0 is Stack_0: one mesh of two primitives, a cube hidden under
//                   the roof and a cube standing on it: masks [0, sun])
//                   GapCube          between the middle roofs, lit by the lamp
//   row C, z =  37: Floating_k       cubes beyond the ground's edge: shadow on nothing
//   row D, z =  16: NoShadow (extras.shadowcull_casts_shadow false) > NoShadowRoof, a slab
//                   that casts no shadow, over UnderNoShadowRoof: that cube must stay 1;
//                   SpotCube under the spot light (kept), SpotRoof over SpotHidden
//                   (hidden from the spot, not from the sun)
//   Lamp: a point light (range 10 m) over the middle roof, bias 0.03 m, and
//         extras.shadowcull_normal_bias 0.03 m (engine normal offset)
//   Spot: a spot light at (12, 8, 16) pointing down, 40 degrees, range 12 m
// The hidden cubes are covered with at least 0.3 m to spare (many shadow-map texels).

import { writeGlb } from './lib/glb.mjs';

// ---- geometry: boxes with flat normals (24 vertices, 12 triangles) and a ground quad ----

function box([sx, sy, sz], [ox, oy, oz] = [0, 0, 0]) {
  const positions = [];
  const normals = [];
  const indices = [];
  const faces = [
    [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
    [[-1, 0, 0], [0, 1, 0], [0, 0, -1]],
    [[0, 1, 0], [0, 0, 1], [1, 0, 0]],
    [[0, -1, 0], [0, 0, -1], [1, 0, 0]],
    [[0, 0, 1], [1, 0, 0], [0, 1, 0]],
    [[0, 0, -1], [-1, 0, 0], [0, 1, 0]],
  ];
  const half = [sx / 2, sy / 2, sz / 2];
  for (const [n, u, v] of faces) {
    const base = positions.length / 3;
    for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, 1]]) {
      for (let k = 0; k < 3; k++) positions.push((n[k] + a * u[k] + b * v[k]) * half[k] + [ox, oy, oz][k]);
      normals.push(...n);
    }
    // u x v = n, so (0, 1, 2) runs counter-clockwise seen from outside: glTF front faces.
    indices.push(base, base + 1, base + 2, base, base + 2, base + 3);
  }
  return { positions, normals, indices };
}

function groundQuad(sizeX, sizeZ) {
  const [h, d] = [sizeX / 2, sizeZ / 2];
  return {
    positions: [-h, 0, d, h, 0, d, h, 0, -d, -h, 0, -d],
    normals: [0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0],
    indices: [0, 1, 2, 0, 2, 3],
  };
}

// ---- a glTF document with one buffer, built as meshes are added ----

class GltfWriter {
  constructor() {
    this.json = {
      asset: { version: '2.0', generator: 'shadowcull examples/threejs/gen_scene.mjs' },
      extensionsUsed: ['KHR_lights_punctual'],
      extensions: { KHR_lights_punctual: { lights: [] } },
      scene: 0,
      scenes: [{ nodes: [] }],
      nodes: [],
      meshes: [],
      materials: [],
      accessors: [],
      bufferViews: [],
      buffers: [{ byteLength: 0 }],
    };
    this.chunks = [];
    this.length = 0;
  }

  view(bytes, target) {
    const pad = (4 - (this.length % 4)) % 4;
    if (pad) this.chunks.push(Buffer.alloc(pad)), (this.length += pad);
    this.json.bufferViews.push({ buffer: 0, byteOffset: this.length, byteLength: bytes.length, target });
    this.chunks.push(bytes);
    this.length += bytes.length;
    return this.json.bufferViews.length - 1;
  }

  accessor(values, type, componentType) {
    const bytes = componentType === 5126 ? Buffer.from(new Float32Array(values).buffer) : Buffer.from(new Uint32Array(values).buffer);
    const a = { bufferView: this.view(bytes, componentType === 5126 ? 34962 : 34963), componentType, count: values.length / (type === 'VEC3' ? 3 : 1), type };
    if (type === 'VEC3') {
      a.min = [0, 1, 2].map((k) => Math.min(...values.filter((_, i) => i % 3 === k)));
      a.max = [0, 1, 2].map((k) => Math.max(...values.filter((_, i) => i % 3 === k)));
    }
    this.json.accessors.push(a);
    return this.json.accessors.length - 1;
  }

  material(name, rgb) {
    this.json.materials.push({ name, pbrMetallicRoughness: { baseColorFactor: [...rgb, 1], metallicFactor: 0, roughnessFactor: 1 } });
    return this.json.materials.length - 1;
  }

  // primitives: [[geometry, material], ...] in order (the primitive groups).
  mesh(name, primitives) {
    this.json.meshes.push({
      name,
      primitives: primitives.map(([g, material]) => ({
        attributes: { POSITION: this.accessor(g.positions, 'VEC3', 5126), NORMAL: this.accessor(g.normals, 'VEC3', 5126) },
        indices: this.accessor(g.indices, 'SCALAR', 5125),
        material,
      })),
    });
    return this.json.meshes.length - 1;
  }

  light(def) {
    this.json.extensions.KHR_lights_punctual.lights.push(def);
    return this.json.extensions.KHR_lights_punctual.lights.length - 1;
  }

  // Adds a node (under `parent`, else to the scene); returns its index.
  node(def, parent = null) {
    this.json.nodes.push(def);
    const index = this.json.nodes.length - 1;
    if (parent === null) this.json.scenes[0].nodes.push(index);
    else (this.json.nodes[parent].children ||= []).push(index);
    return index;
  }

  write(path) {
    const bin = Buffer.concat(this.chunks);
    this.json.buffers[0].byteLength = bin.length;
    writeGlb(path, this.json, bin);
  }
}

// Rotation (quaternion x, y, z, w) turning the node's -Z (where lights shine) to -Y.
const POINT_DOWN = [-Math.SQRT1_2, 0, 0, Math.SQRT1_2];

function buildScene(columns) {
  const w = new GltfWriter();
  const grey = w.material('ground', [0.55, 0.55, 0.55]);
  const orange = w.material('kept cube', [0.9, 0.45, 0.15]);
  const blue = w.material('hidden cube', [0.2, 0.4, 0.9]);
  const purple = w.material('floating cube', [0.6, 0.3, 0.8]);
  const roofColour = w.material('roof', [0.55, 0.45, 0.35]);
  const green = w.material('no-shadow roof', [0.3, 0.75, 0.4]);
  const teal = w.material('spot cube', [0.15, 0.7, 0.7]);

  const cube = w.mesh('cube', [[box([1.5, 1.5, 1.5]), orange]]);
  const hiddenCube = w.mesh('hiddenCube', [[box([1.5, 1.5, 1.5]), blue]]);
  const floatCube = w.mesh('floatCube', [[box([1.5, 1.5, 1.5]), purple]]);
  const roof = w.mesh('roof', [[box([7, 0.4, 7]), roofColour]]);
  const noShadowRoof = w.mesh('noShadowRoof', [[box([7, 0.4, 7]), green]]);
  const smallRoof = w.mesh('smallRoof', [[box([4, 0.3, 4]), roofColour]]);
  const smallCube = w.mesh('smallCube', [[box([1, 1, 1]), teal]]);
  const tealCube = w.mesh('tealCube', [[box([1.5, 1.5, 1.5]), teal]]);
  // Two primitives: a cube under the roof (hidden) and one standing on the roof (lit).
  const stack = w.mesh('stack', [
    [box([1.5, 1.5, 1.5], [0, 0.75, 0]), blue],
    [box([1.5, 1.5, 1.5], [0, 5.15, 0]), orange],
  ]);
  const ground = w.mesh('ground', [[groundQuad(Math.max(64, columns * 12 + 4), 64), grey]]);

  const spacing = 12;
  const xs = Array.from({ length: columns }, (_, k) => (k - (columns - 1) / 2) * spacing);
  w.node({ name: 'Ground', mesh: ground });
  xs.forEach((x, k) => w.node({ name: `OnGround_${k}`, mesh: cube, translation: [x, 0.75, -24] }));
  xs.forEach((x, k) => {
    w.node({ name: `Roof_${k}`, mesh: roof, translation: [x, 4.2, -8] });
    if (k === 0) w.node({ name: 'Stack_0', mesh: stack, translation: [x, 0, -8] });
    else w.node({ name: `UnderRoof_${k}`, mesh: hiddenCube, translation: [x, 0.75, -8] });
  });
  xs.forEach((x, k) => w.node({ name: `Floating_${k}`, mesh: floatCube, translation: [x, 3, 37] }));

  // The lamp over the middle roof's +x edge, and a cube in the gap beside that roof.
  const mid = xs[Math.floor(columns / 2)];
  w.node({ name: 'GapCube', mesh: cube, translation: [mid + 6.5, 0.75, -8] });
  const lamp = w.light({ name: 'lamp', type: 'point', intensity: 80, range: 10 });
  w.node({
    name: 'Lamp',
    translation: [mid + 4.5, 7, -8],
    extensions: { KHR_lights_punctual: { light: lamp } },
    extras: { shadowcull_bias: 0.03, shadowcull_normal_bias: 0.03 },
  });

  // Row D: a roof that casts no shadow (said by its parent), over a cube that must stay 1.
  const parent = w.node({ name: 'NoShadow', translation: [-12, 0, 16], extras: { shadowcull_casts_shadow: false } });
  w.node({ name: 'NoShadowRoof', mesh: noShadowRoof, translation: [0, 4.2, 0] }, parent);
  w.node({ name: 'UnderNoShadowRoof', mesh: cube, translation: [-12, 0.75, 16] });
  // The spot light straight down over SpotCube; SpotRoof hides SpotHidden from it.
  w.node({ name: 'SpotCube', mesh: tealCube, translation: [12, 0.75, 16] });
  w.node({ name: 'SpotRoof', mesh: smallRoof, translation: [15.5, 4, 16] });
  w.node({ name: 'SpotHidden', mesh: smallCube, translation: [16, 0.5, 16] });
  const spot = w.light({ name: 'spot', type: 'spot', intensity: 200, range: 12, spot: { outerConeAngle: (40 * Math.PI) / 180 } });
  w.node({ name: 'Spot', translation: [12, 8, 16], rotation: POINT_DOWN, extensions: { KHR_lights_punctual: { light: spot } } });
  return w;
}

const args = process.argv.slice(2);
const out = args.find((a) => !a.startsWith('--'));
const at = args.indexOf('--columns');
const columns = at >= 0 ? Number(args[at + 1]) : 5;
if (!out || !(Number.isInteger(columns) && columns >= 3 && columns <= 15)) {
  console.error('usage: node gen_scene.mjs OUT.glb [--columns N]   (N from 3 to 15, default 5)');
  process.exit(2);
}
buildScene(columns).write(out);
console.log(`wrote ${out}: ${columns} columns`);
