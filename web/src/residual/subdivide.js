// Subdivision of the base mesh (`core/src/residual/subdivide.rs`, docs/bitstream.md
// section 8.2): 1-to-4 splits with level-of-detail vertex order, midpoint or Loop per
// iteration.
//
// Contract: `subdivide(positions, faces, schemes)` gives the Rust `Subdivision`'s
// positions, faces, parents and level offsets bit for bit. Positions are the stencil sums
// `((0 + w1*p1) + w2*p2) + ...` in the Rust row order; edges are found through a per-vertex
// linked list instead of a hash map (only lookups, so the order of discovery is the same).

/**
 * @typedef {object} Subdivision
 * @property {Float64Array} positions flat xyz
 * @property {Uint32Array} faces flat triangles
 * @property {Uint32Array} parents for vertex v >= lodOffsets[1]: edge [2(v-base), 2(v-base)+1]
 * @property {number[]} lodOffsets [0, base, level 1, ..., total]
 */

/** Edge table: each undirected edge filed under its smaller vertex. */
class EdgeTable {
  constructor(nv, capacity) {
    this.head = new Int32Array(nv).fill(-1);
    this.next = new Int32Array(capacity);
    this.other = new Uint32Array(capacity);
    this.size = 0;
  }
  /** Index of edge {a, b}, or -1. */
  find(a, b) {
    const lo = a < b ? a : b, hi = a < b ? b : a;
    for (let e = this.head[lo]; e !== -1; e = this.next[e]) if (this.other[e] === hi) return e;
    return -1;
  }
  /** Adds edge {a, b} (which must be absent) and returns its index. */
  add(a, b) {
    const lo = a < b ? a : b, hi = a < b ? b : a;
    const e = this.size++;
    this.other[e] = hi;
    this.next[e] = this.head[lo];
    this.head[lo] = e;
    return e;
  }
}

/**
 * @param {Float64Array} positions flat xyz
 * @param {Uint32Array} faces flat triangles
 * @param {number[]} schemes 0 midpoint, 1 Loop, one per iteration
 * @returns {Subdivision}
 */
export function subdivide(positions, faces, schemes) {
  let s = { positions, faces, parents: new Uint32Array(0), lodOffsets: [0, positions.length / 3] };
  for (const scheme of schemes) s = splitOnce(s, scheme);
  return s;
}

/**
 * The faces of `faces` (over `nVertices` vertices) split `iterations` times, without
 * positions (`subdivide::subdivided_faces`): face i is face i of `subdivide(..).faces`.
 * @returns {{faces: Uint32Array, vertexCount: number}}
 */
export function subdividedFaces(faces, nVertices, iterations) {
  let n = nVertices;
  for (let i = 0; i < iterations; i++) {
    const split = splitFaces(faces, n);
    n += split.edges.size;
    faces = split.faces;
  }
  return { faces, vertexCount: n };
}

/** One 1-to-4 split of `faces` over `n0` vertices: the new faces, the edge table, and per new
 * vertex its parent edge [min, max], opposite corners and face count. */
function splitFaces(faces, n0) {
  const nf = faces.length / 3;
  const edges = new EdgeTable(n0, 3 * nf);
  // Per new vertex: its parent edge [min, max], opposite corners c, d and face count.
  const par = new Uint32Array(2 * 3 * nf);
  const opp = new Uint32Array(2 * 3 * nf);
  const count = new Uint32Array(3 * nf);
  const newFaces = new Uint32Array(12 * nf);
  const mids = [0, 0, 0];
  for (let f = 0; f < nf; f++) {
    for (let k = 0; k < 3; k++) {
      const a = faces[3 * f + k], b = faces[3 * f + (k + 1) % 3], c = faces[3 * f + (k + 2) % 3];
      let e = edges.find(a, b);
      if (e === -1) {
        e = edges.add(a, b);
        par[2 * e] = a < b ? a : b;
        par[2 * e + 1] = a < b ? b : a;
        opp[2 * e] = c;
        opp[2 * e + 1] = 0xffffffff;
        count[e] = 1;
      } else {
        opp[2 * e + 1] = c;
        count[e]++;
      }
      mids[k] = n0 + e;
    }
    const f0 = faces[3 * f], f1 = faces[3 * f + 1], f2 = faces[3 * f + 2];
    const m0 = mids[0], m1 = mids[1], m2 = mids[2], o = 12 * f;
    newFaces[o] = f0; newFaces[o + 1] = m0; newFaces[o + 2] = m2;
    newFaces[o + 3] = m0; newFaces[o + 4] = f1; newFaces[o + 5] = m1;
    newFaces[o + 6] = m2; newFaces[o + 7] = m1; newFaces[o + 8] = f2;
    newFaces[o + 9] = m0; newFaces[o + 10] = m1; newFaces[o + 11] = m2;
  }
  return { faces: newFaces, edges, par, opp, count };
}

function splitOnce(s, scheme) {
  const n0 = s.positions.length / 3;
  const faces = s.faces;
  const { faces: newFaces, edges, par, opp, count } = splitFaces(faces, n0);
  const ne = edges.size;
  const st = new Stencils(n0 + ne, 2 * n0 + 4 * ne);
  if (scheme === 1) evenLoopStencils(n0, faces, st);
  else for (let v = 0; v < n0; v++) st.push1(v, 1.0);
  for (let e = 0; e < ne; e++) {
    const a = par[2 * e], b = par[2 * e + 1];
    if (scheme === 0 || count[e] !== 2) st.push2(a, 0.5, b, 0.5);
    else st.push4(a, 0.375, b, 0.375, opp[2 * e], 0.125, opp[2 * e + 1], 0.125);
  }
  const parents = new Uint32Array(s.parents.length + 2 * ne);
  parents.set(s.parents);
  parents.set(par.subarray(0, 2 * ne), s.parents.length);
  return {
    positions: st.apply(s.positions),
    faces: newFaces,
    parents,
    lodOffsets: [...s.lodOffsets, n0 + ne],
  };
}

/** Rows of weighted previous-level vertices, one per new-level vertex. */
class Stencils {
  constructor(rows, capacity) {
    this.starts = new Uint32Array(rows + 1);
    this.index = new Uint32Array(capacity);
    this.weight = new Float64Array(capacity);
    this.rows = 0;
    this.size = 0;
  }
  grow(extra) {
    if (this.size + extra <= this.index.length) return;
    const cap = 2 * (this.size + extra);
    const i = new Uint32Array(cap), w = new Float64Array(cap);
    i.set(this.index); w.set(this.weight);
    this.index = i; this.weight = w;
  }
  entry(u, w) {
    this.index[this.size] = u;
    this.weight[this.size++] = w;
  }
  end() {
    this.starts[++this.rows] = this.size;
  }
  push1(a, wa) { this.grow(1); this.entry(a, wa); this.end(); }
  push2(a, wa, b, wb) { this.grow(2); this.entry(a, wa); this.entry(b, wb); this.end(); }
  push4(a, wa, b, wb, c, wc, d, wd) {
    this.grow(4); this.entry(a, wa); this.entry(b, wb); this.entry(c, wc); this.entry(d, wd); this.end();
  }

  /** The new positions: each row's weighted positions summed in order from zero. */
  apply(p) {
    const out = new Float64Array(3 * this.rows);
    const { starts, index, weight } = this;
    for (let v = 0; v < this.rows; v++) {
      let x = 0, y = 0, z = 0;
      for (let j = starts[v]; j < starts[v + 1]; j++) {
        const u = 3 * index[j], w = weight[j];
        x = x + w * p[u];
        y = y + w * p[u + 1];
        z = z + w * p[u + 2];
      }
      out[3 * v] = x; out[3 * v + 1] = y; out[3 * v + 2] = z;
    }
    return out;
  }
}

/**
 * Loop's rule for the old vertices: interior ones toward their ring (ascending index),
 * boundary ones from their two boundary neighbours, the rest (non-manifold, isolated, other
 * boundaries) stay.
 */
function evenLoopStencils(n, faces, st) {
  const nf = faces.length / 3;
  const edges = new EdgeTable(n, 3 * nf);
  const count = new Uint32Array(3 * nf);
  const degree = new Uint32Array(n + 1);
  for (let i = 0; i < faces.length; i++) {
    const a = faces[i], b = faces[i - (i % 3) + ((i % 3) + 1) % 3];
    let e = edges.find(a, b);
    if (e === -1) {
      e = edges.add(a, b);
      degree[a + 1]++;
      degree[b + 1]++;
    }
    count[e]++;
  }
  for (let v = 0; v < n; v++) degree[v + 1] += degree[v];
  const fill = degree.slice(0, n);
  const ring = new Uint32Array(degree[n]);
  const ringCount = new Uint32Array(degree[n]);
  const pinned = new Uint8Array(n);
  for (let lo = 0; lo < n; lo++) {
    for (let e = edges.head[lo]; e !== -1; e = edges.next[e]) {
      const hi = edges.other[e];
      ring[fill[lo]] = hi; ringCount[fill[lo]++] = count[e];
      ring[fill[hi]] = lo; ringCount[fill[hi]++] = count[e];
      if (count[e] > 2) pinned[lo] = pinned[hi] = 1;
    }
  }
  for (let v = 0; v < n; v++) {
    const from = degree[v], to = degree[v + 1], k = to - from;
    sortRing(ring, ringCount, from, to);
    let boundaries = 0;
    for (let j = from; j < to; j++) if (ringCount[j] === 1) boundaries++;
    if (!pinned[v] && k > 0 && boundaries === 0) {
      const beta = k === 3 ? 3.0 / 16.0 : 3.0 / (8.0 * k);
      st.grow(k + 1);
      st.entry(v, 1.0 - k * beta);
      for (let j = from; j < to; j++) st.entry(ring[j], beta);
      st.end();
    } else if (!pinned[v] && k > 0 && boundaries === 2) {
      st.grow(3);
      st.entry(v, 0.75);
      for (let j = from; j < to; j++) if (ringCount[j] === 1) st.entry(ring[j], 0.125);
      st.end();
    } else {
      st.push1(v, 1.0);
    }
  }
}

/** Insertion sort of ring[from, to) ascending, carrying ringCount along (rings are short). */
function sortRing(ring, ringCount, from, to) {
  for (let i = from + 1; i < to; i++) {
    const r = ring[i], c = ringCount[i];
    let j = i - 1;
    for (; j >= from && ring[j] > r; j--) { ring[j + 1] = ring[j]; ringCount[j + 1] = ringCount[j]; }
    ring[j + 1] = r;
    ringCount[j + 1] = c;
  }
}
