// Decoder of the base mesh block (`core/src/base/coder.rs`, docs/bitstream.md section 6):
// connectivity by a region-growing traversal over gates, then positions in a greedy order,
// predicted by an online least-squares blend.
//
// Contract: `decodeBase(data, bits)` returns exactly the Rust `decode_base` result (the
// canonical mesh: vertices in order of creation, faces in traversal order) or throws an
// Error with the Rust reason. The position predictor feeds float64 results back into the
// decoding, so its arithmetic follows the Rust expressions operation for operation.

import { RangeDecoder, UIntModel, IntModel, bitModels } from '../ec.js';

const MAX_FACES_PER_BYTE = 4;
const MAX_BITS = 30;
const MAX_EDGE_SCAN = 16;
const MAX_WALK = 32;
const CONTEXTS = 512;

/**
 * @param {Uint8Array} data the block
 * @param {number} bits base mesh position bits
 * @returns {{positions: Uint32Array, faces: Uint32Array}} flat xyz and flat triangles
 */
export function decodeBase(data, bits) {
  if (!(bits >= 1 && bits <= MAX_BITS)) throw new Error(`position bit depth ${bits} out of range`);
  const dec = new RangeDecoder(data);
  const header = new UIntModel(8);
  const nv = dec.uint(header);
  const nf = dec.uint(header);
  const e = dec.finish();
  if (e) throw new Error(`header: ${e}`);
  if (nf > data.length * MAX_FACES_PER_BYTE) throw new Error(`${nf} faces cannot fit in ${data.length} bytes`);
  if (nv > 3 * nf || (nf > 0 && nv < 3)) throw new Error(`${nv} vertices cannot belong to ${nf} faces`);
  const faces = connectivity(dec, nv, nf);
  const positions = codePositions(dec, faces, nv, bits);
  const e2 = dec.finish();
  if (e2) throw new Error(e2);
  return { positions, faces };
}

// ---- connectivity --------------------------------------------------------------------

/** Traversal state, as `Conn` in the Rust code; gates are struct-of-arrays. */
class Conn {
  constructor(nv, nf) {
    this.nv = nv;
    this.faces = new Uint32Array(3 * nf);
    this.nfaces = 0;
    this.ga = []; this.gb = []; this.gopen = []; this.gout = []; this.gin = []; this.gbelow = [];
    this.stack = [];
    /** @type {number[][]} */ this.outOpen = [];
    /** @type {number[][]} */ this.inOpen = [];
    this.byPair = new Map();
    this.pairKey = nv * nv < 2 ** 53 ? (a, b) => a * nv + b : (a, b) => `${a},${b}`;
    this.faceCount = [];
    this.borderOut = [];
    this.borderIn = [];
  }

  visited() {
    return this.outOpen.length;
  }

  newVertex() {
    this.outOpen.push([]);
    this.inOpen.push([]);
    this.faceCount.push(0);
    this.borderOut.push(false);
    this.borderIn.push(false);
    return this.outOpen.length - 1;
  }

  /** Pops the next open gate and closes it; null when the stack is empty. */
  popGate() {
    while (this.stack.length > 0) {
      const g = this.stack.pop();
      if (this.gopen[g]) {
        this.close(g);
        return g;
      }
    }
    return null;
  }

  close(g) {
    this.gopen[g] = false;
    // Swap-remove: list positions are coded symbols, so this order is part of the format.
    let list = this.outOpen[this.ga[g]];
    let slot = this.gout[g];
    let last = list.pop();
    if (slot < list.length) { list[slot] = last; this.gout[last] = slot; }
    list = this.inOpen[this.gb[g]];
    slot = this.gin[g];
    last = list.pop();
    if (slot < list.length) { list[slot] = last; this.gin[last] = slot; }
  }

  findOpen(a, b) {
    const key = this.pairKey(a, b);
    let head = this.byPair.get(key);
    if (head === undefined) return -1;
    while (head !== -1) {
      if (this.gopen[head]) break;
      head = this.gbelow[head];
    }
    this.byPair.set(key, head);
    return head;
  }

  openGate(a, b) {
    const g = this.ga.length;
    const key = this.pairKey(a, b);
    const head = this.byPair.get(key);
    this.ga.push(a); this.gb.push(b); this.gopen.push(true);
    this.gout.push(this.outOpen[a].length); this.gin.push(this.inOpen[b].length);
    this.gbelow.push(head === undefined ? -1 : head);
    this.byPair.set(key, g);
    this.outOpen[a].push(g);
    this.inOpen[b].push(g);
    this.stack.push(g);
  }

  /** Adds face (f0, f1, f2); `entry` is the edge crossing the popped gate, or -1. */
  addFace(f0, f1, f2, entry) {
    const i = 3 * this.nfaces++;
    this.faces[i] = f0; this.faces[i + 1] = f1; this.faces[i + 2] = f2;
    this.faceCount[f0]++; this.faceCount[f1]++; this.faceCount[f2]++;
    const f = [f0, f1, f2];
    for (let k = 0; k < 3; k++) {
      if (k === entry) continue;
      const u = f[k], w = f[(k + 1) % 3];
      const g = this.findOpen(w, u);
      if (g !== -1) this.close(g);
      else this.openGate(u, w);
    }
  }

  /** [next, prev] candidate gate lists for a face across a→b. */
  candidates(a, b, flipped) {
    return flipped ? [this.inOpen[b], this.outOpen[a]] : [this.outOpen[b], this.inOpen[a]];
  }

  walk(from, forward, steps) {
    for (let s = 0; s < steps; s++) {
      const list = forward ? this.outOpen[from] : this.inOpen[from];
      if (list.length === 0) return -1;
      const g = list[0];
      from = forward ? this.gb[g] : this.ga[g];
    }
    return from;
  }

  walked(a, b, flipped, j) {
    const steps = 2 + (j >>> 1);
    return j % 2 === 0 ? this.walk(b, !flipped, steps) : this.walk(a, flipped, steps);
  }

  offered(g, at) {
    return this.ga[g] === at ? this.gb[g] : this.ga[g];
  }
}

class ConnModels {
  constructor() {
    this.hasFace = bitModels(6);
    this.misc = bitModels(5); // 0 more, 1 flipped, 2 is_walk, 3 seed_new
    this.isNew = bitModels(CONTEXTS);
    this.isNext = bitModels(CONTEXTS);
    this.isPrev = bitModels(CONTEXTS);
    this.which = new UIntModel(0);
    this.walk = new UIntModel(0);
    this.other = new IntModel(3);
    this.seedIndex = new UIntModel(4);
    this.last = 0;
    this.lastHadFace = true;
  }
}

function connectivity(dec, nv, nf) {
  const st = new Conn(nv, nf);
  const m = new ConnModels();
  while (st.nfaces < nf) {
    if (dec.exhausted()) throw new Error(`connectivity data ends at face ${st.nfaces}`);
    const g = st.popGate();
    if (g !== null) facesAcross(dec, st, m, nv, nf, st.ga[g], st.gb[g]);
    else seed(dec, st, m, nv);
  }
  if (st.visited() !== nv) throw new Error(`${st.visited()} of ${nv} vertices used`);
  return st.faces;
}

function facesAcross(dec, st, m, nv, nf, a, b) {
  let first = true;
  while (st.nfaces < nf && !dec.exhausted()) {
    let has;
    if (first) {
      const ctx = (m.lastHadFace ? 1 : 0) | (((st.borderIn[a] ? 1 : 0) + (st.borderOut[b] ? 1 : 0)) << 1);
      has = dec.bit(m.hasFace, ctx);
      m.lastHadFace = has === 1;
      if (!has) {
        st.borderOut[a] = true;
        st.borderIn[b] = true;
      }
    } else {
      has = dec.bit(m.misc, 0);
    }
    if (!has) break;
    first = false;
    const flipped = dec.bit(m.misc, 1) === 1;
    const c = thirdVertex(dec, st, m, nv, a, b, flipped);
    if (flipped) st.addFace(a, b, c, 0);
    else st.addFace(b, a, c, 0);
  }
}

function thirdVertex(dec, st, m, nv, a, b, flipped) {
  const [next, prev] = st.candidates(a, b, flipped);
  const nNext = next.length, nPrev = prev.length;
  const ctx = Math.min(nNext, 1) | (Math.min(nPrev, 1) << 1) | (m.last << 2)
    | (Math.min(st.faceCount[b], 7) << 4) | (Math.min(st.faceCount[a], 3) << 7);
  let c;
  if (st.visited() < nv && dec.bit(m.isNew, ctx)) {
    m.last = 0;
    return st.newVertex();
  } else if (nNext > 0 && dec.bit(m.isNext, ctx)) {
    m.last = 1;
    const i = nNext > 1 ? dec.uint(m.which) : 0;
    c = i < nNext ? st.offered(next[i], b) : -1;
  } else if (nPrev > 0 && dec.bit(m.isPrev, ctx)) {
    m.last = 2;
    const i = nPrev > 1 ? dec.uint(m.which) : 0;
    c = i < nPrev ? st.offered(prev[i], a) : -1;
  } else if (dec.bit(m.misc, 2)) {
    m.last = 3;
    const j = dec.uint(m.walk);
    c = j < 2 * MAX_WALK ? st.walked(a, b, flipped, j) : -1;
  } else {
    m.last = 3;
    const d = dec.int(m.other);
    c = a + d;
    if (c < 0 || c > 0xffffffff) c = -1;
  }
  if (c === a || c === b || c < 0 || c >= st.visited()) throw new Error(`face ${st.nfaces} has an impossible vertex`);
  return c;
}

function seed(dec, st, m, nv) {
  const f = [0, 0, 0];
  for (let k = 0; k < 3; k++) {
    const visited = st.visited();
    if (visited < nv && dec.bit(m.misc, 3)) {
      f[k] = st.newVertex();
      continue;
    }
    const back = dec.uint(m.seedIndex);
    if (back >= visited) throw new Error(`seed face ${st.nfaces} refers to a future vertex`);
    f[k] = visited - 1 - back;
  }
  if (f[0] === f[1] || f[1] === f[2] || f[2] === f[0]) throw new Error(`seed face ${st.nfaces} repeats a vertex`);
  st.addFace(f[0], f[1], f[2], -1);
}

// ---- positions -----------------------------------------------------------------------

/** Vertex -> faces, and face edge -> faces on it (sorted by edge key, then face). */
class Adjacency {
  constructor(faces, n) {
    const nf = faces.length / 3;
    const start = new Uint32Array(n + 1);
    for (let i = 0; i < faces.length; i++) start[faces[i] + 1]++;
    for (let i = 0; i < n; i++) start[i + 1] += start[i];
    const fill = start.slice();
    const vertexFaces = new Uint32Array(faces.length);
    for (let i = 0; i < faces.length; i++) vertexFaces[fill[faces[i]]++] = (i / 3) | 0;
    // Edges ordered by (min, max, face): the Rust sort of (edge_key, face) pairs.
    const order = new Uint32Array(faces.length);
    const lo = new Float64Array(faces.length);
    for (let i = 0; i < faces.length; i++) {
      order[i] = i;
      const f = i - (i % 3);
      const a = faces[i], b = faces[f + ((i % 3) + 1) % 3];
      lo[i] = Math.min(a, b) * n + Math.max(a, b);
    }
    order.sort((x, y) => lo[x] - lo[y] || x - y);
    const edgeKey = new Float64Array(faces.length);
    const edgeFace = new Uint32Array(faces.length);
    const edgeAt = new Uint32Array(faces.length);
    let group = 0;
    for (let i = 0; i < order.length; i++) {
      const c = order[i];
      edgeKey[i] = lo[c];
      edgeFace[i] = (c / 3) | 0;
      if (edgeKey[i] !== edgeKey[group]) group = i;
      // The Rust code files each face edge under the first corner whose edge has the key.
      const f = edgeFace[i];
      let k = 0;
      for (; k < 3; k++) if (lo[3 * f + k] === lo[c]) break;
      edgeAt[3 * f + (k < 3 ? k : 0)] = group;
    }
    this.start = start; this.vertexFaces = vertexFaces; this.edgeKey = edgeKey; this.edgeFace = edgeFace; this.edgeAt = edgeAt;
    this.nf = nf;
  }

  /** Other faces on edge k of face f, of the first MAX_EDGE_SCAN on it. */
  across(f, k) {
    const from = this.edgeAt[3 * f + k];
    const key = this.edgeKey[from];
    const out = [];
    for (let i = from; i < this.edgeKey.length && i < from + MAX_EDGE_SCAN && this.edgeKey[i] === key; i++) {
      if (this.edgeFace[i] !== f) out.push(this.edgeFace[i]);
    }
    return out;
  }
}

function third(faces, g, x, y) {
  for (let k = 0; k < 3; k++) {
    const u = faces[3 * g + k];
    if (u !== x && u !== y) return u;
  }
  return 0xffffffff;
}

const BUCKETS = 8 * 16;
const bucket = (par, nb) => Math.min(par, 7) * 16 + Math.min(nb, 15);

/** The greedy coding order of positions (`Order` in the Rust code). */
class Order {
  constructor(n) {
    this.par = new Uint32Array(n);
    this.nb = new Uint32Array(n);
    this.done = new Uint8Array(n);
    /** @type {number[][]} */ this.buckets = Array.from({ length: BUCKETS }, () => []);
    this.top = 0;
    this.cursor = 0;
  }

  next() {
    for (;;) {
      const b = this.buckets[this.top];
      while (b.length > 0) {
        const v = b.pop();
        if (!this.done[v] && bucket(this.par[v], this.nb[v]) === this.top) return v;
      }
      if (this.top === 0) break;
      this.top--;
    }
    while (this.cursor < this.done.length && this.done[this.cursor]) this.cursor++;
    return this.cursor < this.done.length ? this.cursor : -1;
  }

  isDone(u) {
    return u < this.done.length && this.done[u] === 1;
  }

  credit(w, dp, dn) {
    if (w >= this.done.length || this.done[w]) return;
    this.par[w] += dp;
    this.nb[w] += dn;
    const b = bucket(this.par[w], this.nb[w]);
    this.buckets[b].push(w);
    if (b > this.top) this.top = b;
  }

  decoded(v, faces, adj) {
    this.done[v] = 1;
    for (let i = adj.start[v]; i < adj.start[v + 1]; i++) {
      const f = adj.vertexFaces[i];
      let kv = 0;
      while (kv < 3 && faces[3 * f + kv] !== v) kv++;
      if (kv === 3) kv = 0;
      const p = faces[3 * f + (kv + 1) % 3], q = faces[3 * f + (kv + 2) % 3];
      this.credit(p, 0, 1);
      this.credit(q, 0, 1);
      if (this.done[p] && this.done[q]) {
        for (const g of adj.across(f, (kv + 1) % 3)) this.credit(third(faces, g, p, q), 1, 0);
      }
      for (const [w, y, k] of [[p, q, (kv + 2) % 3], [q, p, kv]]) {
        if (!this.done[w] && this.done[y]) {
          let n = 0;
          for (const g of adj.across(f, k)) if (this.isDone(third(faces, g, v, y))) n++;
          if (n > 0) this.credit(w, n, 0);
        }
      }
    }
  }
}

const DECAY = 1.0 - 1.0 / 256.0;
const SQRT_075 = Math.sqrt(0.75);

/** The online least-squares blend of the three predictors (`Blend`). */
class Blend {
  constructor() {
    this.a = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];
    this.b = [1, 0, 0];
  }

  weights() {
    const w = solve(this.a.map((r) => r.slice()), this.b.slice());
    if (w === null || !w.every(Number.isFinite)) return [1, 0, 0];
    return w.map((x) => Math.min(Math.max(x, -4), 4));
  }

  learn(x, e) {
    for (let r = 0; r < 3; r++) {
      this.b[r] = this.b[r] * DECAY + dot(x[r], e);
      for (let c = 0; c < 3; c++) this.a[r][c] = this.a[r][c] * DECAY + dot(x[r], x[c]);
    }
  }
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];

function solve(a, b) {
  for (let c = 0; c < 3; c++) {
    let p = c;
    for (let r = c; r < 3; r++) if (Math.abs(a[r][c]) > Math.abs(a[p][c])) p = r;
    if (Number.isNaN(a[p][c]) || Math.abs(a[p][c]) <= 1e-9) return null;
    [a[c], a[p]] = [a[p], a[c]];
    [b[c], b[p]] = [b[p], b[c]];
    const pivot = a[c];
    for (let r = 0; r < 3; r++) {
      if (r === c) continue;
      const f = a[r][c] / pivot[c];
      for (let j = c; j < 3; j++) a[r][j] -= f * pivot[j];
      b[r] -= f * b[c];
    }
  }
  return [b[0] / a[0][0], b[1] / a[1][1], b[2] / a[2][2]];
}

function apex(x, y, z) {
  const e = [y[0] - x[0], y[1] - x[1], y[2] - x[2]];
  const l2 = dot(e, e);
  const t = dot([z[0] - x[0], z[1] - x[1], z[2] - x[2]], e) / l2;
  const perp = [0, 1, 2].map((i) => x[i] + e[i] * t - z[i]);
  const h = Math.sqrt(dot(perp, perp));
  if (!(l2 > 0 && h > 0)) return [0, 1, 2].map((i) => x[i] + y[i] - z[i]);
  const scale = (Math.sqrt(l2) * SQRT_075) / h;
  return [0, 1, 2].map((i) => (x[i] + y[i]) / 2 + perp[i] * scale);
}

/** Rust's `f64::round`: halves away from zero. */
export function roundHalfAway(x) {
  const t = Math.trunc(x);
  return Math.abs(x - t) >= 0.5 ? t + Math.sign(x) : t;
}

/** Centroid, error mean and parallelogram means around v (`neighbourhood`). */
function neighbourhood(v, pos, err, order, faces, adj) {
  const para = [0, 0, 0], equi = [0, 0, 0], cen = [0, 0, 0], rn = [0, 0, 0];
  let np = 0, nc = 0;
  for (let i = adj.start[v]; i < adj.start[v + 1]; i++) {
    const f = adj.vertexFaces[i];
    let k = -1;
    for (let j = 0; j < 3; j++) {
      const u = faces[3 * f + j];
      if (u === v && k < 0) k = j;
      if (u !== v && order.isDone(u)) {
        for (let d = 0; d < 3; d++) cen[d] += pos[3 * u + d];
        for (let d = 0; d < 3; d++) rn[d] += err[3 * u + d];
        nc++;
      }
    }
    if (k < 0) k = 0;
    const x = faces[3 * f + (k + 1) % 3], y = faces[3 * f + (k + 2) % 3];
    if (!order.isDone(x) || !order.isDone(y)) continue;
    for (const g of adj.across(f, (k + 1) % 3)) {
      const z = third(faces, g, x, y);
      if (!order.isDone(z)) continue;
      const px = [pos[3 * x], pos[3 * x + 1], pos[3 * x + 2]];
      const py = [pos[3 * y], pos[3 * y + 1], pos[3 * y + 2]];
      const pz = [pos[3 * z], pos[3 * z + 1], pos[3 * z + 2]];
      const ap = apex(px, py, pz);
      for (let d = 0; d < 3; d++) para[d] += px[d] + py[d] - pz[d];
      for (let d = 0; d < 3; d++) equi[d] += ap[d];
      np++;
    }
  }
  return { cen, rn, nc, para, equi, np };
}

function codePositions(dec, faces, n, bits) {
  const adj = new Adjacency(faces, n);
  const models = Array.from({ length: 12 }, () => new IntModel(2));
  const pos = new Uint32Array(3 * n);
  const err = new Float64Array(3 * n);
  const order = new Order(n);
  const blend = new Blend();
  const max = 2 ** bits - 1;
  let last = -1;
  for (let v = order.next(); v !== -1; v = order.next()) {
    if (dec.exhausted()) throw new Error(`position data ends at vertex ${v}`);
    const nb = neighbourhood(v, pos, err, order, faces, adj);
    let pred, kind, cen = null, x = null;
    if (nb.nc > 0 && nb.np > 0) {
      cen = nb.cen.map((c) => c / nb.nc);
      const rn = nb.rn.map((c) => c / nb.nc);
      const para = nb.para.map((c) => c / nb.np), equi = nb.equi.map((c) => c / nb.np);
      x = [[para[0] - cen[0], para[1] - cen[1], para[2] - cen[2]], [equi[0] - cen[0], equi[1] - cen[1], equi[2] - cen[2]], rn];
      const w = blend.weights();
      // Rust's f64 `sum` starts from -0.0, which leaves its first term unchanged.
      pred = [0, 1, 2].map((i) => cen[i] + ((w[0] * x[0][i] + w[1] * x[1][i]) + w[2] * x[2][i]));
      kind = 1 + Math.min(nb.np, 2);
    } else if (nb.nc > 0) {
      pred = nb.cen.map((c) => c / nb.nc);
      kind = 1;
    } else {
      pred = last < 0 ? [2 ** (bits - 1), 2 ** (bits - 1), 2 ** (bits - 1)] : [pos[3 * last], pos[3 * last + 1], pos[3 * last + 2]];
      kind = 0;
    }
    for (let i = 0; i < 3; i++) {
      const r = roundHalfAway(pred[i]);
      const ip = Number.isNaN(r) ? 0 : Math.min(Math.max(r, 0), max);
      const p = ip + dec.int(models[kind * 3 + i]);
      if (p < 0 || p > max) throw new Error(`vertex ${v} lies outside the ${bits}-bit grid`);
      pos[3 * v + i] = p;
    }
    if (cen !== null) {
      const actual = [pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]];
      for (let i = 0; i < 3; i++) err[3 * v + i] = actual[i] - pred[i];
      blend.learn(x, [actual[0] - cen[0], actual[1] - cen[1], actual[2] - cen[2]]);
    }
    order.decoded(v, faces, adj);
    last = v;
  }
  return pos;
}
