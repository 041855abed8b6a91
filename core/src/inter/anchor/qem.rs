//! The fine stage of the anchor mesh, as the paper writes it: around each coarse match, the
//! input mesh M(t) collapses its edge of least quadric error, and the optimal collapse point
//! becomes the fine anchor vertex.
//!
//! Each input vertex carries the quadric of its faces' planes (Garland and Heckbert). For
//! every reference vertex in turn, the input vertex it was matched to (or the vertex that has
//! since absorbed it) weighs each of its edges by the error of the summed quadric at its
//! optimal point, collapses the least one into that point, and the point is the anchor
//! vertex. The collapse updates the mesh: the merged vertex holds the sum of both quadrics and
//! both rings, so later reference vertices matched nearby see the collapsed mesh, as the
//! paper's "after each collapse, the error matrices of all affected edges are updated" asks.
//!
//! Two choices the paper leaves open. A collapse never absorbs another reference vertex's
//! match: the paper keeps the anchor one-to-one with the reference, and without this lock
//! matches on neighbouring input vertices collapse into each other one after the other, down
//! to a single point. And where the optimal point is not unique (a flat or creased
//! neighbourhood), the match itself is preferred (`collapse_point`).

use crate::geom::mesh::{add, scale, sub, Mesh};
use crate::geom::quadric::Quadric;

/// The fine anchor positions (same units as `input`): one per entry of `matches`, each an
/// input vertex index from the coarse stage. An input vertex without edges gives its own
/// position. Deterministic: reference vertices are refined in index order.
pub fn fine_anchor(input: &Mesh, matches: &[u32]) -> Vec<[f64; 3]> {
    let mut m = Collapsing::new(input);
    for &v in matches {
        m.locked[v as usize] = true;
    }
    matches.iter().map(|&v| m.collapse_cheapest_edge(v)).collect()
}

/// The input mesh under collapses: positions relative to the centre of its box (the quadric's
/// expanded error loses precision far from the origin), quadrics, rings and the vertex each
/// collapsed vertex went into.
struct Collapsing {
    centre: [f64; 3],
    positions: Vec<[f64; 3]>,
    quadrics: Vec<Quadric>,
    rings: Vec<Vec<u32>>,
    merged_into: Vec<u32>,
    /// Matches of reference vertices, which no collapse may absorb.
    locked: Vec<bool>,
}

impl Collapsing {
    fn new(input: &Mesh) -> Self {
        let centre = input.bounds().map_or([0.0; 3], |(lo, hi)| scale(add(lo, hi), 0.5));
        let positions: Vec<[f64; 3]> = input.positions.iter().map(|&p| sub(p, centre)).collect();
        let n = positions.len();
        let mut quadrics = vec![Quadric::ZERO; n];
        let mut rings = vec![Vec::new(); n];
        for f in &input.faces {
            let q = Quadric::from_triangle(positions[f[0] as usize], positions[f[1] as usize], positions[f[2] as usize]);
            for k in 0..3 {
                quadrics[f[k] as usize] += q;
                rings[f[k] as usize].extend([f[(k + 1) % 3], f[(k + 2) % 3]]);
            }
        }
        for r in &mut rings {
            r.sort_unstable();
            r.dedup();
        }
        Self { centre, positions, quadrics, rings, merged_into: (0..n as u32).collect(), locked: vec![false; n] }
    }

    /// The vertex that `v` has been collapsed into, through any number of collapses.
    fn live(&mut self, mut v: u32) -> u32 {
        while self.merged_into[v as usize] != v {
            let next = self.merged_into[v as usize];
            self.merged_into[v as usize] = self.merged_into[next as usize];
            v = next;
        }
        v
    }

    /// Collapses the edge of least error around (the live vertex of) `v` and returns the
    /// collapse point in input units; `v`'s own position when it has no edge left to an
    /// unlocked vertex.
    fn collapse_cheapest_edge(&mut self, v: u32) -> [f64; 3] {
        let v = self.live(v);
        let ring: Vec<u32> = self.rings[v as usize].clone();
        let mut best: Option<(f64, u32, [f64; 3])> = None;
        for w in ring {
            let w = self.live(w);
            if w == v || self.locked[w as usize] {
                continue;
            }
            let q = self.quadrics[v as usize] + self.quadrics[w as usize];
            let (p, e) = collapse_point(&q, self.positions[v as usize], self.positions[w as usize]);
            // Ties go to the lower index, so the result does not depend on ring order.
            if best.map_or(true, |(be, bw, _)| e < be || (e == be && w < bw)) {
                best = Some((e, w, p));
            }
        }
        let Some((_, w, p)) = best else { return add(self.positions[v as usize], self.centre) };
        self.merge(w, v, p);
        add(p, self.centre)
    }

    /// Collapses `w` into `v`, which moves to `p`.
    fn merge(&mut self, w: u32, v: u32, p: [f64; 3]) {
        self.merged_into[w as usize] = v;
        let absorbed = self.quadrics[w as usize];
        self.quadrics[v as usize] += absorbed;
        self.positions[v as usize] = p;
        let mut ring = std::mem::take(&mut self.rings[v as usize]);
        ring.append(&mut std::mem::take(&mut self.rings[w as usize]));
        let mut live: Vec<u32> = ring.into_iter().map(|u| self.live(u)).filter(|&u| u != v).collect();
        live.sort_unstable();
        live.dedup();
        self.rings[v as usize] = live;
    }
}

/// The point of least error of `q` for the edge from the matched vertex `v` to `w`, and its
/// error: the optimal point when it is well defined near the edge, else the best of `v`, the
/// midpoint and `w`, with ties going to `v`. The paper leaves the singular case open (a flat
/// or creased neighbourhood has a plane or line of optimal points); keeping the coarse match
/// there means a match that already lies on the surface stays where it is.
fn collapse_point(q: &Quadric, v: [f64; 3], w: [f64; 3]) -> ([f64; 3], f64) {
    if let Some(p) = q.optimal_point_near(v, w) {
        return (p, q.error(p));
    }
    let mid = scale(add(v, w), 0.5);
    [mid, w].into_iter().fold((v, q.error(v)), |best, p| {
        let e = q.error(p);
        if e < best.1 { (p, e) } else { best }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tent: two planes meeting at a ridge along x = 0, sampled on a grid of unit spacing.
    fn tent(n: i32) -> Mesh {
        let w = (2 * n + 1) as u32;
        let (p, f) = crate::geom::testmesh::grid(w, w, 1.0, [-n as f64, -n as f64, 0.0]);
        Mesh::new(p.into_iter().map(|q| [q[0], q[1], -q[0].abs()]).collect(), f)
    }

    fn on_tent(p: [f64; 3]) -> f64 {
        (p[2] + p[0].abs()).abs()
    }

    #[test]
    fn fine_anchor_vertices_lie_on_the_input_surface_near_their_matches() {
        let m = tent(5);
        let matches: Vec<u32> = vec![60, 61, 17, 100, 60];
        let fine = fine_anchor(&m, &matches);
        assert_eq!(fine.len(), matches.len());
        for (p, &v) in fine.iter().zip(&matches) {
            assert!(on_tent(*p) < 1e-9, "{p:?} is off the surface");
            let d = sub(*p, m.positions[v as usize]);
            assert!(d.iter().map(|c| c * c).sum::<f64>().sqrt() <= 2.5, "{p:?} is far from its match {v}");
        }
    }

    #[test]
    fn matches_are_never_absorbed_and_each_refinement_collapses_one_edge() {
        let m = tent(3);
        // 24 and 25 are neighbours; each collapses one edge to an unmatched vertex.
        let mut c = Collapsing::new(&m);
        c.locked[24] = true;
        c.locked[25] = true;
        c.collapse_cheapest_edge(24);
        c.collapse_cheapest_edge(25);
        let live: Vec<u32> = (0..m.positions.len() as u32).map(|v| c.live(v)).collect();
        assert_eq!((live[24], live[25]), (24, 25));
        assert_eq!(live.iter().filter(|&&v| v == 24).count(), 2);
        assert_eq!(live.iter().filter(|&&v| v == 25).count(), 2);
        assert_eq!(live.iter().enumerate().filter(|&(i, &v)| v != i as u32).count(), 2);
    }

    #[test]
    fn a_second_match_of_the_same_vertex_sees_the_collapsed_mesh() {
        let m = tent(3);
        let mut c = Collapsing::new(&m);
        c.locked[20] = true;
        c.collapse_cheapest_edge(20);
        c.collapse_cheapest_edge(20);
        let absorbed = (0..m.positions.len() as u32).filter(|&v| v != 20 && c.live(v) == 20).count();
        assert_eq!(absorbed, 2, "the second refinement collapsed another edge of the merged vertex");
    }

    #[test]
    fn an_isolated_vertex_keeps_its_position() {
        let mut m = tent(1);
        m.positions.push([7.0, 7.0, 7.0]);
        assert_eq!(fine_anchor(&m, &[9]), vec![[7.0, 7.0, 7.0]]);
    }
}
