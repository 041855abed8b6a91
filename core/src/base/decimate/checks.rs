//! Whether a collapse may go ahead: where it can put the surviving vertex ([`State::candidates`],
//! by quadric error), the shape checks of the faces it moves (no fold, no new sliver) and the
//! topology checks (the link condition, no duplicate face, no vanishing component).

use super::{Placement, State, DEGENERATE_QUALITY, MIN_NORMAL_COS, MIN_QUALITY, NONE};
use crate::geom::mesh::{add, cross, dist2, dot, scale, sub};
use crate::geom::quadric::Quadric;

impl State {
    /// The quadric error of the cheapest candidate of [`State::candidates`]: the queue key, and
    /// what [`State::evaluate`] returns unless the shape checks rule that candidate out.
    pub(super) fn best_error(&self, a: u32, b: u32) -> f64 {
        let (q, optimal, [mid, pa, pb]) = self.candidate_points(a, b);
        match optimal {
            Some(p) => q.error(p),
            None => q.error(mid).min(q.error(pa)).min(q.error(pb)),
        }
    }

    /// Cheapest legal placement for collapsing `(a, b)`, or `None` when every candidate of
    /// [`State::candidates`] folds a face or (with `strict`) makes a sliver.
    pub(super) fn evaluate(&self, a: u32, b: u32, strict: bool) -> Option<Placement> {
        let mut candidates = self.candidates(a, b).into_iter().filter(|c| c.cost.is_finite());
        candidates.find(|c| self.shapes_allow(a, b, c.pos, strict))
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
    /// degenerating (see [`face_change`]) and, with `strict`, leaves no face
    /// below [`MIN_QUALITY`] unless its neighbourhood already had a worse one. Judging the
    /// neighbourhood rather than each face lets collapses that clear slivers away go ahead.
    fn shapes_allow(&self, a: u32, b: u32, p: [f64; 3], strict: bool) -> bool {
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
        !strict || worst_new >= floor || worst_new >= self.worst_shape(a, b)
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
    pub(super) fn topology_allows(&mut self, a: u32, b: u32) -> bool {
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

pub(super) fn triangle_normal([a, b, c]: [[f64; 3]; 3]) -> [f64; 3] {
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
