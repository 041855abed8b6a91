//! The coarse stage of the anchor mesh: every reference base vertex matched to an input
//! vertex by nearest-neighbour search (the paper's octree search; a k-d tree here), with
//! motion estimation in front of it.
//!
//! Motion estimation walks the reference base breadth first and offsets each vertex's search
//! by the mean motion of its already matched neighbours. The unmoved vertex's own match wins
//! when it lies closer to its query: a wrong prediction next to a fast part (a ball) would
//! otherwise drag still vertices off their place (on basketball_player that made motion
//! estimation lose to plain matching).

use std::collections::VecDeque;

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::geom::mesh::{add, norm, sub, Adjacency, Mesh};

/// Nearest input vertex of a point.
pub struct NearestVertex<'a> {
    tree: ImmutableKdTree<f64, 3>,
    positions: &'a [[f64; 3]],
}

impl<'a> NearestVertex<'a> {
    /// Panics on an empty input (the encoder never predicts towards one).
    pub fn new(positions: &'a [[f64; 3]]) -> Self {
        Self { tree: ImmutableKdTree::new_from_slice(positions), positions }
    }

    /// Index of the input vertex nearest to `q`.
    pub fn index(&self, q: [f64; 3]) -> u32 {
        self.tree.nearest_one::<SquaredEuclidean>(&q).item as u32
    }

    pub fn position(&self, v: u32) -> [f64; 3] {
        self.positions[v as usize]
    }
}

/// Per reference vertex, the input vertex nearest to it.
pub fn nearest_matches(reference: &Mesh, nearest: &NearestVertex) -> Vec<u32> {
    reference.positions.iter().map(|&p| nearest.index(p)).collect()
}

/// Per reference vertex, the input vertex matched with motion estimation (see the module
/// notes).
pub fn motion_estimated_matches(reference: &Mesh, nearest: &NearestVertex) -> Vec<u32> {
    let moved = walk_with_predicted_motion(reference, |p, q| {
        let (still, moved) = (nearest.index(p), nearest.index(q));
        let pick = if norm(sub(nearest.position(still), p)) < norm(sub(nearest.position(moved), q)) { still } else { moved };
        (nearest.position(pick), pick)
    });
    moved.into_iter().map(|(_, v)| v).collect()
}

/// Visits the reference vertices breadth first, component by component, and asks `place`
/// where vertex position `p` goes when its neighbours' mean motion predicts `q`; returns
/// what `place` answered per vertex (the motion is the move from `p` to the answered point).
pub fn walk_with_predicted_motion<T: Copy>(reference: &Mesh, mut place: impl FnMut([f64; 3], [f64; 3]) -> ([f64; 3], T)) -> Vec<([f64; 3], T)> {
    let n = reference.positions.len();
    let rings = Adjacency::new(n, &reference.faces);
    let mut motion: Vec<Option<[f64; 3]>> = vec![None; n];
    let mut out: Vec<Option<([f64; 3], T)>> = vec![None; n];
    for seed in 0..n {
        let mut queue = VecDeque::from([seed]);
        while let Some(v) = queue.pop_front() {
            if motion[v].is_some() {
                continue;
            }
            let known: Vec<[f64; 3]> = rings.of(v).iter().filter_map(|&w| motion[w as usize]).collect();
            let pred = mean(&known);
            let p = reference.positions[v];
            let answer = place(p, add(p, pred));
            motion[v] = Some(sub(answer.0, p));
            out[v] = Some(answer);
            queue.extend(rings.of(v).iter().map(|&w| w as usize).filter(|&w| motion[w].is_none()));
        }
    }
    out.into_iter().map(|a| a.expect("every vertex is visited")).collect()
}

/// The mean of `v`; zero for none.
pub(super) fn mean(v: &[[f64; 3]]) -> [f64; 3] {
    if v.is_empty() {
        return [0.0; 3];
    }
    std::array::from_fn(|k| v.iter().map(|m| m[k]).sum::<f64>() / v.len() as f64)
}
