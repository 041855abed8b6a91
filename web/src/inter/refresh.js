// The refresh of a predicted frame's worst-fitting regions (`core/src/inter/refresh.rs`).
//
// Contract: `decodeRefresh` reads what the Rust `encode_refresh` wrote (the dropped flags of
// the moved base's faces, then a base mesh block) or throws an Error with the Rust reason;
// `applyRefresh`, `correspondence` and `carried` return what their Rust namesakes return.

import { RangeDecoder, bitModels } from '../stream/ec.js';
import { decodeBase } from '../base/coder.js';

/** Marks a vertex that repeats none of the reference's (`refresh::NEW`). */
export const NEW = 0xffffffff;

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
 * patch's vertices and faces; `origin[v]` is the moved base's vertex that v repeats, or NEW.
 */
export function applyRefresh(positions, faces, dropped, patch) {
  const n = positions.length / 3;
  const index = new Uint32Array(n).fill(NEW);
  let keptFaces = 0;
  for (let f = 0; f < dropped.length; f++) {
    if (dropped[f]) continue;
    keptFaces++;
    for (let k = 0; k < 3; k++) index[faces[3 * f + k]] = 0;
  }
  const originList = [];
  for (let v = 0; v < n; v++) if (index[v] === 0) { index[v] = originList.length; originList.push(v); }
  const kept = originList.length, np = patch.positions.length / 3;
  const outPositions = new Uint32Array(3 * (kept + np));
  originList.forEach((v, i) => outPositions.set(positions.subarray(3 * v, 3 * v + 3), 3 * i));
  outPositions.set(patch.positions, 3 * kept);
  const outFaces = new Uint32Array(3 * keptFaces + patch.faces.length);
  let o = 0;
  for (let f = 0; f < dropped.length; f++) {
    if (dropped[f]) continue;
    for (let k = 0; k < 3; k++) outFaces[o++] = index[faces[3 * f + k]];
  }
  for (let i = 0; i < patch.faces.length; i++) outFaces[o++] = patch.faces[i] + kept;
  const origin = new Uint32Array(kept + np).fill(NEW);
  origin.set(originList);
  return { positions: outPositions, faces: outFaces, origin };
}

/** For each vertex of the subdivision `refreshed`, the vertex of `reference` it repeats, or NEW. */
export function correspondence(reference, refreshed, origin) {
  const first = reference.lodOffsets[1];
  const splits = new Map();
  const key = (a, b) => (a < b ? a * 4294967296 + b : b * 4294967296 + a);
  for (let i = 0; i < reference.parents.length / 2; i++) {
    splits.set(key(reference.parents[2 * i], reference.parents[2 * i + 1]), first + i);
  }
  const total = refreshed.lodOffsets[refreshed.lodOffsets.length - 1];
  const map = new Uint32Array(total);
  map.set(origin);
  for (let i = 0; i < refreshed.parents.length / 2; i++) {
    const ma = map[refreshed.parents[2 * i]], mb = map[refreshed.parents[2 * i + 1]];
    const m = ma === NEW || mb === NEW ? undefined : splits.get(key(ma, mb));
    map[origin.length + i] = m === undefined ? NEW : m;
  }
  return map;
}

/** The reference's coefficients carried onto the vertices of `map`; 0 for new vertices. */
export function carried(map, reference, components) {
  const out = new Int32Array(map.length * components);
  for (let v = 0; v < map.length; v++) {
    if (map[v] === NEW) continue;
    for (let k = 0; k < components; k++) out[v * components + k] = reference[map[v] * components + k];
  }
  return out;
}
