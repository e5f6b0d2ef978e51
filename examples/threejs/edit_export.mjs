#!/usr/bin/env node
// Edits an exported scene's extras.shadowcull, for tests of the frame check:
//
//   node edit_export.mjs IN.glb OUT.glb cull NODE_NAME LIGHT_NAME [PRIMITIVE]
//       clears the light's bit of a node's primitive (all primitives when none is given),
//       which must be 1: a deliberate false cull, for the check to catch;
//   node edit_export.mjs IN.glb OUT.glb set-light LIGHT_NAME KEY NUMBER
//       sets a parameter of a light entry (e.g. normalBias) for the client.
//
// Exit codes: 0 written, 2 usage or nothing to change.

import { readGlb, writeGlb } from './lib/glb.mjs';

function fail(message) {
  console.error(`edit_export: ${message}`);
  process.exit(2);
}

function lightIndex(json, name) {
  const lights = json.extras?.shadowcull?.lights || [];
  const i = lights.findIndex((L) => L.name === name);
  if (i < 0) fail(`no light named '${name}' in extras.shadowcull.lights (${lights.map((L) => L.name).join(', ')})`);
  return i;
}

function cull(json, nodeName, lightName, primitive) {
  const i = lightIndex(json, lightName);
  const n = (json.nodes || []).findIndex((node) => node.name === nodeName);
  if (n < 0) fail(`no node named '${nodeName}'`);
  const extras = json.nodes[n].extras?.shadowcull;
  if (!extras) fail(`node ${n} '${nodeName}' has no extras.shadowcull (no masks to edit)`);
  const which = primitive === undefined ? extras.groups.map((_, k) => k) : [Number(primitive)];
  for (const k of which) {
    if (!(k >= 0 && k < extras.groups.length)) fail(`node '${nodeName}' has no primitive ${k}`);
    if (((extras.groups[k] >>> i) & 1) === 0) fail(`node '${nodeName}' primitive ${k}: bit ${i} ('${lightName}') is already 0`);
    extras.groups[k] = (extras.groups[k] & ~(1 << i)) >>> 0;
  }
  extras.mask = extras.groups.reduce((m, g) => (m | g) >>> 0, 0);
  console.log(`node ${n} '${nodeName}': cleared bit ${i} ('${lightName}') of primitive(s) ${which.join(', ')}: groups now [${extras.groups.join(', ')}]`);
}

function setLight(json, lightName, key, value) {
  const v = Number(value);
  if (!Number.isFinite(v)) fail(`'${value}' is not a number`);
  const L = json.extras.shadowcull.lights[lightIndex(json, lightName)];
  console.log(`light '${lightName}': ${key} ${L[key]} -> ${v}`);
  L[key] = v;
}

const [input, output, command, ...args] = process.argv.slice(2);
if (!input || !output || !command) fail('usage: edit_export.mjs IN.glb OUT.glb cull NODE LIGHT [PRIMITIVE] | set-light LIGHT KEY NUMBER');
const { json, bin } = readGlb(input);
if (command === 'cull' && args.length >= 2) cull(json, args[0], args[1], args[2]);
else if (command === 'set-light' && args.length === 3) setLight(json, ...args);
else fail(`bad command: ${[command, ...args].join(' ')}`);
writeGlb(output, json, bin);
