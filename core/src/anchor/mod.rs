//! The anchor mesh: the reference base mesh's connectivity moved onto the current input,
//! coarse to fine, as the paper builds it, plus a repair of the folds that moving makes.
//!
//! Stages (`AnchorStages`): nearest-neighbour matching of every reference base vertex to an
//! input vertex (`Nns`, [`coarse`]); motion estimation in front of it (`NnsMe`); the paper's
//! QEM refinement of those matches (`NnsMeQem`, [`qem`]). `NnsMeProj` is our own variant of
//! the fine stage: each motion-predicted point goes to its closest point on the input
//! surface instead of to an input vertex and then a collapse point. [`folds`] then repairs
//! flipped or degenerate anchor triangles whatever the stages (not in the paper; it can be
//! turned off).

pub mod coarse;
pub mod folds;
pub mod qem;

use crate::bvh::Bvh;
use crate::mesh::Mesh;
use coarse::NearestVertex;
pub use folds::FoldStats;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnchorStages {
    /// Nearest input vertex of each reference vertex.
    Nns,
    /// ... searched from the position its neighbours' motion predicts.
    NnsMe,
    /// ... refined by the paper's QEM edge collapse around each match.
    NnsMeQem,
    /// ... with the motion-predicted point projected onto the input surface instead (ours).
    NnsMeProj,
}

#[derive(Debug, Clone)]
pub struct AnchorParams {
    pub stages: AnchorStages,
    /// Repair folded anchor triangles ([`folds`]).
    pub repair_folds: bool,
}

impl Default for AnchorParams {
    fn default() -> Self {
        Self { stages: AnchorStages::NnsMeQem, repair_folds: true }
    }
}

#[derive(Debug, Clone, Default)]
pub struct AnchorStats {
    pub folds: FoldStats,
}

pub struct Anchor {
    /// One position per reference vertex, in the input's units.
    pub positions: Vec<[f64; 3]>,
    pub stats: AnchorStats,
}

/// The anchor mesh of `reference` (a base mesh) on `input` (same units), whose faces are
/// `reference.faces`. `input` must have vertices; `input_bvh` indexes its faces.
pub fn anchor_mesh(reference: &Mesh, input: &Mesh, input_bvh: &Bvh, params: &AnchorParams) -> Anchor {
    let nearest = NearestVertex::new(&input.positions);
    let mut positions = match params.stages {
        AnchorStages::Nns => at(input, &coarse::nearest_matches(reference, &nearest)),
        AnchorStages::NnsMe => at(input, &coarse::motion_estimated_matches(reference, &nearest)),
        AnchorStages::NnsMeQem => qem::fine_anchor(input, &coarse::motion_estimated_matches(reference, &nearest)),
        AnchorStages::NnsMeProj => coarse::walk_with_predicted_motion(reference, |_, q| (input_bvh.closest_point(q).map_or(q, |c| c.point), ()))
            .into_iter()
            .map(|(p, _)| p)
            .collect(),
    };
    let folds = if params.repair_folds { folds::repair_folds(reference, &mut positions, input_bvh) } else { FoldStats::default() };
    Anchor { positions, stats: AnchorStats { folds } }
}

fn at(input: &Mesh, matches: &[u32]) -> Vec<[f64; 3]> {
    matches.iter().map(|&v| input.positions[v as usize]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{norm, sub};

    /// A `n` x `n` grid of unit spacing in the plane z = 0, moved by `offset`.
    fn sheet(n: u32, offset: [f64; 3]) -> Mesh {
        let (p, f) = crate::bvh::testmesh::grid(n, n, 1.0, offset);
        Mesh::new(p, f)
    }

    fn anchor(reference: &Mesh, input: &Mesh, stages: AnchorStages) -> Vec<[f64; 3]> {
        let bvh = Bvh::new(&input.positions, &input.faces);
        anchor_mesh(reference, input, &bvh, &AnchorParams { stages, repair_folds: false }).positions
    }

    #[test]
    fn every_stage_keeps_a_still_input_and_the_connectivity_size() {
        let m = sheet(6, [0.0; 3]);
        for stages in [AnchorStages::Nns, AnchorStages::NnsMe, AnchorStages::NnsMeQem, AnchorStages::NnsMeProj] {
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
