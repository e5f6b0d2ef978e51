// The parameter mapping of page/bias_mapping.js against three.js's depth conventions
// (README.md, "Mapping the parameters"): node --test examples/threejs/test/bias_mapping.test.mjs
import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  directionalShadowBias,
  pcfRadiusTexels,
  perspectiveAxialBias,
  perspectiveShadowBias,
  perspectiveWindowDepth,
} from '../page/bias_mapping.js';

// three.js shadows q when z(q) + shadow.bias > z(p) (shadowmap_pars_fragment, basic map).
const threeShadows = (zq, zp, shadowBias) => zq + shadowBias > zp;

test('directional: linear depth, the bias maps exactly', () => {
  const near = 0;
  const far = 97.8;
  const bias = 0.05;
  const b = directionalShadowBias(bias, near, far);
  assert.ok(b < 0);
  const z = (d) => (d - near) / (far - near);
  for (const dp of [0.5, 10, 50, 97]) {
    assert.equal(threeShadows(z(dp + bias * 1.001), z(dp), b), true);
    assert.equal(threeShadows(z(dp + bias * 0.999), z(dp), b), false);
  }
});

test('perspective: every q the tool shadows, three.js shadows too, anywhere in range', () => {
  for (const [near, far, bias, type, cone] of [
    [0.05, 6, 0.02, 'point'],
    [0.05, 20, 0.05, 'spot', 28.6],
    [0.05, 12, 0.05, 'spot', 40],
    [0.05, 100, 0.5, 'spot', 80],
  ]) {
    const axial = perspectiveAxialBias(bias, type, cone);
    const b = perspectiveShadowBias(axial, near, far);
    const worstCos = type === 'point' ? 1 / Math.sqrt(3) : Math.cos((cone * Math.PI) / 180);
    for (let k = 0; k <= 1000; k++) {
      const dp = near + ((far - near - bias) * k) / 1000; // view depth of p
      // q more than `bias` behind p along the ray, on the worst ray: view depth
      // grows by bias * cos, with a hair more than the tool's bias.
      const dq = dp + bias * 1.0001 * worstCos;
      if (dq > far) continue;
      assert.equal(threeShadows(perspectiveWindowDepth(dq, near, far), perspectiveWindowDepth(dp, near, far), b), true, `${type} dp ${dp}`);
    }
    // At the far plane the offset is worth exactly the axial bias: no slack wasted there.
    const atFar = perspectiveWindowDepth(far, near, far) - perspectiveWindowDepth(far - axial, near, far);
    assert.ok(Math.abs(atFar + b) < 1e-12);
  }
});

test('no bias, no offset; filterRadius 0 means the basic map', () => {
  assert.equal(perspectiveShadowBias(0, 0.05, 10), 0);
  assert.equal(pcfRadiusTexels(0, 0.02), 0);
  assert.equal(pcfRadiusTexels(0.1, 0.02), 3.5); // 5 texels of reach less the 1.5 of a tap
});
