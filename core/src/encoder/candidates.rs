//! The ways of coding a frame: intra (a new base mesh), predicted (the reference's base
//! moved onto the input by tracking or the anchor mesh), and predicted with its worst-fitting
//! regions refreshed; each completed by the same displacement coding ([`SequenceEncoder::finish_candidate`]).

use std::borrow::Cow;
use std::time::Instant;

use crate::base::coder::{decode_base, encode_base};
use crate::base::decimate::decimate;
use crate::base::refit::refit_base;
use crate::error::InputError;
use crate::geom::bvh::Bvh;
use crate::geom::mesh::Mesh;
use crate::inter::anchor::{self, AnchorParams, ReferenceBase};
use crate::inter::{motion, refresh, tracking};
use crate::model::{base_in_grid_units, face_allowance, subdivided_base, FrameModel, FrameState};
use crate::residual::coefcoder;
use crate::residual::displace;
use crate::residual::quantize;
use crate::residual::subdivide::Subdivision;
use crate::stream::bitstream::{FrameType, SequenceHeader};
use crate::ec;
use crate::stream::payload::Payload;

use super::{Candidate, Chosen, EncoderConfig, Head, Motion, Reference, SequenceEncoder};

/// Displacement coefficients as one candidate codes them.
struct Coded {
    block: Vec<u8>,
    /// True for differences from the reference's coefficients (coefficient mode 1).
    predicted: bool,
    /// The quantized coefficients the block decodes to.
    q: Vec<i32>,
}

/// The reference coefficients a predicted candidate may code its own as differences from.
struct Prior<'a> {
    /// The reference frame's base and quantized coefficients.
    state: &'a FrameState,
    /// Differences within this many steps are dropped.
    dead_zone: f64,
    /// For a refreshed base, the reference faces it kept ([`refresh::apply`]).
    kept: Option<&'a [u32]>,
}

impl Prior<'_> {
    /// The reference's coefficients on the vertices of `sub`, the candidate's subdivision,
    /// and for a refreshed base the reference vertex each vertex repeats (or `refresh::NEW`).
    fn coefficients_on(&self, h: &SequenceHeader, sub: &Subdivision) -> (Cow<'_, [i32]>, Option<Vec<u32>>) {
        let Some(kept) = self.kept else { return (Cow::Borrowed(&self.state.coefficients), None) };
        let (carried, map) = refresh::carry(h, self.state, sub, kept).expect("the encoder's own reference state fits its subdivision");
        (Cow::Owned(carried), Some(map))
    }
}

impl SequenceEncoder {
    /// The frame predicted from the reference whose input lies closest to this one (None
    /// for the first frame of a group, or when no reference can be moved onto the input),
    /// and the seconds spent moving the reference's base onto the input.
    pub(super) fn best_predicted(&self, input: &Mesh, target: &Bvh) -> Result<(Option<Chosen>, f64), InputError> {
        if self.frame % self.config.search.intra_period == 0 {
            return Ok((None, 0.0));
        }
        let Some(stored) = self.closest_reference(input) else { return Ok((None, 0.0)) };
        let r = &stored.reference;
        let anchor_start = Instant::now();
        let Some((moved, motion)) = self.anchor_positions(r, input, target) else { return Ok((None, 0.0)) };
        let anchor_seconds = anchor_start.elapsed().as_secs_f64();
        let base = self.predicted_base(r, moved, target);
        let reference_distance = self.frame - stored.frame;
        let candidate = self.predicted(r, reference_distance, &base, motion.dead_zone(), input, target)?;
        Ok((Some(Chosen { candidate, reference_distance, motion: Some(motion) }), anchor_seconds))
    }

    /// The reference base mesh moved onto the current frame (grid units), if it can be,
    /// and how it was moved, which the next frame reuses if this one is predicted from it.
    fn anchor_positions(&self, r: &Reference, input: &Mesh, target: &Bvh) -> Option<(Vec<[f64; 3]>, Motion)> {
        let reference = Mesh::new(base_in_grid_units(&self.header, &r.state.base), r.state.faces.clone());
        let (moved, motion) = if tracking::same_connectivity(&r.input, input) {
            let bindings = match &r.motion {
                Some(Motion::Tracked(b)) => b.clone(),
                _ => tracking::bind(&reference.positions, &r.surface),
            };
            (tracking::bound_positions(&bindings, input, &reference.positions), Motion::Tracked(bindings))
        } else {
            let stages = self.config.search.inter?;
            let params = AnchorParams { stages, rigid_align: self.config.search.rigid_align, motion_parts: self.config.search.motion_parts, repair_folds: self.config.search.fold_repair };
            let motions = match &r.motion {
                Some(Motion::Anchor(m)) => m.as_ref(),
                _ => None,
            };
            let base = ReferenceBase { mesh: &reference, surface: Some(&r.surface), motions };
            let a = anchor::anchor_mesh(&base, input, target, &params);
            (a.positions, Motion::Anchor(a.motions))
        };
        Some((moved, motion))
    }

    /// The predicted frame's base positions on the base grid from the reference base moved
    /// to `moved` (grid units), refitted like an intra frame's base. A tracked base is
    /// refitted too: its vertices stay on their material points, but the surface between
    /// them bends, and the refit moves the base so that its subdivision follows
    /// (horse_gallop, QP 22-34: D1 BD-rate against all-intra -28.6 -> -30.9 %). The next
    /// frame starts again from the bindings, not from the refitted places.
    fn predicted_base(&self, r: &Reference, moved: Vec<[f64; 3]>, target: &Bvh) -> Vec<[u32; 3]> {
        let moved = if self.config.search.refit { refit_base(&Mesh::new(moved, r.state.faces.clone()), &self.header.schemes, target) } else { moved };
        let base_grid = self.header.grid.coarser(self.header.base_bits);
        moved.iter().map(|&p| base_grid.quantize(base_grid.to_grid(p))).collect()
    }

    /// The frame coded intra; its distortion is measured only when `measured`.
    pub(super) fn intra(&self, input: &Mesh, target: &Bvh, measured: bool) -> Result<Candidate, InputError> {
        let h = &self.header;
        let base_block = base_mesh_bytes(h, &self.config, &input.positions, &input.faces, target)?;
        let (base, faces) =
            decode_base(&base_block, h.base_bits).map_err(|e| InputError(format!("internal error: base mesh does not decode: {e}")))?;
        let head = Head::new(FrameType::Intra, 0, base_block);
        self.finish_candidate(head, base, faces, measured.then_some(input), target, None)
    }

    /// The frame predicted from `r`, `distance` frames back, with its base moved to `anchor`,
    /// dropping coefficient differences within `dead_zone` steps.
    fn predicted(&self, r: &Reference, distance: u32, anchor: &[[u32; 3]], dead_zone: f64, input: &Mesh, target: &Bvh) -> Result<Candidate, InputError> {
        let base_block = motion::encode_motion(&r.state.base, anchor, &r.state.faces);
        let head = Head::new(FrameType::Predicted, distance, base_block);
        let prior = Prior { state: &r.state, dead_zone, kept: None };
        self.finish_candidate(head, anchor.to_vec(), r.state.faces.clone(), Some(input), target, Some(prior))
    }

    /// Fits, transforms, quantizes and codes the displacements of the base mesh
    /// `(base, faces)` towards `target`, and completes the payload that `head` starts; the
    /// candidate's distortion is measured against `input` when it is given. A predicted
    /// frame passes its reference's coefficients: they correspond vertex for vertex, and the
    /// coefficients may be coded as differences from them, those within its dead zone
    /// dropped (coefficient mode 1). Differences are kept when they cost less and the
    /// quality their dead zone loses is worth the bytes ([`Self::rd_prefers`]): on dancer,
    /// whose coefficients hardly repeat from frame to frame, coding them directly often is.
    fn finish_candidate(
        &self,
        head: Head,
        base: Vec<[u32; 3]>,
        faces: Vec<[u32; 3]>,
        input: Option<&Mesh>,
        target: &Bvh,
        prior: Option<Prior>,
    ) -> Result<Candidate, InputError> {
        let (h, qp) = (&self.header, self.config.format.qp);
        let model = FrameModel::new(h, qp, subdivided_base(h, &base, &faces, h.schemes.len()));
        let (sub, frames) = (&model.sub, &model.frames);
        let world = if h.components == 1 {
            displace::fit_normal_displacements(&sub.positions, &sub.faces, frames, target, &displace::RefineParams::default())
        } else {
            displace::fit_displacements(&sub.positions, &sub.faces, frames, target, false)
        };
        let steps = model.coefficient_steps(&displace::to_local(&world, frames));
        let coded = |q: Vec<i32>, predicted: bool| {
            let mut enc = ec::Encoder::new();
            coefcoder::encode(&mut enc, &q, h.components as usize, sub);
            Coded { block: enc.finish(), predicted, q }
        };
        let payload = |c: &Coded| {
            Payload {
                reference_distance: head.reference_distance,
                qp,
                base: &head.base_block,
                refresh: &head.refresh_block,
                coefficients_predicted: c.predicted,
                coefficients: &c.block,
            }
            .to_bytes(head.frame_type)
        };
        let measure = |c: &Coded| {
            let reconstruction = model.reconstruct(&c.q);
            let distortion = input.map_or(0.0, |input| self.distortion(&reconstruction, input, target));
            (reconstruction, distortion)
        };
        let mut chosen = coded(quantize::round_levels(&steps, h.components as usize, &sub.lod_offsets), false);
        let mut payload_bytes = payload(&chosen);
        let mut measured = None;
        if let Some(prior) = prior {
            let comps = h.components as usize;
            let (r, map) = prior.coefficients_on(h, sub);
            // A vertex new to the refreshed base has no reference coefficient: it is rounded as intra.
            let dead_zone = |i: usize| if map.as_ref().is_some_and(|m| m[i / comps] == refresh::NEW) { 0.0 } else { prior.dead_zone };
            let residual = differences_from(&steps, &r, dead_zone);
            let q = residual.iter().zip(r.iter()).map(|(d, b)| d + b).collect();
            let differences = Coded { q, ..coded(residual, true) };
            if differences.block.len() < chosen.block.len() {
                let (diff_payload, diff) = (payload(&differences), measure(&differences));
                let direct = measure(&chosen);
                if self.rd_prefers(diff_payload.len(), diff.1, payload_bytes.len(), direct.1) {
                    (chosen, payload_bytes, measured) = (differences, diff_payload, Some(diff));
                } else {
                    measured = Some(direct);
                }
            }
        }
        let (reconstruction, distortion) = measured.unwrap_or_else(|| measure(&chosen));
        if reconstruction.faces.len() > face_allowance(payload_bytes.len()) {
            return Err(InputError(format!(
                "{} output faces from a {}-byte frame exceed what a decoder accepts; use fewer subdivision iterations",
                reconstruction.faces.len(),
                payload_bytes.len()
            )));
        }
        Ok(Candidate {
            head,
            payload: payload_bytes,
            displacement_bytes: chosen.block.len(),
            state: FrameState { base, faces, coefficients: chosen.q },
            reconstruction,
            distortion,
        })
    }

    /// The predicted frame `p` with the regions its moved base fits worst refreshed from
    /// the intra candidate `i`'s base (see [`refresh`]), or None when no region is poor or
    /// the base was tracked (its connectivity is the input's).
    pub(super) fn refreshed(&self, p: &Chosen, i: &Chosen, input: &Mesh, target: &Bvh) -> Result<Option<Chosen>, InputError> {
        if !self.config.search.refresh || !matches!(p.motion, Some(Motion::Anchor(_))) {
            return Ok(None);
        }
        let h = &self.header;
        let children = 1usize << (2 * h.schemes.len());
        let in_grid = |m: &Mesh| Mesh::new(self.in_grid_units(m), m.faces.clone());
        let (pc, ic) = (&p.candidate, &i.candidate);
        let limit = refresh::POOR_FIT * i.candidate.distortion;
        let (dropped, patched) = refresh::regions(&in_grid(&pc.reconstruction), &in_grid(&ic.reconstruction), children, target, limit);
        if !dropped.contains(&true) && !patched.contains(&true) {
            return Ok(None);
        }
        let patch_faces: Vec<[u32; 3]> = ic.state.faces.iter().zip(&patched).filter(|(_, &x)| x).map(|(f, _)| *f).collect();
        let patch_block = encode_base(&ic.state.base, &patch_faces, h.base_bits);
        let patch = decode_base(&patch_block, h.base_bits).map_err(|e| InputError(format!("internal error: refresh patch does not decode: {e}")))?;
        let ((base, faces), kept) = refresh::apply(&pc.state.base, &pc.state.faces, &dropped, &patch);
        let frame = self.frame - p.reference_distance;
        let reference = &self.references.iter().find(|s| s.frame == frame).expect("the predicted frame's reference is kept").reference;
        let head = Head {
            frame_type: FrameType::Predicted,
            reference_distance: p.reference_distance,
            base_block: pc.head.base_block.clone(),
            refresh_block: refresh::encode_refresh(&dropped, &patch_block),
            refreshed_faces: patch.1.len(),
        };
        let prior = Prior { state: &reference.state, dead_zone: quantize::PREDICTED_DEAD_ZONE, kept: Some(&kept) };
        // A refreshed frame beyond the decoder's face allowance is simply not a candidate.
        let Ok(candidate) = self.finish_candidate(head, base, faces, Some(input), target, Some(prior)) else { return Ok(None) };
        Ok(Some(Chosen { candidate, reference_distance: p.reference_distance, motion: None }))
    }
}

/// Decimates the input (grid units), refits the base mesh so that its subdivision fits the
/// input `surface` (with `cfg.search.refit`) and codes the quantized base mesh.
fn base_mesh_bytes(h: &SequenceHeader, cfg: &EncoderConfig, input: &[[f64; 3]], faces: &[[u32; 3]], surface: &Bvh) -> Result<Vec<u8>, InputError> {
    let target = ((faces.len() as f64 * cfg.base_ratio()).ceil() as usize).max(1);
    let base = decimate(input, faces, target);
    if base.faces.len() > max_base_faces(target) {
        // Decimation keeps every connected piece, so a soup of tiny pieces stays as large as
        // the input, and its subdivision and fitting would cost quadratic time.
        return Err(InputError(format!(
            "the mesh falls apart into pieces too small to simplify: its {} faces decimate to {} base faces, \
             not the {target} asked for (a triangle soup cannot be coded; weld or clean the mesh first)",
            faces.len(),
            base.faces.len()
        )));
    }
    let refitted = if cfg.search.refit { refit_base(&base, &h.schemes, surface) } else { base.positions };
    let base_grid = h.grid.coarser(h.base_bits);
    let positions: Vec<[u32; 3]> = refitted.iter().map(|&p| base_grid.quantize(base_grid.to_grid(p))).collect();
    Ok(encode_base(&positions, &base.faces, h.base_bits))
}

/// The most base faces a decimation to `target` faces may leave before the input is
/// refused: generous for meshes with a few small pieces (a captured frame's loose buttons),
/// far below what a triangle soup leaves.
fn max_base_faces(target: usize) -> usize {
    4 * target + 1024
}

/// The quantized differences of coefficients `steps` (in quantization steps) from the
/// reference's quantized coefficients. The difference is what gets quantized, not the
/// coefficient: a coefficient within the dead zone of its reference's then costs nothing,
/// where rounding it first could leave a difference of one either way.
fn differences_from(steps: &[f64], reference: &[i32], dead_zone: impl Fn(usize) -> f64) -> Vec<i32> {
    steps.iter().zip(reference).enumerate().map(|(i, (&x, &r))| quantize::round_beyond_dead_zone(x - r as f64, dead_zone(i))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stream::bitstream;
    use crate::encoder::FormatParams;

    #[test]
    fn differences_within_the_dead_zone_of_the_reference_are_zero() {
        // 2.6 rounds to 2 on its own (dead zone), which would leave -1 against a reference of 3.
        // Beyond the dead zone (one step) differences are rounded as intra coefficients are.
        assert_eq!(differences_from(&[2.6, -0.2, 5.0, -4.9, 7.7], &[3, 0, 3, -3, 2], |_| 1.0), vec![0, 0, 2, -2, 6]);
    }

    /// Whether the predicted candidate of `next` (coded after `first`, at QP 16) codes its
    /// coefficients as differences from the first frame's.
    fn codes_differences(first: &Mesh, next: &Mesh) -> bool {
        let cfg = EncoderConfig { format: FormatParams { qp: 16, ..Default::default() }, ..Default::default() };
        let mut enc = SequenceEncoder::new(cfg, 2, [0.0; 3], [1.0; 3]).expect("valid configuration");
        enc.encode(first).expect("a valid mesh");
        let input = Mesh::new(next.positions.iter().map(|&p| enc.header.grid.to_grid(p)).collect(), next.faces.clone());
        let target = Bvh::new(&input.positions, &input.faces);
        let p = enc.best_predicted(&input, &target).expect("a valid mesh").0.expect("a predicted candidate");
        let unit = bitstream::Unit { frame_type: FrameType::Predicted, payload: &p.candidate.payload, offset: 0, texture: None };
        Payload::read(&unit, 1).expect("a readable payload").0.coefficients_predicted
    }

    /// A bumpy sphere in the unit box with `stacks` rings, fine ripples of amplitude
    /// `ripple`, and each vertex moved radially by up to `noise` (random, from `seed`).
    fn sphere(stacks: u32, ripple: f64, noise: f64, seed: u64) -> Mesh {
        let radius = |t: f64, f: f64| 0.35 + 0.03 * (3.0 * t).sin() * (2.0 * f).cos() + ripple * (29.0 * t).sin() * (31.0 * f).sin();
        let (p, faces) = crate::geom::testmesh::uv_sphere(stacks, 2 * stacks, radius);
        let mut rng = crate::geom::testmesh::Rng(seed);
        let moved = p.iter().map(|q| q.map(|c| c * (1.0 + noise * rng.range(-1.0, 1.0) / 0.35) + 0.5)).collect();
        Mesh::new(moved, faces)
    }

    #[test]
    fn differences_are_coded_where_the_detail_repeats_and_coefficients_where_it_is_new() {
        // The next frames have another connectivity, so their bases are anchored, not tracked.
        assert!(codes_differences(&sphere(60, 0.004, 0.0, 1), &sphere(61, 0.004, 0.0, 1)));
        // Fresh noise of about a quantization step: its differences code smaller than the
        // coefficients (many fall in the dead zone), but what they drop costs more than the
        // bytes they save, as on dancer. Choosing by bytes alone coded differences here.
        assert!(!codes_differences(&sphere(60, 0.0, 0.0007, 1), &sphere(61, 0.0, 0.0007, 2)));
    }
}
