// The dynmesh decoder for JavaScript: the public entry points.
export { Decoder } from './decoder.js';
export { faceAllowance } from './model.js';
export { DecodeError } from './error.js';
export { readHeader, readUnits, SCHEME_NAMES } from './stream/bitstream.js';
