// The player page: fetches the stream, has worker.js decode it, shows the frames with
// renderer.js at the stream's frame rate, with play/pause, frame steps, a scrub bar, a
// wireframe toggle, a level-of-detail choice, and a timeline of frame types and sizes.
//
// Contract for tests: `window.dynmeshPlayer` exposes `state` ({frame, shown (the frame on
// screen), faces (its triangles), lod, advanced (frames played), decoded, frames, playing, error, textured, textureNote,
// view (the box {lo, hi} the camera framed, and the `front` it looks from)}), `seek(i)`, `play()`, `pause()`,
// `renderer`, and `boxCorners()` (where the box's corners project with the current camera).

import { Renderer } from './renderer.js';
import { TexturePlayer } from './video.js';

const $ = (id) => document.getElementById(id);
const state = { frame: 0, shown: -1, faces: 0, lod: -1, advanced: 0, decoded: 0, frames: 0, playing: false, error: null, textured: false, textureNote: '' };
const frames = [];
let infos = [], header = null, fps = 30, token = 0, worker = null, stream = null, texture = null;
const renderer = new Renderer($('view'));

function status(text) {
  $('status').textContent = text;
}

async function start() {
  const params = new URLSearchParams(location.search);
  const url = params.get('stream') ?? '../stream.dmsh';
  try {
    const info = await fetch('../info.json').then((r) => (r.ok ? r.json() : {})).catch(() => ({}));
    fps = Number(params.get('fps') ?? info.fps ?? 30) || 30;
    const response = await fetch(url);
    if (!response.ok) throw new Error(`cannot fetch ${url}: HTTP ${response.status}`);
    stream = await response.arrayBuffer();
    document.title = `dynmesh player: ${info.name ?? url}`;
    decode(Number(params.get('lod') ?? -1));
  } catch (e) {
    fail(e.message);
  }
}

function fail(message) {
  state.error = message;
  status(`error: ${message}`);
}

/** (Re)starts decoding at level of detail `lod` (-1: all); frames shown so far are dropped. */
function decode(lod) {
  if (worker) worker.terminate();
  frames.length = 0;
  state.decoded = 0;
  const my = ++token;
  worker = new Worker(new URL('./worker.js', import.meta.url), { type: 'module' });
  worker.onmessage = ({ data }) => {
    if (data.token !== my) return;
    if (data.error) fail(data.error);
    else if (data.header) setup(data.header, data.infos, data.view, lod);
    else if (data.frame) received(data.frame);
    else if (data.done) status(describe());
  };
  worker.onerror = (e) => fail(e.message || 'the decoder worker failed');
  worker.postMessage({ stream: stream.slice(0), lod: lod < 0 ? undefined : lod, token: my });
}

function setup(h, frameInfos, view, lod) {
  const first = header === null;
  if (first) {
    renderer.fit(view.lo, view.hi, view.front);
    state.view = view;
  }
  header = h;
  infos = frameInfos;
  state.frames = infos.length;
  $('scrub').max = String(Math.max(0, infos.length - 1));
  const select = $('lod');
  if (first) {
    for (let k = h.schemes.length; k >= 0; k--) select.add(new Option(k === h.schemes.length ? `${k} (full)` : String(k), String(k)));
    setupTexture();
  }
  select.value = String(lod < 0 ? h.schemes.length : lod);
  state.lod = Number(select.value);
  drawTimeline();
}

function setupTexture() {
  texture = new TexturePlayer(new Uint8Array(stream), infos);
  state.textured = texture.textured;
  state.textureNote = texture.note;
}

function received(frame) {
  frames[frame.index] = frame;
  state.decoded = frame.index + 1;
  if (frame.index === state.frame) show(state.frame);
  status(describe());
  drawTimeline();
}

function describe() {
  const f = frames[state.frame];
  const faces = f ? f.faces.length / 3 : 0;
  const note = state.textureNote ? ` - ${state.textureNote}` : '';
  return `${state.decoded}/${state.frames} frames decoded, ${fps} fps, frame ${state.frame}: ${faces} faces${note}`;
}

async function show(i) {
  state.frame = i;
  $('scrub').value = String(i);
  $('label').textContent = `frame ${i} / ${Math.max(0, state.frames - 1)} ${infos[i] ? infos[i].type : ''}`;
  const f = frames[i];
  if (f) {
    // The texture first (decoding may take a while), then mesh and texture together, so that
    // a frame's geometry never shows with another frame's texture.
    const image = texture && f.uvs ? await texture.image(i) : null;
    state.textured = Boolean(texture && texture.textured);
    state.textureNote = texture ? texture.note : '';
    if (state.frame !== i) return;
    renderer.setMesh(f);
    renderer.setTexture(image);
    state.shown = i;
    state.faces = f.faces.length / 3;
  }
  renderer.draw();
  drawTimeline();
  status(describe());
}

function seek(i) {
  show(Math.max(0, Math.min(state.frames - 1, i)));
}

let last = 0;
function tick(now) {
  if (state.playing && now - last >= 1000 / fps) {
    const next = (state.frame + 1) % Math.max(1, state.frames);
    if (frames[next]) {
      last = now;
      state.advanced++;
      show(next);
    }
  }
  requestAnimationFrame(tick);
}

function play() {
  state.playing = true;
  $('play').textContent = 'Pause';
}

function pause() {
  state.playing = false;
  $('play').textContent = 'Play';
}

/** Bars per frame: height by the square root of the bytes (predicted frames are often a
 * hundredth of an intra frame with its texture), orange for intra, blue for predicted; the
 * current frame marked. */
function drawTimeline() {
  const c = $('timeline');
  const w = (c.width = c.clientWidth), h = c.height;
  const g = c.getContext('2d');
  g.clearRect(0, 0, w, h);
  if (!infos.length) return;
  const most = Math.max(...infos.map((f) => f.bytes + f.textureBytes));
  const bw = w / infos.length;
  infos.forEach((f, i) => {
    const bh = Math.max(2, (h - 12) * Math.sqrt((f.bytes + f.textureBytes) / most));
    g.fillStyle = frames[i] ? (f.type === 'I' ? '#e8913a' : '#4a8fe0') : '#556';
    g.fillRect(i * bw + 0.5, h - bh, Math.max(1, bw - 1), bh);
  });
  g.fillStyle = '#fff';
  g.fillRect(state.frame * bw, 0, Math.max(2, bw), 3);
  g.fillStyle = '#9ab';
  const f = infos[state.frame];
  g.fillText(`${f.type} ${f.bytes} B${f.textureBytes ? ` + ${f.textureBytes} B texture` : ''}`, 4, 11);
}

function bind() {
  $('play').onclick = () => (state.playing ? pause() : play());
  $('step').onclick = () => { pause(); seek(state.frame + 1); };
  $('back').onclick = () => { pause(); seek(state.frame - 1); };
  $('scrub').oninput = (e) => seek(Number(e.target.value));
  $('wire').onchange = (e) => { renderer.wireframe = e.target.checked; renderer.draw(); };
  $('lod').onchange = (e) => decode(Number(e.target.value));
  $('timeline').onclick = (e) => seek(Math.floor((e.offsetX / e.target.clientWidth) * state.frames));
  const view = $('view');
  let drag = null;
  view.onpointerdown = (e) => { drag = [e.clientX, e.clientY]; view.setPointerCapture(e.pointerId); };
  view.onpointermove = (e) => {
    if (!drag) return;
    renderer.orbit(e.clientX - drag[0], e.clientY - drag[1]);
    drag = [e.clientX, e.clientY];
    renderer.draw();
  };
  view.onpointerup = () => { drag = null; };
  view.onwheel = (e) => { e.preventDefault(); renderer.zoom(Math.exp(e.deltaY * 0.001)); renderer.draw(); };
  window.onkeydown = (e) => {
    if (e.key === ' ') { e.preventDefault(); state.playing ? pause() : play(); }
    if (e.key === 'ArrowRight') { pause(); seek(state.frame + 1); }
    if (e.key === 'ArrowLeft') { pause(); seek(state.frame - 1); }
  };
  window.onresize = () => { renderer.draw(); drawTimeline(); };
}

/** Normalized device coordinates of the corners of the sequence's box with the current camera. */
function boxCorners() {
  const { lo, hi } = state.view;
  return [0, 1, 2, 3, 4, 5, 6, 7].map((c) => renderer.project([0, 1, 2].map((k) => ((c >> k) & 1 ? hi[k] : lo[k]))));
}

window.dynmeshPlayer = { state, seek, play, pause, renderer, boxCorners };
bind();
requestAnimationFrame(tick);
start();
