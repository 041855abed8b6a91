#!/usr/bin/env node
// decode-batch.js [--lod K] FILE...: decodes each stream with the JavaScript decoder and
// prints one JSON line per file, {"file", "hashes"} or {"file", "error"} with the decoder's
// message; for the Python tests that compare both decoders on many streams in one process.
import { readFileSync } from 'node:fs';
import { Decoder } from '../../src/index.js';
import { frameHash } from '../../src/hash.js';

let args = process.argv.slice(2);
let lod;
if (args[0] === '--lod') {
  lod = Number(args[1]);
  args = args.slice(2);
}
for (const file of args) {
  const hashes = [];
  try {
    const dec = new Decoder(new Uint8Array(readFileSync(file)), { lod });
    for (let i = 0; i < dec.frameCount; i++) hashes.push(frameHash(dec.decodeFrame(i)));
    console.log(JSON.stringify({ file, hashes }));
  } catch (e) {
    console.log(JSON.stringify({ file, hashes, error: e.message }));
  }
}
