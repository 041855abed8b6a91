// Damaged streams: the JS decoder throws the Rust decoder's message (frame, byte offset,
// reason) and never hangs. The Python tests compare both decoders on many more.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { Decoder, DecodeError } from '../src/index.js';
import { crc32 } from '../src/stream/crc32.js';

const data = new Uint8Array(readFileSync(new URL('../../tests/vectors/constant_midpoint_all.dmsh', import.meta.url)));
const headerLength = 75 + 3 * data[43]; // docs/bitstream.md section 2

function error(bytes) {
  try {
    const dec = new Decoder(bytes);
    for (let i = 0; i < dec.frameCount; i++) dec.decodeFrame(i);
  } catch (e) {
    assert.ok(e instanceof DecodeError, String(e));
    return e.message;
  }
  return null;
}

test('a truncated or foreign file names what is missing', () => {
  assert.equal(error(data.subarray(0, 3)), 'byte offset 0: magic: needs 4 bytes, 3 left');
  assert.equal(error(new TextEncoder().encode('PLY!xxxxxxxxxx')), 'byte offset 0: not a dynmesh stream (bad magic)');
  assert.match(error(data.subarray(0, data.length - 1)), /^frame 2, byte offset \d+: unit CRC: needs 4 bytes, 3 left$/);
  assert.equal(error(data.subarray(0, headerLength + 3)), 'byte offset 5: header claims 3 frames; the stream has room for at most 0');
  assert.match(error(data.subarray(0, headerLength + 30)), /^frame 0, byte offset \d+: unit payload: needs \d+ bytes, 25 left$/);
});

test('a flipped bit fails a CRC', () => {
  const d = data.slice();
  d[10] ^= 4;
  assert.equal(error(d), `byte offset ${headerLength - 4}: sequence header CRC mismatch`);
  const e = data.slice();
  e[headerLength + 20] ^= 1;
  assert.match(error(e), /^frame 0, byte offset \d+: unit CRC mismatch \(corrupted data\)$/);
});

test('garbage behind a valid CRC is an error or a frame, quickly, never a hang', () => {
  const length = new DataView(data.buffer, data.byteOffset).getUint32(headerLength + 1, true);
  let errors = 0;
  const start = Date.now();
  for (let seed = 1; seed <= 60; seed++) {
    const d = data.slice();
    let x = seed;
    for (let k = 0; k < 3; k++) {
      x = (x * 1103515245 + 12345) >>> 0;
      d[headerLength + 5 + (x % length)] = x >>> 24;
    }
    const crc = crc32(d, headerLength, headerLength + 5 + length);
    new DataView(d.buffer).setUint32(headerLength + 5 + length, crc, true);
    const m = error(d);
    if (m !== null) {
      errors++;
      assert.match(m, /^frame \d+, byte offset \d+: /);
    }
  }
  assert.ok(errors > 30, `${errors} of 60 damaged streams refused`);
  assert.ok(Date.now() - start < 20000);
});

test('a level of detail beyond the stream is refused', () => {
  assert.throws(() => new Decoder(data, { lod: 9 }), /level of detail 9 out of range \(the stream has 2 subdivision iterations\)/);
});

test('the output face allowance is the Rust decoder\'s (docs/bitstream.md section 9)', async () => {
  const { faceAllowance } = await import('../src/index.js');
  assert.equal(faceAllowance(0), 2 ** 20);
  assert.equal(faceAllowance(4096), 4096 * 512);
  assert.equal(faceAllowance(2 ** 30), 2 ** 23);
});

test('a frame the stream does not have is a RangeError, not damage', () => {
  const dec = new Decoder(data);
  const n = dec.frameCount;
  assert.throws(() => dec.decodeFrame(n), (e) => e instanceof RangeError && e.message === `frame ${n} does not exist: the stream has ${n} frame${n === 1 ? '' : 's'}`);
  assert.throws(() => dec.decodeFrame(-1), RangeError);
  assert.ok(dec.decodeFrame(n - 1));
});
