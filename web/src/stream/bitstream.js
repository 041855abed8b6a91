// The container (`core/src/stream/bitstream.rs`): sequence header, then one unit per frame
// with type, length, payload and CRC-32, and optional texture units (type 2) after a frame.
//
// Contract: `readHeader` and `readUnits` accept exactly the streams the Rust reader accepts
// and fail with the same message at the same offset; every length and count is checked
// against the bytes present before it is used. `readUnit(data, pos, frame)` reads and checks
// one unit at `pos` ({type, offset, length, next}); the player's worker splits a stream that
// is still arriving with it, unit by unit.

//
// The fields, codes and limits come from ./syntax.js (`core/src/stream/syntax.rs`).

import { crc32 } from './crc32.js';
import { DecodeError } from '../error.js';
import {
  MAGIC, VERSION, FRAME_INTRA, FRAME_PREDICTED, TEXTURE_UNIT, MAX_SUBDIV, UNIT_OVERHEAD, UNIT_LENGTH_AT, UNIT_PAYLOAD_AT,
  HEADER, HEADER_VERSION_AT, HEADER_FRAME_COUNT_AT, SCHEME_MIDPOINT, SCHEME_LOOP, POSITION_BITS_MIN, POSITION_BITS_MAX,
  COMPONENTS_NORMAL, COMPONENTS_ALL, FLAG_ON, UPDATE_DEN_MIN, Ty, width, offset as fieldOffset,
} from './syntax.js';

export { VERSION, UNIT_OVERHEAD, MAX_SUBDIV, TEXTURE_UNIT };
export const INTRA = FRAME_INTRA;
export const PREDICTED = FRAME_PREDICTED;
export const SCHEME_NAMES = [];
SCHEME_NAMES[SCHEME_MIDPOINT] = 'midpoint';
SCHEME_NAMES[SCHEME_LOOP] = 'loop';

/** Bounds-checked little-endian reader that knows where its bytes sit in the stream. */
export class Reader {
  /**
   * @param {Uint8Array} data the stream
   * @param {number} start first byte this reader may read
   * @param {number} end one past the last
   * @param {number|null} frame frame the bytes belong to, for errors
   */
  constructor(data, start, end, frame) {
    this.data = data;
    this.view = new DataView(data.buffer, data.byteOffset, data.byteLength);
    this.pos = start;
    this.end = end;
    this.frame = frame;
  }

  remaining() {
    return this.end - this.pos;
  }

  /** @param {string} reason */
  error(reason) {
    return new DecodeError(this.frame, this.pos, reason);
  }

  /** Offset of `n` bytes, after checking they are there. */
  take(n, what) {
    if (n > this.remaining()) throw this.error(`${what}: needs ${n} bytes, ${this.remaining()} left`);
    const at = this.pos;
    this.pos += n;
    return at;
  }

  u8(what) {
    return this.data[this.take(1, what)];
  }
  u32(what) {
    return this.view.getUint32(this.take(4, what), true);
  }
  i32(what) {
    return this.view.getInt32(this.take(4, what), true);
  }
  f64(what) {
    return this.view.getFloat64(this.take(8, what), true);
  }
  /** A length-prefixed block: its bytes and their offset in the stream. */
  block(what) {
    const n = this.u32(what);
    const at = this.take(n, what);
    return { bytes: this.data.subarray(at, at + n), offset: at };
  }
}

/**
 * @typedef {object} Header
 * @property {number} frameCount
 * @property {number[]} origin
 * @property {number} step
 * @property {number} bits
 * @property {number} baseBits
 * @property {number[]} schemes 0 midpoint, 1 Loop, coarsest first
 * @property {{update: number[][], perValence: boolean}} lifting per iteration the update
 *   weight as [numerator, denominator], and whether it is divided by each parent's children
 * @property {number} components 1 or 3
 * @property {{alpha:number, delta:number, h:number}|null} aq
 * @property {number} length bytes of the header with its CRC
 */

/**
 * Parses and checks the sequence header.
 * @param {Uint8Array} data
 * @returns {Header}
 */
export function readHeader(data) {
  const r = new Reader(data, 0, data.length, null);
  const m = r.take(MAGIC.length, 'magic');
  if (MAGIC.some((b, i) => data[m + i] !== b)) {
    throw new DecodeError(null, 0, 'not a dynmesh stream (bad magic)');
  }
  const version = r.u8('version');
  if (version !== VERSION) throw r.error(`unsupported format version ${version} (this decoder reads ${VERSION})`);
  const frameCount = r.u32('frame count');
  const origin = [r.f64('origin'), r.f64('origin'), r.f64('origin')];
  const step = r.f64('step');
  const bits = r.u8('position bits');
  const baseBits = r.u8('base mesh position bits');
  const iterations = r.u8('subdivision iterations');
  if (iterations > MAX_SUBDIV) throw r.error(`${iterations} subdivision iterations (at most ${MAX_SUBDIV})`);
  const schemesAt = r.take(iterations, 'subdivision schemes');
  const liftingAt = r.pos;
  const perValence = r.u8('lifting valence flag');
  const pair = width(Ty.U8Pair);
  const weightsAt = r.take(pair * iterations, 'lifting update weights');
  const components = r.u8('displacement components');
  const aqFlag = r.u8('adaptive quantization flag');
  const aq = { alpha: r.f64('AQ alpha'), delta: r.f64('AQ delta'), h: r.f64('AQ h') };
  const end = r.pos;
  const crc = r.u32('header CRC');
  const length = r.pos;
  if (crc !== crc32(data, 0, end)) throw new DecodeError(null, end, 'sequence header CRC mismatch');
  const schemes = [];
  for (let i = 0; i < iterations; i++) {
    const s = data[schemesAt + i];
    if (s !== SCHEME_MIDPOINT && s !== SCHEME_LOOP) throw new DecodeError(null, schemesAt + i, `unknown subdivision scheme ${s}`);
    schemes.push(s);
  }
  const update = [];
  for (let i = 0; i < iterations; i++) update.push([data[weightsAt + pair * i], data[weightsAt + pair * i + 1]]);
  if (perValence > FLAG_ON || update.some(([, den]) => den < UPDATE_DEN_MIN)) {
    throw new DecodeError(null, liftingAt, 'invalid lifting update weights');
  }
  const aqValid = Number.isFinite(aq.alpha) && aq.alpha > 0 && Number.isFinite(aq.h) && aq.h > 0 && Math.abs(aq.delta) < 1;
  if (aqFlag > FLAG_ON || (aqFlag === FLAG_ON && !aqValid)) {
    throw new DecodeError(null, fieldOffset(HEADER, 'aq', iterations, () => 0, true), 'invalid adaptive quantization parameters');
  }
  const lifting = { update, perValence: perValence === FLAG_ON };
  const header = { frameCount, origin, step, bits, baseBits, schemes, lifting, components, aq: aqFlag === FLAG_ON ? aq : null, length };
  const invalid = validate(header);
  if (invalid) throw new DecodeError(null, HEADER_VERSION_AT, invalid);
  return header;
}

/** @param {Header} h @returns {string|null} */
function validate(h) {
  if (!h.origin.every(Number.isFinite) || !Number.isFinite(h.step) || h.step <= 0) return 'invalid position grid';
  const bitsOk = (b) => b >= POSITION_BITS_MIN && b <= POSITION_BITS_MAX;
  if (!bitsOk(h.bits)) return `position bits ${h.bits} out of range`;
  if (!bitsOk(h.baseBits) || h.baseBits > h.bits) return `base mesh position bits ${h.baseBits} out of range`;
  if (h.components !== COMPONENTS_NORMAL && h.components !== COMPONENTS_ALL) return `${h.components} displacement components (1 or 3)`;
  return null;
}

/**
 * @typedef {object} Unit
 * @property {number} type INTRA or PREDICTED
 * @property {number} offset offset of the payload in the stream
 * @property {number} length payload bytes
 * @property {{offset:number, length:number}|null} texture the texture unit's payload
 */

/**
 * Splits the stream after the header into frame units, checking lengths and CRCs.
 * @param {Uint8Array} data
 * @param {Header} header
 * @returns {Unit[]}
 */
export function readUnits(data, header) {
  const start = header.length;
  const plausible = Math.floor(Math.max(0, data.length - start) / UNIT_OVERHEAD);
  if (header.frameCount > plausible) {
    throw new DecodeError(null, HEADER_FRAME_COUNT_AT, `header claims ${header.frameCount} frames; the stream has room for at most ${plausible}`);
  }
  const units = [];
  let pos = start;
  for (let f = 0; f < header.frameCount; f++) {
    const { unit, next } = readFrameUnit(data, pos, f);
    units.push(unit);
    pos = next;
  }
  if (pos !== data.length) throw new DecodeError(null, pos, `${data.length - pos} unexpected bytes after the last frame`);
  return units;
}

/**
 * Frame `frame`'s unit at `pos` and the texture unit after it, if one follows: the unit as
 * `readUnits` lists it, and where the next frame's unit starts.
 * @returns {{unit: Unit, next: number}}
 */
export function readFrameUnit(data, pos, frame) {
  const u = readUnit(data, pos, frame);
  if (u.type !== INTRA && u.type !== PREDICTED) {
    throw new DecodeError(frame, pos, `unit type ${u.type} where a frame unit was expected`);
  }
  let next = u.next, texture = null;
  if (next < data.length && data[next] === TEXTURE_UNIT) {
    const t = readUnit(data, next, frame);
    texture = { offset: t.offset, length: t.length };
    next = t.next;
  }
  return { unit: { type: u.type, offset: u.offset, length: u.length, texture }, next };
}

/**
 * Where the unit at `pos` ends (after its type, length, payload and CRC), from its length
 * field alone, without reading or checking it; null while the length field is not in `data`.
 */
export function unitEnd(data, pos) {
  if (pos + UNIT_PAYLOAD_AT > data.length) return null;
  return pos + UNIT_OVERHEAD + new DataView(data.buffer, data.byteOffset + pos + UNIT_LENGTH_AT, 4).getUint32(0, true);
}

export function readUnit(data, pos, frame) {
  const r = new Reader(data, pos, data.length, frame);
  const type = r.u8('unit type');
  const { offset, bytes } = r.block('unit payload');
  const end = r.pos;
  const crc = r.u32('unit CRC');
  if (crc !== crc32(data, pos, end)) throw new DecodeError(frame, end, 'unit CRC mismatch (corrupted data)');
  return { type, offset, length: bytes.length, next: r.pos };
}
