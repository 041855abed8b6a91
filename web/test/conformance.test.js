// The JavaScript decoder against the conformance vectors (tests/vectors): every frame of
// every stream at every level of detail hashes as the manifest, which the Rust decoder wrote.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { Decoder } from '../src/index.js';
import { frameHash } from '../src/hash.js';

const DIR = fileURLToPath(new URL('../../tests/vectors/', import.meta.url));

/** manifest.txt as {stream: {lod: [hash of frame 0, 1, ...]}}. */
export function readManifest(dir = DIR) {
  const out = {};
  for (const line of readFileSync(dir + 'manifest.txt', 'utf8').split('\n')) {
    if (!line.trim()) continue;
    const [stream, , lod, , frame, , hash] = line.split(' ');
    ((out[stream] ??= {})[lod] ??= [])[Number(frame)] = hash;
  }
  return out;
}

const manifest = readManifest();

test('the manifest covers several streams and levels', () => {
  assert.ok(Object.keys(manifest).length >= 5);
});

for (const [stream, levels] of Object.entries(manifest)) {
  test(`${stream} decodes to the manifest's hashes at every level of detail`, () => {
    const data = new Uint8Array(readFileSync(DIR + stream));
    for (const [lod, hashes] of Object.entries(levels)) {
      const dec = new Decoder(data, { lod: Number(lod) });
      assert.equal(dec.frameCount, hashes.length);
      for (let i = 0; i < dec.frameCount; i++) {
        assert.equal(frameHash(dec.decodeFrame(i)), hashes[i], `frame ${i} at lod ${lod}`);
      }
    }
  });
}
