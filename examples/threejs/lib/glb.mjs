// Reading and writing a .glb's JSON chunk (glTF 2.0 binary container, little-endian):
// a 12-byte header ("glTF", version 2, total length), then chunks of
// (length, type, data), the first one JSON (padded with spaces to 4 bytes), the second,
// optional, BIN (padded with zeros). Used by the scene generator and the export editor;
// the page reads scenes with three's GLTFLoader.

import fs from 'node:fs';

const MAGIC = 0x46546c67; // "glTF"
const JSON_CHUNK = 0x4e4f534a; // "JSON"
const BIN_CHUNK = 0x004e4942; // "BIN\0"

// { json, bin } of a .glb file: bin is a Buffer or null.
export function readGlb(path) {
  const bytes = fs.readFileSync(path);
  if (bytes.length < 20 || bytes.readUInt32LE(0) !== MAGIC) throw new Error(`${path}: not a .glb file`);
  let json = null;
  let bin = null;
  for (let at = 12; at + 8 <= bytes.length; ) {
    const length = bytes.readUInt32LE(at);
    const type = bytes.readUInt32LE(at + 4);
    const data = bytes.subarray(at + 8, at + 8 + length);
    if (type === JSON_CHUNK) json = JSON.parse(data.toString('utf8'));
    else if (type === BIN_CHUNK && bin === null) bin = Buffer.from(data);
    at += 8 + length;
  }
  if (!json) throw new Error(`${path}: no JSON chunk`);
  return { json, bin };
}

function padded(buffer, fill) {
  const pad = (4 - (buffer.length % 4)) % 4;
  return pad ? Buffer.concat([buffer, Buffer.alloc(pad, fill)]) : buffer;
}

// The bytes of a .glb holding `json` and, when given, `bin` (a Buffer).
export function glbBytes(json, bin) {
  const jsonChunk = padded(Buffer.from(JSON.stringify(json), 'utf8'), 0x20);
  const chunks = [[JSON_CHUNK, jsonChunk]];
  if (bin) chunks.push([BIN_CHUNK, padded(bin, 0)]);
  const total = 12 + chunks.reduce((n, [, data]) => n + 8 + data.length, 0);
  const header = Buffer.alloc(12);
  header.writeUInt32LE(MAGIC, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(total, 8);
  const parts = [header];
  for (const [type, data] of chunks) {
    const head = Buffer.alloc(8);
    head.writeUInt32LE(data.length, 0);
    head.writeUInt32LE(type, 4);
    parts.push(head, data);
  }
  return Buffer.concat(parts);
}

export function writeGlb(path, json, bin) {
  fs.writeFileSync(path, glbBytes(json, bin));
}
