// The refresh of a predicted frame's worst-fitting regions (`core/src/inter/refresh.rs`).
//
// Contract: `decodeRefresh` reads what the Rust `encode_refresh` wrote (the dropped flags of
// the moved base's faces, then a base mesh block) or throws an Error with the Rust reason;
// `applyRefresh` and `carry` return what the Rust `apply` and `carry` return.

import { RangeDecoder, bitModels } from '../ec.js';
import { decodeBase } from '../base/coder.js';
import { subdividedFaces } from '../residual/subdivide.js';

/** Marks a vertex no kept face uses. */
const NEW = 0xffffffff;

/**
 * @param {Uint8Array} data the refresh block
 * @param {number} faceCount faces of the moved base
 * @param {number} bits base mesh position bits
 * @returns {{dropped: Uint8Array, patch: {positions: Uint32Array, faces: Uint32Array}}}
 */
export function decodeRefresh(data, faceCount, bits) {
  const corrupt = () => new Error('refresh block is truncated or corrupt');
  if (data.length < 4) throw corrupt();
  const n = new DataView(data.buffer, data.byteOffset, data.byteLength).getUint32(0, true);
  if (n > data.length - 4) throw corrupt();
  const dec = new RangeDecoder(data.subarray(4, 4 + n));
  const models = bitModels(2);
  const dropped = new Uint8Array(faceCount);
  let previous = 0;
  for (let f = 0; f < faceCount; f++) {
    previous = dec.bit(models, previous);
    dropped[f] = previous;
    if (dec.exhausted()) throw corrupt();
  }
  if (dec.finish()) throw corrupt();
  let patch;
  try {
    patch = decodeBase(data.subarray(4 + n), bits);
  } catch (e) {
    throw new Error(`refresh patch: ${e.message}`);
  }
  return { dropped, patch };
}

/**
 * The refreshed base: the kept faces over the vertices they use (in their order), then the
 * patch's vertices and faces; `kept` lists the moved base's index of each kept face.
 */
export function applyRefresh(positions, faces, dropped, patch) {
  const n = positions.length / 3;
  const index = new Uint32Array(n).fill(NEW);
  const kept = [];
  for (let f = 0; f < dropped.length; f++) {
    if (dropped[f]) continue;
    kept.push(f);
    for (let k = 0; k < 3; k++) index[faces[3 * f + k]] = 0;
  }
  let used = 0;
  for (let v = 0; v < n; v++) if (index[v] === 0) index[v] = used++;
  const np = patch.positions.length / 3;
  const outPositions = new Uint32Array(3 * (used + np));
  for (let v = 0; v < n; v++) if (index[v] !== NEW) outPositions.set(positions.subarray(3 * v, 3 * v + 3), 3 * index[v]);
  outPositions.set(patch.positions, 3 * used);
  const outFaces = new Uint32Array(3 * kept.length + patch.faces.length);
  let o = 0;
  for (const f of kept) for (let k = 0; k < 3; k++) outFaces[o++] = index[faces[3 * f + k]];
  for (let i = 0; i < patch.faces.length; i++) outFaces[o++] = patch.faces[i] + used;
  return { positions: outPositions, faces: outFaces, kept };
}

/**
 * The reference state's coefficients carried onto `sub`, the subdivision of a refreshed base
 * whose first faces are the reference faces `kept` (`refresh::carry`), 0 on new vertices;
 * null when the reference's coefficient count does not fit its subdivision.
 */
export function carry(reference, sub, kept, components) {
  const levels = sub.lodOffsets.length - 2;
  const { faces: theirs, vertexCount } = subdividedFaces(reference.faces, reference.positions.length / 3, levels);
  if (vertexCount * components !== reference.coefficients.length) return null;
  const children = 4 ** levels;
  const mine = sub.faces;
  const total = sub.lodOffsets[sub.lodOffsets.length - 1];
  const out = new Int32Array(total * components);
  // The children of a kept face repeat, corner for corner, those of the reference face it is.
  kept.forEach((f, k) => {
    for (let i = 0; i < 3 * children; i++) {
      const v = mine[3 * k * children + i], m = theirs[3 * f * children + i];
      for (let c = 0; c < components; c++) out[v * components + c] = reference.coefficients[m * components + c];
    }
  });
  return out;
}
