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

use crate::geom::mesh::{add, bounds, cross, scale, sub, Mesh};
use crate::geom::quadric::Quadric;

mod checks;
mod queue;
#[cfg(test)]
mod tests;

use queue::EdgeQueue;

/// Weight of the open-boundary constraint planes relative to the area-weighted face planes.
/// Capture data has holes whose rims must not shrink, so this is large.
const BOUNDARY_WEIGHT: f64 = 100.0;
/// A collapse must not turn any surviving face's normal by more than about 78 degrees
/// (cosine below this); larger turns fold the surface over itself.
const MIN_NORMAL_COS: f64 = 0.2;
/// A collapse may not leave a face of quality below this (see [`checks`]) unless its
/// neighbourhood already had a worse one. 0.3 is about a 10-degree needle, or a cap with
/// 15-degree base angles. Subdivision copies the shape of every base face into all its
/// children, so slivers here are slivers all over the coded surface. On basketball_player
/// frame 11 at 1/8 of the faces, this rule cut faces with a smallest angle under 10 degrees
/// from 4.3 % to 0.1 % for 7 % more RMS distance to the input (0.2: 2.4 % and 2 %; 0.4:
/// none and 13 %). Shape penalties in the cost, of several forms and weights, did worse on
/// both counts and reordered the queue so often that decimation took half as long again.
const MIN_QUALITY: f64 = 0.3;
/// The [`MIN_QUALITY`] rule yields to a collapse it refused once the collapse that would go
/// ahead instead costs this many times its quadric error (16 times the distance), errors
/// below [`ERROR_FLOOR`] counting as that floor. Without a bound, a region whose every collapse
/// makes a sliver (a flat cap tessellated with needles, as marching cubes leaves when the
/// surface passes near grid nodes) stays at full density while the target is met by
/// collapses of any error elsewhere: on a thin disc those were its rim, until base faces cut
/// through the disc from cap to cap (fused gears, gap 0.1, frame 1: RMS distance from the input
/// to the base 373 grid units, 3 with this bound). On dancer and basketball_player it changes
/// nothing.
const YIELD_RATIO: f64 = 256.0;
/// Distance, as a fraction of the bounding box's largest side (one grid unit at 12 bits),
/// below which a refused collapse's error counts as this much for [`YIELD_RATIO`], so that
/// exactly flat collapses do not yield to the first one with any error.
const ERROR_FLOOR: f64 = 1.0 / 4096.0;
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
/// the mesh and the target, or until the collapses left cost far more error ([`YIELD_RATIO`]). Open boundaries are held in place by constraint quadrics.
/// Vertices that were never moved keep their input coordinates bit for bit. Deterministic:
/// the same input gives the same output on every run and machine.
pub fn decimate(positions: &[[f64; 3]], faces: &[[u32; 3]], target_faces: usize) -> Mesh {
    let faces = clean_faces(positions, faces);
    let finite: Vec<[f64; 3]> =
        positions.iter().copied().filter(|p| p.iter().all(|c| c.is_finite())).collect();
    let (center, side) = match bounds(&finite) {
        Some((lo, hi)) => (scale(add(lo, hi), 0.5), (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)),
        None => ([0.0; 3], 0.0),
    };
    let mut state = State::new(positions, center, faces);
    state.error_floor = (ERROR_FLOOR * side).powi(2);
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
    /// Edges the [`MIN_QUALITY`] rule refused, keyed by the cost the queue's front must
    /// exceed before the rule yields to them ([`YIELD_RATIO`]).
    deferred: EdgeQueue,
    /// Squared distance below which a deferred collapse's error counts as this ([`ERROR_FLOOR`]).
    error_floor: f64,
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
            deferred: EdgeQueue::new(0),
            error_floor: 0.0,
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
        self.deferred = EdgeQueue::new(self.edges.len());
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
        self.deferred.remove(e);
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
            let front = self.queue.front();
            if let Some((d, key)) = self.deferred.front() {
                if front.map_or(true, |(_, cost)| key < cost) {
                    self.yield_to(d);
                    continue;
                }
            }
            let Some((e, queued_cost)) = front else { break };
            let [a, b] = self.edges[e as usize];
            let Some(p) = self.evaluate(a, b, self.strict_shapes) else {
                self.queue.remove(e);
                self.defer(e);
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

    /// Keeps edge `e`, which the [`MIN_QUALITY`] rule alone refused, until the queue's front
    /// costs [`YIELD_RATIO`] times as much as collapsing it.
    fn defer(&mut self, e: u32) {
        if !self.strict_shapes {
            return;
        }
        let [a, b] = self.edges[e as usize];
        if let Some(p) = self.evaluate(a, b, false) {
            let area = self.quadric[a as usize] + self.quadric[b as usize];
            self.deferred.set(e, YIELD_RATIO * p.cost.max(self.error_floor * area.area()));
        }
    }

    /// Collapses the deferred edge `e` without the [`MIN_QUALITY`] rule, if it still may.
    fn yield_to(&mut self, e: u32) {
        self.deferred.remove(e);
        let [a, b] = self.edges[e as usize];
        if let Some(p) = self.evaluate(a, b, false) {
            if self.topology_allows(a, b) {
                self.collapse(e, p);
            }
        }
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
                self.deferred.remove(e);
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
