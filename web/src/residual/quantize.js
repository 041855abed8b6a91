// Quantization scales (`core/src/residual/quantize.rs`, docs/bitstream.md section 8.3): the
// scale of each level of detail, and the valences by which adaptive quantization weights a
// vertex's scale.
//
// Contract: `lodScales` gives the Rust `quantize::lod_scales` bit for bit; its one libm call,
// `powf`, is `pow2` here (Math.pow is not correctly rounded: see pow2.js).

import { pow2 } from './pow2.js';

/**
 * Quantization scale of each level of detail (`quantize::lod_scales`).
 * @param {number} qp
 * @param {number} bits
 * @param {number} lodCount
 * @returns {number[]}
 */
export function lodScales(qp, bits, lodCount) {
  const top = pow2(16.0 - bits + (4.0 - qp) / 6.0);
  const out = [];
  for (let l = 0; l < lodCount; l++) out.push(top / 2 ** l);
  return out;
}

/** Distinct neighbours of each vertex of `faces` (valence; AQ weights). */
export function valences(n, faces) {
  const start = new Uint32Array(n + 1);
  for (let i = 0; i < faces.length; i++) start[faces[i] + 1] += 2;
  for (let v = 0; v < n; v++) start[v + 1] += start[v];
  const fill = start.slice(0, n);
  const nb = new Uint32Array(start[n]);
  for (let i = 0; i < faces.length; i++) {
    const a = faces[i], b = faces[i - (i % 3) + ((i % 3) + 1) % 3];
    nb[fill[a]++] = b;
    nb[fill[b]++] = a;
  }
  const out = new Uint32Array(n);
  for (let v = 0; v < n; v++) {
    // Insertion sort in place: lists are short (twice the faces around the vertex).
    const from = start[v], to = start[v + 1];
    for (let i = from + 1; i < to; i++) {
      const x = nb[i];
      let j = i - 1;
      for (; j >= from && nb[j] > x; j--) nb[j + 1] = nb[j];
      nb[j + 1] = x;
    }
    let d = 0;
    for (let j = from; j < to; j++) if (j === from || nb[j] !== nb[j - 1]) d++;
    out[v] = d;
  }
  return out;
}
