// A tiny static file server on 127.0.0.1 for the frame-check page: ES modules and an
// import map do not load from file:// in Chromium (module scripts need CORS), so the page,
// three.js and the scene are served over HTTP from this machine only.
//
//   node server.mjs SCENE.glb [--port N]     then open the printed address in a browser
//
// Serves page/ and node_modules/three/ of this folder, and the scene as /scene.glb.

import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));

const TYPES = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.mjs': 'text/javascript; charset=utf-8',
  '.json': 'application/json',
  '.glb': 'model/gltf-binary',
  '.gltf': 'model/gltf+json',
  '.png': 'image/png',
  '.bin': 'application/octet-stream',
};

// The file a request path names, or null: only page/ and node_modules/three/ of this
// folder, never a path that climbs out of them.
function fileFor(urlPath, scenePath) {
  if (urlPath === '/' || urlPath === '/index.html') return path.join(HERE, 'page', 'index.html');
  if (urlPath === '/scene.glb') return scenePath;
  const roots = { '/page/': path.join(HERE, 'page'), '/node_modules/three/': path.join(HERE, 'node_modules', 'three') };
  for (const [prefix, root] of Object.entries(roots)) {
    if (!urlPath.startsWith(prefix)) continue;
    const file = path.resolve(root, '.' + urlPath.slice(prefix.length - 1));
    return file.startsWith(root + path.sep) ? file : null;
  }
  return null;
}

// Starts serving; resolves to { url, close() }. Port 0: any free port.
export function startServer({ scenePath, port = 0 }) {
  const server = http.createServer((req, res) => {
    const urlPath = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
    const file = fileFor(urlPath, scenePath);
    if (!file || !fs.existsSync(file) || !fs.statSync(file).isFile()) {
      res.writeHead(404, { 'content-type': 'text/plain' });
      res.end(`not found: ${urlPath}\n`);
      return;
    }
    res.writeHead(200, {
      'content-type': TYPES[path.extname(file).toLowerCase()] || 'application/octet-stream',
      'cache-control': 'no-store',
    });
    fs.createReadStream(file).pipe(res);
  });
  return new Promise((resolve, reject) => {
    server.once('error', reject);
    server.listen(port, '127.0.0.1', () => {
      const { port: bound } = server.address();
      resolve({ url: `http://127.0.0.1:${bound}/`, close: () => new Promise((done) => server.close(done)) });
    });
  });
}

if (process.argv[1] && path.resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  const args = process.argv.slice(2);
  const scenePath = args.find((a) => !a.startsWith('--'));
  const portAt = args.indexOf('--port');
  if (!scenePath) {
    console.error('usage: node server.mjs SCENE.glb [--port N]');
    process.exit(2);
  }
  const { url } = await startServer({ scenePath: path.resolve(scenePath), port: portAt >= 0 ? Number(args[portAt + 1]) : 8080 });
  console.log(`serving ${scenePath} at ${url} (Ctrl-C stops)`);
}
