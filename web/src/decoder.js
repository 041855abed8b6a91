// The decoder (`core/src/decoder.rs`): a checked stream whose frames decode in any order.
//
// Contract: `new Decoder(bytes, {lod})` checks the header and every unit's CRC up front, as
// the Rust `Decoder::new` does; `decodeFrame(i)` returns frame i's positions (flat float64
// xyz) and faces (flat uint32) bit for bit as the Rust decoder at the same level of detail,
// or throws a DecodeError with the Rust message. A predicted frame is decoded from the intra
// frame that starts its chain, or from the nearest state on the chain that the cache holds
// (the last CACHED_STATES decoded frames and the latest intra frame, as `StateCache`).
// `lod` (0 ..= subdivision iterations, default all) stops after that many subdivisions:
// coefficients of finer levels are not read, and the frame is reconstructed without them.

import { readHeader, readUnits, Reader, INTRA, PREDICTED } from './stream/bitstream.js';
import { QP_MIN, QP_MAX, MODE_COEFFICIENT_DIFFERENCES, MODE_REFRESH, MODE_MAX, UNIT_OVERHEAD } from './stream/syntax.js';
import { DecodeError } from './error.js';
import { RangeDecoder } from './ec.js';
import { decodeBase } from './base/coder.js';
import { decodeMotion } from './inter/motion.js';
import { decodeRefresh, applyRefresh, carry } from './inter/refresh.js';
import { decodeCoefficients } from './residual/coefcoder.js';
import { faceAllowance, subdividedBase, reconstruct } from './model.js';

/** Decoded frames whose states are kept besides the latest intra frame's (`CACHED_STATES`). */
export const CACHED_STATES = 8;

/**
 * @typedef {object} Frame
 * @property {Float64Array} positions flat xyz in the input's units
 * @property {Uint32Array} faces flat triangles
 * @property {number} type 0 intra, 1 predicted
 */

export class Decoder {
  /**
   * @param {Uint8Array} data the whole stream
   * @param {{lod?: number, header?: object, units?: object[]}} [options] `header` and `units`
   *   already read (`readHeader`, `readUnit`) skip reading them: a stream still arriving (the
   *   player's worker) passes the units it has, appends to that array as more arrive, and may
   *   replace `data` by a longer copy; frames decode once their units are there.
   */
  constructor(data, options = {}) {
    this.data = data;
    this.header = options.header ?? readHeader(data);
    this.units = options.units ?? readUnits(data, this.header);
    const s = this.header.schemes.length;
    const lod = options.lod ?? s;
    if (!Number.isInteger(lod) || lod < 0 || lod > s) throw new RangeError(`level of detail ${lod} out of range (the stream has ${s} subdivision iterations)`);
    this.lod = lod;
    /** Oldest first; the last entry is the frame decoded last. @type {{index:number, state:object}[]} */
    this.recent = [];
    /** @type {{index:number, state:object}|null} */
    this.intra = null;
  }

  get frameCount() {
    return this.units.length;
  }

  /** Type, reference, QP and sizes of frame `index` (`Decoder::frame_info`). */
  frameInfo(index) {
    const u = this.unit(index);
    const p = readPayload(this.data, u, index);
    return {
      type: u.type === INTRA ? 'I' : 'P',
      reference: u.type === PREDICTED ? index - p.referenceDistance : null,
      qp: p.qp,
      bytes: u.length + UNIT_OVERHEAD,
      baseBytes: p.base.length + p.refresh.length,
      refreshBytes: p.refresh.length,
      displacementBytes: p.coefficients.length,
      textureBytes: u.texture ? u.texture.length : 0,
    };
  }

  /** The payload of frame `index`'s texture unit, or null. */
  texturePayload(index) {
    const t = this.unit(index).texture;
    return t ? this.data.subarray(t.offset, t.offset + t.length) : null;
  }

  unit(index) {
    if (!(index >= 0 && index < this.units.length)) throw new RangeError(`frame ${index} does not exist: the stream has ${this.units.length} frame${this.units.length === 1 ? '' : 's'}`);
    return this.units[index];
  }

  /**
   * Decodes frame `index`.
   * @param {number} index
   * @returns {Frame}
   */
  decodeFrame(index) {
    // Back from `index` to the first frame that is cached or intra, then forward again.
    const chain = [index];
    for (;;) {
      const f = chain[chain.length - 1];
      if (chain.length > 1 && this.cached(f) !== null) break;
      const u = this.unit(f);
      if (u.type === INTRA) break;
      chain.push(f - readPayload(this.data, u, f).referenceDistance);
    }
    for (let k = chain.length - 1; k >= 1; k--) {
      if (this.cached(chain[k]) !== null) continue;
      const reference = k + 1 < chain.length ? this.cached(chain[k + 1]) : null;
      this.keep(chain[k], this.decodeState(chain[k], reference).state);
    }
    const { state, sub, qp } = this.decodeState(index, chain.length > 1 ? this.cached(chain[1]) : null);
    const positions = reconstruct(this.header, sub, state.coefficients, qp);
    this.keep(index, state);
    return { positions, faces: sub.faces, type: this.units[index].type };
  }

  /** The kept state of frame `f`, or null. */
  cached(f) {
    for (let i = this.recent.length - 1; i >= 0; i--) if (this.recent[i].index === f) return this.recent[i].state;
    return this.intra !== null && this.intra.index === f ? this.intra.state : null;
  }

  keep(index, state) {
    this.recent = this.recent.filter((e) => e.index !== index);
    if (this.units[index].type === INTRA) this.intra = { index, state };
    this.recent.push({ index, state });
    if (this.recent.length > CACHED_STATES) this.recent.shift();
  }

  /** The base mesh of the frame decoded last, in the input's units: the texture atlas of an
   * intra frame is coded on it (`Decoder::last_base`). */
  lastBase() {
    const last = this.recent.length > 0 ? this.recent[this.recent.length - 1] : null;
    if (last === null) return null;
    const h = this.header, s = last.state;
    const step = 2 ** (h.bits - h.baseBits);
    const p = new Float64Array(s.positions.length);
    for (let i = 0; i < p.length; i++) p[i] = h.origin[i % 3] + (0.0 + s.positions[i] * step) * h.step;
    return { index: last.index, positions: p, faces: s.faces };
  }

  decodeState(f, reference) {
    const u = this.unit(f);
    const p = readPayload(this.data, u, f);
    const h = this.header;
    // For a refreshed base, the reference base faces it kept.
    let positions, faces, kept = null;
    if (u.type === INTRA) {
      try {
        ({ positions, faces } = decodeBase(p.base, h.baseBits));
      } catch (e) {
        throw new DecodeError(f, p.baseOffset, `base mesh: ${e.message}`);
      }
    } else if (reference !== null) {
      positions = decodeMotion(new RangeDecoder(p.base), reference.positions, reference.faces, h.baseBits);
      if (positions === null) throw new DecodeError(f, p.baseOffset, 'base mesh motion is truncated or corrupt');
      faces = reference.faces;
      if (p.refresh.length > 0) {
        let r;
        try {
          r = decodeRefresh(p.refresh, faces.length / 3, h.baseBits);
        } catch (e) {
          throw new DecodeError(f, p.refreshOffset, e.message);
        }
        ({ positions, faces, kept } = applyRefresh(positions, faces, r.dropped, r.patch));
      }
    } else {
      throw new DecodeError(f, p.baseOffset, 'predicted frame without its reference');
    }
    const nf = faces.length / 3;
    const s = h.schemes.length;
    if (nf === 0 || nf * 4 ** s > faceAllowance(u.length)) {
      throw new DecodeError(f, p.baseOffset, `base mesh of ${nf} faces cannot be subdivided ${s} times`);
    }
    const sub = subdividedBase(h, positions, faces, this.lod);
    let q = decodeCoefficients(new RangeDecoder(p.coefficients), h.components, sub);
    if (q === null) throw new DecodeError(f, p.coefficientsOffset, 'displacement data is truncated or corrupt');
    if (p.coefficientsPredicted) {
      const prior = kept === null ? reference.coefficients : carry(reference, sub, kept, h.components);
      q = prior === null ? null : addCoefficients(q, prior);
      if (q === null) throw new DecodeError(f, p.coefficientsOffset, 'predicted displacements do not match their reference');
    }
    return { state: { positions, faces, coefficients: q }, sub, qp: p.qp };
  }
}

function addCoefficients(residual, reference) {
  if (residual.length !== reference.length) return null;
  const out = new Int32Array(residual.length);
  for (let i = 0; i < out.length; i++) {
    const s = residual[i] + reference[i];
    if (s > 0x7fffffff || s < -0x80000000) return null;
    out[i] = s;
  }
  return out;
}

/** Splits a frame payload into its fields (`stream::payload::Payload::read`; syntax.js
 * INTRA_PAYLOAD, PREDICTED_PAYLOAD). */
export function readPayload(data, unit, frame) {
  const r = new Reader(data, unit.offset, unit.offset + unit.length, frame);
  let referenceDistance = 0;
  if (unit.type === PREDICTED) {
    referenceDistance = r.u32('reference distance');
    if (referenceDistance === 0 || referenceDistance > frame) {
      throw r.error(`reference distance ${referenceDistance} does not name an earlier frame`);
    }
  }
  const qp = r.i32('QP');
  if (qp < QP_MIN || qp > QP_MAX) throw r.error(`QP ${qp} out of range`);
  const base = r.block('base mesh');
  let coefficientsPredicted = false;
  let refresh = { bytes: new Uint8Array(0), offset: 0 };
  if (unit.type === PREDICTED) {
    const m = r.u8('predicted frame mode');
    if (m > MODE_MAX) throw r.error(`unknown predicted frame mode ${m}`);
    coefficientsPredicted = (m & MODE_COEFFICIENT_DIFFERENCES) !== 0;
    if (m & MODE_REFRESH) refresh = r.block('refresh');
    if ((m & MODE_REFRESH) && refresh.bytes.length === 0) throw r.error('empty refresh block');
  }
  const coef = r.block('displacements');
  if (r.remaining() !== 0) throw r.error('unexpected bytes at the end of the frame');
  return {
    referenceDistance, qp, base: base.bytes, baseOffset: base.offset, refresh: refresh.bytes, refreshOffset: refresh.offset,
    coefficientsPredicted, coefficients: coef.bytes, coefficientsOffset: coef.offset,
  };
}
