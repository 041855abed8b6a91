//! The positions of the base mesh block ([`crate::base::coder`]), coded after its
//! connectivity by both sides through one loop driven by [`Side`].
//!
//! **Positions** follow, in a greedy order computed from the connectivity (the vertex with
//! the most parallelograms available next). A vertex with a parallelogram (a face (v,x,y)
//! with x, y decoded and a face (x,y,z) across xy with z decoded) is predicted by a
//! least-squares blend, learnt online on both sides, of: the mean parallelogram x + y - z,
//! the mean apex of the equilateral triangle on xy, and the mean prediction error of its
//! decoded neighbours, each taken relative to the centroid of those neighbours. Otherwise it
//! is predicted by that centroid, else by the last decoded vertex (the grid centre for the
//! first). The prediction is rounded, clamped into [0, 2^bits), and the residual is coded per
//! axis as an adaptive zero flag, sign and Exp-Golomb magnitude, with contexts by axis and
//! kind of prediction (none, centroid, one parallelogram, several).
//!

use crate::error::Corrupt;
use crate::ec::{IntModel, Side};
use crate::geom::mesh::{dot, edge_key, sub};

/// Faces across one edge considered for a parallelogram: bounds work on hostile fans.
const MAX_EDGE_SCAN: usize = 16;

/// Vertex -> faces and face edge -> faces across it, of the decoded connectivity.
struct Adjacency {
    start: Vec<u32>,
    vertex_faces: Vec<u32>,
    /// (undirected edge key, face), sorted.
    edges: Vec<(u64, u32)>,
    /// For edge k of face f (from corner k to k+1), where its key starts in `edges`.
    edge_at: Vec<u32>,
}

impl Adjacency {
    fn new(faces: &[[u32; 3]], n: usize) -> Self {
        let mut start = vec![0u32; n + 1];
        faces.iter().flatten().for_each(|&v| start[v as usize + 1] += 1);
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut vertex_faces = vec![0u32; faces.len() * 3];
        let mut edges = Vec::with_capacity(faces.len() * 3);
        for (i, f) in faces.iter().enumerate() {
            for k in 0..3 {
                let v = f[k] as usize;
                vertex_faces[fill[v] as usize] = i as u32;
                fill[v] += 1;
                edges.push((edge_key(f[k], f[(k + 1) % 3]), i as u32));
            }
        }
        edges.sort_unstable();
        let mut edge_at = vec![0u32; faces.len() * 3];
        let mut group = 0;
        for (i, &(key, f)) in edges.iter().enumerate() {
            if key != edges[group].0 {
                group = i;
            }
            let t = faces[f as usize];
            let k = (0..3).find(|&k| edge_key(t[k], t[(k + 1) % 3]) == key).unwrap_or(0);
            edge_at[f as usize * 3 + k] = group as u32;
        }
        Self { start, vertex_faces, edges, edge_at }
    }

    fn faces_of(&self, v: u32) -> &[u32] {
        &self.vertex_faces[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }

    /// The other faces on edge k of face f (at most `MAX_EDGE_SCAN` looked at).
    fn across(&self, f: u32, k: usize) -> impl Iterator<Item = u32> + '_ {
        let from = self.edge_at[f as usize * 3 + k] as usize;
        let key = self.edges[from].0;
        self.edges[from..]
            .iter()
            .take_while(move |e| e.0 == key)
            .take(MAX_EDGE_SCAN)
            .map(|e| e.1)
            .filter(move |&g| g != f)
    }
}

/// Kinds of prediction, each with its own residual contexts.
const PRED_KINDS: usize = 4;

/// The order positions are coded in: greedily a vertex with the most parallelograms
/// available, then the most decoded neighbours, so that most vertices are predicted from
/// several sides. Both sides derive it from the connectivity alone.
struct Order {
    /// Parallelograms and decoded neighbours (with multiplicity) per vertex.
    score: Vec<(u32, u32)>,
    done: Vec<bool>,
    /// Vertices by capped score (stale entries are skipped when met); LIFO within one.
    buckets: Vec<Vec<u32>>,
    top: usize,
    /// Lowest index that may still be undecoded: where a new component starts.
    cursor: usize,
}

const ORDER_BUCKETS: usize = 8 * 16;

fn bucket((parallelograms, neighbours): (u32, u32)) -> usize {
    parallelograms.min(7) as usize * 16 + neighbours.min(15) as usize
}

impl Order {
    fn new(n: usize) -> Self {
        let buckets = vec![vec![]; ORDER_BUCKETS];
        Self { score: vec![(0, 0); n], done: vec![false; n], buckets, top: 0, cursor: 0 }
    }

    fn next(&mut self) -> Option<u32> {
        loop {
            while let Some(v) = self.buckets[self.top].pop() {
                if !self.done[v as usize] && bucket(self.score[v as usize]) == self.top {
                    return Some(v);
                }
            }
            if self.top == 0 {
                break;
            }
            self.top -= 1;
        }
        while self.cursor < self.done.len() && self.done[self.cursor] {
            self.cursor += 1;
        }
        (self.cursor < self.done.len()).then_some(self.cursor as u32)
    }

    /// Marks `v` decoded and credits the vertices whose predictions it completes.
    fn decoded(&mut self, v: u32, faces: &[[u32; 3]], adj: &Adjacency) {
        self.done[v as usize] = true;
        for &f in adj.faces_of(v) {
            let t = faces[f as usize];
            let kv = t.iter().position(|&u| u == v).unwrap_or(0);
            let (p, q) = (t[(kv + 1) % 3], t[(kv + 2) % 3]);
            self.credit(p, 0, 1);
            self.credit(q, 0, 1);
            if self.done[p as usize] && self.done[q as usize] {
                // v is the far vertex z of parallelograms across edge pq.
                for g in adj.across(f, (kv + 1) % 3) {
                    self.credit(third(faces[g as usize], p, q), 1, 0);
                }
            }
            // v is x of a parallelogram for w in face (v, w, y) across edge vy.
            for (w, y, k) in [(p, q, (kv + 2) % 3), (q, p, kv)] {
                if !self.done[w as usize] && self.done[y as usize] {
                    let n = adj
                        .across(f, k)
                        .filter(|&g| self.is_done(third(faces[g as usize], v, y)))
                        .count();
                    if n > 0 {
                        self.credit(w, n as u32, 0);
                    }
                }
            }
        }
    }

    fn is_done(&self, u: u32) -> bool {
        self.done.get(u as usize).copied().unwrap_or(false)
    }

    fn credit(&mut self, w: u32, parallelograms: u32, neighbours: u32) {
        if w as usize >= self.done.len() || self.done[w as usize] {
            return;
        }
        let sc = &mut self.score[w as usize];
        sc.0 += parallelograms;
        sc.1 += neighbours;
        let b = bucket(*sc);
        self.buckets[b].push(w);
        self.top = self.top.max(b);
    }
}

/// The vertex of `t` other than `x` and `y` (`u32::MAX` if none).
fn third(t: [u32; 3], x: u32, y: u32) -> u32 {
    t.iter().copied().find(|&u| u != x && u != y).unwrap_or(u32::MAX)
}

/// Predictors blended for a vertex with a parallelogram, as offsets from the centroid of its
/// decoded neighbours: the mean parallelogram (exact on regular meshes), the mean apex of an
/// equilateral triangle on the shared edge (decimated meshes have well-shaped triangles more
/// than parallelograms), and the mean prediction error of the decoded neighbours (curvature
/// that the others miss consistently).
const FEATURES: usize = 3;
/// Forgetting factor of the blend's statistics: about the last 256 vertices count.
const BLEND_DECAY: f64 = 1.0 - 1.0 / 256.0;

/// Online least-squares weights of the predictors, learnt identically by encoder and decoder
/// from the decoded positions: no fixed weights suit both smooth regular meshes and
/// decimated captures. Only IEEE basic operations are used, so both sides agree bit for bit.
struct Blend {
    a: [[f64; FEATURES]; FEATURES],
    b: [f64; FEATURES],
}

impl Blend {
    fn new() -> Self {
        // A small ridge that starts the weights at the plain parallelogram.
        let mut a = [[0.0; FEATURES]; FEATURES];
        (0..FEATURES).for_each(|k| a[k][k] = 1.0);
        let mut b = [0.0; FEATURES];
        b[0] = 1.0;
        Self { a, b }
    }

    fn weights(&self) -> [f64; FEATURES] {
        solve(self.a, self.b)
            .filter(|w| w.iter().all(|x| x.is_finite()))
            .map_or([1.0, 0.0, 0.0], |w| w.map(|x| x.clamp(-4.0, 4.0)))
    }

    fn learn(&mut self, x: &[[f64; 3]; FEATURES], e: [f64; 3]) {
        for r in 0..FEATURES {
            self.b[r] = self.b[r] * BLEND_DECAY + dot(x[r], e);
            for c in 0..FEATURES {
                self.a[r][c] = self.a[r][c] * BLEND_DECAY + dot(x[r], x[c]);
            }
        }
    }
}

/// Gaussian elimination with partial pivoting; None if (nearly) singular.
fn solve(mut a: [[f64; FEATURES]; FEATURES], mut b: [f64; FEATURES]) -> Option<[f64; FEATURES]> {
    for c in 0..FEATURES {
        let p = (c..FEATURES).fold(c, |p, r| if a[r][c].abs() > a[p][c].abs() { r } else { p });
        if a[p][c].is_nan() || a[p][c].abs() <= 1e-9 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        let pivot = a[c];
        for r in (0..FEATURES).filter(|&r| r != c) {
            let f = a[r][c] / pivot[c];
            a[r].iter_mut().zip(pivot).skip(c).for_each(|(x, p)| *x -= f * p);
            b[r] -= f * b[c];
        }
    }
    Some(std::array::from_fn(|k| b[k] / a[k][k]))
}

/// Apex of the equilateral triangle on edge xy, in the plane of triangle xyz, opposite z.
fn equilateral_apex(x: [f64; 3], y: [f64; 3], z: [f64; 3]) -> [f64; 3] {
    let e = sub(y, x);
    let l2 = dot(e, e);
    let t = dot(sub(z, x), e) / l2;
    let perp: [f64; 3] = std::array::from_fn(|i| x[i] + e[i] * t - z[i]);
    let h = dot(perp, perp).sqrt();
    if !(l2 > 0.0 && h > 0.0) {
        return std::array::from_fn(|i| x[i] + y[i] - z[i]);
    }
    let scale = l2.sqrt() * (0.75f64).sqrt() / h;
    std::array::from_fn(|i| (x[i] + y[i]) / 2.0 + perp[i] * scale)
}

fn as_f64(p: [u32; 3]) -> [f64; 3] {
    p.map(|c| c as f64)
}

/// What is known around a vertex about to be decoded.
struct Neighbourhood {
    /// Centroid of decoded neighbours (one count per face) and the mean of their errors.
    centroid: Option<([f64; 3], [f64; 3])>,
    /// Mean parallelogram and mean equilateral apex, and how many there are.
    parallelograms: Option<([f64; 3], [f64; 3], usize)>,
}

fn neighbourhood(
    v: u32,
    pos: &[[u32; 3]],
    err: &[[f64; 3]],
    done: &[bool],
    faces: &[[u32; 3]],
    adj: &Adjacency,
) -> Neighbourhood {
    let is_done = |u: u32| done.get(u as usize).copied().unwrap_or(false);
    let (mut para, mut equi, mut np) = ([0.0; 3], [0.0; 3], 0usize);
    let (mut cen, mut rn, mut nc) = ([0.0; 3], [0.0; 3], 0usize);
    for &f in adj.faces_of(v) {
        let t = faces[f as usize];
        for &u in t.iter().filter(|&&u| u != v && is_done(u)) {
            (0..3).for_each(|i| cen[i] += pos[u as usize][i] as f64);
            (0..3).for_each(|i| rn[i] += err[u as usize][i]);
            nc += 1;
        }
        let k = t.iter().position(|&u| u == v).unwrap_or(0);
        let (x, y) = (t[(k + 1) % 3], t[(k + 2) % 3]);
        if !is_done(x) || !is_done(y) {
            continue;
        }
        for g in adj.across(f, (k + 1) % 3) {
            let z = third(faces[g as usize], x, y);
            if is_done(z) {
                let (px, py, pz) =
                    (as_f64(pos[x as usize]), as_f64(pos[y as usize]), as_f64(pos[z as usize]));
                let apex = equilateral_apex(px, py, pz);
                (0..3).for_each(|i| para[i] += px[i] + py[i] - pz[i]);
                (0..3).for_each(|i| equi[i] += apex[i]);
                np += 1;
            }
        }
    }
    let mean = |s: [f64; 3], n: usize| s.map(|c| c / n as f64);
    Neighbourhood {
        centroid: (nc > 0).then(|| (mean(cen, nc), mean(rn, nc))),
        parallelograms: (np > 0).then(|| (mean(para, np), mean(equi, np), np)),
    }
}

/// The features the blend used: the centroid they are relative to, and their values.
type Features = Option<([f64; 3], [[f64; 3]; FEATURES])>;

/// Prediction and its kind: the [`Blend`] where a parallelogram exists, else the centroid of
/// decoded neighbours, else `fallback`.
fn predict(nb: Neighbourhood, blend: &Blend, fallback: [f64; 3]) -> ([f64; 3], usize, Features) {
    match (nb.centroid, nb.parallelograms) {
        (Some((cen, rn)), Some((para, equi, np))) => {
            let x = [sub(para, cen), sub(equi, cen), rn];
            let w = blend.weights();
            let p = std::array::from_fn(|i| {
                cen[i] + (0..FEATURES).map(|k| w[k] * x[k][i]).sum::<f64>()
            });
            (p, 1 + np.min(2), Some((cen, x)))
        }
        (Some((cen, _)), None) => (cen, 1, None),
        _ => (fallback, 0, None),
    }
}

/// Codes positions in [`Order`], with [`predict`]ions from the last decoded vertex (or the
/// centre of the grid) as the last resort; `enc` holds the positions when encoding.
pub(crate) fn code_positions<S: Side>(
    s: &mut S,
    faces: &[[u32; 3]],
    n: usize,
    bits: u32,
    enc: Option<&[[u32; 3]]>,
) -> Result<Vec<[u32; 3]>, Corrupt> {
    let adj = Adjacency::new(faces, n);
    let mut models: Vec<IntModel> = (0..PRED_KINDS * 3).map(|_| IntModel::new(2)).collect();
    let mut pos = vec![[0u32; 3]; n];
    let mut err = vec![[0f64; 3]; n];
    let mut order = Order::new(n);
    let mut blend = Blend::new();
    let mut last = None;
    let max = (1i64 << bits) - 1;
    while let Some(v) = order.next() {
        if s.failed() {
            return Err(format!("position data ends at vertex {v}").into());
        }
        let nb = neighbourhood(v, &pos, &err, &order.done, faces, &adj);
        let fallback = last.map_or([(1u64 << (bits - 1)) as f64; 3], |u| as_f64(pos[u as usize]));
        let (pred, kind, features) = predict(nb, &blend, fallback);
        let ipred = pred.map(|c| (c.round() as i64).clamp(0, max));
        for i in 0..3 {
            let actual = enc.map_or(0, |e| e[v as usize][i] as i64);
            let r = s.int(&mut models[kind * 3 + i], (actual - ipred[i]) as i32) as i64;
            pos[v as usize][i] = u32::try_from(ipred[i] + r)
                .ok()
                .filter(|&c| c as i64 <= max)
                .ok_or_else(|| Corrupt(format!("vertex {v} lies outside the {bits}-bit grid")))?;
        }
        if let Some((cen, x)) = features {
            let actual = as_f64(pos[v as usize]);
            err[v as usize] = sub(actual, pred);
            blend.learn(&x, sub(actual, cen));
        }
        order.decoded(v, faces, &adj);
        last = Some(v);
    }
    Ok(pos)
}

