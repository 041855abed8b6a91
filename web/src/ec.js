// The range decoder of `core/src/ec.rs` (LZMA's, with two-speed 16-bit probabilities).
//
// Contract: reads exactly what the Rust encoder wrote, symbol for symbol. All state is
// unsigned 32-bit and kept in JS numbers; products stay below 2^32, so they are exact.
// Past the end of its data the decoder reads zero bytes and counts them (`overrun`); it
// never throws: callers test `exhausted()` where the Rust code does.
//
// Bit models live in Uint16Array banks, two counters (fast, slow) per model, so that a
// coder's many contexts are one allocation: model i of a bank is at [2i, 2i + 1].

const TOP = 1 << 24;
const HALF = 32768;
/** Exp-Golomb prefixes longer than this cannot come from the encoder. */
const MAX_EG_PREFIX = 32;

/**
 * A bank of `n` fresh bit models.
 * @param {number} n
 * @returns {Uint16Array}
 */
export function bitModels(n) {
  return new Uint16Array(2 * n).fill(HALF);
}

/** Models of an adaptive Exp-Golomb integer of order k. */
export class UIntModel {
  /** @param {number} k */
  constructor(k) {
    this.k = k;
    this.prefix = bitModels(MAX_EG_PREFIX + 1);
  }
}

/** Models of a signed integer: zero flag, sign, magnitude - 1. */
export class IntModel {
  /** @param {number} k */
  constructor(k) {
    this.flags = bitModels(2); // 0: zero flag, 1: sign
    this.magnitude = new UIntModel(k);
  }
}

export class RangeDecoder {
  /** @param {Uint8Array} data the block */
  constructor(data) {
    this.data = data;
    this.pos = 0;
    this.range = 0xffffffff;
    this.code = 0;
    this.overrun = 0;
    this.corrupt = false;
    for (let i = 0; i < 4; i++) this.code = ((this.code << 8) | this.nextByte()) >>> 0;
  }

  /** @returns {number} */
  nextByte() {
    if (this.pos < this.data.length) return this.data[this.pos++];
    this.overrun++;
    return 0;
  }

  /**
   * One bit with model `i` of `bank`, which it updates.
   * @param {Uint16Array} bank
   * @param {number} i
   * @returns {number} 0 or 1
   */
  bit(bank, i) {
    const j = 2 * i;
    const fast = bank[j], slow = bank[j + 1];
    const bound = (this.range >>> 16) * ((fast + slow) >>> 1);
    let bit;
    if (this.code < bound) {
      this.range = bound;
      bank[j] = fast + ((65536 - fast) >>> 4);
      bank[j + 1] = slow + ((65536 - slow) >>> 7);
      bit = 0;
    } else {
      this.code -= bound;
      this.range -= bound;
      bank[j] = fast - (fast >>> 4);
      bank[j + 1] = slow - (slow >>> 7);
      bit = 1;
    }
    while (this.range < TOP) {
      this.range *= 256;
      this.code = ((this.code << 8) | this.nextByte()) >>> 0;
    }
    return bit;
  }

  /**
   * `n` equiprobable bits, most significant first (n <= 16 as the coders use it).
   * @param {number} n
   * @returns {number}
   */
  bypass(n) {
    let v = 0;
    for (let i = 0; i < n; i++) {
      this.range = this.range >>> 1;
      let b = 0;
      if (this.code >= this.range) {
        this.code -= this.range;
        b = 1;
      }
      v = v * 2 + b;
      while (this.range < TOP) {
        this.range *= 256;
        this.code = ((this.code << 8) | this.nextByte()) >>> 0;
      }
    }
    return v;
  }

  /**
   * An adaptive Exp-Golomb integer; an impossible prefix or value marks the stream corrupt
   * and gives 0.
   * @param {UIntModel} m
   * @returns {number}
   */
  uint(m) {
    let prefix = 0;
    while (this.bit(m.prefix, prefix)) {
      prefix++;
      if (prefix + m.k > MAX_EG_PREFIX) {
        this.corrupt = true;
        return 0;
      }
    }
    const n = prefix + m.k;
    const suffix = n > 16 ? this.bypass(n - 16) * 65536 + this.bypass(16) : this.bypass(n);
    const v = 2 ** n + suffix - 2 ** m.k;
    if (v > 0xffffffff) {
      this.corrupt = true;
      return 0;
    }
    return v;
  }

  /**
   * A signed integer of magnitude below 2^31.
   * @param {IntModel} m
   * @returns {number}
   */
  int(m) {
    if (!this.bit(m.flags, 0)) return 0;
    const negative = this.bit(m.flags, 1);
    const magnitude = this.uint(m.magnitude) + 1;
    if (magnitude > 0x7fffffff) {
      this.corrupt = true;
      return 0;
    }
    return negative ? -magnitude : magnitude;
  }

  /** @returns {string|null} the Rust `finish` error, or null when the block read cleanly */
  finish() {
    if (this.corrupt) return 'impossible entropy-coded value';
    if (this.overrun > 4) return 'entropy-coded data ends early';
    return null;
  }

  /** True once decoding only produces garbage. */
  exhausted() {
    return this.overrun > 4 || this.corrupt;
  }
}
