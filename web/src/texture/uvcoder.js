// Decoder of a texture group's UV atlas
// (`core/src/texture/uvcoder.rs::decode_uv_with_positions`) and its subdivision
// (`subdivide::subdivide_uv`), for textured streams.
//
// Contract: `decodeUvAtlas(data, positions, faces, bits)` returns the Rust result (canonical
// UV numbering: `uvFaces` flat, `uv` flat quantized integers) or throws an Error with the
// Rust reason. The atlas is coded face by face: per corner which UV of its vertex it uses
// (ranked candidates, a new UV, or an explicit index), then each new UV predicted from the
// face's known corners and the 3D shape of the triangle; predictions use IEEE basic
// operations and sqrt only, in the Rust order, so both decoders agree bit for bit.

import { RangeDecoder, bitModels, IntModel } from '../ec.js';
import { roundHalfAway } from '../base/coder.js';

const MAX_UV_BITS = 16;
const MAX_CANDIDATES = 32;
const BEND_COS = 0.9;
const NONE = 0xffffffff;
// Prediction kinds, in the order of their residual models.
const PARALLELOGRAM = 0, TWO_CORNERS = 1, ONE_CORNER = 2, SHAPE_ACROSS = 3, SHAPE_ORIENTED = 4, SHAPE_ONE_CORNER = 5;

/** Map keyed by an undirected pair of indices below 2^26. */
const pair = (a, b) => (a < b ? a * 67108864 + b : b * 67108864 + a);

const sub3 = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const dot3 = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross3 = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const sqDist = (a, b) => (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2;
/** Twice the signed area of UV triangle (a, b, c). */
const cross2 = (a, b, c) => (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);

class Models {
  constructor() {
    this.first = bitModels(2 * 4 * 3 * 3);
    this.fresh = bitModels(1);
    this.new = bitModels(2 * 3);
    this.rank = bitModels(4);
    this.residual = Array.from({ length: 6 }, () => [new IntModel(0), new IntModel(0)]);
  }
}

/** What the walk has decoded so far (`Atlas` in the Rust code). */
class Atlas {
  constructor(faces, positions, usedVertices) {
    this.faces = faces; // array of [a, b, c]
    this.positions = positions; // array of [x, y, z]
    this.edgeFace = new Map();
    this.uvLength = 0; this.length3d = 0; this.edges = 0;
    this.ccw = true;
    this.vertex = []; this.neighbour = []; this.ccwAt = [];
    this.uv = []; this.uvFaces = [];
    this.candidates = Array.from({ length: usedVertices }, () => []);
    this.lastUsed = [];
    this.opposite = new Map();
  }
}

/**
 * @param {Uint8Array} data the atlas block
 * @param {Float64Array} positions flat xyz of the base mesh it was coded on
 * @param {Uint32Array} faces flat base faces
 * @param {number} bits UV bits
 * @returns {{uvFaces: Uint32Array, uv: Uint32Array}}
 */
export function decodeUvAtlas(data, positions, faces, bits) {
  if (!(bits >= 1 && bits <= MAX_UV_BITS)) throw new Error(`UV atlas: bit depth ${bits} out of range`);
  const n = positions.length / 3;
  const tri = [];
  for (let f = 0; f < faces.length; f += 3) tri.push([faces[f], faces[f + 1], faces[f + 2]]);
  const bad = tri.findIndex((t) => t.some((v) => v >= n));
  if (bad >= 0) throw new Error(`UV atlas: face ${bad} refers to a vertex beyond the ${n} vertices`);
  if (3 * tri.length >= 67108864) throw new Error('UV atlas: too many faces for this decoder');
  const pos = Array.from({ length: n }, (_, v) => [positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]]);
  const dec = new RangeDecoder(data);
  const used = Math.min(tri.reduce((m, t) => Math.max(m, t[0] + 1, t[1] + 1, t[2] + 1), 0), n);
  const atlas = new Atlas(tri, pos, used);
  const models = new Models();
  tri.forEach((face, f) => {
    const ids = decideCorners(dec, models, atlas, face);
    codeNewUvs(dec, models, atlas, face, ids, bits);
    if (dec.exhausted()) throw new Error('UV atlas: data ends early or is corrupt');
    recordFace(atlas, face, ids, f);
  });
  const e = dec.finish();
  if (e) throw new Error(`UV atlas: ${e}`);
  return canonical(atlas.uvFaces, atlas.uv);
}

/** UVs renumbered in order of first use (`canonical_uv`). */
function canonical(uvFaces, uv) {
  const renumbered = new Map();
  const outUv = [];
  const outFaces = new Uint32Array(3 * uvFaces.length);
  uvFaces.forEach((f, i) => f.forEach((id, k) => {
    if (!renumbered.has(id)) { renumbered.set(id, outUv.length / 2); outUv.push(uv[id][0], uv[id][1]); }
    outFaces[3 * i + k] = renumbered.get(id);
  }));
  return { uvFaces: outFaces, uv: Uint32Array.from(outUv) };
}

function decideCorners(dec, models, atlas, face) {
  const coded = atlas.uv.length;
  const ids = [NONE, NONE, NONE];
  let pending = 0, news = 0;
  const order = [0, 1, 2].sort((a, b) => atlas.candidates[face[a]].length - atlas.candidates[face[b]].length);
  for (const k of order) {
    const references = ids.filter((i) => i < coded);
    const ranked = rankedCandidates(atlas, atlas.candidates[face[k]], references);
    const referenceCorners = [0, 1, 2].filter((j) => ids[j] < coded);
    let reference = 0;
    if (ranked.length > 0 && references.length > 0) {
      const c = ranked[0];
      if (references.some((r) => atlas.opposite.has(pair(c, r)))) reference = 1;
      else if (referenceCorners.some((j) => plausible(atlas, face, k, c, j, ids[j]))) reference = 2;
      else reference = 3;
    }
    const bendCx = ranked.length > 0 && references.length === 0 ? bend(atlas, face, k, ranked[0]) : 0;
    const cx = { several: ranked.length > 1 ? 1 : 0, reference, news, bend: bendCx };
    const choice = codeChoice(dec, models, ranked, cx, coded + pending);
    if (choice === null) {
      news = Math.max(news, ranked.length === 0 ? 1 : 2);
      pending++;
      ids[k] = coded + pending - 1;
    } else {
      ids[k] = choice;
    }
  }
  return ids;
}

function plausible(atlas, face, k, c, j, r) {
  if (atlas.edges === 0) return true;
  let expected;
  if (atlas.length3d > 0) {
    const d = sub3(atlas.positions[face[k]], atlas.positions[face[j]]);
    expected = (Math.sqrt(dot3(d, d)) * atlas.uvLength) / atlas.length3d;
  } else {
    expected = atlas.uvLength / atlas.edges;
  }
  return Math.sqrt(sqDist(atlas.uv[c], atlas.uv[r])) <= 2.0 * expected + 2.0;
}

function bend(atlas, face, k, c) {
  const n = faceNormal(atlas.positions, face);
  if (n === null) return 0;
  const v = face[k];
  let smoothest = -Infinity;
  for (let d = 1; d < 3; d++) {
    const g = atlas.edgeFace.get(pair(v, face[(k + d) % 3]));
    if (g === undefined) continue;
    if (![0, 1, 2].some((i) => atlas.faces[g][i] === v && atlas.uvFaces[g][i] === c)) continue;
    const m = faceNormal(atlas.positions, atlas.faces[g]);
    if (m === null) continue;
    const x = dot3(n, m);
    if (x > smoothest) smoothest = x; // f64::max: a NaN never wins
  }
  if (smoothest === -Infinity) return 0;
  return smoothest >= BEND_COS ? 1 : 2;
}

function rankedCandidates(atlas, candidates, references) {
  const keyed = candidates.map((c, i) => {
    const connected = references.some((r) => atlas.opposite.has(pair(c, r)));
    const distance = references.length ? Math.min(...references.map((r) => sqDist(atlas.uv[c], atlas.uv[r]))) : 0;
    return { c, i, key: [connected ? 0 : 1, distance, -atlas.lastUsed[c]] };
  });
  keyed.sort((a, b) => a.key[0] - b.key[0] || a.key[1] - b.key[1] || a.key[2] - b.key[2] || a.i - b.i);
  return keyed.map((x) => x.c);
}

/** A corner's choice: a coded or pending UV index, or null for a new UV. */
function codeChoice(dec, models, ranked, cx, total) {
  if (ranked.length === 0) {
    if (dec.bit(models.fresh, 0)) return null;
  } else {
    if (dec.bit(models.first, ((cx.several * 4 + cx.reference) * 3 + cx.news) * 3 + cx.bend)) return ranked[0];
    if (dec.bit(models.new, cx.several * 3 + cx.news)) return null;
    for (let r = 1; r < ranked.length; r++) if (dec.bit(models.rank, Math.min(r - 1, 3))) return ranked[r];
  }
  if (total === 0) throw new Error('UV atlas: a corner refers to an earlier UV before any');
  const i = dec.bypass(total - 1 === 0 ? 0 : 32 - Math.clz32(total - 1));
  if (i >= total) throw new Error(`UV atlas: a corner refers to UV ${i} of ${total}`);
  return i;
}

function codeNewUvs(dec, models, atlas, face, ids, bits) {
  const max = 2 ** bits - 1;
  const firstNew = atlas.uv.length;
  const known = ids.map((i) => (i < firstNew ? atlas.uv[i] : null));
  const values = [];
  for (let k = nextToCode(known); k !== -1; k = nextToCode(known)) {
    const p = predict(atlas, face, ids, known, k, max);
    let value;
    if (p === null) value = [dec.bypass(bits), dec.bypass(bits)];
    else value = codeResidual(dec, models.residual[p[0]], p[1], max);
    for (let j = 0; j < 3; j++) if (ids[j] === ids[k]) known[j] = value;
    values.push([ids[k], value]);
  }
  values.sort((a, b) => a[0] - b[0]);
  for (const [, v] of values) atlas.uv.push(v);
}

function codeResidual(dec, models, prediction, max) {
  const value = [0, 0];
  for (let axis = 0; axis < 2; axis++) {
    const v = prediction[axis] + dec.int(models[axis]);
    if (v < 0 || v > max) throw new Error(`UV atlas: a UV coordinate ${v} outside the range from 0 to ${max}`);
    value[axis] = v;
  }
  return value;
}

/** The unknown corner with the most known corners beside it (the first on ties), or -1. */
function nextToCode(known) {
  let best = -1, bestCount = -1;
  for (let k = 0; k < 3; k++) {
    if (known[k] !== null) continue;
    const count = (known[(k + 1) % 3] !== null ? 1 : 0) + (known[(k + 2) % 3] !== null ? 1 : 0);
    if (count > bestCount) { best = k; bestCount = count; }
  }
  return best;
}

function predict(atlas, face, ids, known, k, max) {
  const b = (k + 1) % 3, c = (k + 2) % 3;
  const firstNew = atlas.uv.length;
  const clamp = (p) => p.map((x) => Math.min(Math.max(x, 0), max));
  const ub = known[b], uc = known[c];
  if (ub !== null && uc !== null) {
    let across = null;
    if (ids[b] < firstNew && ids[c] < firstNew) {
      const d = atlas.opposite.get(pair(ids[b], ids[c]));
      if (d !== undefined) across = atlas.uv[d];
    }
    const chartCcw = ids[b] < firstNew ? atlas.ccwAt[ids[b]] : atlas.ccw;
    const x = across !== null ? cross2(ub, uc, across) : 0;
    const left = x !== 0 ? x < 0 : chartCcw;
    const shape = shapePrediction(atlas.positions, face, k, ub, uc, left);
    if (shape !== null) return [across !== null ? SHAPE_ACROSS : SHAPE_ORIENTED, clamp(shape)];
    if (across !== null) return [PARALLELOGRAM, clamp([ub[0] + uc[0] - across[0], ub[1] + uc[1] - across[1]])];
    return [TWO_CORNERS, clamp([Math.floor((ub[0] + uc[0]) / 2), Math.floor((ub[1] + uc[1]) / 2)])];
  }
  if (ub === null && uc === null) return null;
  const j = ub !== null ? b : c;
  const u = ub !== null ? ub : uc;
  const x = ids[j] < atlas.neighbour.length ? atlas.neighbour[ids[j]] : NONE;
  let shape = null;
  if (x !== NONE) {
    const n = faceNormal(atlas.positions, face);
    if (n !== null) {
      const p = atlas.positions;
      shape = tangentPrediction(p[face[k]], p[face[j]], p[atlas.vertex[x]], n, u, atlas.uv[x], atlas.ccwAt[ids[j]]);
    }
  }
  return shape !== null ? [SHAPE_ONE_CORNER, clamp(shape)] : [ONE_CORNER, u];
}

/** Rounds a finite prediction as Rust's `x.round().clamp(-1e9, 1e9) as i64`; null if not finite. */
function rounded(p) {
  if (!p.every(Number.isFinite)) return null;
  return p.map((x) => Math.min(Math.max(roundHalfAway(x), -1e9), 1e9));
}

function shapePrediction(positions, face, k, ub, uc, left) {
  const pa = positions[face[k]], pb = positions[face[(k + 1) % 3]], pc = positions[face[(k + 2) % 3]];
  const e = sub3(pc, pb), w = sub3(pa, pb);
  const len2 = dot3(e, e);
  if (len2 <= 0 || !Number.isFinite(len2)) return null;
  const t = dot3(w, e) / len2;
  const q = dot3(w, w) / len2 - t * t;
  let h = Math.sqrt(q > 0 ? q : 0); // Rust's f64::max(q, 0.0) also turns NaN into 0
  if (!left) h = -h;
  const eu = [uc[0] - ub[0], uc[1] - ub[1]];
  return rounded([ub[0] + t * eu[0] - h * eu[1], ub[1] + t * eu[1] + h * eu[0]]);
}

function faceNormal(p, face) {
  const a = p[face[0]], b = p[face[1]], c = p[face[2]];
  const n = cross3(sub3(b, a), sub3(c, a));
  const len = Math.sqrt(dot3(n, n));
  return len > 0 && Number.isFinite(len) ? [n[0] / len, n[1] / len, n[2] / len] : null;
}

function tangentPrediction(pa, pb, px, n, ub, ux, ccw) {
  const flat = (v) => {
    const d = dot3(v, n);
    return [v[0] - d * n[0], v[1] - d * n[1], v[2] - d * n[2]];
  };
  const u = flat(sub3(px, pb)), w = flat(sub3(pa, pb));
  const len2 = dot3(u, u);
  if (len2 <= 0 || !Number.isFinite(len2)) return null;
  const t = dot3(w, u) / len2;
  let h = dot3(w, cross3(n, u)) / len2;
  if (!ccw) h = -h;
  const eu = [ux[0] - ub[0], ux[1] - ub[1]];
  return rounded([ub[0] + t * eu[0] - h * eu[1], ub[1] + t * eu[1] + h * eu[0]]);
}

function recordFace(atlas, face, ids, f) {
  while (atlas.lastUsed.length < atlas.uv.length) atlas.lastUsed.push(0);
  const x = cross2(atlas.uv[ids[0]], atlas.uv[ids[1]], atlas.uv[ids[2]]);
  if (x !== 0) atlas.ccw = x > 0;
  while (atlas.vertex.length < atlas.uv.length) {
    atlas.vertex.push(NONE); atlas.neighbour.push(NONE); atlas.ccwAt.push(atlas.ccw);
  }
  ids.forEach((id, k) => {
    if (atlas.vertex[id] === NONE) atlas.vertex[id] = face[k];
    if (atlas.neighbour[id] === NONE) {
      const other = [ids[(k + 1) % 3], ids[(k + 2) % 3]].find((j) => j !== id);
      atlas.neighbour[id] = other === undefined ? NONE : other;
    }
  });
  for (let k = 0; k < 3; k++) {
    const va = face[k], vb = face[(k + 1) % 3];
    const key = pair(va, vb);
    if (!atlas.edgeFace.has(key)) atlas.edgeFace.set(key, f);
    atlas.uvLength += Math.sqrt(sqDist(atlas.uv[ids[k]], atlas.uv[ids[(k + 1) % 3]]));
    atlas.edges += 1;
    const d = sub3(atlas.positions[va], atlas.positions[vb]);
    const l = Math.sqrt(dot3(d, d));
    if (Number.isFinite(l)) atlas.length3d += l;
    const list = atlas.candidates[face[k]];
    if (!list.includes(ids[k]) && list.length < MAX_CANDIDATES) list.push(ids[k]);
    atlas.lastUsed[ids[k]] = f;
    const a = ids[(k + 1) % 3], b = ids[(k + 2) % 3];
    if (a !== b && !atlas.opposite.has(pair(a, b))) atlas.opposite.set(pair(a, b), ids[k]);
  }
  atlas.uvFaces.push(ids);
}

/**
 * The atlas subdivided with the mesh, `iterations` times (`subdivide::subdivide_uv`): edge
 * midpoints keyed by UV index, so seams stay seams; face `i` matches the mesh's face `i`.
 * @param {Float64Array} uv flat UVs
 * @param {Uint32Array} uvFaces flat
 * @returns {{uv: Float64Array, uvFaces: Uint32Array}}
 */
export function subdivideUv(uv, uvFaces, iterations) {
  let pts = Array.from(uv), faces = uvFaces;
  for (let it = 0; it < iterations; it++) {
    const mids = new Map();
    const out = new Uint32Array(4 * faces.length);
    const m = [0, 0, 0];
    for (let f = 0; f < faces.length; f += 3) {
      for (let k = 0; k < 3; k++) {
        const a = faces[f + k], b = faces[f + (k + 1) % 3];
        const key = pair(a, b);
        let v = mids.get(key);
        if (v === undefined) {
          v = pts.length / 2;
          pts.push(0.5 * (pts[2 * a] + pts[2 * b]), 0.5 * (pts[2 * a + 1] + pts[2 * b + 1]));
          mids.set(key, v);
        }
        m[k] = v;
      }
      out.set([faces[f], m[0], m[2], m[0], faces[f + 1], m[1], m[2], m[1], faces[f + 2], m[0], m[1], m[2]], 4 * f);
    }
    faces = out;
  }
  return { uv: Float64Array.from(pts), uvFaces: faces };
}
