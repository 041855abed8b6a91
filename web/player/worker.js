// Decoding off the page's thread, while the stream arrives: the worker keeps the stream's
// bytes as they come (chunks from a fetch, or all at once), splits them into units as soon as
// each is whole, and decodes every frame at one level of detail, posting each as it is done
// (float32 positions relative to the grid centre, vertex normals, faces; and, for textured
// streams, the frame's UVs unwelded per corner). A frame can be decoded once its unit is in
// and, when it starts a texture group, the texture unit after it (docs/bitstream.md, section
// 3: a group's texture unit follows the group's first frame unit, so the later frames of the
// group find it there). Frames go in order from `first`, except that a frame asked for by a
// seek is decoded next, or as soon as it arrives (the decoder starts it from the nearest
// intra frame, or a state it holds), and the order goes on after it.
//
// Messages in: {start: {lod, token, first}}, then {chunk: ArrayBuffer} as bytes arrive and
// {end: true} after the last; {stream: ArrayBuffer, lod, token, first} is all three at once.
// Any time after start: {token, seek: i}; {token, lod, first} decodes again at another level
// of detail, from frame `first` (frames already posted come again; `token` is the new decode's).
// Out: {token, header} as soon as the sequence header is in; {arrived, infos, bytes, complete}
// whenever units arrive (`infos` the new frames' types and sizes, in order; `arrived` the
// frames in so far); {texture: {first, payload}} for each texture group, before any of its
// frames; {token, view} once, before the first frame; then {token, frame} per frame and
// {token, done}; or {error} with the decoder's message (a unit that fails its check stops the
// stream there: the frames decoded by then have been posted).

import { Decoder } from '../src/decoder.js';
import { readFrameUnit, readHeader, readUnits, unitEnd, INTRA, TEXTURE_UNIT } from '../src/stream/bitstream.js';
import { frameUvs } from '../src/texture/unit.js';

/** A sequence header is under 100 bytes: with this many in and none parsed, the stream is bad. */
const HEADER_ROOM = 256;

/** The stream as it arrives: bytes, header, units. */
let input = null;
/** The decode at one level of detail. */
let job = null;

self.onmessage = ({ data }) => {
  try {
    if (data.stream) {
      begin(data);
      receive(data.stream);
      finish();
    } else if (data.start) begin(data.start);
    else if (data.chunk) receive(data.chunk);
    else if (data.end) finish();
    else if (data.lod !== undefined) relod(data.lod, data.token, data.first);
    else if (job && data.token === job.token) {
      job.wanted = data.seek;
      wake();
    }
  } catch (e) {
    fail(e);
  }
};

function fail(e) {
  if (input) input.failed = true;
  self.postMessage({ error: e.message });
}

function begin({ lod, token, first }) {
  input = { bytes: new Uint8Array(1 << 16), filled: 0, header: null, units: [], pos: 0, ended: false, failed: false };
  job = { token, lod, first: first ?? 0, dec: null };
}

/** Appends a chunk, splits off the units now whole, and wakes the decoding. */
function receive(chunk) {
  if (input.failed) return;
  const add = new Uint8Array(chunk);
  if (input.filled + add.length > input.bytes.length) {
    const grown = new Uint8Array(Math.max(2 * input.bytes.length, input.filled + add.length));
    grown.set(input.bytes.subarray(0, input.filled));
    input.bytes = grown;
  }
  input.bytes.set(add, input.filled);
  input.filled += add.length;
  split();
}

function finish() {
  if (input.failed) return;
  input.ended = true;
  split();
  const data = input.bytes.subarray(0, input.filled);
  if (!input.header || input.units.length < input.header.frameCount || input.pos !== input.filled) {
    // The whole stream's reading names the problem as the Rust decoder does.
    readUnits(data, input.header ?? readHeader(data));
    throw new Error('the stream ends early');
  }
}

/** Splits off the header and each unit whose bytes (and texture unit) are all in. */
function split() {
  const data = input.bytes.subarray(0, input.filled);
  if (job.dec) job.dec.data = data;
  if (!input.header) {
    try {
      input.header = readHeader(data);
    } catch (e) {
      if (input.ended || input.filled >= HEADER_ROOM) throw e;
      return;
    }
    input.pos = input.header.length;
    started();
  }
  const h = input.header, units = input.units, before = units.length;
  const inData = (end) => end !== null && end <= data.length;
  while (units.length < h.frameCount && inData(unitEnd(data, input.pos))) {
    const f = units.length;
    // Whether a texture unit follows shows in the next byte (or the end of the stream).
    const after = unitEnd(data, input.pos);
    if (after === data.length && !input.ended) break;
    if (after < data.length && data[after] === TEXTURE_UNIT && !inData(unitEnd(data, after))) break;
    const { unit, next } = readFrameUnit(data, input.pos, f);
    if (unit.texture) {
      const payload = data.slice(unit.texture.offset, unit.texture.offset + unit.texture.length).buffer;
      self.postMessage({ texture: { first: f, payload } }, [payload]);
    }
    units.push(unit);
    input.pos = next;
  }
  const complete = input.ended && units.length === h.frameCount && input.pos === input.filled;
  if (units.length > before || complete) {
    const infos = [];
    for (let i = before; i < units.length; i++) infos.push(job.dec.frameInfo(i));
    self.postMessage({ arrived: units.length, infos, bytes: input.filled, complete });
    wake();
  }
}

/** The header is in: say so, and set up the decoding. */
function started() {
  const h = input.header;
  const half = (2 ** h.bits - 1) / 2;
  const centre = h.origin.map((o) => o + half * h.step);
  self.postMessage({ token: job.token, header: { ...h, centre, extent: 2 * half * h.step } });
  job.centre = centre;
  relod(job.lod, job.token, job.first);
}

/** (Re)starts decoding at level of detail `lod` under `token`, from frame `first`. */
function relod(lod, token, first = 0) {
  if (!input || !input.header) {
    Object.assign(job, { lod, token, first });
    return;
  }
  const n = input.header.frameCount;
  const dec = new Decoder(input.bytes.subarray(0, input.filled), { header: input.header, units: input.units, lod });
  job = { ...job, dec, lod, token, uvs: null, groups: new Map(), sent: new Uint8Array(n), left: n, next: Math.max(0, Math.min(first, n - 1)), wanted: undefined, timer: null, viewed: job.viewed ?? false };
  wake();
}

/** Schedules the next decode step unless one is due or nothing can be decoded yet. */
function wake() {
  if (job && job.dec && job.timer === null && job.left > 0 && !input.failed) job.timer = setTimeout(step, 0);
}

/** Decodes and posts one frame that has arrived, then yields (so that a seek or bytes can come in) and goes on. */
function step() {
  job.timer = null;
  const arrived = input.units.length, n = job.sent.length;
  let i = job.wanted;
  if (i !== undefined && job.sent[i]) i = job.wanted = undefined;
  if (i === undefined || i >= arrived) {
    i = undefined;
    for (let k = 0, j = job.next; k < n; k++, j = (j + 1) % n) {
      if (j < arrived && !job.sent[j]) { i = j; break; }
    }
    if (i === undefined) return; // waits for more bytes (receive wakes it)
  }
  if (i === job.wanted) job.wanted = undefined;
  try {
    if (!job.viewed) {
      self.postMessage({ token: job.token, view: sequenceView(input.bytes.subarray(0, input.filled), input.header, input.units, job.centre) });
      job.viewed = true;
    }
    post(i);
  } catch (e) {
    fail(e);
    return;
  }
  job.next = (i + 1) % n;
  if (--job.left > 0) wake();
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
  job.uvs ??= frameUvs(job.dec); // made once frame 0 is in (it looks at frame 0's texture unit)
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
 * `front`, the horizontal unit direction the camera looks from (y is up). The box is the
 * union of the intra frames' base meshes (those that have arrived when the first frame is
 * shown: all of them for bytes, or a download that was quicker than the first decode) (level
 * of detail 0: cheap, and a predicted frame stays near its group's intra frame). The front is
 * that of the first of those frames that tells one: the area-weighted mean normal where it
 * clearly has one (an open surface, a relief); for a closed surface, whose normals cancel (every
 * capture of a person), the way a standing figure faces, told by its feet (`standingFront`);
 * else +z (the glTF convention's front).
 */
function sequenceView(stream, header, units, centre) {
  const dec = new Decoder(stream, { header, units: units.slice(), lod: 0 });
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  let front = null;
  units.forEach((unit, i) => {
    if (unit.type !== INTRA) return;
    const f = dec.decodeFrame(i);
    for (let j = 0; j < f.positions.length; j++) {
      const k = j % 3, x = f.positions[j] - centre[k];
      if (x < lo[k]) lo[k] = x;
      if (x > hi[k]) hi[k] = x;
    }
    front ??= facing(f) ?? standingFront(f);
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

/** Heights as fractions of the figure's (y extent): the sole slice (the lowest faces: whole
 * feet, toes to heels), the ankle slice above it (the lower legs only), the hip slice; the grid
 * cell of the footprint. The feet tell a front when they point at least STEP of the height
 * away from the legs, with at least ON_FEET ankle area over the footprint per sole area (a foot
 * has its leg on it; a round bottom, whose next slice is wider, has none); the hips give it
 * its axis when they are at least WIDE times as wide as deep (in variance) and it is within
 * 60 degrees of the feet's way. */
const SOLE = 0.03, ANKLE = [0.05, 0.1], HIPS = [0.4, 0.55], CELL = 0.02, STEP = 0.01, ON_FEET = 0.1, WIDE = 1.5;

/**
 * The horizontal unit direction a standing figure faces, or null when the frame does not
 * show one clearly. Feet point forward: their soles reach further to the front of the legs
 * above them (toes) than to the back (heels). So the area-weighted centre of the lowest faces
 * (the SOLE slice) minus that of the faces of the ANKLE slice that stand on the footprint (over
 * a grid cell, CELL of the height, that holds a sole face; a lifted foot's leg is thus left
 * out, with its foot) is the way the feet point. On people captures it is 3 to 5 % of the
 * height, but off the body's front by up to 45 degrees (feet turned out, a stance); the front
 * is then the body's depth axis, the minor horizontal axis of the HIPS slice (hips are wider
 * than deep, and hanging arms are beside them), on the feet's side.
 */
function standingFront({ positions: p, faces }) {
  let bottom = Infinity, top = -Infinity;
  for (let j = 1; j < p.length; j += 3) { bottom = Math.min(bottom, p[j]); top = Math.max(top, p[j]); }
  const h = top - bottom;
  if (!(h > 0)) return null;
  const cell = CELL * h, key = (x, z) => `${Math.floor(x / cell)},${Math.floor(z / cell)}`;
  const sole = [0, 0, 0], ankle = [0, 0, 0], footprint = new Set(), legs = [];
  const hips = [0, 0, 0, 0, 0, 0]; // area, and its moments x, z, xx, xz, zz
  for (let t = 0; t < faces.length; t += 3) {
    const a = 3 * faces[t], b = 3 * faces[t + 1], c = 3 * faces[t + 2];
    const y = ((p[a + 1] + p[b + 1] + p[c + 1]) / 3 - bottom) / h;
    const low = y < SOLE, leg = y >= ANKLE[0] && y < ANKLE[1], hip = y >= HIPS[0] && y < HIPS[1];
    if (!low && !leg && !hip) continue;
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const w = Math.hypot(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx);
    const x = (p[a] + p[b] + p[c]) / 3, z = (p[a + 2] + p[b + 2] + p[c + 2]) / 3;
    if (low) {
      sole[0] += w * x; sole[1] += w * z; sole[2] += w;
      footprint.add(key(x, z));
    } else if (leg) legs.push(x, z, w);
    else [w, w * x, w * z, w * x * x, w * x * z, w * z * z].forEach((m, k) => { hips[k] += m; });
  }
  for (let k = 0; k < legs.length; k += 3) {
    if (!footprint.has(key(legs[k], legs[k + 1]))) continue;
    ankle[0] += legs[k + 2] * legs[k]; ankle[1] += legs[k + 2] * legs[k + 1]; ankle[2] += legs[k + 2];
  }
  if (!(sole[2] > 0) || !(ankle[2] >= ON_FEET * sole[2])) return null;
  let dx = sole[0] / sole[2] - ankle[0] / ankle[2], dz = sole[1] / sole[2] - ankle[1] / ankle[2];
  const l = Math.hypot(dx, dz);
  if (!(l >= STEP * h)) return null;
  dx /= l; dz /= l;
  if (hips[0] > 0) {
    const [w, mx, mz] = hips, x = mx / w, z = mz / w;
    const sxx = hips[3] / w - x * x, sxz = hips[4] / w - x * z, szz = hips[5] / w - z * z;
    const mean = (sxx + szz) / 2, r = Math.hypot((sxx - szz) / 2, sxz);
    const wide = 0.5 * Math.atan2(2 * sxz, sxx - szz); // the major axis's angle from x toward z
    let ax = -Math.sin(wide), az = Math.cos(wide); // the minor axis
    const along = ax * dx + az * dz;
    if (along < 0) { ax = -ax; az = -az; }
    if (mean + r >= WIDE * (mean - r) && Math.abs(along) >= 0.5) return [ax, 0, az];
  }
  return [dx, 0, dz];
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
