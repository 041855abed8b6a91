// Texture units of a textured stream (docs/bitstream.md section 11): their header, the
// group's UV atlas decoded on the group's intra base mesh, and each frame's subdivided UVs.
//
// Contract: `readTextureUnit(bytes)` parses a texture unit payload or throws an Error worded
// as python/dynmesh/texture/coder.py's; `frameUvs(decoder)` gives a function that, called right
// after `decoder.decodeFrame(i)` in frame order, returns frame i's UVs ({uv: Float64Array,
// uvFaces: Uint32Array}, UV face f for output face f) as the Python decoder gives them, or
// null for an untextured stream. The video itself is the player's (web/player/video.js).

import { decodeUvAtlas, subdivideUv } from './uvcoder.js';

export const CODECS = ['hevc', 'av1'];

/**
 * @param {Uint8Array} data a texture unit payload
 * @returns {{codec: string, width: number, height: number, uvBits: number, frames: number, atlas: Uint8Array, video: Uint8Array}}
 */
export function readTextureUnit(data) {
  if (data.length < 11) throw new Error('texture unit is truncated');
  const v = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const [version, codec, width, height, uvBits, frames] = [v.getUint8(0), v.getUint8(1), v.getUint16(2, true), v.getUint16(4, true), v.getUint8(6), v.getUint32(7, true)];
  if (version !== 1) throw new Error(`texture unit version ${version} is not supported`);
  if (codec >= CODECS.length) throw new Error(`unknown texture codec ${codec}`);
  if (!(width >= 16 && width <= 16384 && height >= 16 && height <= 16384 && width % 2 === 0 && height % 2 === 0)) {
    throw new Error(`texture size ${width} x ${height} is out of range`);
  }
  if (!(uvBits >= 1 && uvBits <= 16) || frames === 0) throw new Error('texture unit has invalid UV bits or frame count');
  const blocks = [];
  let pos = 11;
  for (const what of ['atlas', 'video']) {
    if (pos + 4 > data.length) throw new Error(`texture unit is truncated before its ${what}`);
    const n = v.getUint32(pos, true);
    if (pos + 4 + n > data.length) throw new Error(`texture unit's ${what} is truncated`);
    blocks.push(data.subarray(pos + 4, pos + 4 + n));
    pos += 4 + n;
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
