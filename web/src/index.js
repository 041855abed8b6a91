// The dynmesh decoder for JavaScript: the public entry points.
export { Decoder, faceAllowance } from './decoder.js';
export { DecodeError } from './error.js';
export { readHeader, readUnits, SCHEME_NAMES } from './stream/bitstream.js';
