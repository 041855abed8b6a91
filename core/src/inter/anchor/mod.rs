//! The anchor mesh: the reference base mesh's connectivity moved onto the current input,
//! coarse to fine, as the paper builds it, plus a repair of the folds that moving makes.
//!
//! Stages (`AnchorStages`): nearest-neighbour matching of every reference base vertex to an
//! input vertex (`Nns`, [`coarse`]); motion estimation in front of it (`NnsMe`); the paper's
//! QEM refinement of those matches (`NnsMeQem`, [`qem`]). `NnsMeProj` is our own variant of
//! the fine stage: each motion-predicted point goes to its closest point on the input
//! surface instead of to an input vertex and then a collapse point. [`folds`] then repairs
//! flipped or degenerate anchor triangles whatever the stages, and [`rigid`] moves each
//! connected part rigidly onto the input before them (neither is in the paper; both can be
//! turned off). The stages run on the reference base's closest points on its own input;
//! each vertex's offset from there, which the refit gave it, is carried along.

pub mod coarse;
pub mod folds;
pub mod parts;
pub mod qem;
pub mod rigid;

use crate::geom::bvh::Bvh;
use crate::geom::mesh::{add, sub, Mesh};
use coarse::NearestVertex;
pub use rigid::PartMotions;

/// The stages that make the anchor mesh: the paper's ablation switches, and our variant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AnchorStages {
    /// Nearest input vertex of each reference vertex (the paper's NNS).
    Nns,
    /// ... searched from the position its neighbours' motion predicts (+ME).
    NnsMe,
    /// ... refined by the paper's QEM edge collapse around each match (+QEM: the paper's
    /// full method).
    NnsMeQem,
    /// ... with the motion-predicted point projected onto the input surface instead of the
    /// QEM stage (ours, not in the paper).
    NnsMeProj,
}

impl AnchorStages {
    /// The stages' names, as `--inter` takes them, in the order of the variants.
    pub const NAMES: [&'static str; 4] = ["nns", "nns+me", "nns+me+qem", "nns+me+proj"];
    const ALL: [Self; 4] = [Self::Nns, Self::NnsMe, Self::NnsMeQem, Self::NnsMeProj];

    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().position(|&n| n == name).map(|i| Self::ALL[i])
    }

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
}

#[derive(Debug, Clone)]
pub struct AnchorParams {
    pub stages: AnchorStages,
    /// Move each part of the reference rigidly onto the input first ([`rigid`]).
    pub rigid_align: bool,
    /// ... and cut each connected part into the parts that move apart inside it
    /// ([`parts`]), with `rigid_align`.
    pub motion_parts: bool,
    /// Repair folded anchor triangles ([`folds`]).
    pub repair_folds: bool,
}

/// What the anchor of a predicted frame starts from: the reference frame's base mesh, and
/// what the reference frame knew about it.
pub struct ReferenceBase<'a> {
    /// The base mesh, in the input's units.
    pub mesh: &'a Mesh,
    /// The reference frame's input surface. A refitted base lies off it, by what lets its
    /// subdivision fit (`refit`); the anchor moves the base's closest points on it and
    /// carries each vertex's offset along, so that the motion is the surface's and the
    /// offset survives it.
    pub surface: Option<&'a Bvh>,
    /// The rigid motion of each part in the reference frame, which predicts this frame's.
    pub motions: Option<&'a PartMotions>,
}

pub struct Anchor {
    /// One position per reference vertex, in the input's units.
    pub positions: Vec<[f64; 3]>,
    /// The rigid motion of each part of the reference (`rigid::parts`), with `rigid_align`.
    pub motions: Option<PartMotions>,
}

/// The anchor mesh of `reference` on `input` (same units), whose faces are the reference's.
/// `input` must have vertices; `input_bvh` indexes its faces.
pub fn anchor_mesh(reference: &ReferenceBase, input: &Mesh, input_bvh: &Bvh, params: &AnchorParams) -> Anchor {
    let base = reference.mesh;
    let offsets: Vec<[f64; 3]> = match reference.surface {
        Some(s) => base.positions.iter().map(|&p| s.closest_point(p).map_or([0.0; 3], |c| sub(p, c.point))).collect(),
        None => vec![[0.0; 3]; base.positions.len()],
    };
    let on_surface: Vec<[f64; 3]> = base.positions.iter().zip(&offsets).map(|(&p, &o)| sub(p, o)).collect();
    let mut start = Mesh::new(on_surface, base.faces.clone());
    let mut aligned = params.rigid_align.then(|| {
        let mut a = rigid::align_parts(&start, input_bvh, reference.motions);
        if params.motion_parts {
            parts::split_by_motion(&start, input_bvh, reference.motions, &mut a);
        }
        a
    });
    if let Some(a) = &mut aligned {
        start.positions = std::mem::take(&mut a.positions);
    }
    let mut positions = matched(&start, input, input_bvh, params.stages);
    if params.repair_folds {
        folds::repair_folds(&start, &mut positions, input_bvh);
    }
    for (v, (p, &o)) in positions.iter_mut().zip(&offsets).enumerate() {
        let o = aligned.as_ref().map_or(o, |a| a.motions.of(v).rotate(o));
        *p = add(*p, o);
    }
    Anchor { positions, motions: aligned.map(|a| a.motions) }
}

/// The stages' positions for the vertices of `reference` (moved as far as it already is).
fn matched(reference: &Mesh, input: &Mesh, input_bvh: &Bvh, stages: AnchorStages) -> Vec<[f64; 3]> {
    let nearest = NearestVertex::new(&input.positions);
    match stages {
        AnchorStages::Nns => at(input, &coarse::nearest_matches(reference, &nearest)),
        AnchorStages::NnsMe => at(input, &coarse::motion_estimated_matches(reference, &nearest)),
        AnchorStages::NnsMeQem => qem::fine_anchor(input, &coarse::motion_estimated_matches(reference, &nearest)),
        AnchorStages::NnsMeProj => coarse::walk_with_predicted_motion(reference, |_, q| (input_bvh.closest_point(q).map_or(q, |c| c.point), ()))
            .into_iter()
            .map(|(p, _)| p)
            .collect(),
    }
}

fn at(input: &Mesh, matches: &[u32]) -> Vec<[f64; 3]> {
    matches.iter().map(|&v| input.positions[v as usize]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::mesh::{norm, sub};

    /// A `n` x `n` grid of unit spacing in the plane z = 0, moved by `offset`.
    fn sheet(n: u32, offset: [f64; 3]) -> Mesh {
        let (p, f) = crate::geom::testmesh::grid(n, n, 1.0, offset);
        Mesh::new(p, f)
    }

    fn anchor(reference: &Mesh, input: &Mesh, stages: AnchorStages) -> Vec<[f64; 3]> {
        let bvh = Bvh::new(&input.positions, &input.faces);
        let base = ReferenceBase { mesh: reference, surface: None, motions: None };
        anchor_mesh(&base, input, &bvh, &AnchorParams { stages, rigid_align: false, motion_parts: false, repair_folds: false }).positions
    }

    #[test]
    fn every_stage_keeps_a_still_input_and_the_connectivity_size() {
        let m = sheet(6, [0.0; 3]);
        for stages in AnchorStages::ALL {
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
