#!/usr/bin/env node
// decode-batch.js [--lod K] FILE...: decodes each stream with the JavaScript decoder and
// prints one JSON line per file, {"file", "hashes", "uvHashes" (textured streams)} or
// {"file", "error"} with the decoder's message; for the Python tests that compare both decoders on many streams in one process.
import { readFileSync } from 'node:fs';
import { Decoder } from '../../src/index.js';
import { frameHash } from '../../src/hash.js';
import { frameUvs } from '../../src/texture/unit.js';
import { createHash } from 'node:crypto';

const bytes = (a) => new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
const uvHash = ({ uv, uvFaces }) => createHash('sha256').update(bytes(uv)).update(bytes(uvFaces)).digest('hex');

let args = process.argv.slice(2);
let lod;
if (args[0] === '--lod') {
  lod = Number(args[1]);
  args = args.slice(2);
}
for (const file of args) {
  const hashes = [], uvHashes = [];
  try {
    const dec = new Decoder(new Uint8Array(readFileSync(file)), { lod });
    const uvs = frameUvs(dec);
    for (let i = 0; i < dec.frameCount; i++) {
      hashes.push(frameHash(dec.decodeFrame(i)));
      const uv = uvs(i);
      if (uv) uvHashes.push(uvHash(uv));
    }
    console.log(JSON.stringify({ file, hashes, ...(uvHashes.length ? { uvHashes } : {}) }));
  } catch (e) {
    console.log(JSON.stringify({ file, hashes, error: e.message }));
  }
}
