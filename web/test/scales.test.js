// The level scale is the decoder's one libm call (Rust `powf`, here `pow2`): the two
// must agree on every bit depth and QP the format allows, or decoded positions differ.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { lodScales } from '../src/residual/quantize.js';

const FILE = new URL('../../tests/vectors/scales.txt', import.meta.url);

test('pow2 gives the reference scale for every bit depth and QP', () => {
  const lines = readFileSync(FILE, 'utf8').trim().split('\n');
  assert.equal(lines.length, 13 * 88);
  const view = new DataView(new ArrayBuffer(8));
  const bad = [];
  for (const line of lines) {
    const [bits, qp, hex] = line.split(' ');
    view.setFloat64(0, lodScales(Number(qp), Number(bits), 1)[0]);
    const got = [...new Uint8Array(view.buffer)].map((b) => b.toString(16).padStart(2, '0')).join('');
    if (got !== hex) bad.push(`bits ${bits} qp ${qp}: ${got} != ${hex}`);
  }
  assert.deepEqual(bad, []);
});
