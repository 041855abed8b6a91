// Texture images of a textured stream for the player: each texture group's video decoded
// with the browser's WebCodecs (AV1 in IVF), converted to RGB as the core does (full-range
// BT.709, which the video does not signal, so the browser's own conversion would be off).
// HEVC textures are not decoded (browsers generally cannot): the page says so and plays
// the geometry.
//
// Contract: `new TexturePlayer(streamBytes, frameInfos)`, or `new TexturePlayer()` and
// `add(first, payload)` per texture group as its unit arrives; `textured` says whether images
// will come, `note` why not; `await image(i)` gives frame i's texture (ImageData) or null.
// Decoding goes forward through a group's pictures; seeking back restarts the group.

import { Decoder } from '../src/decoder.js';
import { readTextureUnit } from '../src/texture/unit.js';

const CACHE = 8;

/** The frames of an IVF file: [{data, pts}]. */
export function ivfFrames(bytes) {
  const v = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (bytes.length < 32 || String.fromCharCode(...bytes.subarray(0, 4)) !== 'DKIF') throw new Error('the texture video is not IVF');
  const out = [];
  for (let pos = v.getUint16(6, true); pos + 12 <= bytes.length;) {
    const size = v.getUint32(pos, true);
    const pts = Number(v.getBigUint64(pos + 4, true));
    if (pos + 12 + size > bytes.length) throw new Error('the texture video is truncated');
    out.push({ data: bytes.subarray(pos + 12, pos + 12 + size), pts });
    pos += 12 + size;
  }
  return out;
}

/** AV1 codec string for 10-bit main profile at a level that fits the picture size. */
function av1Codec(width, height) {
  const level = width * height <= 2228224 ? '08' : width * height <= 8912896 ? '12' : '16';
  return `av01.0.${level}M.10`;
}

/** RGBA of a decoded picture: planes read back and converted as `texture::rgb_of_yuv420_10bit`. */
async function rgba(frame) {
  const w = frame.codedWidth, h = frame.codedHeight;
  if (frame.format !== 'I420P10' && frame.format !== 'I420') {
    const c = new OffscreenCanvas(frame.displayWidth, frame.displayHeight);
    const g = c.getContext('2d');
    g.drawImage(frame, 0, 0);
    return g.getImageData(0, 0, c.width, c.height);
  }
  const buffer = new ArrayBuffer(frame.allocationSize());
  const layout = await frame.copyTo(buffer);
  const deep = frame.format === 'I420P10';
  const peak = deep ? 1023 : 255;
  const plane = (i) => (deep ? new Uint16Array(buffer, layout[i].offset) : new Uint8Array(buffer, layout[i].offset));
  const stride = (i) => layout[i].stride / (deep ? 2 : 1);
  const [Y, U, V] = [plane(0), plane(1), plane(2)];
  const [sy, su, sv] = [stride(0), stride(1), stride(2)];
  const out = new ImageData(frame.displayWidth, frame.displayHeight);
  const px = out.data;
  for (let y = 0; y < out.height && y < h; y++) {
    for (let x = 0; x < out.width && x < w; x++) {
      const l = Y[y * sy + x] / peak;
      const u = U[(y >> 1) * su + (x >> 1)] / peak - 0.5, v = V[(y >> 1) * sv + (x >> 1)] / peak - 0.5;
      const r = l + 1.5748 * v, b = l + 1.8556 * u;
      const g = (l - 0.2126 * r - 0.0722 * b) / 0.7152;
      const o = 4 * (y * out.width + x);
      px[o] = r * 255 + 0.5; px[o + 1] = g * 255 + 0.5; px[o + 2] = b * 255 + 0.5; px[o + 3] = 255;
    }
  }
  return out;
}

/** Chunks fed beyond the picture asked for before the decoder is flushed for it (a decoder
 * may hold a few pictures back; after a flush it needs a key frame, so the group restarts). */
const FEED_AHEAD = 8;

/** One texture group's video, decoded forward picture by picture. */
class GroupVideo {
  constructor(unit) {
    this.unit = unit;
    this.frames = null; // parsed when first needed: only AV1 is carried in IVF
    this.decoder = null;
  }

  start() {
    this.frames ??= ivfFrames(this.unit.video);
    if (this.decoder && this.decoder.state !== 'closed') this.decoder.close();
    this.fed = 0;
    this.outputs = 0;
    this.flushed = false;
    this.ready = new Map(); // picture index -> VideoFrame
    this.failure = null;
    this.wake = null;
    this.decoder = new VideoDecoder({
      output: (f) => { this.ready.set(this.outputs++, f); this.wake?.(); },
      error: (e) => { this.failure = e; this.wake?.(); },
    });
    this.decoder.configure({ codec: av1Codec(this.unit.width, this.unit.height), optimizeForLatency: true });
  }

  /** Resolves at the next output or error, or after `ms`. */
  nextEvent(ms) {
    return new Promise((resolve) => {
      const t = setTimeout(resolve, ms);
      this.wake = () => { clearTimeout(t); this.wake = null; resolve(); };
    });
  }

  /** Picture k, decoding forward (a picture already passed restarts the group). */
  async picture(k) {
    this.frames ??= ivfFrames(this.unit.video);
    if (k >= this.frames.length) throw new Error('the texture video ends early');
    if (!this.decoder || k < this.outputs - this.ready.size || (this.flushed && !this.ready.has(k) && k >= this.outputs)) this.start();
    while (!this.ready.has(k)) {
      if (this.failure) throw this.failure;
      if (this.fed < this.frames.length && this.fed <= k + FEED_AHEAD) {
        const { data, pts } = this.frames[this.fed];
        this.decoder.decode(new EncodedVideoChunk({ type: this.fed === 0 ? 'key' : 'delta', timestamp: pts * 33333, data }));
        this.fed++;
        await this.nextEvent(this.fed > k ? 20 : 0);
      } else if (!this.flushed) {
        this.flushed = true;
        await this.decoder.flush();
      } else {
        throw new Error('the texture video ends early');
      }
    }
    for (const [j, f] of this.ready) if (j < k) { f.close(); this.ready.delete(j); }
    const frame = this.ready.get(k);
    this.ready.delete(k);
    try {
      return await rgba(frame);
    } finally {
      frame.close();
    }
  }
}

export class TexturePlayer {
  /**
   * @param {Uint8Array|null} [stream] the whole stream; or none, and `add` each group as it arrives
   * @param {{textureBytes: number}[]} [infos] per frame
   */
  constructor(stream = null, infos = []) {
    this.textured = false;
    this.note = '';
    this.cache = new Map();
    this.groups = [];
    this.queue = Promise.resolve();
    if (!stream || !infos.length || infos[0].textureBytes === 0) return;
    const dec = new Decoder(stream);
    for (let i = 0; i < infos.length; i++) {
      const p = dec.texturePayload(i);
      if (p !== null) this.add(i, p);
    }
  }

  /** Adds the texture group that starts at frame `first` (its texture unit's payload), in
   * stream order; a group's frames may ask for images once it is added. */
  add(first, payload) {
    let video;
    try {
      video = new GroupVideo(readTextureUnit(payload));
    } catch (e) {
      this.textured = false;
      this.note = `texture: ${e.message}`;
      this.groups.push({ first, video: null });
      return;
    }
    this.groups.push({ first, video });
    if (this.groups.length > 1) return;
    const codec = video.unit.codec;
    if (codec !== 'av1') this.note = `the ${codec.toUpperCase()} texture cannot be decoded by this browser: playing the geometry`;
    else if (typeof VideoDecoder === 'undefined') this.note = 'this browser has no WebCodecs to decode the AV1 texture: playing the geometry';
    else {
      this.textured = true;
      this.note = 'AV1 texture';
    }
  }

  /** Frame i's texture, or null. Requests are served one at a time, in order. */
  image(i) {
    if (!this.textured) return Promise.resolve(null);
    if (this.cache.has(i)) return Promise.resolve(this.cache.get(i));
    const g = this.groups.filter((x) => x.first <= i).pop();
    if (!g) return Promise.resolve(null); // its group has not arrived
    const run = this.queue.then(async () => {
      if (this.cache.has(i)) return this.cache.get(i);
      const image = await g.video.picture(i - g.first);
      this.cache.set(i, image);
      if (this.cache.size > CACHE) this.cache.delete(this.cache.keys().next().value);
      return image;
    });
    this.queue = run.catch((e) => {
      this.textured = false;
      this.note = `texture: ${e.message}`;
      return null;
    });
    return this.queue;
  }
}
