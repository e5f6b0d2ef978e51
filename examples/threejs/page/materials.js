// Materials of the check: a plain lit one for the frames, and one flat shader for the
// analysis passes (object ID, world position, world normal), both with the glTF's side and
// alpha test, so every pass sees the same surface at a pixel.

import * as THREE from 'three';

// glTF: a primitive without normals gets flat normals (the spec asks clients for that).
// three.js needs them as an attribute: its shadow lookup offsets along the vertex normal
// (normalBias), and without one it offsets by nothing. Shared geometries are converted once.
export function withFlatNormals(records) {
  const converted = new Map();
  for (const { mesh } of records) {
    const g = mesh.geometry;
    if (g.attributes.normal) continue;
    if (!converted.has(g)) {
      const flat = g.index ? g.toNonIndexed() : g.clone();
      flat.computeVertexNormals(); // per triangle on a non-indexed geometry: flat
      converted.set(g, flat);
    }
    mesh.geometry = converted.get(g);
  }
}

// The frame material: Lambert (diffuse only, so lit and shadowed differ clearly; the
// glTF's metallic-roughness would leave metals black without an environment) with the
// glTF's colour, texture, alpha test and side. shadowSide DoubleSide: every triangle goes
// into the shadow map, so the map holds the first surface of any kind along each texel's
// ray, as the bake assumes (three's default draws only back faces of one-sided materials,
// which drops the shadow of an open mesh lit from its front).
export function frameMaterial(original) {
  const m = new THREE.MeshLambertMaterial({
    color: original.color ? original.color.clone() : new THREE.Color(0xcccccc),
    map: original.map || null,
    alphaTest: original.alphaTest || (original.transparent ? 0.5 : 0),
    opacity: original.opacity ?? 1,
    side: original.side,
  });
  m.shadowSide = THREE.DoubleSide;
  return m;
}

const ANALYSIS_VERTEX = /* glsl */ `
  varying vec2 vUv;
  varying vec3 vWorld;
  varying vec3 vNormalWorld;
  void main() {
    vUv = uv;
    vec4 world = modelMatrix * vec4(position, 1.0);
    vWorld = world.xyz;
    // The world normal exactly as three's shadow lookup takes it (shadowmap_vertex:
    // transformNormalByInverseViewMatrix of normalMatrix * normal).
    vNormalWorld = normalize((vec4(normalMatrix * normal, 0.0) * viewMatrix).xyz);
    gl_Position = projectionMatrix * viewMatrix * world;
  }
`;

const ANALYSIS_FRAGMENT = /* glsl */ `
  uniform int mode;          // 0 object ID, 1 world position (metres), 2 world normal
  uniform vec3 idColor;      // the primitive's ID, 8 bits a channel
  uniform sampler2D map;
  uniform bool useMap;
  uniform float alphaTest;
  uniform float opacity;
  varying vec2 vUv;
  varying vec3 vWorld;
  varying vec3 vNormalWorld;
  void main() {
    float alpha = opacity;
    if (useMap) alpha *= texture2D(map, vUv).a;
    if (alpha < alphaTest) discard;
    if (mode == 0) gl_FragColor = vec4(idColor, 1.0);
    else if (mode == 1) gl_FragColor = vec4(vWorld, 1.0);
    else gl_FragColor = vec4(normalize(vNormalWorld), 1.0);
  }
`;

export const PASS_ID = 0;
export const PASS_POSITION = 1;
export const PASS_NORMAL = 2;

// The ID pass's colour for record id k (k >= 1; 0 is the background).
export function idColor(id) {
  return new THREE.Color(((id >> 16) & 255) / 255, ((id >> 8) & 255) / 255, (id & 255) / 255);
}

export function analysisMaterial(frame, id) {
  return new THREE.ShaderMaterial({
    uniforms: {
      mode: { value: PASS_ID },
      idColor: { value: idColor(id) },
      map: { value: frame.map },
      useMap: { value: Boolean(frame.map) },
      alphaTest: { value: frame.alphaTest },
      opacity: { value: frame.opacity },
    },
    vertexShader: ANALYSIS_VERTEX,
    fragmentShader: ANALYSIS_FRAGMENT,
    side: frame.side,
  });
}

// Gives every record its two materials and puts the frame one on.
export function assignMaterials(records) {
  for (const r of records) {
    r.frameMaterial = frameMaterial(r.mesh.material);
    r.analysisMaterial = analysisMaterial(r.frameMaterial, r.id);
    r.twoSided = r.frameMaterial.side === THREE.DoubleSide;
    r.mesh.material = r.frameMaterial;
  }
}

export function useFrameMaterials(records) {
  for (const r of records) r.mesh.material = r.frameMaterial;
}

export function useAnalysisMaterials(records, mode) {
  for (const r of records) {
    r.analysisMaterial.uniforms.mode.value = mode;
    r.mesh.material = r.analysisMaterial;
  }
}
