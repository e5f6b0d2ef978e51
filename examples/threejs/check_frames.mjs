#!/usr/bin/env node
// The frame check's driver: renders a scene exported by `shadowcull export` in three.js
// (WebGL2 in headless Chromium), with every caster and with the kept ones, per light and
// camera, and says where the frames differ and why (page/classify.js).
//
//   node check_frames.mjs SCENE.glb [--out DIR] [--json FILE] [--width W] [--height H]
//                         [--cameras N] [--chromium PATH]
//
// Exit codes: 0 no false cull and fewer shadow-pass draw calls with the masks; 1 a false
// cull found (each named: node, primitive, light), or the draw calls did not drop;
// 2 usage; 3 the browser or the page failed.

import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import puppeteer from 'puppeteer-core';
import { startServer } from './server.mjs';

const USAGE = 'usage: node check_frames.mjs SCENE.glb [--out DIR] [--json FILE] [--width W] [--height H] [--cameras N] [--chromium PATH]';

// Software WebGL2: no GPU here (or in CI). ANGLE on SwiftShader is what works headless;
// Chromium 137+ wants --enable-unsafe-swiftshader to allow it for WebGL.
const CHROMIUM_FLAGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--disable-extensions',
  '--disable-default-apps',
  '--mute-audio',
];

function parseArgs(argv) {
  const o = { out: '.', json: null, width: 600, height: 400, cameras: 4, chromium: process.env.CHROMIUM || '/usr/bin/chromium' };
  const rest = [];
  for (let k = 0; k < argv.length; k++) {
    const a = argv[k];
    const value = () => {
      if (k + 1 >= argv.length) throw new Error(`${a} needs a value`);
      return argv[++k];
    };
    if (a === '--out') o.out = value();
    else if (a === '--json') o.json = value();
    else if (a === '--width') o.width = Number(value());
    else if (a === '--height') o.height = Number(value());
    else if (a === '--cameras') o.cameras = Number(value());
    else if (a === '--chromium') o.chromium = value();
    else if (a === '--help' || a === '-h') throw new Error('help');
    else if (a.startsWith('--')) throw new Error(`unknown option ${a}`);
    else rest.push(a);
  }
  if (rest.length !== 1) throw new Error('give one scene (.glb)');
  o.scene = path.resolve(rest[0]);
  if (!fs.existsSync(o.scene)) throw new Error(`${rest[0]}: no such file`);
  for (const key of ['width', 'height', 'cameras']) if (!(Number.isInteger(o[key]) && o[key] > 0)) throw new Error(`--${key} must be a positive whole number`);
  return o;
}

// Runs the page's check in a fresh headless Chromium; resolves to the page's report.
async function renderInBrowser(options) {
  const server = await startServer({ scenePath: options.scene });
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'shadowcull-chromium-'));
  const browser = await puppeteer.launch({
    executablePath: options.chromium,
    headless: true,
    userDataDir: profile,
    args: CHROMIUM_FLAGS,
    protocolTimeout: 900_000, // ms: a large scene renders for minutes on software GL
  });
  const pageErrors = [];
  try {
    const page = await browser.newPage();
    page.on('pageerror', (e) => pageErrors.push(String(e)));
    page.on('console', (m) => m.type() === 'error' && pageErrors.push(m.text()));
    await page.goto(`${server.url}?driven`, { waitUntil: 'load' });
    await page.waitForFunction('window.frameCheckReady === true', { timeout: 60_000 });
    return await page.evaluate((opts) => window.frameCheck.run(opts), {
      scene: '/scene.glb',
      width: options.width,
      height: options.height,
      cameras: options.cameras,
    });
  } catch (e) {
    const detail = pageErrors.length ? `\npage errors:\n  ${pageErrors.join('\n  ')}` : '';
    throw new Error(`${e.message}${detail}`);
  } finally {
    await browser.close();
    await server.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
}

// One PNG per light: <scene>-light<i>-<name>.png in --out.
function writePictures(report, options) {
  fs.mkdirSync(options.out, { recursive: true });
  const base = path.basename(options.scene).replace(/\.[^.]*$/, '');
  for (const light of report.lights) {
    if (!light.picture) continue;
    const file = path.join(options.out, `${base}-light${light.light}-${light.name.replace(/[^A-Za-z0-9_.-]+/g, '_')}.png`);
    fs.writeFileSync(file, Buffer.from(light.picture.replace(/^data:image\/png;base64,/, ''), 'base64'));
    light.pictureFile = file;
    delete light.picture;
  }
}

function printReport(report, options) {
  const cm = (m) => `${(m * 100).toFixed(1)} cm`;
  console.log(`scene ${options.scene}: ${report.primitives.length} primitives, ${report.lights.length} lights`);
  for (const L of report.lights) {
    const p = L.parameters;
    console.log(`light ${L.light} '${L.name}' (${L.type}${L.node === null ? ', no node' : `, node ${L.node}`}): bias ${p.bias} m -> three.js shadow.bias ${p.threeShadowBias.toExponential(3)}, normalBias ${p.normalBias} m, slopeBias ${p.slopeBias} m, filterRadius ${p.filterRadius} m -> ${p.shadowMap} map, texel ${cm(p.texelMetres)}`);
    console.log(`  culled casters (${L.culledCasters.length}): ${L.culledCasters.join(', ') || '-'}`);
    console.log(`  shadow-pass draw calls: all ${L.drawCalls.all}, kept ${L.drawCalls.kept}`);
    for (const c of L.cameras)
      console.log(`  ${c.camera}: ${c.compared} px compared, ${c.differing} differ: ${c.culledSurface} on culled casters' own surfaces, ${c.keptSurface} on kept surfaces (band ${c.band}, not receiving ${c.notReceiving}); false cull ${c.falseCull} (${c.falseCullOnKept} on kept surfaces)`);
    if (L.cameras.length === 0) console.log('  no camera: the light reaches no part of the scene');
    if (L.pictureFile) console.log(`  picture: ${L.pictureFile}`);
    for (const f of L.falseCulls)
      console.log(`  FALSE CULL: node ${f.node} '${f.nodeName}' (${f.primitive}) for light ${L.light} '${f.light}': its shadow is missing on ${f.pixels} px (up to ${cm(f.maxGapMetres)} behind it beyond the bias)`);
  }
}

// The gate: { ok, lines }.
function verdict(report) {
  const sum = (f) => report.lights.reduce((n, L) => n + f(L), 0);
  const falseCull = sum((L) => L.cameras.reduce((n, c) => n + c.falseCull, 0));
  const band = sum((L) => L.cameras.reduce((n, c) => n + c.band, 0));
  const culledOwn = sum((L) => L.cameras.reduce((n, c) => n + c.culledSurface, 0));
  const all = sum((L) => L.drawCalls.all);
  const kept = sum((L) => L.drawCalls.kept);
  const anyCulled = report.lights.some((L) => L.culledCasters.length > 0);
  const lines = [
    `differing pixels: ${falseCull} false cull (any surface), ${band} band (kept surfaces), ${culledOwn} on culled casters' own surfaces`,
    `shadow-pass draw calls: ${all} with every caster, ${kept} with the masks`,
  ];
  let ok = true;
  if (falseCull > 0) lines.push('FAIL: false-cull pixels: the bake culled a shadow three.js draws'), (ok = false);
  if (report.lights.some((L) => L.drawCalls.kept > L.drawCalls.all)) lines.push('FAIL: a light draws more casters with the masks than without'), (ok = false);
  if (anyCulled && !(kept < all)) lines.push('FAIL: the scene has culled casters but the shadow pass draws no fewer'), (ok = false);
  if (ok) lines.push('PASS');
  return { ok, lines };
}

async function main() {
  let options;
  try {
    options = parseArgs(process.argv.slice(2));
  } catch (e) {
    console.error(e.message === 'help' ? USAGE : `check_frames: ${e.message}\n${USAGE}`);
    return e.message === 'help' ? 0 : 2;
  }
  let report;
  const started = Date.now();
  try {
    report = await renderInBrowser(options);
  } catch (e) {
    console.error(`check_frames: the browser check failed: ${e.message}`);
    return 3;
  }
  writePictures(report, options);
  printReport(report, options);
  if (options.json) fs.writeFileSync(options.json, JSON.stringify(report, null, 1) + '\n');
  const { ok, lines } = verdict(report);
  for (const line of lines) console.log(line);
  console.log(`(${((Date.now() - started) / 1000).toFixed(1)} s)`);
  return ok ? 0 : 1;
}

process.exitCode = await main();
