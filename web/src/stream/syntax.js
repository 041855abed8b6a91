// The syntax of the container and the payloads (`core/src/stream/syntax.rs`, mirrored name
// for name): every unit, field, width, code and limit that docs/bitstream.md lists for the
// sequence header (§2), the frame unit (§3), the intra and predicted payloads (§4, §4b) and
// the texture unit payload (§11), as named constants and one table of fields per structure,
// in stream order.
//
// Contract: the constants and tables hold exactly the names and values of syntax.rs
// (web/test/syntax.test.js checks them against that file and against docs/bitstream.md); the
// readers (stream/bitstream.js, decoder.js, texture/unit.js, model.js) take their codes,
// limits and offsets from here. Functions are the Rust ones in camelCase.

/** The type of one element of a field: its name as docs/bitstream.md writes it. */
export const Ty = Object.freeze({
  U8: 'u8',
  U16: 'u16',
  U32: 'u32',
  I32: 'i32',
  F64: 'f64',
  /** Two u8s (a numerator and a denominator). */
  U8Pair: '(u8, u8)',
  /** Raw bytes: a block whose length a length field gives. */
  Bytes: 'bytes',
});

const WIDTHS = { u8: 1, u16: 2, u32: 4, i32: 4, f64: 8, '(u8, u8)': 2, bytes: 1 };

/** Bytes per element of type `ty` (1 for raw bytes). */
export function width(ty) {
  return WIDTHS[ty];
}

/** Counts: a fixed number, one per subdivision iteration, or the bytes a length field gives. */
export const N = (n) => Object.freeze({ kind: 'N', n });
export const S = Object.freeze({ kind: 'S' });
export const Len = (sym) => Object.freeze({ kind: 'Len', sym });

const f = (name, ty, count) => Object.freeze({ name, ty, count, optional: false });
const opt = (name, ty, count) => Object.freeze({ name, ty, count, optional: true });
const { U8, U16, U32, I32, F64, U8Pair, Bytes } = Ty;

// ---- Container (§2, §3) ----

/** The first four bytes of every stream ("DMSH"). */
export const MAGIC = Object.freeze([0x44, 0x4d, 0x53, 0x48]);
/** Format version (§10). */
export const VERSION = 5;

export const FRAME_INTRA = 0;
export const FRAME_PREDICTED = 1;
/** Unit type of a texture unit: it follows the frame unit it belongs to (§3, §11). */
export const TEXTURE_UNIT = 2;

/** Subdivision iterations the format allows. */
export const MAX_SUBDIV = 6;
export const SCHEME_MIDPOINT = 0;
export const SCHEME_LOOP = 1;
/** Bit depth of the position grid (`bits`) and of the base mesh positions (`base_bits` ≤ `bits`). */
export const POSITION_BITS_MIN = 8;
export const POSITION_BITS_MAX = 20;
export const COMPONENTS_NORMAL = 1;
export const COMPONENTS_ALL = 3;
/** The value of the flag bytes `per_valence` and `aq` when on (0 is off, other values invalid). */
export const FLAG_ON = 1;
export const UPDATE_DEN_MIN = 1;

/** The sequence header (§2), in stream order. */
export const HEADER = Object.freeze([
  f('magic', U8, N(4)),
  f('version', U8, N(1)),
  f('frame_count', U32, N(1)),
  f('origin', F64, N(3)),
  f('step', F64, N(1)),
  f('bits', U8, N(1)),
  f('base_bits', U8, N(1)),
  f('subdiv_iterations', U8, N(1)),
  f('schemes', U8, S),
  f('per_valence', U8, N(1)),
  f('update', U8Pair, S),
  f('components', U8, N(1)),
  f('aq', U8, N(1)),
  f('aq_alpha', F64, N(1)),
  f('aq_delta', F64, N(1)),
  f('aq_h', F64, N(1)),
  f('header_crc', U32, N(1)),
]);

export const HEADER_VERSION_AT = 4;
export const HEADER_FRAME_COUNT_AT = 5;
export const HEADER_LEN = 75;
export const HEADER_LEN_PER_ITERATION = 3;

/** A frame unit, and a texture unit of the same layout (§3). */
export const FRAME_UNIT = Object.freeze([
  f('frame_type', U8, N(1)),
  f('length', U32, N(1)),
  f('payload', Bytes, Len('L')),
  f('crc', U32, N(1)),
]);

export const UNIT_LENGTH_AT = 1;
export const UNIT_PAYLOAD_AT = 5;
export const UNIT_OVERHEAD = 9;

// ---- Frame payloads (§4, §4b) ----

export const QP_MIN = -24;
export const QP_MAX = 63;

/** The intra payload (§4). */
export const INTRA_PAYLOAD = Object.freeze([
  f('qp', I32, N(1)),
  f('base_len', U32, N(1)),
  f('base_block', Bytes, Len('B')),
  f('coef_len', U32, N(1)),
  f('coef_block', Bytes, Len('C')),
]);

/** `mode` bit 0: coefficient differences; bit 1: a refresh block follows. */
export const MODE_COEFFICIENT_DIFFERENCES = 1;
export const MODE_REFRESH = 2;
export const MODE_MAX = 3;

/** The predicted payload (§4b); the optional fields are there with MODE_REFRESH. */
export const PREDICTED_PAYLOAD = Object.freeze([
  f('reference_distance', U32, N(1)),
  f('qp', I32, N(1)),
  f('motion_len', U32, N(1)),
  f('motion_block', Bytes, Len('M')),
  f('mode', U8, N(1)),
  opt('refresh_len', U32, N(1)),
  opt('refresh_block', Bytes, Len('R')),
  f('coef_len', U32, N(1)),
  f('coef_block', Bytes, Len('C')),
]);

/** The face allowance of a frame of L payload bytes (§9):
 * clamp(FACE_ALLOWANCE_PER_BYTE * L, FACE_ALLOWANCE_MIN, FACE_ALLOWANCE_MAX). */
export const FACE_ALLOWANCE_PER_BYTE = 512;
export const FACE_ALLOWANCE_MIN = 1 << 20;
export const FACE_ALLOWANCE_MAX = 1 << 23;

// ---- Texture unit payload (§11) ----

export const TEXTURE_PAYLOAD_VERSION = 1;
export const TEXTURE_CODEC_HEVC = 0;
export const TEXTURE_CODEC_AV1 = 1;
export const TEXTURE_CODECS = Object.freeze(['hevc', 'av1']);
export const MIN_SIDE = 16;
export const MAX_SIDE = 16384;
export const UV_BITS_MIN = 1;
export const UV_BITS_MAX = 16;
export const TEXTURE_FRAMES_MIN = 1;

/** The texture unit payload (§11). */
export const TEXTURE_PAYLOAD = Object.freeze([
  f('version', U8, N(1)),
  f('codec', U8, N(1)),
  f('width', U16, N(1)),
  f('height', U16, N(1)),
  f('uv_bits', U8, N(1)),
  f('frames', U32, N(1)),
  f('atlas_len', U32, N(1)),
  f('atlas_block', Bytes, Len('A')),
  f('video_len', U32, N(1)),
  f('video_block', Bytes, Len('V')),
]);

/** Bytes of the texture payload's fixed fields, before `atlas_len`. */
export const TEXTURE_FIXED = 11;

/** The header's length for `s` subdivision iterations. */
export function headerLen(s) {
  return HEADER_LEN + HEADER_LEN_PER_ITERATION * s;
}

/** A field's size in bytes with `s` subdivision iterations; null for a block. */
export function size(field, s) {
  const c = field.count;
  if (c.kind === 'N') return c.n * width(field.ty);
  if (c.kind === 'S') return s * width(field.ty);
  return null;
}

/**
 * A field's offset in its structure, with `s` subdivision iterations, blocks of `lens(sym)`
 * bytes and the optional fields present if `withOptional`; null for an unknown name.
 */
export function offset(fields, name, s, lens, withOptional) {
  let at = 0;
  for (const field of fields) {
    if (field.name === name) return at;
    if (field.optional && !withOptional) continue;
    at += field.count.kind === 'Len' ? lens(field.count.sym) : size(field, s);
  }
  return null;
}
