// The JavaScript decoder against the conformance vectors (tests/vectors): every frame of
// every stream at every level of detail hashes as the manifest, which the Rust decoder wrote.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { Decoder } from '../src/index.js';
import { readPayload } from '../src/decoder.js';
import { RangeDecoder, bitModels } from '../src/ec.js';
import { frameHash } from '../src/hash.js';
import { frameUvs } from '../src/texture/unit.js';
import { createHash } from 'node:crypto';

const DIR = fileURLToPath(new URL('../../tests/vectors/', import.meta.url));

/** manifest.txt lines of one kind (sha256: frames; uvsha256: UVs of textured frames) as
 * {stream: {lod: [hash of frame 0, 1, ...]}}. */
export function readManifest(kind = 'sha256', dir = DIR) {
  const out = {};
  for (const line of readFileSync(dir + 'manifest.txt', 'utf8').split('\n')) {
    if (!line.trim()) continue;
    const [stream, , lod, , frame, what, hash] = line.split(' ');
    if (what === kind) ((out[stream] ??= {})[lod] ??= [])[Number(frame)] = hash;
  }
  return out;
}

const manifest = readManifest();
const uvManifest = readManifest('uvsha256');

function uvHash({ uv, uvFaces }) {
  return createHash('sha256').update(new Uint8Array(uv.buffer, uv.byteOffset, uv.byteLength))
    .update(new Uint8Array(uvFaces.buffer, uvFaces.byteOffset, uvFaces.byteLength)).digest('hex');
}

for (const [stream, levels] of Object.entries(uvManifest)) {
  test(`${stream}: the UV atlas decodes and subdivides to the manifest's UVs at every level`, () => {
    const data = new Uint8Array(readFileSync(DIR + stream));
    for (const [lod, hashes] of Object.entries(levels)) {
      const dec = new Decoder(data, { lod: Number(lod) });
      const uvs = frameUvs(dec);
      for (let i = 0; i < dec.frameCount; i++) {
        dec.decodeFrame(i);
        const frame = uvs(i);
        assert.equal(frame.uvFaces.length, dec.decodeFrame(i).faces.length);
        assert.equal(uvHash(frame), hashes[i], `frame ${i} at lod ${lod}`);
      }
    }
  });
}

test('the vectors hold intra frames, predicted frames of both coefficient modes, a refreshed one and both motion predictors', () => {
  const kinds = new Set();
  for (const stream of Object.keys(manifest)) {
    const dec = new Decoder(new Uint8Array(readFileSync(DIR + stream)));
    dec.units.forEach((u, i) => {
      if (u.type === 0) return kinds.add('I');
      const p = readPayload(dec.data, u, i);
      kinds.add(`P${p.coefficientsPredicted ? 1 : 0}`);
      if (p.refresh.length > 0) kinds.add(`refreshed P${p.coefficientsPredicted ? 1 : 0}`);
      // The motion block's first bit selects its predictor (docs/bitstream.md section 6.5).
      kinds.add(new RangeDecoder(p.base).bit(bitModels(1), 0) ? 'affine' : 'mean');
    });
  }
  assert.deepEqual([...kinds].sort(), ['I', 'P0', 'P1', 'affine', 'mean', 'refreshed P1']);
});

test('an untextured stream has no UVs', () => {
  const dec = new Decoder(new Uint8Array(readFileSync(DIR + 'anchor_mixed_aq.dmsh')));
  dec.decodeFrame(0);
  assert.equal(frameUvs(dec)(0), null);
});

test('the manifest covers several streams and levels, and textured UVs', () => {
  assert.ok(Object.keys(manifest).length >= 5);
  assert.ok(Object.keys(uvManifest).length >= 1);
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
