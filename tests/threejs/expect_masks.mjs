#!/usr/bin/env node
// Checks the masks an export wrote on named nodes, before the frame check looks at them
// (so that a scene whose casters the bake kept after all cannot pass as "nothing culled"):
//
//   node expect_masks.mjs EXPORTED.glb 'NODE_PATTERN:LIGHT=BIT[,BIT...]' ...
//
// NODE_PATTERN is a node name, or a prefix ending in '*' (every node starting with it,
// at least one); LIGHT a light name of extras.shadowcull.lights; BIT the expected bit per
// primitive (0 or 1). Prints each mismatch; exit 0 all as expected, 1 otherwise.

import { readGlb } from '../../examples/threejs/lib/glb.mjs';

const [file, ...expectations] = process.argv.slice(2);
if (!file || expectations.length === 0) {
  console.error("usage: expect_masks.mjs EXPORTED.glb 'NODE:LIGHT=BIT[,BIT...]' ...");
  process.exit(2);
}
const { json } = readGlb(file);
const lights = json.extras.shadowcull.lights.map((L) => L.name);
let failures = 0;
for (const e of expectations) {
  const m = /^(.+):([^:=]+)=([01](,[01])*)$/.exec(e);
  if (!m) throw new Error(`bad expectation '${e}'`);
  const [, pattern, light, bits] = m;
  const bit = lights.indexOf(light);
  if (bit < 0) throw new Error(`no light '${light}' (${lights.join(', ')})`);
  const matches = (name) => (pattern.endsWith('*') ? name?.startsWith(pattern.slice(0, -1)) : name === pattern);
  const nodes = json.nodes.filter((n) => matches(n.name));
  if (nodes.length === 0) {
    console.log(`MISMATCH ${e}: no node matches`);
    failures++;
  }
  for (const n of nodes) {
    const groups = n.extras?.shadowcull?.groups;
    const got = groups ? groups.map((g) => (g >>> bit) & 1).join(',') : 'no extras.shadowcull';
    if (got !== bits) {
      console.log(`MISMATCH node '${n.name}' light '${light}': expected ${bits}, exported ${got}`);
      failures++;
    }
  }
}
console.log(failures ? `${failures} mask(s) not as expected in ${file}` : `masks as expected (${expectations.length} checks) in ${file}`);
process.exit(failures ? 1 : 0);
