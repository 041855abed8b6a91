// Errors of the decoder, worded and placed as the Rust core's `DecodeError` so that both
// decoders report a damaged stream with the same one-line message.

/** A stream that cannot be decoded: names the frame (null in the header) and byte offset. */
export class DecodeError extends Error {
  /**
   * @param {number|null} frame index of the frame being decoded, null for the header
   * @param {number} offset byte offset in the whole stream
   * @param {string} reason what was wrong
   */
  constructor(frame, offset, reason) {
    super(`${frame === null ? '' : `frame ${frame}, `}byte offset ${offset}: ${reason}`);
    this.name = 'DecodeError';
    this.frame = frame;
    this.offset = offset;
    this.reason = reason;
  }
}
