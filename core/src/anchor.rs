//! The anchor mesh: the reference base mesh's connectivity moved onto the current input.
//!
//! Interim version: nearest-vertex matching (`Nns`), with motion estimation (`NnsMe`:
//! breadth-first, each vertex offset by the mean motion of its matched neighbours before
//! the search). The refinement stage (`NnsMeQem`) currently projects each motion-estimated
//! point onto the input surface (closest point) instead of the paper's QEM collapse; the
//! QEM refinement replaces it when it lands.

use kiddo::SquaredEuclidean;

use crate::mesh::Mesh;

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
            let hit = if params.stages == AnchorStages::NnsMeQem { bvh.closest_point(q).map_or(q, |c| c.point) } else { nearest(q) };
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
