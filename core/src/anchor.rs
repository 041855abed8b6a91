//! The anchor mesh: the reference base mesh's connectivity moved onto the current input.
//!
//! Interim version: nearest-vertex matching (`Nns`), with motion estimation (`NnsMe`:
//! breadth-first, each vertex offset by the mean motion of its matched neighbours before
//! the search; the unmoved vertex's own match wins when it lies closer to its query, since
//! a wrong prediction next to a fast part, e.g. a ball, otherwise drags still vertices off
//! their place: on basketball_player that made `NnsMe` lose to `Nns`). The refinement stage
//! (`NnsMeQem`) currently projects each motion-estimated point onto the input surface
//! (closest point) instead of the paper's QEM collapse; the QEM refinement replaces it when
//! it lands.

use kiddo::SquaredEuclidean;

use crate::mesh::{norm, sub, Mesh};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnchorStages {
    Nns,
    NnsMe,
    NnsMeQem,
}

#[derive(Debug, Clone)]
pub struct AnchorParams {
    pub stages: AnchorStages,
}

impl Default for AnchorParams {
    fn default() -> Self {
        Self { stages: AnchorStages::NnsMeQem }
    }
}

#[derive(Debug, Clone, Default)]
pub struct AnchorStats {
    pub matched: usize,
}

pub struct Anchor {
    pub positions: Vec<[f64; 3]>,
    pub stats: AnchorStats,
}

pub fn anchor_mesh(reference: &Mesh, input: &Mesh, params: &AnchorParams) -> Anchor {
    let tree: kiddo::ImmutableKdTree<f64, 3> = kiddo::ImmutableKdTree::new_from_slice(&input.positions);
    let nearest = |q: [f64; 3]| input.positions[tree.nearest_one::<SquaredEuclidean>(&q).item as usize];
    let bvh = crate::bvh::Bvh::new(&input.positions, &input.faces);
    let n = reference.positions.len();
    if params.stages == AnchorStages::Nns {
        let positions = reference.positions.iter().map(|&p| nearest(p)).collect();
        return Anchor { positions, stats: AnchorStats { matched: n } };
    }
    let mut adj = vec![Vec::new(); n];
    for f in &reference.faces {
        for k in 0..3 {
            adj[f[k] as usize].push(f[(k + 1) % 3]);
            adj[f[(k + 1) % 3] as usize].push(f[k]);
        }
    }
    let mut motion: Vec<Option<[f64; 3]>> = vec![None; n];
    let mut out = reference.positions.clone();
    for seed in 0..n {
        if motion[seed].is_some() {
            continue;
        }
        let mut queue = std::collections::VecDeque::from([seed]);
        while let Some(v) = queue.pop_front() {
            if motion[v].is_some() {
                continue;
            }
            let known: Vec<[f64; 3]> = adj[v].iter().filter_map(|&w| motion[w as usize]).collect();
            let pred = if known.is_empty() {
                [0.0; 3]
            } else {
                std::array::from_fn(|k| known.iter().map(|m| m[k]).sum::<f64>() / known.len() as f64)
            };
            let p = reference.positions[v];
            let q = [p[0] + pred[0], p[1] + pred[1], p[2] + pred[2]];
            let hit = if params.stages == AnchorStages::NnsMeQem {
                bvh.closest_point(q).map_or(q, |c| c.point)
            } else {
                let (moved, still) = (nearest(q), nearest(p));
                if norm(sub(still, p)) < norm(sub(moved, q)) { still } else { moved }
            };
            out[v] = hit;
            motion[v] = Some([hit[0] - p[0], hit[1] - p[1], hit[2] - p[2]]);
            for &w in &adj[v] {
                if motion[w as usize].is_none() {
                    queue.push_back(w as usize);
                }
            }
        }
    }
    Anchor { positions: out, stats: AnchorStats { matched: n } }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `n` x `n` grid of unit spacing in the plane z = 0, moved by `offset`.
    fn sheet(n: u32, offset: [f64; 3]) -> Mesh {
        let p = (0..n).flat_map(|y| (0..n).map(move |x| [x as f64 + offset[0], y as f64 + offset[1], offset[2]])).collect();
        let mut f = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                let i = y * n + x;
                f.push([i, i + 1, i + n]);
                f.push([i + 1, i + n + 1, i + n]);
            }
        }
        Mesh::new(p, f)
    }

    fn anchor(reference: &Mesh, input: &Mesh, stages: AnchorStages) -> Vec<[f64; 3]> {
        anchor_mesh(reference, input, &AnchorParams { stages }).positions
    }

    #[test]
    fn every_stage_keeps_a_still_input_and_the_connectivity_size() {
        let m = sheet(6, [0.0; 3]);
        for stages in [AnchorStages::Nns, AnchorStages::NnsMe, AnchorStages::NnsMeQem] {
            assert_eq!(anchor(&m, &m, stages), m.positions, "{stages:?}");
        }
    }

    #[test]
    fn motion_estimation_follows_a_shift_that_nearest_neighbours_miss() {
        // Shifted by 1.4 along x: the nearest input vertex of every reference vertex is one
        // column short of its true match; ME offsets each search by its neighbours' motion
        // and lands on the true column from the second vertex on.
        let (reference, input) = (sheet(8, [0.0; 3]), sheet(8, [1.4, 0.0, 0.1]));
        let err = |a: &[[f64; 3]]| a.iter().zip(&reference.positions).map(|(p, r)| norm(sub(*p, [r[0] + 1.4, r[1], 0.1]))).sum::<f64>();
        let nns = err(&anchor(&reference, &input, AnchorStages::Nns));
        let me = err(&anchor(&reference, &input, AnchorStages::NnsMe));
        assert!(me < nns, "me {me} nns {nns}");
    }

    #[test]
    fn a_still_vertex_keeps_its_match_when_its_neighbours_move() {
        // Two sheets side by side, joined: the right one (walked first) jumps up by 3, too far
        // for nearest neighbours, so its vertices land on the left sheet with a large motion.
        // That motion offsets the searches of the left sheet's vertices, but their own
        // positions match exactly, so they stay.
        let mut reference = sheet(4, [3.5, 0.0, 0.0]);
        let left = sheet(4, [0.0; 3]);
        let n = reference.positions.len();
        reference.positions.extend(&left.positions);
        reference.faces.extend(left.faces.iter().map(|f| f.map(|v| v + n as u32)));
        reference.faces.push([0, n as u32 + 3, n as u32 + 7]); // joins the sheets
        let mut input = reference.clone();
        input.positions[..n].iter_mut().for_each(|p| p[2] += 3.0);
        let a = anchor(&reference, &input, AnchorStages::NnsMe);
        assert_eq!(a[n..], input.positions[n..]);
    }
}
