// The masks as an engine applies them: read extras.shadowcull from the glTF JSON, map each
// mesh primitive to the three.js Mesh GLTFLoader made for it, and route every primitive to
// the shadow maps of the lights whose bit is 1.
//
// three.js decides per object whether it casts (castShadow) but not per light. Layers give
// the per-light choice: the shadow pass draws an object only when `object.layers` shares a
// layer with the light's shadow camera (WebGLShadowMap.renderObject). So:
//   layer 0           the main camera (every primitive, so every surface is seen and lit);
//   layer 1 + i       light i's kept casters (bit i of the primitive's mask is 1);
//   layer 31          every caster the engine draws without masks (the "all" frame).
// A light's shadow camera sees layer 1 + i in the "kept" frame and layer 31 in the "all"
// frame. Primitives that cast no shadow at all (castShadow false) are on layer 0 only.

export const LAYER_MAIN = 0;
export const LAYER_ALL_CASTERS = 31;
export const MAX_LIGHTS = 30; // layers 1..30: one per light
export const layerOfLight = (i) => 1 + i;

export const bitOf = (mask, light) => ((mask >>> light) & 1) === 1;

// The root's extras.shadowcull.lights, in bit order, checked: an engine must not guess.
export function readLightEntries(json) {
  const lights = json.extras?.shadowcull?.lights;
  if (!Array.isArray(lights) || lights.length === 0)
    throw new Error('the scene has no extras.shadowcull.lights: export it with `shadowcull export` first');
  if (lights.length > MAX_LIGHTS) throw new Error(`${lights.length} lights: this client has layers for ${MAX_LIGHTS}`);
  lights.forEach((L, i) => {
    const where = `extras.shadowcull.lights[${i}]`;
    if (!['directional', 'point', 'spot'].includes(L.type)) throw new Error(`${where}: unknown type '${L.type}'`);
    if (L.node === null && !Array.isArray(L.direction)) throw new Error(`${where}: a light without a node needs a "direction"`);
    if (L.node !== null && !Number.isInteger(L.node)) throw new Error(`${where}: "node" is not a node index`);
    if (L.type !== 'directional' && !(L.range > 0)) throw new Error(`${where}: a ${L.type} light needs a "range" (metres)`);
    if (L.type === 'spot' && !(L.coneAngle > 0)) throw new Error(`${where}: a spot light needs a "coneAngle" (degrees)`);
  });
  return lights;
}

// Per glTF node: does it cast shadows? extras.shadowcull_casts_shadow on the node, else on
// its nearest ancestor that states it, else true (docs/format.md, "glTF scenes").
export function castsShadowPerNode(json) {
  const nodes = json.nodes || [];
  const parent = new Array(nodes.length).fill(-1);
  nodes.forEach((n, i) => (n.children || []).forEach((c) => (parent[c] = i)));
  return nodes.map((_, i) => {
    for (let at = i; at >= 0; at = parent[at]) {
      const says = nodes[at].extras?.shadowcull_casts_shadow;
      if (typeof says === 'boolean') return says;
    }
    return true;
  });
}

// The glTF node a three.js object stands for: itself or its nearest ancestor that
// GLTFLoader associated with a node (a mesh of several primitives is a Group of Meshes
// under the node's object; a single-primitive mesh is the node's object itself).
function nodeIndexOf(object, associations) {
  for (let o = object; o; o = o.parent) {
    const a = associations.get(o);
    if (a && a.nodes !== undefined) return a.nodes;
  }
  return undefined;
}

// One record per drawn primitive: { mesh, node, nodeName, primitive, mask, castsShadow,
// alphaTested, label }. A node without extras.shadowcull keeps all its shadows (mask all
// ones). Sets each mesh's layers and castShadow as described at the top.
export function applyMasks(gltf, lightCount) {
  const json = gltf.parser.json;
  const associations = gltf.parser.associations;
  const casts = castsShadowPerNode(json);
  const allBits = lightCount >= 32 ? 0xffffffff : 2 ** lightCount - 1;
  const records = [];
  gltf.scene.traverse((mesh) => {
    if (!mesh.isMesh) return;
    const primitive = associations.get(mesh)?.primitives;
    const node = nodeIndexOf(mesh, associations);
    if (primitive === undefined || node === undefined) throw new Error(`mesh '${mesh.name}' has no glTF primitive or node`);
    const nodeDef = json.nodes[node];
    const extras = nodeDef.extras?.shadowcull;
    const primitives = json.meshes[nodeDef.mesh].primitives.length;
    if (extras && (!Array.isArray(extras.groups) || extras.groups.length !== primitives))
      throw new Error(`nodes[${node}] '${nodeDef.name}': extras.shadowcull.groups has ${extras.groups?.length} masks for ${primitives} primitives`);
    const record = {
      mesh,
      node,
      nodeName: nodeDef.name || `node ${node}`,
      primitive,
      primitives,
      mask: extras ? extras.groups[primitive] >>> 0 : allBits,
      hasMask: Boolean(extras),
      castsShadow: casts[node],
      alphaTested: mesh.material.alphaTest > 0 || mesh.material.transparent === true,
    };
    record.label = primitives > 1 ? `${record.nodeName}[${primitive}]` : record.nodeName;
    mesh.castShadow = record.castsShadow;
    mesh.receiveShadow = true;
    mesh.layers.set(LAYER_MAIN);
    if (record.castsShadow) {
      mesh.layers.enable(LAYER_ALL_CASTERS);
      for (let i = 0; i < lightCount; i++) if (bitOf(record.mask, i)) mesh.layers.enable(layerOfLight(i));
    }
    records.push(record);
  });
  records.forEach((r, k) => (r.id = k + 1)); // 0: background in the object-ID pass
  return records;
}

// Is the primitive's shadow culled for light i (drawn in the "all" frame, not in "kept")?
export const culledFor = (record, i) => record.castsShadow && !bitOf(record.mask, i);
