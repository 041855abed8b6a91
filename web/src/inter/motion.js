// Decoder of a predicted frame's base mesh motion (`core/src/inter/motion.rs`,
// docs/bitstream.md section 6.5): breadth-first over the reference connectivity, each
// vertex's motion predicted from its decoded neighbours' (their rounded mean, or the block's
// first bit set, a ridge-regularised affine fit over two rings) and coded as a skip flag or
// three integers.
//
// Contract: `decodeMotion` returns the Rust `decode_motion` positions, or null where it
// returns None (truncated, corrupt, or a vertex moved off the grid). The affine fit's sums
// stay below 2^53 (the Rust side bounds the samples for this), so JS numbers hold them
// exactly, and its solve repeats the Rust doubles operation for operation.

import { bitModels, IntModel } from '../ec.js';

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

// The Rust constants RIDGE, AFFINE_MIN_SAMPLES, MAX_SAMPLES, MAX_SCAN.
const RIDGE = 30;
const AFFINE_MIN_SAMPLES = 4;
const MAX_SAMPLES = 32;
const MAX_SCAN = 256;

/** Rust's `two_ring`: decoded vertices within two rings of `v`, in its order and limits. */
function twoRing(v, g, known, mark) {
  const stamp = v + 1;
  mark[v] = stamp;
  const out = [];
  let scanned = 0;
  const lists = [v];
  for (let j = g.start[v]; j < g.start[v + 1]; j++) lists.push(g.adj[j]);
  for (const u of lists) {
    for (let j = g.start[u]; j < g.start[u + 1]; j++) {
      if (scanned === MAX_SCAN || out.length === MAX_SAMPLES) return out;
      scanned++;
      const w = g.adj[j];
      if (mark[w] !== stamp && known[w]) {
        mark[w] = stamp;
        out.push(w);
      }
    }
  }
  return out;
}

/** Rust's `affine_at`: the affine fit's motion at `v`, or null when it is not finite. */
function affineAt(v, samples, reference, motion) {
  const n = samples.length;
  const sx = [0, 0, 0], sm = [0, 0, 0];
  const sxx = [[0, 0, 0], [0, 0, 0], [0, 0, 0]], sxm = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
  for (const w of samples) {
    const x = [0, 1, 2].map((i) => reference[3 * w + i] - reference[3 * v + i]);
    for (let i = 0; i < 3; i++) {
      sx[i] += x[i];
      sm[i] += motion[3 * w + i];
      for (let j = 0; j < 3; j++) {
        sxx[i][j] += x[i] * x[j];
        sxm[i][j] += x[i] * motion[3 * w + j];
      }
    }
  }
  const s = (i, j) => n * sxx[i][j] - sx[i] * sx[j] + (i === j ? n * RIDGE : 0);
  const c = (i, k) => n * sxm[i][k] - sx[i] * sm[k];
  const m00 = s(0, 0), m01 = s(0, 1), m02 = s(0, 2), m11 = s(1, 1), m12 = s(1, 2), m22 = s(2, 2);
  const adj = [
    [m11 * m22 - m12 * m12, m02 * m12 - m01 * m22, m01 * m12 - m02 * m11],
    [m02 * m12 - m01 * m22, m00 * m22 - m02 * m02, m01 * m02 - m00 * m12],
    [m01 * m12 - m02 * m11, m01 * m02 - m00 * m12, m00 * m11 - m01 * m01],
  ];
  const det = m00 * adj[0][0] + m01 * adj[0][1] + m02 * adj[0][2];
  const pred = [0, 0, 0];
  for (let k = 0; k < 3; k++) {
    const gr = [0, 1, 2].map((i) => (adj[i][0] * c(0, k) + adj[i][1] * c(1, k) + adj[i][2] * c(2, k)) / det);
    const t = Math.floor((sm[k] - (gr[0] * sx[0] + gr[1] * sx[1] + gr[2] * sx[2])) / n + 0.5);
    if (!Number.isFinite(t) || Math.abs(t) > 2 ** 40) return null;
    pred[k] = t;
  }
  return pred;
}

/**
 * @param {import('../ec.js').RangeDecoder} dec
 * @param {Uint32Array} reference flat xyz on the base grid
 * @param {Uint32Array} faces the reference connectivity
 * @param {number} bits base grid bits
 * @returns {Uint32Array|null}
 */
export function decodeMotion(dec, reference, faces, bits) {
  const n = reference.length / 3;
  const max = 2 ** bits - 1;
  const affine = dec.bit(bitModels(1), 0);
  const g = adjacency(n, faces);
  const mark = new Uint32Array(affine ? n : 0);
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
    let pred = count === 0 ? [0, 0, 0] : [divRound(sx, count), divRound(sy, count), divRound(sz, count)];
    if (affine) {
      const samples = twoRing(v, g, known, mark);
      const fit = samples.length >= AFFINE_MIN_SAMPLES ? affineAt(v, samples, reference, motion) : null;
      if (fit !== null) pred = fit;
    }
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
