// The player as a module for other pages: `createPlayer(canvas, options)` draws a dynmesh
// stream into a canvas (WebGL2), decoding it in a worker (worker.js) and its AV1 texture with
// WebCodecs (video.js). The player page (player.js) is this plus its controls.
//
// Contract: `const p = createPlayer(canvas, {fps = 30, lod = -1 (all levels), loop = true})`;
// `await p.load(urlOrBytes)` resolves once the stream's header is read (frame count, types);
// `p.play()`, `p.pause()`, `p.seek(i)` (a frame not yet decoded is decoded next, from the
// nearest intra frame), `p.setLod(k)` (decodes again at level of detail k). Events (an
// EventTarget): `loaded`, `decoded` {detail: {index}}, `frame` {detail: {index, type}} when a
// frame is on screen (geometry and its texture together), `ended` when playback reaches the last
// frame without `loop`, `error` {detail: {message}}. `p.state` holds {frame, shown, faces,
// lod, advanced, decoded, frames, playing, error, textured, textureNote, view}; `p.infos` the
// frames' types and sizes; `p.renderer` the camera (orbit, zoom, wireframe).

import { Renderer } from './renderer.js';
import { TexturePlayer } from './video.js';

export class DynmeshPlayer extends EventTarget {
  /**
   * @param {HTMLCanvasElement} canvas
   * @param {{fps?: number, lod?: number, loop?: boolean}} [options]
   */
  constructor(canvas, options = {}) {
    super();
    this.renderer = new Renderer(canvas);
    this.fps = options.fps > 0 ? options.fps : 30;
    this.loop = options.loop ?? true;
    this.state = { frame: 0, shown: -1, faces: 0, lod: options.lod ?? -1, advanced: 0, decoded: 0, frames: 0, playing: false, error: null, textured: false, textureNote: '', view: null };
    this.frames = [];
    this.infos = [];
    this.header = null;
    this.stream = null;
    this.texture = null;
    this.worker = null;
    this.token = 0;
    this.last = 0;
    this.destroyed = false;
    requestAnimationFrame((now) => this.tick(now));
  }

  /** Fetches (a URL) or takes (bytes) a stream and starts decoding it; resolves at its header. */
  async load(source) {
    try {
      if (typeof source === 'string' || source instanceof URL) {
        const response = await fetch(source);
        if (!response.ok) throw new Error(`cannot fetch ${source}: HTTP ${response.status}`);
        this.stream = await response.arrayBuffer();
      } else {
        this.stream = source instanceof ArrayBuffer ? source.slice(0) : new Uint8Array(source).slice().buffer;
      }
    } catch (e) {
      this.fail(e.message);
      throw e;
    }
    this.header = null;
    const loaded = new Promise((resolve, reject) => {
      const done = () => { this.removeEventListener('error', failed); resolve(this); };
      const failed = (e) => { this.removeEventListener('loaded', done); reject(new Error(e.detail.message)); };
      this.addEventListener('loaded', done, { once: true });
      this.addEventListener('error', failed, { once: true });
    });
    this.decode(this.state.lod);
    return loaded;
  }

  /** Decodes again at level of detail `lod` (-1: all); the frame on screen stays until its new version comes. */
  setLod(lod) {
    if (this.stream) this.decode(lod);
  }

  play() {
    if (this.state.frame >= this.state.frames - 1 && !this.loop) this.seek(0);
    this.state.playing = true;
  }

  pause() {
    this.state.playing = false;
  }

  /** Shows frame `i` (clamped to the stream) as soon as it is decoded. */
  seek(i) {
    const k = Math.max(0, Math.min(this.state.frames - 1, Math.trunc(i)));
    if (!this.frames[k] && this.worker) this.worker.postMessage({ seek: k, token: this.token });
    return this.show(k);
  }

  /** Stops decoding and playing; the canvas keeps its last picture. */
  destroy() {
    this.destroyed = true;
    if (this.worker) this.worker.terminate();
  }

  fail(message) {
    this.state.error = message;
    this.dispatchEvent(new CustomEvent('error', { detail: { message } }));
  }

  decode(lod) {
    if (this.worker) this.worker.terminate();
    this.frames = [];
    this.state.decoded = 0;
    const my = ++this.token;
    this.worker = new Worker(new URL('./worker.js', import.meta.url), { type: 'module' });
    this.worker.onmessage = ({ data }) => {
      if (data.token !== my) return;
      if (data.error) this.fail(data.error);
      else if (data.header) this.setup(data.header, data.infos, data.view, lod);
      else if (data.frame) this.received(data.frame);
    };
    this.worker.onerror = (e) => this.fail(e.message || 'the decoder worker failed');
    this.worker.postMessage({ stream: this.stream.slice(0), lod: lod < 0 ? undefined : lod, token: my, first: this.state.frame });
  }

  setup(header, infos, view, lod) {
    const first = this.header === null;
    this.header = header;
    this.infos = infos;
    this.state.frames = infos.length;
    this.state.lod = lod < 0 ? header.schemes.length : lod;
    if (first) {
      this.renderer.fit(view.lo, view.hi, view.front);
      this.state.view = view;
      this.texture = new TexturePlayer(new Uint8Array(this.stream), infos);
      this.state.textured = this.texture.textured;
      this.state.textureNote = this.texture.note;
    }
    this.dispatchEvent(new Event('loaded'));
  }

  received(frame) {
    this.frames[frame.index] = frame;
    this.state.decoded++;
    if (frame.index === this.state.frame) this.show(frame.index);
    this.dispatchEvent(new CustomEvent('decoded', { detail: { index: frame.index } }));
  }

  async show(i) {
    this.state.frame = i;
    const f = this.frames[i];
    if (!f) return;
    // The texture first (decoding may take a while), then mesh and texture together, so that
    // a frame's geometry never shows with another frame's texture.
    const image = this.texture && f.uvs ? await this.texture.image(i) : null;
    this.state.textured = Boolean(this.texture && this.texture.textured);
    this.state.textureNote = this.texture ? this.texture.note : '';
    if (this.state.frame !== i || this.frames[i] !== f) return;
    this.renderer.setMesh(f);
    this.renderer.setTexture(image);
    this.renderer.draw();
    this.state.shown = i;
    this.state.faces = f.faces.length / 3;
    this.dispatchEvent(new CustomEvent('frame', { detail: { index: i, type: this.infos[i].type } }));
  }

  tick(now) {
    if (this.destroyed) return;
    const s = this.state;
    if (s.playing && now - this.last >= 1000 / this.fps && s.shown === s.frame) this.advance(now);
    requestAnimationFrame((t) => this.tick(t));
  }

  advance(now) {
    const s = this.state;
    if (s.frame === s.frames - 1 && !this.loop) {
      this.pause();
      this.dispatchEvent(new Event('ended'));
      return;
    }
    const next = (s.frame + 1) % Math.max(1, s.frames);
    if (!this.frames[next]) return;
    this.last = now;
    s.advanced++;
    this.show(next);
  }

  /** Normalized device coordinates of the corners of the sequence's box with the current camera. */
  boxCorners() {
    const { lo, hi } = this.state.view;
    return [0, 1, 2, 3, 4, 5, 6, 7].map((c) => this.renderer.project([0, 1, 2].map((k) => ((c >> k) & 1 ? hi[k] : lo[k]))));
  }
}

/** A player drawing into `canvas`; see the contract above. */
export function createPlayer(canvas, options) {
  return new DynmeshPlayer(canvas, options);
}
