// Decoder of the displacement coefficient block (`core/src/residual/coefcoder.rs`,
// docs/bitstream.md section 7): level by level, component by component, each slice with
// fresh contexts.
//
// Contract: `decodeCoefficients` returns the Rust `coefcoder::decode` values for the
// levels of `sub` (which may stop short of the stream's last level: level-of-detail
// decoding reads only the levels it keeps, since later levels come later in the block),
// or null where the Rust code returns None.

import { bitModels, UIntModel } from '../ec.js';

// Bank layout of one (level, component) slice.
const ALL_ZERO = 0, ZERO = 1, SIGN = 4, GT1 = 5, GT2 = 6;

/**
 * @param {import('../ec.js').RangeDecoder} dec
 * @param {number} comps 1 or 3
 * @param {import('./subdivide.js').Subdivision} sub
 * @returns {Int32Array|null} vertex-major, `comps` values per vertex
 */
export function decodeCoefficients(dec, comps, sub) {
  const lod = sub.lodOffsets;
  const base = lod[1];
  const q = new Int32Array((sub.positions.length / 3) * comps);
  const parents = sub.parents;
  for (let level = 0; level + 1 < lod.length; level++) {
    for (let k = 0; k < comps; k++) {
      const bank = bitModels(7);
      const rem = new UIntModel(0);
      if (dec.bit(bank, ALL_ZERO)) continue;
      let prev = 0;
      for (let v = lod[level]; v < lod[level + 1]; v++) {
        let ctx;
        if (level === 0) ctx = prev !== 0 ? 1 : 0;
        else {
          const i = 2 * (v - base);
          ctx = (q[parents[i] * comps + k] !== 0 ? 1 : 0) + (q[parents[i + 1] * comps + k] !== 0 ? 1 : 0);
        }
        let c = 0;
        if (dec.bit(bank, ZERO + ctx)) {
          const negative = dec.bit(bank, SIGN);
          let m = 1;
          if (dec.bit(bank, GT1)) {
            m = 2;
            if (dec.bit(bank, GT2)) m = 3 + dec.uint(rem);
          }
          if (m > 0x7fffffff) return null;
          c = negative ? -m : m;
        }
        q[v * comps + k] = c;
        prev = c;
      }
      if (dec.exhausted()) return null;
    }
  }
  return dec.finish() === null ? q : null;
}
