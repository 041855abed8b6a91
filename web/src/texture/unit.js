// Texture units of a textured stream (docs/bitstream.md section 11): their header, the
// group's UV atlas decoded on the group's intra base mesh, and each frame's subdivided UVs.
//
// Contract: `readTextureUnit(bytes)` parses a texture unit payload or throws an Error worded
// as python/dynmesh/texture/coder.py's; `frameUvs(decoder)` gives a function that, called right
// after `decoder.decodeFrame(i)` in frame order, returns frame i's UVs ({uv: Float64Array,
// uvFaces: Uint32Array}, UV face f for output face f) as the Python decoder gives them, or
// null for an untextured stream. The video itself is the player's (web/player/video.js).

import { decodeUvAtlas, subdivideUv } from './uvcoder.js';
import {
  TEXTURE_CODECS, TEXTURE_PAYLOAD_VERSION, TEXTURE_FIXED, MIN_SIDE, MAX_SIDE, UV_BITS_MIN, UV_BITS_MAX, TEXTURE_FRAMES_MIN,
} from '../stream/syntax.js';

export const CODECS = TEXTURE_CODECS;
/** Bytes of a block's length field (`atlas_len`, `video_len`). */
const LEN = 4;

/**
 * @param {Uint8Array} data a texture unit payload
 * @returns {{codec: string, width: number, height: number, uvBits: number, frames: number, atlas: Uint8Array, video: Uint8Array}}
 */
export function readTextureUnit(data) {
  if (data.length < TEXTURE_FIXED) throw new Error('texture unit is truncated');
  const v = new DataView(data.buffer, data.byteOffset, data.byteLength);
  // The fixed fields, in the order and widths of TEXTURE_PAYLOAD.
  let at = 0;
  const next = (n) => (at += n) - n;
  const version = v.getUint8(next(1)), codec = v.getUint8(next(1));
  const width = v.getUint16(next(2), true), height = v.getUint16(next(2), true);
  const uvBits = v.getUint8(next(1)), frames = v.getUint32(next(4), true);
  if (version !== TEXTURE_PAYLOAD_VERSION) throw new Error(`texture unit version ${version} is not supported`);
  if (codec >= CODECS.length) throw new Error(`unknown texture codec ${codec}`);
  const sideOk = (s) => s >= MIN_SIDE && s <= MAX_SIDE && s % 2 === 0;
  if (!(sideOk(width) && sideOk(height))) {
    throw new Error(`texture size ${width} x ${height} is out of range`);
  }
  if (!(uvBits >= UV_BITS_MIN && uvBits <= UV_BITS_MAX) || frames < TEXTURE_FRAMES_MIN) throw new Error('texture unit has invalid UV bits or frame count');
  const blocks = [];
  let pos = TEXTURE_FIXED;
  for (const what of ['atlas', 'video']) {
    if (pos + LEN > data.length) throw new Error(`texture unit is truncated before its ${what}`);
    const n = v.getUint32(pos, true);
    if (pos + LEN + n > data.length) throw new Error(`texture unit's ${what} is truncated`);
    blocks.push(data.subarray(pos + LEN, pos + LEN + n));
    pos += LEN + n;
  }
  if (pos !== data.length) throw new Error('unexpected bytes at the end of the texture unit');
  return { codec: CODECS[codec], width, height, uvBits, frames, atlas: blocks[0], video: blocks[1] };
}

/** Frame i's UVs, for frames decoded in order (see the module contract). */
export function frameUvs(decoder) {
  if (decoder.frameCount === 0 || decoder.texturePayload(0) === null) return () => null;
  let group = null;
  return (i) => {
    const payload = decoder.texturePayload(i);
    if (payload !== null) {
      let unit;
      try {
        unit = readTextureUnit(payload);
      } catch (e) {
        throw new Error(`frame ${i}: ${e.message}`);
      }
      const base = decoder.lastBase();
      const { uvFaces, uv } = decodeUvAtlas(unit.atlas, base.positions, base.faces, unit.uvBits);
      const top = 2 ** unit.uvBits - 1;
      const real = Float64Array.from(uv, (q) => q / top);
      group = subdivideUv(real, uvFaces, decoder.lod);
    }
    return group;
  };
}
