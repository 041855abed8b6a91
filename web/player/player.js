// The player page: the module API (api.js) in a canvas, with play/pause, frame steps, a scrub
// bar, a wireframe toggle, a level-of-detail choice, a timeline of frame types and sizes, and
// an orbit camera on the mouse. The stream is ../stream.dmsh (or ?stream=URL) beside
// ../info.json (its name and frame rate), as `dynmesh play` serves and `--export` writes them.
//
// Contract for tests: `window.dynmeshPlayer` exposes `state` (the API's: {frame, shown (the
// frame on screen), faces (its triangles), lod, advanced (frames played), decoded, frames,
// playing, error, textured, textureNote, view (the box {lo, hi} the camera framed, and the
// `front` it looks from)}), `seek(i)`, `play()`, `pause()`, `renderer`, `boxCorners()` (where
// the box's corners project with the current camera) and `player` (the API object).

import { createPlayer } from './api.js';

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
let player = null;

function status(text) {
  $('status').textContent = text;
}

async function start() {
  const url = params.get('stream') ?? '../stream.dmsh';
  const info = await fetch('../info.json').then((r) => (r.ok ? r.json() : {})).catch(() => ({}));
  try {
    player = createPlayer($('view'), { fps: Number(params.get('fps') ?? info.fps ?? 30) || 30, lod: Number(params.get('lod') ?? -1) });
  } catch (e) {
    status(`error: ${e.message}`);
    return;
  }
  window.dynmeshPlayer = { state: player.state, seek, play, pause, renderer: player.renderer, boxCorners: () => player.boxCorners(), player };
  document.title = `dynmesh player: ${info.name ?? url}`;
  player.addEventListener('error', (e) => status(`error: ${e.detail.message}`));
  player.addEventListener('loaded', loaded, { once: true });
  player.addEventListener('decoded', refresh);
  player.addEventListener('progress', refresh);
  player.addEventListener('frame', refresh);
  bind();
  player.load(url).catch(() => {}); // reported by the error event
}

function loaded() {
  const h = player.header, select = $('lod');
  $('scrub').max = String(Math.max(0, player.state.frames - 1));
  for (let k = h.schemes.length; k >= 0; k--) select.add(new Option(k === h.schemes.length ? `${k} (full)` : String(k), String(k)));
  select.value = String(player.state.lod);
  refresh();
}

function refresh() {
  const s = player.state, info = player.infos[s.frame];
  $('scrub').value = String(s.frame);
  $('label').textContent = `frame ${s.frame} / ${Math.max(0, s.frames - 1)} ${info ? info.type : ''}`;
  if (!s.error) status(describe());
  drawTimeline();
}

function describe() {
  const s = player.state, f = player.frames[s.frame];
  const note = s.textureNote ? ` - ${s.textureNote}` : '';
  const arriving = s.complete ? '' : `${s.arrived}/${s.frames} frames downloaded, `;
  return `${arriving}${s.decoded}/${s.frames} frames decoded, ${player.fps} fps, frame ${s.frame}: ${f ? f.faces.length / 3 : 0} faces${note}`;
}

function seek(i) {
  player.seek(i);
  refresh();
}

function play() {
  player.play();
  $('play').textContent = 'Pause';
}

function pause() {
  player.pause();
  $('play').textContent = 'Play';
}

/** Bars per frame: height by the square root of the bytes (predicted frames are often a
 * hundredth of an intra frame with its texture), orange for intra, blue for predicted, grey
 * until decoded; the current frame marked. */
function drawTimeline() {
  const c = $('timeline'), infos = player.infos;
  const w = (c.width = c.clientWidth), h = c.height;
  const g = c.getContext('2d');
  g.clearRect(0, 0, w, h);
  if (!infos.length) return;
  const most = Math.max(1, ...infos.map((f) => (f ? f.bytes + f.textureBytes : 0)));
  const bw = w / infos.length;
  infos.forEach((f, i) => {
    if (!f) return; // not downloaded yet
    const bh = Math.max(2, (h - 12) * Math.sqrt((f.bytes + f.textureBytes) / most));
    g.fillStyle = player.frames[i] ? (f.type === 'I' ? '#e8913a' : '#4a8fe0') : '#556';
    g.fillRect(i * bw + 0.5, h - bh, Math.max(1, bw - 1), bh);
  });
  const k = player.state.frame, f = infos[k];
  g.fillStyle = '#fff';
  g.fillRect(k * bw, 0, Math.max(2, bw), 3);
  g.fillStyle = '#9ab';
  if (f) g.fillText(`${f.type} ${f.bytes} B${f.textureBytes ? ` + ${f.textureBytes} B texture` : ''}`, 4, 11);
}

function bind() {
  const renderer = player.renderer, redraw = () => renderer.draw();
  const toggle = () => (player.state.playing ? pause() : play());
  $('play').onclick = toggle;
  $('step').onclick = () => { pause(); seek(player.state.frame + 1); };
  $('back').onclick = () => { pause(); seek(player.state.frame - 1); };
  $('scrub').oninput = (e) => seek(Number(e.target.value));
  $('wire').onchange = (e) => { renderer.wireframe = e.target.checked; redraw(); };
  $('lod').onchange = (e) => { player.setLod(Number(e.target.value)); refresh(); };
  $('timeline').onclick = (e) => seek(Math.floor((e.offsetX / e.target.clientWidth) * player.state.frames));
  const view = $('view');
  let drag = null;
  view.onpointerdown = (e) => { drag = [e.clientX, e.clientY]; view.setPointerCapture(e.pointerId); };
  view.onpointermove = (e) => {
    if (!drag) return;
    renderer.orbit(e.clientX - drag[0], e.clientY - drag[1]);
    drag = [e.clientX, e.clientY];
    redraw();
  };
  view.onpointerup = () => { drag = null; };
  view.onwheel = (e) => { e.preventDefault(); renderer.zoom(Math.exp(e.deltaY * 0.001)); redraw(); };
  window.onkeydown = (e) => {
    if (e.key === ' ') { e.preventDefault(); toggle(); }
    if (e.key === 'ArrowRight') { pause(); seek(player.state.frame + 1); }
    if (e.key === 'ArrowLeft') { pause(); seek(player.state.frame - 1); }
  };
  window.onresize = () => { redraw(); drawTimeline(); };
}

start();
