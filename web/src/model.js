// Reconstruction (`core/src/decoder.rs::reconstruct`, `quantize.rs`, `transform.rs`,
// `displace.rs::local_frames`; docs/bitstream.md section 8): dequantize, inverse lifting,
// local frames of the subdivided mesh, displacement, back to the input's units.
//
// Contract: `reconstruct` gives the Rust positions bit for bit. Every expression keeps the
// Rust operation order (JS never fuses a multiply-add, and neither does Rust without
// explicit `mul_add`, which the decoder does not use). The one libm call is `powf` in the
// level scales, which `pow2` reproduces (Math.pow does not: see residual/pow2.js).

import { pow2 } from './residual/pow2.js';

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
function valences(n, faces) {
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

/**
 * The scale of every vertex: its level's, times its AQ weight `alpha * valence / h`.
 * @returns {Float64Array}
 */
export function vertexScales(header, qp, sub) {
  const n = sub.positions.length / 3;
  const lod = sub.lodOffsets;
  const scales = lodScales(qp, header.bits, lod.length - 1);
  const out = new Float64Array(n);
  const val = header.aq ? valences(n, sub.faces) : null;
  const alpha = header.aq ? header.aq.alpha : 1, h = header.aq ? header.aq.h : 1;
  for (let level = 0; level + 1 < lod.length; level++) {
    const s = scales[level];
    if (val === null) {
      out.fill(1.0 * s, lod[level], lod[level + 1]);
      continue;
    }
    for (let v = lod[level]; v < lod[level + 1]; v++) out[v] = ((alpha * Math.max(val[v], 1)) / h) * s;
  }
  return out;
}

/**
 * The update weight of each parent (vertices below `lod[level]`) for the step to `level`
 * (`transform.rs::Lifting::weights`): numerator / denominator, divided by the parent's
 * number of children at that level when `lifting.perValence`.
 */
function updateWeights(sub, lifting, level) {
  const lod = sub.lodOffsets, base = lod[1], par = sub.parents;
  const [num, den] = lifting.update[level - 1];
  const w = num / Math.max(den, 1);
  const out = new Float64Array(lod[level]);
  if (!lifting.perValence) return out.fill(w);
  const children = new Uint32Array(lod[level]);
  for (let v = lod[level]; v < lod[level + 1]; v++) {
    children[par[2 * (v - base)]]++;
    children[par[2 * (v - base) + 1]]++;
  }
  for (let p = 0; p < out.length; p++) out[p] = w / Math.max(children[p], 1);
  return out;
}

/** Inverse lifting over the levels of `sub`, in place on flat xyz `c`, with the header's `lifting`. */
export function inverseLifting(c, sub, lifting) {
  const lod = sub.lodOffsets, base = lod[1], par = sub.parents;
  for (let level = 1; level + 1 < lod.length; level++) {
    const w = updateWeights(sub, lifting, level);
    for (let v = lod[level + 1] - 1; v >= lod[level]; v--) {
      const pa = par[2 * (v - base)], pb = par[2 * (v - base) + 1];
      const a = 3 * pa, b = 3 * pb, i = 3 * v;
      for (let k = 0; k < 3; k++) {
        c[a + k] -= w[pa] * c[i + k];
        c[b + k] -= w[pb] * c[i + k];
      }
    }
    for (let v = lod[level]; v < lod[level + 1]; v++) {
      const a = 3 * par[2 * (v - base)], b = 3 * par[2 * (v - base) + 1], i = 3 * v;
      for (let k = 0; k < 3; k++) c[i + k] += 0.5 * (c[a + k] + c[b + k]);
    }
  }
}

/** Area-weighted unit vertex normals, zero where there is none (`mesh::vertex_normals`). */
export function vertexNormals(p, faces) {
  const acc = new Float64Array(p.length);
  for (let f = 0; f < faces.length; f += 3) {
    const a = 3 * faces[f], b = 3 * faces[f + 1], c = 3 * faces[f + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    acc[a] += nx; acc[a + 1] += ny; acc[a + 2] += nz;
    acc[b] += nx; acc[b + 1] += ny; acc[b + 2] += nz;
    acc[c] += nx; acc[c + 1] += ny; acc[c + 2] += nz;
  }
  for (let i = 0; i < acc.length; i += 3) {
    const n = Math.sqrt(acc[i] * acc[i] + acc[i + 1] * acc[i + 1] + acc[i + 2] * acc[i + 2]);
    if (n > 1e-300) {
      const s = 1.0 / n;
      acc[i] *= s; acc[i + 1] *= s; acc[i + 2] *= s;
    } else {
      acc[i] = 0; acc[i + 1] = 0; acc[i + 2] = 0;
    }
  }
  return acc;
}

/**
 * World displacement of one vertex from local (n, t, b) components `c`, for its unit normal
 * `n` (`displace::frame_from_normal` and `to_world`). Writes into `out` at `o`.
 */
function frameToWorld(nx, ny, nz, c0, c1, c2, out, o) {
  if (nx === 0 && ny === 0 && nz === 0) { nx = 0; ny = 0; nz = 1; }
  // The least aligned axis, the lowest on ties (the Rust fold over k = 1, 2).
  const ax = Math.abs(nx), ay = Math.abs(ny), az = Math.abs(nz);
  let axis = ay < ax ? 1 : 0;
  if (az < (axis === 0 ? ax : ay)) axis = 2;
  const na = axis === 0 ? nx : axis === 1 ? ny : nz;
  let tx = (axis === 0 ? 1 : 0) - nx * na, ty = (axis === 1 ? 1 : 0) - ny * na, tz = (axis === 2 ? 1 : 0) - nz * na;
  const len = Math.sqrt(tx * tx + ty * ty + tz * tz);
  if (len > 1e-300) {
    const s = 1.0 / len;
    tx *= s; ty *= s; tz *= s;
  } else {
    tx = 0; ty = 0; tz = 0;
  }
  const bx = ny * tz - nz * ty, by = nz * tx - nx * tz, bz = nx * ty - ny * tx;
  out[o] = nx * c0 + tx * c1 + bx * c2;
  out[o + 1] = ny * c0 + ty * c1 + by * c2;
  out[o + 2] = nz * c0 + tz * c1 + bz * c2;
}

/**
 * Positions of the decoded frame in the input's units.
 * @param {import('./stream/bitstream.js').Header} header
 * @param {import('./residual/subdivide.js').Subdivision} sub
 * @param {Int32Array} q quantized coefficients, `header.components` per vertex
 * @param {number} qp
 * @returns {Float64Array}
 */
export function reconstruct(header, sub, q, qp) {
  const comps = header.components;
  const offset = header.aq ? header.aq.delta : 0.0;
  const scales = vertexScales(header, qp, sub);
  const n = scales.length;
  const local = new Float64Array(3 * n);
  for (let v = 0; v < n; v++) {
    for (let k = 0; k < comps; k++) local[3 * v + k] = (q[v * comps + k] - offset) / scales[v];
  }
  inverseLifting(local, sub, header.lifting);
  const p = sub.positions;
  const normals = vertexNormals(p, sub.faces);
  const d = new Float64Array(3);
  const out = new Float64Array(3 * n);
  const [ox, oy, oz] = header.origin, step = header.step;
  for (let v = 0, i = 0; v < n; v++, i += 3) {
    frameToWorld(normals[i], normals[i + 1], normals[i + 2], local[i], local[i + 1], local[i + 2], d, 0);
    out[i] = ox + (p[i] + d[0]) * step;
    out[i + 1] = oy + (p[i + 1] + d[1]) * step;
    out[i + 2] = oz + (p[i + 2] + d[2]) * step;
  }
  return out;
}
