// The per-frame hash both decoders print with --hash: SHA-256 of the positions as
// little-endian float64 followed by the faces as little-endian uint32.

import { createHash } from 'node:crypto';

const LITTLE = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

/** Bytes of a typed array in little-endian order. */
function le(a, size) {
  const bytes = new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
  if (LITTLE) return bytes;
  const out = new Uint8Array(bytes.length);
  for (let i = 0; i < bytes.length; i += size) for (let j = 0; j < size; j++) out[i + j] = bytes[i + size - 1 - j];
  return out;
}

/**
 * @param {{positions: Float64Array, faces: Uint32Array}} frame
 * @returns {string} hex digest
 */
export function frameHash(frame) {
  return createHash('sha256').update(le(frame.positions, 8)).update(le(frame.faces, 4)).digest('hex');
}
