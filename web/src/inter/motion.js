// Decoder of a predicted frame's base mesh motion (`core/src/inter/motion.rs`,
// docs/bitstream.md section 6.5): breadth-first over the reference connectivity, each
// vertex's motion predicted as the rounded mean of its decoded neighbours' and coded as a
// skip flag or three integers.
//
// Contract: `decodeMotion` returns the Rust `decode_motion` positions, or null where it
// returns None (truncated, corrupt, or a vertex moved off the grid). Integers stay far
// below 2^53, so JS numbers hold them exactly.

import { bitModels, IntModel } from '../stream/ec.js';

/**
 * Sorted, repeat-free neighbour lists of `faces` over `n` vertices, as compressed rows.
 * @param {number} n
 * @param {Uint32Array} faces
 * @returns {{start: Uint32Array, adj: Uint32Array}}
 */
export function adjacency(n, faces) {
  const start = new Uint32Array(n + 1);
  for (let i = 0; i < faces.length; i++) start[faces[i] + 1] += 2;
  for (let v = 0; v < n; v++) start[v + 1] += start[v];
  const fill = start.slice(0, n);
  const all = new Uint32Array(start[n]);
  for (let i = 0; i < faces.length; i++) {
    const a = faces[i], b = faces[i - (i % 3) + ((i % 3) + 1) % 3];
    all[fill[a]++] = b;
    all[fill[b]++] = a;
  }
  const out = new Uint32Array(start[n]);
  const starts = new Uint32Array(n + 1);
  let m = 0;
  for (let v = 0; v < n; v++) {
    const list = all.subarray(start[v], start[v + 1]).sort();
    for (let j = 0; j < list.length; j++) if (j === 0 || list[j] !== list[j - 1]) out[m++] = list[j];
    starts[v + 1] = m;
  }
  return { start: starts, adj: out.subarray(0, m) };
}

function codingOrder(g, n) {
  const seen = new Uint8Array(n);
  const order = new Uint32Array(n);
  let len = 0;
  for (let seed = 0; seed < n; seed++) {
    if (seen[seed]) continue;
    seen[seed] = 1;
    let head = len;
    order[len++] = seed;
    while (head < len) {
      const v = order[head++];
      for (let j = g.start[v]; j < g.start[v + 1]; j++) {
        const w = g.adj[j];
        if (!seen[w]) { seen[w] = 1; order[len++] = w; }
      }
    }
  }
  return order;
}

/** Rust's `div_round`: integer division rounding halves away from zero. */
function divRound(a, b) {
  const h = Math.trunc(b / 2);
  return a >= 0 ? Math.trunc((a + h) / b) : -Math.trunc((-a + h) / b);
}

/**
 * @param {import('../stream/ec.js').RangeDecoder} dec
 * @param {Uint32Array} reference flat xyz on the base grid
 * @param {Uint32Array} faces the reference connectivity
 * @param {number} bits base grid bits
 * @returns {Uint32Array|null}
 */
export function decodeMotion(dec, reference, faces, bits) {
  const n = reference.length / 3;
  const max = 2 ** bits - 1;
  const g = adjacency(n, faces);
  const skipModels = bitModels(3);
  const res = [new IntModel(0), new IntModel(0), new IntModel(0)];
  const motion = new Float64Array(3 * n);
  const known = new Uint8Array(n);
  const skipped = new Uint8Array(n);
  const current = new Uint32Array(3 * n);
  for (const v of codingOrder(g, n)) {
    let sx = 0, sy = 0, sz = 0, count = 0, skips = 0;
    for (let j = g.start[v]; j < g.start[v + 1]; j++) {
      const w = g.adj[j];
      if (!known[w]) continue;
      sx += motion[3 * w]; sy += motion[3 * w + 1]; sz += motion[3 * w + 2];
      count++;
      skips += skipped[w];
    }
    const pred = count === 0 ? [0, 0, 0] : [divRound(sx, count), divRound(sy, count), divRound(sz, count)];
    const skip = dec.bit(skipModels, Math.min(skips, 2));
    const r = skip ? [0, 0, 0] : [dec.int(res[0]), dec.int(res[1]), dec.int(res[2])];
    if (dec.exhausted()) return null;
    for (let k = 0; k < 3; k++) {
      const m = pred[k] + r[k];
      const p = reference[3 * v + k] + m;
      if (p < 0 || p > max) return null;
      current[3 * v + k] = p;
      motion[3 * v + k] = m;
    }
    known[v] = 1;
    skipped[v] = skip;
  }
  return dec.finish() === null ? current : null;
}
