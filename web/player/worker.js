// Decoding off the page's thread: decodes every frame of a stream at one level of detail and
// posts each as it is done (float32 positions relative to the grid centre, vertex normals,
// faces; and, for textured streams, the frame's UVs unwelded per corner). Frames go in order
// from `first`, except that a frame asked for by a seek is decoded next (the decoder starts
// it from the nearest intra frame, or a state it holds) and the order goes on after it.
//
// Messages in: {stream: ArrayBuffer, lod, token, first}, then any number of {token, seek}.
// Out: {token, header, infos, view}, then {token, frame}, per frame, then {token, done}; or
// {token, error} with the decoder's message.

import { Decoder } from '../src/decoder.js';
import { frameUvs } from '../src/texture/unit.js';

let job = null;

self.onmessage = ({ data }) => {
  if (data.stream) start(data);
  else if (job && data.token === job.token) job.wanted.push(data.seek);
};

function start({ stream, lod, token, first }) {
  try {
    const dec = new Decoder(new Uint8Array(stream), { lod });
    const h = dec.header;
    const infos = Array.from({ length: dec.frameCount }, (_, i) => dec.frameInfo(i));
    const half = (2 ** h.bits - 1) / 2;
    const centre = h.origin.map((o) => o + half * h.step);
    const view = sequenceView(new Uint8Array(stream), infos, centre);
    self.postMessage({ token, header: { ...h, centre, extent: 2 * half * h.step }, infos, view });
    const n = dec.frameCount;
    job = { dec, token, centre, uvs: frameUvs(dec), groups: new Map(), sent: new Uint8Array(n), left: n, next: Math.min(first ?? 0, n - 1), wanted: [] };
    setTimeout(step, 0);
  } catch (e) {
    self.postMessage({ token, error: e.message });
  }
}

/** Decodes and posts one frame, then yields (so that a seek can come in) and goes on. */
function step() {
  let i = job.wanted.pop();
  job.wanted.length = 0; // only the latest seek matters
  if (i === undefined || job.sent[i]) {
    for (i = job.next; job.sent[i]; i = (i + 1) % job.sent.length);
  }
  try {
    post(i);
  } catch (e) {
    self.postMessage({ token: job.token, error: e.message });
    return;
  }
  job.next = (i + 1) % job.sent.length;
  if (--job.left > 0) setTimeout(step, 0);
  else self.postMessage({ token: job.token, done: true });
}

function post(i) {
  const frame = renderable(job.dec.decodeFrame(i), job.centre);
  frame.index = i;
  const uv = groupUvs(i);
  if (uv) Object.assign(frame, unweld(frame, uv));
  const transfer = [frame.positions.buffer, frame.normals.buffer, frame.faces.buffer];
  if (frame.uvs) transfer.push(frame.uvs.buffer);
  job.sent[i] = 1;
  self.postMessage({ token: job.token, frame }, transfer);
}

/** Frame i's UVs (its texture group's), or null. `frameUvs` reads a group's UVs right after
 * the decode of the group's first frame, on its base mesh; frames come out of order here, so
 * each group's are read that way once and kept (the last few groups). */
function groupUvs(i) {
  if (job.dec.texturePayload(0) === null) return null; // untextured
  let g = i;
  while (g > 0 && job.dec.texturePayload(g) === null) g--;
  if (!job.groups.has(g)) {
    if (g !== i) job.dec.decodeFrame(g);
    job.groups.set(g, job.uvs(g));
    if (job.groups.size > 4) job.groups.delete(job.groups.keys().next().value);
  }
  return job.groups.get(g);
}

/**
 * What the default camera frames: {lo, hi} the box of the sequence around `centre`, and
 * `front`, the horizontal direction the surface faces. The box is the union of the intra
 * frames' base meshes (level of detail 0: cheap, and a predicted frame stays near its
 * group's intra frame); the front is the area-weighted mean normal of the first frame where
 * it clearly has one (an open surface, a relief), else +z (a closed surface, whose normals
 * cancel: the glTF convention's front).
 */
function sequenceView(stream, infos, centre) {
  const dec = new Decoder(stream, { lod: 0 });
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  let front = null;
  infos.forEach((info, i) => {
    if (info.type !== 'I') return;
    const f = dec.decodeFrame(i);
    for (let j = 0; j < f.positions.length; j++) {
      const k = j % 3, x = f.positions[j] - centre[k];
      if (x < lo[k]) lo[k] = x;
      if (x > hi[k]) hi[k] = x;
    }
    front ??= facing(f);
  });
  return { lo, hi, front: front ?? [0, 0, 1] };
}

/** The horizontal unit direction of a frame's summed face normals (twice the area each), or
 * null when it is under a fifth of the area (no clear side). */
function facing({ positions: p, faces }) {
  let sx = 0, sz = 0, area = 0;
  for (let t = 0; t < faces.length; t += 3) {
    const a = 3 * faces[t], b = 3 * faces[t + 1], c = 3 * faces[t + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    sx += nx; sz += nz; area += Math.hypot(nx, ny, nz);
  }
  const l = Math.hypot(sx, sz);
  return l > 0.2 * area ? [sx / l, 0, sz / l] : null;
}

/** Float32 positions around `centre`, unit vertex normals and the faces of a decoded frame. */
function renderable(f, centre) {
  const n = f.positions.length / 3;
  const positions = new Float32Array(3 * n);
  for (let i = 0; i < 3 * n; i++) positions[i] = f.positions[i] - centre[i % 3];
  const normals = new Float32Array(3 * n);
  const p = f.positions, faces = f.faces;
  for (let t = 0; t < faces.length; t += 3) {
    const a = 3 * faces[t], b = 3 * faces[t + 1], c = 3 * faces[t + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const v of [a, b, c]) { normals[v] += nx; normals[v + 1] += ny; normals[v + 2] += nz; }
  }
  for (let i = 0; i < 3 * n; i += 3) {
    const l = Math.hypot(normals[i], normals[i + 1], normals[i + 2]) || 1;
    normals[i] /= l; normals[i + 1] /= l; normals[i + 2] /= l;
  }
  return { positions, normals, faces: new Uint32Array(faces), type: f.type };
}

/** One vertex per face corner, so that a UV seam can split a vertex (WebGL has one index list). */
function unweld(frame, { uv, uvFaces }) {
  const m = frame.faces.length;
  const positions = new Float32Array(3 * m), normals = new Float32Array(3 * m), uvs = new Float32Array(2 * m);
  for (let c = 0; c < m; c++) {
    const v = frame.faces[c], t = uvFaces[c];
    positions.set(frame.positions.subarray(3 * v, 3 * v + 3), 3 * c);
    normals.set(frame.normals.subarray(3 * v, 3 * v + 3), 3 * c);
    uvs[2 * c] = uv[2 * t];
    uvs[2 * c + 1] = 1 - uv[2 * t + 1];
  }
  const faces = new Uint32Array(m);
  for (let c = 0; c < m; c++) faces[c] = c;
  return { positions, normals, uvs, faces };
}
