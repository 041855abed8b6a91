// The reconstruction model (`core/src/model.rs`, which the Rust encoder and decoder share;
// docs/bitstream.md sections 8 and 9): the face allowance of a frame, the subdivided base
// mesh, the scale of every vertex, and the reconstruction of a frame's positions:
// dequantize, inverse lifting, local frames of the subdivided mesh, displacement, back to
// the input's units.
//
// Contract: `reconstruct` gives the Rust positions bit for bit. Every expression keeps the
// Rust operation order (JS never fuses a multiply-add, and neither does Rust without
// explicit `mul_add`, which the decoder does not use). The one libm call is `powf` in the
// level scales, which `pow2` reproduces (Math.pow does not: see residual/pow2.js).

import { subdivide } from './residual/subdivide.js';
import { lodScales, valences } from './residual/quantize.js';
import { inverseLifting } from './residual/transform.js';
import { vertexNormals, frameToWorld } from './residual/displace.js';
import { FACE_ALLOWANCE_MAX, FACE_ALLOWANCE_PER_BYTE, FACE_ALLOWANCE_MIN } from './stream/syntax.js';

// The bounds on what a frame may decode to, as core/src/model.rs and docs/bitstream.md give
// them (declared in stream/syntax.js): a stream the Rust decoder refuses for its size is
// refused here too.
export const MAX_OUTPUT_FACES = FACE_ALLOWANCE_MAX;
export const FACES_PER_UNIT_BYTE = FACE_ALLOWANCE_PER_BYTE;
export const MIN_FACE_ALLOWANCE = FACE_ALLOWANCE_MIN;

/** The most output faces a frame unit of `bytes` payload bytes may decode to. */
export function faceAllowance(bytes) {
  return Math.min(Math.max(bytes * FACES_PER_UNIT_BYTE, MIN_FACE_ALLOWANCE), MAX_OUTPUT_FACES);
}

/** Subdivision of a base mesh on the base grid, `lod` iterations of the header's schemes. */
export function subdividedBase(h, positions, faces, lod) {
  const step = 2 ** (h.bits - h.baseBits);
  const p = new Float64Array(positions.length);
  for (let i = 0; i < p.length; i++) p[i] = 0.0 + positions[i] * step;
  return subdivide(p, faces, h.schemes.slice(0, lod));
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
