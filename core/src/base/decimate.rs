//! Base mesh: quadric-error edge-collapse decimation (Garland and Heckbert), as the V-DMC test
//! model makes the base mesh of an intra frame.
//!
//! Every edge sits in an indexed priority queue keyed by the quadric error of its cheapest
//! candidate placement. A collapse re-keys the edges of the surviving vertex in place, so the
//! queue never holds stale entries (lazy invalidation popped about eight dead entries per
//! collapse). Only the edge at the front pays for the shape and topology checks; if they
//! rule out its cheapest placement and the next one costs more than the runner-up edge, it is
//! re-keyed and the loop looks again. Ties go to the lower edge number and nothing depends on
//! hash order or threads, so the output is the same on every run.

use crate::geom::mesh::{add, bounds, cross, dot, scale, sub, Mesh};
use crate::geom::quadric::Quadric;

/// Weight of the open-boundary constraint planes relative to the area-weighted face planes.
/// Capture data has holes whose rims must not shrink, so this is large.
const BOUNDARY_WEIGHT: f64 = 100.0;
/// A collapse must not turn any surviving face's normal by more than about 78 degrees
/// (cosine below this); larger turns fold the surface over itself.
const MIN_NORMAL_COS: f64 = 0.2;
/// A collapse may not leave a face of quality below this (see [`shape_ratio`]) unless its
/// neighbourhood already had a worse one. 0.3 is about a 10-degree needle, or a cap with
/// 15-degree base angles. Subdivision copies the shape of every base face into all its
/// children, so slivers here are slivers all over the coded surface. On basketball_player
/// frame 11 at 1/8 of the faces, this rule cut faces with a smallest angle under 10 degrees
/// from 4.3 % to 0.1 % for 7 % more RMS distance to the input (0.2: 2.4 % and 2 %; 0.4:
/// none and 13 %). Shape penalties in the cost, of several forms and weights, did worse on
/// both counts and reordered the queue so often that decimation took half as long again.
const MIN_QUALITY: f64 = 0.3;
/// Faces below this quality count as degenerate: no collapse may make one, even after the
/// [`MIN_QUALITY`] rule has been relaxed.
const DEGENERATE_QUALITY: f64 = 1e-3;
/// "No vertex", "no edge" or "not queued" in index arrays.
const NONE: u32 = u32::MAX;

/// Simplifies by QEM edge collapse until at most `target_faces` faces remain (or no legal collapse is left).
///
/// Faces that repeat a vertex, repeat another face (same three vertices), or name a vertex
/// out of range or with a non-finite coordinate are dropped first. The result is compact
/// (every vertex is used, in the order of the input indices), keeps each face's
/// counter-clockwise orientation, and has no degenerate or duplicate faces.
///
/// Collapses that would fold a face over, create a non-manifold edge or vertex, duplicate a
/// face, or erase the last face of a connected component are refused, so every component
/// keeps at least one face and the target is missed only when such collapses are all that
/// is left. Collapses that would leave a sliver (a face about as thin as a 10-degree needle,
/// where the neighbourhood had none) are refused too, until that rule alone stands between
/// the mesh and the target. Open boundaries are held in place by constraint quadrics.
/// Vertices that were never moved keep their input coordinates bit for bit. Deterministic:
/// the same input gives the same output on every run and machine.
pub fn decimate(positions: &[[f64; 3]], faces: &[[u32; 3]], target_faces: usize) -> Mesh {
    let faces = clean_faces(positions, faces);
    let finite: Vec<[f64; 3]> =
        positions.iter().copied().filter(|p| p.iter().all(|c| c.is_finite())).collect();
    let center = match bounds(&finite) {
        Some((lo, hi)) => scale(add(lo, hi), 0.5),
        None => [0.0; 3],
    };
    let mut state = State::new(positions, center, faces);
    // One pass normally suffices. Another retries the edges that were refused and became
    // legal only because their one-ring (not their ends) changed; when one makes no progress,
    // the sliver rule yields.
    while state.live_faces > target_faces {
        let before = state.live_faces;
        state.queue_all_edges();
        state.drain(target_faces);
        if state.live_faces == before {
            if !state.strict_shapes {
                break;
            }
            state.strict_shapes = false;
        }
    }
    state.into_mesh(positions, center)
}

/// Drops faces that no stage can use, keeping the first of any set of duplicates.
fn clean_faces(positions: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let usable =
        |v: u32| positions.get(v as usize).is_some_and(|p| p.iter().all(|c| c.is_finite()));
    let keep: Vec<bool> = faces
        .iter()
        .map(|f| f.iter().all(|&v| usable(v)) && f[0] != f[1] && f[1] != f[2] && f[0] != f[2])
        .collect();
    let keys: Vec<[u32; 3]> = faces.iter().map(|&f| sorted(f)).collect();
    // Duplicates share their lowest vertex, so bucket the faces by it (a counting sort that
    // keeps face order) and compare within buckets, which hold a few faces each.
    let mut start = vec![0u32; positions.len() + 1];
    for (k, _) in keys.iter().zip(&keep).filter(|(_, &ok)| ok) {
        start[k[0] as usize + 1] += 1;
    }
    for v in 0..positions.len() {
        start[v + 1] += start[v];
    }
    let mut bucketed = vec![0u32; start[positions.len()] as usize];
    let mut fill = start.clone();
    for (f, k) in keys.iter().enumerate().filter(|&(f, _)| keep[f]) {
        bucketed[fill[k[0] as usize] as usize] = f as u32;
        fill[k[0] as usize] += 1;
    }
    let mut keep = keep;
    for bucket in start.windows(2).map(|w| &bucketed[w[0] as usize..w[1] as usize]) {
        for (i, &f) in bucket.iter().enumerate() {
            keep[f as usize] = !bucket[..i].iter().any(|&g| keys[g as usize] == keys[f as usize]);
        }
    }
    faces.iter().zip(&keep).filter(|(_, &ok)| ok).map(|(f, _)| *f).collect()
}

fn sorted(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

/// Binary min-heap of edges by cost that knows where each edge sits, so that a cost can change
/// or an edge leave in place. Order is `(cost, edge)`: ties go to the lower edge number.
struct EdgeQueue {
    /// `(key, edge)`; the key is the cost's bits remapped so that integer order is the
    /// order of [`f64::total_cmp`], which keeps comparisons cheap.
    heap: Vec<(u64, u32)>,
    /// Position of each edge in `heap`, or [`NONE`].
    slot: Vec<u32>,
}

impl EdgeQueue {
    fn new(edges: usize) -> Self {
        EdgeQueue { heap: Vec::with_capacity(edges), slot: vec![NONE; edges] }
    }

    fn key(cost: f64) -> u64 {
        let bits = cost.to_bits();
        if bits >> 63 == 1 {
            !bits
        } else {
            bits | 1 << 63
        }
    }

    fn cost(key: u64) -> f64 {
        f64::from_bits(if key >> 63 == 1 { key & !(1 << 63) } else { !key })
    }

    /// The cheapest edge and its cost.
    fn front(&self) -> Option<(u32, f64)> {
        self.heap.first().map(|&(k, e)| (e, Self::cost(k)))
    }

    /// The cost of the second cheapest edge (infinite when there is none).
    fn runner_up(&self) -> f64 {
        let second = self.heap[1.min(self.heap.len())..self.heap.len().min(3)].iter().min();
        second.map_or(f64::INFINITY, |&(k, _)| Self::cost(k))
    }

    /// Queues `edge` at `cost`, or moves it there if it is queued already.
    fn set(&mut self, edge: u32, cost: f64) {
        let item = (Self::key(cost), edge);
        match self.slot[edge as usize] {
            NONE => {
                self.heap.push(item);
                self.sift_up(self.heap.len() - 1);
            }
            i => {
                let old = std::mem::replace(&mut self.heap[i as usize], item);
                self.restore(i as usize, old);
            }
        }
    }

    /// Takes `edge` out of the queue if it is there.
    fn remove(&mut self, edge: u32) {
        let i = self.slot[edge as usize];
        if i == NONE {
            return;
        }
        self.slot[edge as usize] = NONE;
        let last = self.heap.pop().expect("a queued edge is in the heap");
        if (i as usize) < self.heap.len() {
            let old = std::mem::replace(&mut self.heap[i as usize], last);
            self.restore(i as usize, old);
        }
    }

    /// Re-establishes heap order after the item at `i` replaced `old`.
    fn restore(&mut self, i: usize, old: (u64, u32)) {
        if self.heap[i] < old {
            self.sift_up(i);
        } else {
            self.sift_down(i);
        }
    }

    fn place(&mut self, i: usize, item: (u64, u32)) {
        self.heap[i] = item;
        self.slot[item.1 as usize] = i as u32;
    }

    fn sift_up(&mut self, mut i: usize) {
        let item = self.heap[i];
        while i > 0 {
            let parent = (i - 1) / 2;
            if self.heap[parent] <= item {
                break;
            }
            self.place(i, self.heap[parent]);
            i = parent;
        }
        self.place(i, item);
    }

    fn sift_down(&mut self, mut i: usize) {
        let item = self.heap[i];
        let n = self.heap.len();
        loop {
            let left = 2 * i + 1;
            if left >= n {
                break;
            }
            let child =
                if left + 1 < n && self.heap[left + 1] < self.heap[left] { left + 1 } else { left };
            if item <= self.heap[child] {
                break;
            }
            self.place(i, self.heap[child]);
            i = child;
        }
        self.place(i, item);
    }
}

/// Where a collapse puts the surviving vertex, and the quadric error there.
#[derive(Debug, Clone, Copy)]
struct Placement {
    cost: f64,
    pos: [f64; 3],
    /// The input vertex whose exact coordinates `pos` are, or [`NONE`] for a new point.
    origin: u32,
}

/// The mesh being simplified. Positions are relative to `center` so that quadrics of a mesh
/// far from the origin do not lose their precision to large constant terms.
struct State {
    pos: Vec<[f64; 3]>,
    origin: Vec<u32>,
    quadric: Vec<Quadric>,
    faces: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    /// Live faces around each vertex.
    vertex_faces: Vec<Vec<u32>>,
    live_faces: usize,
    /// Ends of each edge, lower index first; `[NONE; 2]` once the edge is gone.
    edges: Vec<[u32; 2]>,
    /// Live edges at each vertex.
    vertex_edges: Vec<Vec<u32>>,
    queue: EdgeQueue,
    /// Whether the [`MIN_QUALITY`] rule applies; dropped when it alone stands between the
    /// mesh and the target.
    strict_shapes: bool,
    /// Per-vertex marks and counts for neighbourhood tests, all zero between tests so that
    /// none pays for clearing it.
    tally: Vec<u32>,
}

impl State {
    fn new(positions: &[[f64; 3]], center: [f64; 3], faces: Vec<[u32; 3]>) -> Self {
        let n = positions.len();
        let mut degree = vec![0usize; n];
        faces.iter().flatten().for_each(|&v| degree[v as usize] += 1);
        let mut vertex_faces: Vec<Vec<u32>> =
            degree.iter().map(|&d| Vec::with_capacity(d)).collect();
        for (f, face) in faces.iter().enumerate() {
            for &v in face {
                vertex_faces[v as usize].push(f as u32);
            }
        }
        let mut state = State {
            pos: positions.iter().map(|&p| sub(p, center)).collect(),
            origin: (0..n as u32).collect(),
            quadric: vec![Quadric::ZERO; n],
            face_alive: vec![true; faces.len()],
            live_faces: faces.len(),
            faces,
            vertex_faces,
            edges: Vec::new(),
            vertex_edges: degree.iter().map(|&d| Vec::with_capacity(d + 2)).collect(),
            queue: EdgeQueue::new(0),
            tally: vec![0; n],
            strict_shapes: true,
        };
        state.init_edges_and_quadrics();
        state
    }

    fn corners(&self, f: u32) -> [[f64; 3]; 3] {
        self.faces[f as usize].map(|v| self.pos[v as usize])
    }

    /// Builds the edge table, numbered in (lower, higher) order, and the vertex quadrics: face
    /// planes, plus constraint planes along every edge that does not have exactly two faces
    /// (open boundaries, and non-manifold edges, which are features too).
    fn init_edges_and_quadrics(&mut self) {
        for f in 0..self.faces.len() {
            let [a, b, c] = self.corners(f as u32);
            let q = Quadric::from_triangle(a, b, c);
            for v in self.faces[f] {
                self.quadric[v as usize] += q;
            }
        }
        // Per vertex, the higher neighbours with the face through each: small sorts that stay
        // in cache, and edges come out numbered in (lower, higher) order.
        let mut sides: Vec<(u32, u32)> = Vec::new();
        for u in 0..self.pos.len() as u32 {
            sides.clear();
            for &f in &self.vertex_faces[u as usize] {
                sides.extend(self.faces[f as usize].iter().filter(|&&w| w > u).map(|&w| (w, f)));
            }
            sides.sort_unstable();
            for group in sides.chunk_by(|x, y| x.0 == y.0) {
                let v = group[0].0;
                let e = self.edges.len() as u32;
                self.edges.push([u, v]);
                self.vertex_edges[u as usize].push(e);
                self.vertex_edges[v as usize].push(e);
                if group.len() != 2 {
                    for &(_, f) in group {
                        self.add_edge_constraint(u, v, f);
                    }
                }
            }
        }
        self.queue = EdgeQueue::new(self.edges.len());
    }

    fn add_edge_constraint(&mut self, u: u32, v: u32, f: u32) {
        let [a, b, c] = self.corners(f);
        let normal = cross(sub(b, a), sub(c, a));
        let (pu, pv) = (self.pos[u as usize], self.pos[v as usize]);
        let q = Quadric::from_boundary_edge(pu, pv, normal, BOUNDARY_WEIGHT);
        self.quadric[u as usize] += q;
        self.quadric[v as usize] += q;
    }

    fn queue_all_edges(&mut self) {
        for e in 0..self.edges.len() as u32 {
            self.requeue(e);
        }
    }

    /// Puts a live edge in the queue at the error of its cheapest candidate placement (or out
    /// of it when no placement has a finite error).
    fn requeue(&mut self, e: u32) {
        let [a, b] = self.edges[e as usize];
        if a == NONE {
            return;
        }
        let bound = self.best_error(a, b);
        if bound.is_finite() {
            self.queue.set(e, bound);
        } else {
            self.queue.remove(e);
        }
    }

    /// Collapses cheapest-first until the target is met or the queue runs dry.
    fn drain(&mut self, target: usize) {
        while self.live_faces > target {
            let Some((e, queued_cost)) = self.queue.front() else { break };
            let [a, b] = self.edges[e as usize];
            let Some(p) = self.evaluate(a, b) else {
                self.queue.remove(e);
                continue;
            };
            // The shape checks ruled out the cheapest placement, and the next is dearer than
            // another edge.
            if p.cost > queued_cost && self.queue.runner_up() < p.cost {
                self.queue.set(e, p.cost);
                continue;
            }
            if !self.topology_allows(a, b) {
                self.queue.remove(e);
                continue;
            }
            self.collapse(e, p);
        }
    }

    /// The quadric error of the cheapest candidate of [`State::candidates`]: the queue key, and
    /// what [`State::evaluate`] returns unless the shape checks rule that candidate out.
    fn best_error(&self, a: u32, b: u32) -> f64 {
        let (q, optimal, [mid, pa, pb]) = self.candidate_points(a, b);
        match optimal {
            Some(p) => q.error(p),
            None => q.error(mid).min(q.error(pa)).min(q.error(pb)),
        }
    }

    /// Cheapest legal placement for collapsing `(a, b)`, or `None` when every candidate of
    /// [`State::candidates`] folds a face or makes a sliver.
    fn evaluate(&self, a: u32, b: u32) -> Option<Placement> {
        let mut candidates = self.candidates(a, b).into_iter().filter(|c| c.cost.is_finite());
        candidates.find(|c| self.shapes_allow(a, b, c.pos))
    }

    /// The summed quadric of `(a, b)`, its optimal point when that is well defined and near
    /// the edge, and the midpoint and the two ends.
    fn candidate_points(&self, a: u32, b: u32) -> (Quadric, Option<[f64; 3]>, [[f64; 3]; 3]) {
        let (ia, ib) = (a as usize, b as usize);
        let q = self.quadric[ia] + self.quadric[ib];
        let (pa, pb) = (self.pos[ia], self.pos[ib]);
        (q, q.optimal_point_near(pa, pb), [scale(add(pa, pb), 0.5), pa, pb])
    }

    /// Where `(a, b)` may collapse to, cheapest quadric error first: the optimal point (when
    /// there is one), the midpoint and the ends. Ties keep that order, which favours the
    /// midpoint over the ends since it makes better shaped faces.
    fn candidates(&self, a: u32, b: u32) -> [Placement; 4] {
        let (q, optimal, [mid, pa, pb]) = self.candidate_points(a, b);
        let (ia, ib) = (a as usize, b as usize);
        let mut candidates = [
            Placement {
                cost: optimal.map_or(f64::INFINITY, |p| q.error(p)),
                pos: optimal.unwrap_or(mid),
                origin: NONE,
            },
            Placement { cost: q.error(mid), pos: mid, origin: NONE },
            Placement { cost: q.error(pa), pos: pa, origin: self.origin[ia] },
            Placement { cost: q.error(pb), pos: pb, origin: self.origin[ib] },
        ];
        candidates.sort_by(|x, y| x.cost.total_cmp(&y.cost));
        candidates
    }

    /// Whether collapsing `(a, b)` to `p` keeps every surviving face from folding over or
    /// degenerating (see [`face_change`]) and, while `self.strict_shapes` holds, leaves no face
    /// below [`MIN_QUALITY`] unless its neighbourhood already had a worse one. Judging the
    /// neighbourhood rather than each face lets collapses that clear slivers away go ahead.
    fn shapes_allow(&self, a: u32, b: u32, p: [f64; 3]) -> bool {
        let mut worst_new = f64::INFINITY;
        for (f, v) in self.one_ring(a, b) {
            let face = self.faces[f as usize];
            if face.contains(&a) && face.contains(&b) {
                continue;
            }
            let new = face.map(|w| if w == v { p } else { self.pos[w as usize] });
            let Some(ratio) = face_change(self.corners(f), new) else { return false };
            worst_new = worst_new.min(ratio);
        }
        let floor = MIN_QUALITY * MIN_QUALITY / 12.0;
        !self.strict_shapes || worst_new >= floor || worst_new >= self.worst_shape(a, b)
    }

    /// The faces around `a` and `b`, each with the end it was found at (the faces on the edge
    /// come twice).
    fn one_ring(&self, a: u32, b: u32) -> impl Iterator<Item = (u32, u32)> + '_ {
        [a, b]
            .into_iter()
            .flat_map(move |v| self.vertex_faces[v as usize].iter().map(move |&f| (f, v)))
    }

    /// The least [`shape_ratio`] among the faces around `a` and `b`.
    fn worst_shape(&self, a: u32, b: u32) -> f64 {
        self.one_ring(a, b)
            .map(|(f, _)| self.corners(f))
            .fold(f64::INFINITY, |worst, c| worst.min(shape_ratio(c, triangle_normal(c))))
    }

    /// Whether collapsing `(a, b)` keeps the surface a valid mesh: the edge has one or two
    /// faces, the link condition holds (the only common neighbours are the vertices opposite
    /// the edge, else the collapse pinches a fin or a non-manifold vertex), an interior edge
    /// does not join two boundary vertices, some face survives (so a component never
    /// vanishes), and no face is duplicated.
    fn topology_allows(&mut self, a: u32, b: u32) -> bool {
        let Some(opposite) = self.opposite_vertices(a, b) else { return false };
        let interior = opposite[1] != NONE;
        let edge_faces = 1 + interior as usize;
        self.common_neighbours_are(a, b, opposite)
            && !(interior && self.on_boundary(a) && self.on_boundary(b))
            && self.vertex_faces[a as usize].len() + self.vertex_faces[b as usize].len()
                > 2 * edge_faces
            && !(interior && self.has_face_with(a, opposite) && self.has_face_with(b, opposite))
    }

    /// The vertices opposite edge `(a, b)`: `[c, NONE]` for a boundary edge, `[c, d]` for an
    /// interior one; `None` when the edge has no face, more than two, or two on the same side.
    fn opposite_vertices(&self, a: u32, b: u32) -> Option<[u32; 2]> {
        let mut found = [NONE; 2];
        let mut count = 0;
        for &f in &self.vertex_faces[a as usize] {
            let [x, y, z] = self.faces[f as usize];
            if x == b || y == b || z == b {
                *found.get_mut(count)? = x ^ y ^ z ^ a ^ b;
                count += 1;
            }
        }
        (count > 0 && found[0] != found[1]).then_some(found)
    }

    /// Whether the common neighbours of `a` and `b` are exactly `opposite`.
    fn common_neighbours_are(&mut self, a: u32, b: u32, opposite: [u32; 2]) -> bool {
        self.mark_neighbours(a, 1);
        let (mut common, mut stray) = (0, false);
        for &e in &self.vertex_edges[b as usize] {
            let x = self.other_end(e, b);
            if x != a && self.tally[x as usize] == 1 {
                common += 1;
                stray |= !opposite.contains(&x);
            }
        }
        self.mark_neighbours(a, 0);
        !stray && common == opposite.iter().filter(|&&c| c != NONE).count()
    }

    /// Whether `v` has an edge with a single face (a neighbour met by exactly one face).
    fn on_boundary(&mut self, v: u32) -> bool {
        let tally = &mut self.tally;
        let faces = &self.vertex_faces[v as usize];
        let others = || faces.iter().flat_map(|&f| self.faces[f as usize]).filter(|&w| w != v);
        others().for_each(|w| tally[w as usize] += 1);
        let boundary = others().any(|w| tally[w as usize] == 1);
        others().for_each(|w| tally[w as usize] = 0);
        boundary
    }

    /// Whether `v` has a face on the other two vertices `[c, d]`. When both ends of an
    /// interior edge have one, collapsing it would leave two copies of the face `a c d` (the
    /// tetrahedron case, which the link condition on vertices alone lets through).
    fn has_face_with(&self, v: u32, [c, d]: [u32; 2]) -> bool {
        self.vertex_faces[v as usize].iter().any(|&f| {
            let face = self.faces[f as usize];
            face.contains(&c) && face.contains(&d)
        })
    }

    /// Merges the higher end `b` of edge `e` into the lower end `a` at `p.pos`, then re-keys
    /// the edges of `a`.
    fn collapse(&mut self, e: u32, p: Placement) {
        let [a, b] = self.edges[e as usize];
        let (ia, ib) = (a as usize, b as usize);
        self.pos[ia] = p.pos;
        self.origin[ia] = p.origin;
        let qb = self.quadric[ib];
        self.quadric[ia] += qb;
        self.move_faces(a, b);
        self.move_edges(a, b);
        for i in 0..self.vertex_edges[ia].len() {
            self.requeue(self.vertex_edges[ia][i]);
        }
    }

    /// The faces on edge `(a, b)` die; `b`'s other faces become `a`'s.
    fn move_faces(&mut self, a: u32, b: u32) {
        for f in std::mem::take(&mut self.vertex_faces[b as usize]) {
            let face = &mut self.faces[f as usize];
            if face.contains(&a) {
                let c = face.iter().copied().find(|&w| w != a && w != b).unwrap_or(a);
                self.face_alive[f as usize] = false;
                self.live_faces -= 1;
                self.vertex_faces[c as usize].retain(|&g| g != f);
            } else {
                face.iter_mut().filter(|w| **w == b).for_each(|w| *w = a);
                self.vertex_faces[a as usize].push(f);
            }
        }
        let face_alive = &self.face_alive;
        self.vertex_faces[a as usize].retain(|&g| face_alive[g as usize]);
    }

    /// Edge `(a, b)` dies, and so does `(b, x)` when `(a, x)` exists; `b`'s other edges
    /// become `a`'s.
    fn move_edges(&mut self, a: u32, b: u32) {
        self.mark_neighbours(a, 1);
        for e in std::mem::take(&mut self.vertex_edges[b as usize]) {
            let x = self.other_end(e, b);
            if x == a || self.tally[x as usize] == 1 {
                self.edges[e as usize] = [NONE; 2];
                self.queue.remove(e);
                self.vertex_edges[x as usize].retain(|&g| g != e);
            } else {
                self.edges[e as usize] = [a.min(x), a.max(x)];
                self.vertex_edges[a as usize].push(e);
            }
        }
        // Every old neighbour of `a` but `b` still is one, so this clears all marks.
        self.tally[b as usize] = 0;
        self.mark_neighbours(a, 0);
    }

    fn other_end(&self, e: u32, v: u32) -> u32 {
        let [x, y] = self.edges[e as usize];
        x ^ y ^ v
    }

    fn mark_neighbours(&mut self, v: u32, mark: u32) {
        for &e in &self.vertex_edges[v as usize] {
            let [x, y] = self.edges[e as usize];
            self.tally[(x ^ y ^ v) as usize] = mark;
        }
    }

    /// The live faces over the vertices they use, renumbered in input order.
    fn into_mesh(self, input: &[[f64; 3]], center: [f64; 3]) -> Mesh {
        let mut used = vec![false; self.pos.len()];
        let live: Vec<[u32; 3]> = self
            .faces
            .iter()
            .zip(&self.face_alive)
            .filter(|(_, &ok)| ok)
            .map(|(f, _)| *f)
            .collect();
        for f in &live {
            for &v in f {
                used[v as usize] = true;
            }
        }
        let mut remap = vec![NONE; self.pos.len()];
        let mut positions = Vec::new();
        for v in (0..self.pos.len()).filter(|&v| used[v]) {
            remap[v] = positions.len() as u32;
            positions.push(match self.origin[v] {
                NONE => add(self.pos[v], center),
                o => input[o as usize],
            });
        }
        let faces = live.into_iter().map(|f| f.map(|v| remap[v as usize])).collect();
        Mesh { positions, faces }
    }
}

/// The [`shape_ratio`] of a face whose corners change from `old` to `new`, or `None` when it
/// would turn by more than the [`MIN_NORMAL_COS`] limit or degenerate (fall below
/// [`DEGENERATE_QUALITY`] unless it already was that bad).
fn face_change(old: [[f64; 3]; 3], new: [[f64; 3]; 3]) -> Option<f64> {
    let (n_old, n_new) = (triangle_normal(old), triangle_normal(new));
    let ratio = shape_ratio(new, n_new);
    let degenerate = DEGENERATE_QUALITY * DEGENERATE_QUALITY / 12.0;
    if ratio < degenerate && ratio < shape_ratio(old, n_old) {
        return None;
    }
    // cos(turn) >= MIN_NORMAL_COS > 0, squared to spare two square roots.
    let turn = dot(n_old, n_new);
    let limit = MIN_NORMAL_COS * MIN_NORMAL_COS * dot(n_old, n_old) * dot(n_new, n_new);
    (turn >= 0.0 && turn * turn >= limit).then_some(ratio)
}

fn triangle_normal([a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
    cross(sub(b, a), sub(c, a))
}

/// `|n|^2 / s^2` for the unnormalized normal `n` and the sum `s` of squared edge lengths: the
/// square of the shape quality `4 sqrt(3) area / s` (1 for an equilateral triangle, 0 for a
/// degenerate one) over 12, which orders faces the same way without a square root.
fn shape_ratio([a, b, c]: [[f64; 3]; 3], normal: [f64; 3]) -> f64 {
    let s = dist2(a, b) + dist2(b, c) + dist2(c, a);
    if s > 0.0 {
        dot(normal, normal) / (s * s)
    } else {
        0.0
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::mesh::norm;
    use std::collections::BTreeMap;

    /// Panics unless `m` is compact, in range, and free of degenerate and duplicate faces.
    fn assert_valid(m: &Mesh) {
        let n = m.positions.len();
        let mut used = vec![false; n];
        let mut seen = std::collections::BTreeSet::new();
        for f in &m.faces {
            assert!(f.iter().all(|&v| (v as usize) < n), "index out of range in {f:?}");
            assert!(f[0] != f[1] && f[1] != f[2] && f[0] != f[2], "degenerate face {f:?}");
            assert!(seen.insert(sorted(*f)), "duplicate face {f:?}");
            f.iter().for_each(|&v| used[v as usize] = true);
        }
        assert!(used.iter().all(|&u| u), "unreferenced vertex");
        assert!(m.positions.iter().flatten().all(|c| c.is_finite()));
    }

    fn normal(m: &Mesh, f: [u32; 3]) -> [f64; 3] {
        triangle_normal(f.map(|v| m.positions[v as usize]))
    }

    /// Number of faces on each edge, keyed by sorted index pairs.
    fn edge_face_counts(m: &Mesh) -> BTreeMap<(u32, u32), usize> {
        let mut count = BTreeMap::new();
        for f in &m.faces {
            for k in 0..3 {
                let (u, v) = (f[k], f[(k + 1) % 3]);
                *count.entry((u.min(v), u.max(v))).or_insert(0) += 1;
            }
        }
        count
    }

    /// Edges with one face, as sorted index pairs.
    fn boundary_edges(m: &Mesh) -> Vec<(u32, u32)> {
        edge_face_counts(m).into_iter().filter(|&(_, c)| c == 1).map(|(e, _)| e).collect()
    }

    fn components(m: &Mesh) -> usize {
        let mut parent: Vec<usize> = (0..m.positions.len()).collect();
        fn find(p: &mut [usize], mut x: usize) -> usize {
            while p[x] != x {
                p[x] = p[p[x]];
                x = p[x];
            }
            x
        }
        for f in &m.faces {
            let r = find(&mut parent, f[0] as usize);
            for &v in &f[1..] {
                let s = find(&mut parent, v as usize);
                parent[s] = r;
            }
        }
        (0..parent.len()).filter(|&v| find(&mut parent, v) == v).count()
    }

    /// `n` x `n` squares over the unit square in z = 0, two CCW triangles each (normal +z).
    fn grid(n: u32) -> Mesh {
        let mut positions = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions.push([i as f64 / n as f64, j as f64 / n as f64, 0.0]);
            }
        }
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let mut faces = Vec::new();
        for j in 0..n {
            for i in 0..n {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Mesh::new(positions, faces)
    }

    /// Unit icosphere with `levels` midpoint subdivisions, outward CCW faces.
    fn icosphere(levels: u32) -> Mesh {
        let (positions, faces) = crate::geom::bvh::testmesh::icosphere(levels, 1.0);
        Mesh::new(positions, faces)
    }

    /// Cube [-1, 1]^3 with each side split into `n` x `n` squares, outward CCW faces.
    fn cube(n: u32) -> Mesh {
        let mut index = BTreeMap::new();
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        let mut vid = |p: [i64; 3], positions: &mut Vec<[f64; 3]>| {
            *index.entry(p).or_insert_with(|| {
                positions.push(p.map(|c| 2.0 * c as f64 / n as f64 - 1.0));
                positions.len() as u32 - 1
            })
        };
        let n = n as i64;
        for axis in 0..3 {
            for side in [0, n] {
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let at = |i: i64, j: i64| {
                    let mut p = [0; 3];
                    p[axis] = side;
                    p[u] = i;
                    p[v] = j;
                    p
                };
                for j in 0..n {
                    for i in 0..n {
                        let q = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
                            .map(|p| vid(p, &mut positions));
                        // (u, v, axis) is right-handed, so CCW in (u, v) faces +axis.
                        let (t1, t2) = ([q[0], q[1], q[2]], [q[0], q[2], q[3]]);
                        if side == n {
                            faces.extend([t1, t2]);
                        } else {
                            faces.extend([[t1[0], t1[2], t1[1]], [t2[0], t2[2], t2[1]]]);
                        }
                    }
                }
            }
        }
        Mesh::new(positions, faces)
    }

    /// Open unit-radius cylinder of height `h`, `m` segments around, `rows` rows, outward faces.
    fn cylinder(m: u32, rows: u32, h: f64) -> Mesh {
        let mut positions = Vec::new();
        for r in 0..=rows {
            for k in 0..m {
                let a = 2.0 * std::f64::consts::PI * k as f64 / m as f64;
                positions.push([a.cos(), a.sin(), h * r as f64 / rows as f64]);
            }
        }
        let id = |k: u32, r: u32| r * m + k % m;
        let mut faces = Vec::new();
        for r in 0..rows {
            for k in 0..m {
                faces.push([id(k, r), id(k + 1, r), id(k + 1, r + 1)]);
                faces.push([id(k, r), id(k + 1, r + 1), id(k, r + 1)]);
            }
        }
        Mesh::new(positions, faces)
    }

    /// Deterministic pseudo-random radial noise on every vertex.
    fn jitter(mut m: Mesh, amount: f64) -> Mesh {
        let mut s: u64 = 0x9E37_79B9_7F4A_7C15;
        for p in &mut m.positions {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let r = 1.0 + amount * (((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5);
            *p = scale(*p, r);
        }
        m
    }

    fn run(m: &Mesh, target: usize) -> Mesh {
        let out = decimate(&m.positions, &m.faces, target);
        assert_valid(&out);
        out
    }

    #[test]
    fn flat_grid_stays_flat_inside_its_boundary_and_reaches_the_target() {
        let input = grid(16);
        let out = run(&input, 64);
        assert!(out.faces.len() <= 64, "{} faces", out.faces.len());
        assert!(out.faces.len() >= 32, "{} faces", out.faces.len());
        for p in &out.positions {
            assert!(p[2].abs() < 1e-12, "left the plane: {p:?}");
            assert!(p[0] >= -1e-12 && p[0] <= 1.0 + 1e-12 && p[1] >= -1e-12 && p[1] <= 1.0 + 1e-12);
        }
        for corner in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]] {
            assert!(
                out.positions.iter().any(|&p| dist2(p, corner) < 1e-24),
                "corner {corner:?} lost"
            );
        }
        // All normals up and the areas add up to the square: nothing folded, nothing torn.
        let mut area = 0.0;
        for &f in &out.faces {
            let n = normal(&out, f);
            assert!(n[2] > 0.0, "face {f:?} turned over");
            area += 0.5 * n[2];
        }
        assert!((area - 1.0).abs() < 1e-9, "area {area}");
        // The rim is still the square's perimeter.
        let mut rim = 0.0;
        for (u, v) in boundary_edges(&out) {
            let (p, q) = (out.positions[u as usize], out.positions[v as usize]);
            let on_side =
                |p: [f64; 3]| p[..2].iter().any(|&c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12);
            assert!(on_side(p) && on_side(q), "rim vertex moved inside: {p:?} {q:?}");
            rim += dist2(p, q).sqrt();
        }
        assert!((rim - 4.0).abs() < 1e-9, "perimeter {rim}");
    }

    #[test]
    fn sphere_stays_round_closed_and_outward() {
        let input = icosphere(3);
        let out = run(&input, 160);
        assert!(out.faces.len() <= 160 && out.faces.len() >= 150, "{} faces", out.faces.len());
        for p in &out.positions {
            let r = norm(*p);
            assert!((0.95..=1.03).contains(&r), "radius {r}");
        }
        for &f in &out.faces {
            let n = normal(&out, f);
            let c = f.iter().fold([0.0; 3], |s, &v| add(s, out.positions[v as usize]));
            assert!(dot(n, c) > 0.0, "face {f:?} points inward");
        }
        assert!(boundary_edges(&out).is_empty(), "sphere was torn open");
        let edges = out.faces.len() * 3 / 2;
        assert_eq!(
            out.positions.len() + out.faces.len() - edges,
            2,
            "Euler characteristic changed"
        );
    }

    #[test]
    fn cube_keeps_its_corners_and_sides() {
        let input = cube(4);
        let out = run(&input, 24);
        assert!(out.faces.len() <= 24, "{} faces", out.faces.len());
        for p in &out.positions {
            let m = p.iter().fold(0.0f64, |m, c| m.max(c.abs()));
            assert!((m - 1.0).abs() < 1e-9, "vertex off the surface: {p:?}");
        }
        for corner in 0..8 {
            let c = [0, 1, 2].map(|k| if corner >> k & 1 == 1 { 1.0 } else { -1.0 });
            assert!(out.positions.iter().any(|p| dist2(*p, c) < 1e-18), "corner {c:?} lost");
        }
        for &f in &out.faces {
            let c = f.iter().fold([0.0; 3], |s, &v| add(s, out.positions[v as usize]));
            assert!(dot(normal(&out, f), c) > 0.0, "face {f:?} points inward");
        }
    }

    #[test]
    fn open_cylinder_keeps_its_rims() {
        let input = cylinder(32, 8, 2.0);
        let out = run(&input, 64);
        assert!(out.faces.len() <= 64, "{} faces", out.faces.len());
        let rims = boundary_edges(&out);
        assert!(rims.len() >= 6, "rims collapsed to {} edges", rims.len());
        for (u, v) in rims {
            for p in [out.positions[u as usize], out.positions[v as usize]] {
                assert!(
                    p[2].abs() < 1e-9 || (p[2] - 2.0).abs() < 1e-9,
                    "rim left its plane: {p:?}"
                );
            }
        }
        for p in &out.positions {
            let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
            assert!((0.85..=1.05).contains(&r), "radius {r}");
        }
    }

    #[test]
    fn disjoint_components_all_survive() {
        let a = icosphere(2);
        let b = grid(6);
        let mut positions = a.positions.clone();
        let mut faces = a.faces.clone();
        let shift = |p: [f64; 3], d: f64| [p[0] + d, p[1], p[2]];
        let base = positions.len() as u32;
        positions.extend(b.positions.iter().map(|&p| shift(p, 5.0)));
        faces.extend(b.faces.iter().map(|f| f.map(|v| v + base)));
        let base = positions.len() as u32;
        positions.extend([[10.0, 0.0, 0.0], [11.0, 0.0, 0.0], [10.0, 1.0, 0.0]]);
        faces.push([base, base + 1, base + 2]);
        let input = Mesh::new(positions, faces);
        assert_eq!(components(&input), 3);
        let out = run(&input, 100);
        assert_eq!(components(&out), 3);
        assert!(out.faces.len() <= 100, "{} faces", out.faces.len());
        // Even an unreachable target leaves every component a face.
        let out = run(&input, 0);
        assert_eq!(components(&out), 3);
    }

    #[test]
    fn output_is_identical_across_runs() {
        let input = jitter(icosphere(4), 0.02);
        let first = run(&input, 500);
        for _ in 0..3 {
            assert_eq!(run(&input, 500), first);
        }
    }

    #[test]
    fn messy_input_does_not_panic_and_gives_a_valid_mesh() {
        let mut m = grid(8);
        let n = m.positions.len() as u32;
        m.faces.push([0, 0, 1]); // repeated index
        m.faces.push(m.faces[3]); // duplicate
        let f = m.faces[5];
        m.faces.push([f[1], f[0], f[2]]); // duplicate with the opposite orientation
        m.faces.push([0, 1, n + 7]); // out of range
        m.positions.push([0.5, 0.5, 1.0]); // fin on an interior edge: non-manifold
        let e = m.faces[40];
        m.faces.push([e[1], e[0], n]);
        m.positions.push(m.positions[10]); // duplicate vertex, own triangle
        m.faces.push([n + 1, 11, 20]);
        m.positions.push([0.25, 0.0, 0.0]); // zero-area face on the rim
        m.faces.push([0, n + 2, 2]);
        m.positions.push([f64::NAN, f64::INFINITY, 0.0]); // unusable vertex
        m.faces.push([0, 1, n + 3]);
        m.positions.push([9.0, 9.0, 9.0]); // unreferenced
        for target in [0, 1, 10, 40, 1000] {
            let out = run(&m, target);
            assert!(!out.faces.is_empty());
        }
        assert_eq!(decimate(&[], &[], 10), Mesh::default());
        assert_eq!(decimate(&[[0.0; 3]; 3], &[[0, 1, 2]], 0).faces.len(), 1);
    }

    #[test]
    fn tiny_closed_meshes_stay_closed_and_valid() {
        let tetra = Mesh::new(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        );
        let out = run(&tetra, 0);
        assert_eq!(out, tetra, "a tetrahedron has no legal collapse");
        let octa = Mesh::new(
            vec![
                [1.0, 0.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, -1.0, 0.0],
                [0.0, 0.0, 1.0],
                [0.0, 0.0, -1.0],
            ],
            vec![
                [0, 2, 4],
                [2, 1, 4],
                [1, 3, 4],
                [3, 0, 4],
                [2, 0, 5],
                [1, 2, 5],
                [3, 1, 5],
                [0, 3, 5],
            ],
        );
        let out = run(&octa, 0);
        assert!(out.faces.len() >= 4 && boundary_edges(&out).is_empty(), "{out:?}");
    }

    #[test]
    fn non_manifold_spine_is_kept() {
        // Three 6 x 6 sheets sharing their left column, the z axis: its six edges have
        // three faces each.
        let n = 6;
        let mut m = Mesh::default();
        m.positions.extend((0..=n).map(|j| [0.0, 0.0, j as f64 / n as f64]));
        for k in 0..3 {
            let (s, c) = (2.0 * std::f64::consts::PI * k as f64 / 3.0).sin_cos();
            let base = m.positions.len() as u32;
            for j in 0..=n {
                for i in 1..=n {
                    let r = i as f64 / n as f64;
                    m.positions.push([r * c, r * s, j as f64 / n as f64]);
                }
            }
            let id = |i: u32, j: u32| if i == 0 { j } else { base + j * n + i - 1 };
            for j in 0..n {
                for i in 0..n {
                    let q = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                    m.faces.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
                }
            }
        }
        let out = run(&m, m.faces.len() / 3);
        assert!(out.faces.len() <= m.faces.len() / 3);
        let fins: Vec<_> =
            edge_face_counts(&out).into_iter().filter(|&(_, n)| n > 2).map(|(e, _)| e).collect();
        assert!(!fins.is_empty(), "the non-manifold spine was collapsed away");
        for v in fins.iter().flat_map(|&(u, v)| [u, v]) {
            let p = out.positions[v as usize];
            assert!(p[0].abs() < 1e-9 && p[1].abs() < 1e-9, "the spine left its line: {p:?}");
        }
        for end in [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]] {
            assert!(
                out.positions.iter().any(|&p| dist2(p, end) < 1e-18),
                "spine end {end:?} moved"
            );
        }
    }

    #[test]
    fn target_above_the_face_count_only_cleans() {
        let input = grid(4);
        assert_eq!(run(&input, 1000), input);
    }

    mod shared_data {
        use super::*;

        #[test]
        #[ignore = "needs ../shared/data"]
        fn basketball_frame_decimates_to_an_eighth() {
            let input = crate::shared_data::read_obj("basketball_player/basketball_player_fr0011.obj");
            let target = input.faces.len() / 8;
            let start = std::time::Instant::now();
            let out = decimate(&input.positions, &input.faces, target);
            let elapsed = start.elapsed();
            assert_valid(&out);
            assert!(out.faces.len() <= target, "{} faces for target {target}", out.faces.len());
            assert_eq!(components(&out), components(&input), "a component vanished");
            assert_eq!(decimate(&input.positions, &input.faces, target), out, "not deterministic");
            println!(
                "basketball fr0011: {} -> {} faces, {} -> {} vertices, {} -> {} components, in {:.1} ms",
                input.faces.len(),
                out.faces.len(),
                input.positions.len(),
                out.positions.len(),
                components(&input),
                components(&out),
                elapsed.as_secs_f64() * 1e3
            );
        }
    }
}
