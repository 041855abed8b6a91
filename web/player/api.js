// The player as a module for other pages: `createPlayer(canvas, options)` draws a dynmesh
// stream into a canvas (WebGL2), decoding it in a worker (worker.js) and its AV1 texture with
// WebCodecs (video.js). The player page (player.js) is this plus its controls.
//
// Contract: `const p = createPlayer(canvas, {fps = 30, lod = -1 (all levels), loop = true})`;
// `await p.load(urlOrBytes)` resolves once the stream's header is read (frame count, types).
// A URL's body is streamed: its chunks go to the worker as they arrive, and each frame is
// decoded and shown as soon as its bytes (and its texture group's unit) are in, so playback
// starts before the download ends; playing waits at a frame that has not arrived.
// `p.play()`, `p.pause()`, `p.seek(i)` (a frame not yet decoded is decoded next, from the
// nearest intra frame; one not yet downloaded as soon as it arrives), `p.setLod(k)` (decodes
// again at level of detail k), `p.destroy()`. Events (an EventTarget): `loaded` (the header),
// `progress` {detail: {arrived, bytes, complete}} as frames arrive, `decoded` {detail:
// {index}}, `frame` {detail: {index, type}} when a frame is on screen (geometry and its texture
// together), `ended` when playback reaches the last frame without `loop`, `error` {detail:
// {message}}. `p.state` holds {frame, shown, faces, lod, advanced, decoded, frames, arrived
// (frames whose bytes are in), bytes, complete (the whole stream is in and checked), playing,
// error, textured, textureNote, view}; `p.infos` the frames' types and sizes (null until a
// frame arrives); `p.renderer` the camera (orbit, zoom, wireframe), fitted when the first
// frame is decoded to the intra frames in by then.

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
    this.requestedLod = options.lod ?? -1;
    this.state = { frame: 0, shown: -1, faces: 0, lod: this.requestedLod, advanced: 0, decoded: 0, frames: 0, arrived: 0, bytes: 0, complete: false, playing: false, error: null, textured: false, textureNote: '', view: null };
    this.frames = [];
    this.infos = [];
    this.header = null;
    this.texture = null;
    this.worker = null;
    this.reader = null;
    this.token = 0;
    this.last = 0;
    this.destroyed = false;
    requestAnimationFrame((now) => this.tick(now));
  }

  /** Fetches (a URL) or takes (bytes) a stream and starts decoding it; resolves at its header.
   * A URL's body is read as it arrives and passed on to the decoder chunk by chunk. */
  async load(source) {
    this.stop();
    let response = null, bytes = null;
    try {
      if (typeof source === 'string' || source instanceof URL) {
        response = await fetch(source);
        if (!response.ok) throw new Error(`cannot fetch ${source}: HTTP ${response.status}`);
      } else {
        bytes = source instanceof ArrayBuffer ? source.slice(0) : new Uint8Array(source).slice().buffer;
      }
    } catch (e) {
      this.fail(e.message);
      throw e;
    }
    this.header = null;
    this.infos = [];
    Object.assign(this.state, { frames: 0, decoded: 0, arrived: 0, bytes: 0, complete: false, error: null });
    const loaded = new Promise((resolve, reject) => {
      const done = () => { this.removeEventListener('error', failed); resolve(this); };
      const failed = (e) => { this.removeEventListener('loaded', done); reject(new Error(e.detail.message)); };
      this.addEventListener('loaded', done, { once: true });
      this.addEventListener('error', failed, { once: true });
    });
    const worker = this.startWorker();
    if (bytes) {
      worker.postMessage({ chunk: bytes }, [bytes]);
      worker.postMessage({ end: true });
    } else {
      this.pump(response, worker);
    }
    return loaded;
  }

  /** Passes a response's body to `worker` as it arrives (each chunk's buffer transferred). */
  async pump(response, worker) {
    try {
      if (!response.body) {
        const all = await response.arrayBuffer();
        if (worker === this.worker) worker.postMessage({ chunk: all }, [all]);
      } else {
        const reader = response.body.getReader();
        this.reader = reader;
        for (;;) {
          const { done, value } = await reader.read();
          if (worker !== this.worker) return;
          if (done) break;
          const whole = value.byteOffset === 0 && value.byteLength === value.buffer.byteLength;
          const chunk = whole ? value.buffer : value.slice().buffer;
          worker.postMessage({ chunk }, [chunk]);
        }
      }
      if (worker === this.worker) worker.postMessage({ end: true });
    } catch (e) {
      if (worker === this.worker) this.fail(`cannot fetch the stream: ${e.message}`);
    }
  }

  /** Decodes again at level of detail `lod` (-1: all); the frame on screen stays until its new version comes. */
  setLod(lod) {
    this.requestedLod = lod;
    if (!this.worker) return;
    this.frames = [];
    this.state.decoded = 0;
    if (this.header) this.state.lod = lod < 0 ? this.header.schemes.length : lod;
    this.worker.postMessage({ lod: lod < 0 ? null : lod, token: ++this.token, first: this.state.frame });
  }

  play() {
    if (this.state.frame >= this.state.frames - 1 && !this.loop) this.seek(0);
    this.state.playing = true;
  }

  pause() {
    this.state.playing = false;
  }

  /** Shows frame `i` (clamped to the stream) as soon as it is decoded (and, while the stream
   * is arriving, as soon as its bytes are in). */
  seek(i) {
    const k = Math.max(0, Math.min(this.state.frames - 1, Math.trunc(i)));
    if (!this.frames[k] && this.worker) this.worker.postMessage({ seek: k, token: this.token });
    return this.show(k);
  }

  /** Stops downloading, decoding and playing; the canvas keeps its last picture. */
  destroy() {
    this.destroyed = true;
    this.stop();
  }

  /** Ends the current load: its download and its worker. */
  stop() {
    if (this.reader) this.reader.cancel().catch(() => {});
    if (this.worker) this.worker.terminate();
    this.reader = null;
    this.worker = null;
  }

  fail(message) {
    this.state.error = message;
    this.dispatchEvent(new CustomEvent('error', { detail: { message } }));
  }

  startWorker() {
    this.frames = [];
    const my = ++this.token;
    const worker = new Worker(new URL('./worker.js', import.meta.url), { type: 'module' });
    this.worker = worker;
    worker.onmessage = ({ data }) => {
      if (worker !== this.worker) return; // a previous load's
      if (data.error) this.fail(data.error);
      else if (data.header) this.setup(data.header);
      else if (data.texture) this.addTexture(data.texture);
      else if (data.infos) this.arrived(data);
      else if (data.view) this.fit(data.view);
      else if (data.token === this.token && data.frame) this.received(data.frame);
    };
    worker.onerror = (e) => this.fail(e.message || 'the decoder worker failed');
    const lod = this.requestedLod;
    worker.postMessage({ start: { lod: lod < 0 ? null : lod, token: my, first: this.state.frame } });
    return worker;
  }

  setup(header) {
    this.header = header;
    this.infos = new Array(header.frameCount).fill(null);
    this.state.frames = header.frameCount;
    this.state.lod = this.requestedLod < 0 ? header.schemes.length : this.requestedLod;
    this.texture = new TexturePlayer();
    this.state.textured = false;
    this.state.textureNote = '';
    this.dispatchEvent(new Event('loaded'));
  }

  addTexture({ first, payload }) {
    this.texture.add(first, new Uint8Array(payload));
    this.state.textured = this.texture.textured;
    this.state.textureNote = this.texture.note;
  }

  arrived({ arrived, infos, bytes, complete }) {
    infos.forEach((info, k) => { this.infos[arrived - infos.length + k] = info; });
    Object.assign(this.state, { arrived, bytes, complete });
    this.dispatchEvent(new CustomEvent('progress', { detail: { arrived, bytes, complete } }));
  }

  /** The default camera, from the sequence's box (see worker.js). */
  fit(view) {
    this.renderer.fit(view.lo, view.hi, view.front);
    this.state.view = view;
    if (this.frames[this.state.shown]) this.renderer.draw();
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
