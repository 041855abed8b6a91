//! The encoder: one input frame to one frame unit, plus the reconstruction that the
//! decoder will produce from it. Its options are [`config`].

mod config;

pub use config::{base_ratio_for_qp, EncoderConfig, LiftingChoice, MAX_REFERENCES};

use std::borrow::Cow;
use std::time::Instant;

use rayon::prelude::*;

use crate::base::coder::{decode_base, encode_base};
use crate::base::decimate::decimate;
use crate::base::refit::refit_base;
use crate::error::InputError;
use crate::geom::bvh::Bvh;
use crate::geom::limits;
use crate::geom::mesh::{dot, sub, Mesh};
use crate::geom::weld::{surface_faces, weld};
use crate::inter::anchor::{self, AnchorParams, PartMotions, ReferenceBase};
use crate::inter::{motion, refresh};
use crate::inter::tracking::{self, Bindings};
use crate::model::{base_in_grid_units, base_in_world_units, face_allowance, subdivided_base, FrameModel, FrameState};
use crate::residual::coefcoder;
use crate::residual::displace;
use crate::residual::quantize;
use crate::residual::subdivide::Subdivision;
use crate::stream::bitstream::{self, FrameType, SequenceHeader};
use crate::stream::ec;
use crate::stream::payload::Payload;

/// Input vertices that [`SequenceEncoder::closest_reference`] measures.
const REFERENCE_SAMPLES: usize = 1024;

/// What encoding one frame produced.
#[derive(Debug, Clone)]
pub struct EncodedFrame {
    /// The complete frame unit, ready to append to the stream.
    pub unit: Vec<u8>,
    /// Exactly what the decoder will output for this frame.
    pub reconstruction: Mesh,
    /// The decoded base mesh, in the input's units: what the texture atlas of an intra
    /// frame is made on. `reconstruction` is its subdivision, face for face.
    pub base: Mesh,
    pub stats: FrameStats,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub frame_type: Option<FrameType>,
    /// Frames back to the reference of a predicted frame; 0 for intra.
    pub reference_distance: u32,
    pub bytes: usize,
    /// Bytes of the base mesh (intra) or of its motion and refresh (predicted).
    pub base_bytes: usize,
    /// Base faces of a predicted frame coded intra by the refresh of its worst-fitting
    /// regions (0 when nothing was refreshed).
    pub refreshed_faces: usize,
    pub displacement_bytes: usize,
    pub base_vertices: usize,
    pub base_faces: usize,
    pub output_vertices: usize,
    pub output_faces: usize,
    /// Input faces left out for having no area or repeating another face
    /// ([`crate::geom::weld`]).
    pub dropped_faces: usize,
    /// Whether the input had the previous input's connectivity.
    pub same_topology: bool,
    /// Bytes the other candidate (intra or predicted) would have cost; 0 if it was not coded.
    pub rejected_bytes: usize,
    /// Seconds spent making the predicted frame's base mesh (anchor or tracking).
    pub anchor_seconds: f64,
    pub seconds: f64,
}

/// The state a predicted frame refers to: the previous frame's input and base mesh.
struct Reference {
    /// Input in grid units.
    input: Mesh,
    /// Its base mesh and quantized coefficients, which a predicted frame may code its own
    /// against.
    state: FrameState,
    /// How the base was moved to this frame, when it was predicted.
    motion: Option<Motion>,
    /// Index of `input`'s faces.
    surface: Bvh,
}

/// How a predicted frame's base mesh was found, which the next frame builds on.
#[derive(Clone)]
enum Motion {
    /// Tracked on an input of constant connectivity: the base vertices' places on the input.
    Tracked(Bindings),
    /// By the anchor mesh, with the rigid motion of each part when it was aligned.
    Anchor(Option<PartMotions>),
}

impl Motion {
    /// The dead zone of the coefficient differences of a frame whose base moved this way.
    fn dead_zone(&self) -> f64 {
        match self {
            Self::Tracked(_) => quantize::TRACKED_DEAD_ZONE,
            Self::Anchor(_) => quantize::PREDICTED_DEAD_ZONE,
        }
    }
}

/// A candidate with what the decision needs and the next frames reuse.
struct Chosen {
    candidate: Candidate,
    /// Frames back to the reference; 0 for intra.
    reference_distance: u32,
    /// How the reference's base was moved onto this frame (predicted frames).
    motion: Option<Motion>,
}

/// One way of coding the current frame.
struct Candidate {
    /// Its fields before the displacements (a refreshed candidate repeats a predicted one's
    /// motion block).
    head: Head,
    payload: Vec<u8>,
    displacement_bytes: usize,
    state: FrameState,
    reconstruction: Mesh,
    /// Estimated distortion (see `SequenceEncoder::distortion`); 0 when it was not measured.
    distortion: f64,
}

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

/// The payload fields of a candidate that come before its displacements.
struct Head {
    frame_type: FrameType,
    reference_distance: u32,
    /// The base mesh block (intra) or the motion block (predicted).
    base_block: Vec<u8>,
    /// The refresh block (predicted frames; empty when nothing is refreshed).
    refresh_block: Vec<u8>,
    /// Faces of the patch the refresh block codes intra.
    refreshed_faces: usize,
}

impl Head {
    /// A head without a refresh.
    fn new(frame_type: FrameType, reference_distance: u32, base_block: Vec<u8>) -> Self {
        Self { frame_type, reference_distance, base_block, refresh_block: Vec::new(), refreshed_faces: 0 }
    }
}

/// Encodes the frames of one sequence in order, predicting from earlier frames of the group.
pub struct SequenceEncoder {
    header: SequenceHeader,
    config: EncoderConfig,
    frame: u32,
    /// The coded frames of the current group a predicted frame may refer to, oldest first:
    /// the last `config.references` frames and the latest intra frame.
    references: Vec<Stored>,
    /// Payload bytes and estimated distortion of the last frame coded intra.
    last_intra: Option<(usize, f64)>,
    /// What the frame's texture will cost, when the stream is textured ([`TextureCost`]).
    texture_cost: Option<TextureCost>,
}

/// The bytes a textured frame's texture adds, which the frame type decides: a frame whose
/// base keeps the previous frame's connectivity continues the texture group (its atlas,
/// and a video frame predicted from the previous one); an intra frame, and a predicted one
/// whose base changed (refreshed, or moved from an older reference), starts a new group
/// (a new atlas, an intra video frame). The texture stage measures both as it goes
/// ([`SequenceEncoder::set_texture_cost`]) so that the decision weighs them with the
/// geometry's bytes: texture is most of a textured stream.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureCost {
    pub continued: f64,
    pub restarted: f64,
}

/// A coded frame kept as a possible reference.
struct Stored {
    frame: u32,
    intra: bool,
    reference: Reference,
}

impl SequenceEncoder {
    /// An encoder for `frame_count` frames whose positions lie in the box `[min, max]`.
    pub fn new(config: EncoderConfig, frame_count: u32, min: [f64; 3], max: [f64; 3]) -> Result<Self, InputError> {
        config.validate()?;
        if !min.iter().chain(&max).all(|c| c.is_finite()) {
            return Err(InputError("bounding box must be finite".into()));
        }
        Ok(Self { header: config.header(frame_count, min, max), config, frame: 0, references: Vec::new(), last_intra: None, texture_cost: None })
    }

    /// Makes the decisions of the following frames weigh their texture's bytes too (None:
    /// geometry alone, as for an untextured stream).
    pub fn set_texture_cost(&mut self, cost: Option<TextureCost>) {
        self.texture_cost = cost;
    }

    pub fn header(&self) -> &SequenceHeader {
        &self.header
    }

    /// The index of the frame that [`Self::encode`] codes next.
    pub fn next_frame(&self) -> u32 {
        self.frame
    }

    /// Makes the next frame frame `index`, the first of a group (a multiple of the intra
    /// period), and forgets the references and the last intra frame. The first frame of a
    /// group is intra and reads neither, so from there on this encoder produces the units
    /// the sequential encoder does, and the groups of a sequence can be encoded apart. Only
    /// the `same_topology` statistic of that first frame differs: it has no previous input.
    pub fn start_group(&mut self, index: u32) -> Result<(), InputError> {
        let period = self.config.intra_period;
        if index % period != 0 || index >= self.header.frame_count {
            return Err(InputError(format!(
                "frame {index} does not start a group: groups start at multiples of the intra period {period} below {}",
                self.header.frame_count
            )));
        }
        self.frame = index;
        self.references.clear();
        self.last_intra = None;
        Ok(())
    }

    /// Encodes the next frame (in the input's units, inside the header's box).
    pub fn encode(&mut self, mesh: &Mesh) -> Result<EncodedFrame, InputError> {
        let start = Instant::now();
        mesh.validate()?;
        limits::check_size(mesh)?;
        let welded = weld(mesh);
        let h = &self.header;
        let (input, _) = surface_faces(Mesh::new(welded.positions.iter().map(|&p| h.grid.to_grid(p)).collect(), welded.faces));
        if input.faces.is_empty() {
            return Err(InputError(format!(
                "every face is degenerate: the mesh has no area to code (each of its {} faces has corners that coincide \
                 or lie on one line once coincident vertices are merged)",
                mesh.faces.len()
            )));
        }
        limits::check_valence(&input)?;
        let target = Bvh::new(&input.positions, &input.faces);
        let same_topology = self.references.last().is_some_and(|s| tracking::same_connectivity(&s.reference.input, &input));
        let (predicted, anchor_seconds) = self.best_predicted(&input, &target)?;
        let (chosen, rejected_bytes) = self.choose(predicted, &input, &target)?;
        let unit = bitstream::write_unit(chosen.candidate.head.frame_type, &chosen.candidate.payload);
        let c = chosen.candidate;
        let stats = FrameStats {
            frame_type: Some(c.head.frame_type),
            reference_distance: chosen.reference_distance,
            bytes: unit.len(),
            base_bytes: c.head.base_block.len() + c.head.refresh_block.len(),
            refreshed_faces: c.head.refreshed_faces,
            displacement_bytes: c.displacement_bytes,
            base_vertices: c.state.base.len(),
            base_faces: c.state.faces.len(),
            output_vertices: c.reconstruction.positions.len(),
            output_faces: c.reconstruction.faces.len(),
            dropped_faces: mesh.faces.len() - input.faces.len(),
            same_topology,
            rejected_bytes,
            anchor_seconds,
            seconds: start.elapsed().as_secs_f64(),
        };
        let base = Mesh::new(base_in_world_units(&self.header, &c.state.base), c.state.faces.clone());
        let intra = c.head.frame_type == FrameType::Intra;
        let reference = Reference { input, state: c.state, motion: chosen.motion, surface: target };
        self.keep_reference(Stored { frame: self.frame, intra, reference });
        self.frame += 1;
        Ok(EncodedFrame { unit, reconstruction: c.reconstruction, base, stats })
    }

    /// Adds the frame just coded to the references and forgets those no later frame may try.
    fn keep_reference(&mut self, stored: Stored) {
        self.references.push(stored);
        let recent = self.references.len().saturating_sub(self.config.references as usize);
        let latest_intra = self.references.iter().rposition(|s| s.intra).filter(|_| self.config.intra_reference);
        let kept = std::mem::take(&mut self.references).into_iter().enumerate();
        self.references = kept.filter(|(i, _)| *i >= recent || Some(*i) == latest_intra).map(|(_, s)| s).collect();
    }

    /// The references this frame tries, most recent first.
    fn reference_candidates(&self) -> Vec<&Stored> {
        let recent = self.references.len().saturating_sub(self.config.references as usize);
        let mut candidates: Vec<&Stored> = self.references[recent..].iter().rev().collect();
        if self.config.intra_reference {
            if let Some(intra) = self.references[..recent].iter().rev().find(|s| s.intra) {
                candidates.push(intra);
            }
        }
        candidates
    }

    /// The frame predicted from the reference whose input lies closest to this one (None
    /// for the first frame of a group, or when no reference can be moved onto the input),
    /// and the seconds spent moving the reference's base onto the input.
    fn best_predicted(&self, input: &Mesh, target: &Bvh) -> Result<(Option<Chosen>, f64), InputError> {
        if self.frame % self.config.intra_period == 0 {
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

    /// Of the references this frame may try, the one whose input lies closest to `input`:
    /// the previous coded frame, or an older one whose input has this input's connectivity
    /// and moved less to it (mean squared motion of at most [`REFERENCE_SAMPLES`] vertices
    /// against the previous frame's, which is measured to its surface when the connectivity
    /// changed; the most recent on a tie). A frame close to its reference costs little motion
    /// and few coefficient differences, and measuring that is far cheaper than coding the
    /// frame from each reference: horse_gallop returns to its first pose after 24 frames, and
    /// frame 24 is then predicted from frame 0. Older references of another connectivity
    /// are not tried: the distance between surfaces took a gear turned by two teeth less one
    /// frame's turn for a closer reference than the previous frame, from which the turn is
    /// known.
    fn closest_reference(&self, input: &Mesh) -> Option<&Stored> {
        let tried: Vec<(&Stored, bool)> = (self.reference_candidates().into_iter().enumerate())
            .map(|(i, s)| (i, s, tracking::same_connectivity(&s.reference.input, input)))
            .filter(|&(i, _, same)| same || (i == 0 && self.config.inter.is_some()))
            .map(|(_, s, same)| (s, same))
            .collect();
        if tried.len() < 2 {
            return tried.first().map(|&(s, _)| s);
        }
        let step = input.positions.len().div_ceil(REFERENCE_SAMPLES).max(1);
        let sampled = || input.positions.iter().enumerate().step_by(step);
        let distance = |r: &Reference, same: bool| -> f64 {
            if same {
                sampled().map(|(v, &p)| sub(p, r.input.positions[v])).map(|d| dot(d, d)).sum()
            } else {
                sampled().map(|(_, &p)| r.surface.closest_point(p).map_or(0.0, |h| h.dist2)).sum()
            }
        };
        let mut best: Option<(&Stored, f64)> = None;
        for (s, same) in tried {
            let d = distance(&s.reference, same);
            if best.map_or(true, |(_, bd)| d < bd) {
                best = Some((s, d));
            }
        }
        best.map(|(s, _)| s)
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
            let stages = self.config.inter?;
            let params = AnchorParams { stages, rigid_align: self.config.rigid_align, motion_parts: self.config.motion_parts, repair_folds: self.config.fold_repair };
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
        let moved = if self.config.refit { refit_base(&Mesh::new(moved, r.state.faces.clone()), &self.header.schemes, target) } else { moved };
        let base_grid = self.header.grid.coarser(self.header.base_bits);
        moved.iter().map(|&p| base_grid.quantize(base_grid.to_grid(p))).collect()
    }
    /// The frame coded intra; its distortion is measured only when `measured`.
    fn intra(&self, input: &Mesh, target: &Bvh, measured: bool) -> Result<Candidate, InputError> {
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
        let (h, qp) = (&self.header, self.config.qp);
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

    /// The candidate to keep, and the bytes of the other one if it was coded (else 0).
    ///
    /// A rate-distortion decision: the test model keeps inter unless intra wins by a fixed
    /// PSNR margin whatever the rates; here the PSNR the predicted frame loses is weighed
    /// against the rate it saves, at the exchange rate `rd_slope_db`. The predicted frame is
    /// first held against the last intra frame's (rate, distortion); only when it loses
    /// there is this frame also coded intra, and the predicted frame with its worst-fitting
    /// regions refreshed from the intra candidate's base ([`Self::refreshed`]) tried in its
    /// place when it costs less; this spares most predicted frames a second encoding.
    fn choose(&mut self, predicted: Option<Chosen>, input: &Mesh, target: &Bvh) -> Result<(Chosen, usize), InputError> {
        // All-intra streams make no decision: their distortion is not estimated.
        let measured = self.config.intra_period > 1;
        let intra = |s: &Self| -> Result<Chosen, InputError> {
            let candidate = s.intra(input, target, measured)?;
            Ok(Chosen { candidate, reference_distance: 0, motion: None })
        };
        let Some(p) = predicted else {
            let i = intra(self)?;
            self.last_intra = measured.then_some((i.candidate.payload.len(), i.candidate.distortion));
            return Ok((i, 0));
        };
        if let Some((bytes, di)) = self.last_intra {
            if self.rd_prefers(self.frame_bytes(&p), p.candidate.distortion, bytes + self.texture_bytes(true), di) {
                return Ok((p, 0));
            }
        }
        let i = intra(self)?;
        self.last_intra = Some((i.candidate.payload.len(), i.candidate.distortion));
        let prefers = |s: &Self, a: &Chosen, b: &Chosen| s.rd_prefers(s.frame_bytes(a), a.candidate.distortion, s.frame_bytes(b), b.candidate.distortion);
        let rejected = |c: &Chosen| c.candidate.payload.len();
        let (p, passed_over) = match self.refreshed(&p, &i, input, target)? {
            Some(r) if !prefers(self, &p, &r) => (r, None),
            r => (p, r),
        };
        if prefers(self, &p, &i) {
            return Ok((p, rejected(&i)));
        }
        // A refreshed frame that lost to the plain predicted one may still beat intra: with
        // texture both start a texture group, and then the refresh costs intra's texture too.
        Ok(match passed_over {
            Some(r) if prefers(self, &r, &i) => (r, rejected(&i)),
            _ => (i, rejected(&p)),
        })
    }

    /// The bytes of a candidate with what its texture will cost ([`TextureCost`]).
    fn frame_bytes(&self, c: &Chosen) -> usize {
        let previous = self.references.iter().find(|s| s.frame + 1 == self.frame);
        let restarts = c.candidate.head.frame_type == FrameType::Intra || previous.is_none_or(|s| s.reference.state.faces != c.candidate.state.faces);
        c.candidate.payload.len() + self.texture_bytes(restarts)
    }

    /// What the texture of a frame that continues (or restarts) its texture group costs.
    fn texture_bytes(&self, restarts: bool) -> usize {
        self.texture_cost.map_or(0, |t| (if restarts { t.restarted } else { t.continued }).max(0.0).round() as usize)
    }

    /// The predicted frame `p` with the regions its moved base fits worst refreshed from
    /// the intra candidate `i`'s base (see [`refresh`]), or None when no region is poor or
    /// the base was tracked (its connectivity is the input's).
    fn refreshed(&self, p: &Chosen, i: &Chosen, input: &Mesh, target: &Bvh) -> Result<Option<Chosen>, InputError> {
        if !self.config.refresh || !matches!(p.motion, Some(Motion::Anchor(_))) {
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

    /// True when a predicted frame of `p_bytes` and distortion `dp` beats an intra frame of
    /// `i_bytes` and `di`: its PSNR loss is at most `rd_slope_db` per halving of the rate.
    fn rd_prefers(&self, p_bytes: usize, dp: f64, i_bytes: usize, di: f64) -> bool {
        let loss_db = 10.0 * (dp.max(f64::MIN_POSITIVE) / di.max(f64::MIN_POSITIVE)).log10();
        let rate_saving = (i_bytes as f64 / p_bytes as f64).log2();
        loss_db <= self.config.rd_slope_db * rate_saving
    }

    /// The positions of a reconstruction (in the input's units) in grid units.
    fn in_grid_units(&self, reconstruction: &Mesh) -> Vec<[f64; 3]> {
        reconstruction.positions.iter().map(|&p| self.header.grid.to_grid(p)).collect()
    }

    /// An estimate of D1 that needs no sampling, in grid units: the larger of the two
    /// directions' squared distances from one surface to the other, measured at face
    /// centroids and weighted by face area. D1 samples both surfaces uniformly, so a few
    /// stretched or folded triangles weigh what their area weighs, and a finely tessellated
    /// part of the input (hands, a face) no more than its area: weighting the input's
    /// vertices instead made predicted frames look 2-4 dB worse than D1 finds them.
    fn distortion(&self, reconstruction: &Mesh, input: &Mesh, target: &Bvh) -> f64 {
        let rec = self.in_grid_units(reconstruction);
        let forward = area_weighted_squared_distance(&rec, &reconstruction.faces, target);
        let backward = area_weighted_squared_distance(&input.positions, &input.faces, &Bvh::new(&rec, &reconstruction.faces));
        forward.max(backward)
    }
}

/// Mean squared distance from the surface `(positions, faces)` to `surface`, sampled at face
/// centroids and weighted by face area (0 for a surface without area).
fn area_weighted_squared_distance(positions: &[[f64; 3]], faces: &[[u32; 3]], surface: &Bvh) -> f64 {
    // Summed in order after the parallel map: a parallel reduction's grouping depends on
    // the thread scheduling, and the decision it feeds must not, or streams would differ
    // from run to run (and between a sequential and a parallel encode).
    let terms: Vec<(f64, f64)> = faces.par_iter().map(|f| surface.area_weighted_dist2(f.map(|v| positions[v as usize]))).collect();
    let (weighted, area) = terms.iter().fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
    if area > 0.0 { weighted / area } else { 0.0 }
}

/// Decimates the input (grid units), refits the base mesh so that its subdivision fits the
/// input `surface` (with `cfg.refit`) and codes the quantized base mesh.
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
    let refitted = if cfg.refit { refit_base(&base, &h.schemes, surface) } else { base.positions };
    let base_grid = h.grid.coarser(h.base_bits);
    let positions: Vec<[u32; 3]> = refitted.iter().map(|&p| base_grid.quantize(base_grid.to_grid(p))).collect();
    Ok(encode_base(&positions, &base.faces, h.base_bits))
}

/// The most base faces a decimation to `target` faces may leave before the input is
/// refused: generous for meshes with a few small pieces (a captured frame's loose buttons),
/// far below what a triangle soup leaves.
pub fn max_base_faces(target: usize) -> usize {
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

    /// Squares of side 1 at `x0 <= x <= x0 + 1`, `0 <= y <= 1`, height `z`, split `n` x `n`.
    fn square(x0: f64, z: f64, n: u32, mesh: &mut Mesh) {
        let first = mesh.positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                mesh.positions.push([x0 + i as f64 / n as f64, j as f64 / n as f64, z]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let v = first + j * (n + 1) + i;
                mesh.faces.push([v, v + 1, v + n + 2]);
                mesh.faces.push([v, v + n + 2, v + n + 1]);
            }
        }
    }

    #[test]
    fn differences_within_the_dead_zone_of_the_reference_are_zero() {
        // 2.6 rounds to 2 on its own (dead zone), which would leave -1 against a reference of 3.
        // Beyond the dead zone (one step) differences are rounded as intra coefficients are.
        assert_eq!(differences_from(&[2.6, -0.2, 5.0, -4.9, 7.7], &[3, 0, 3, -3, 2], |_| 1.0), vec![0, 0, 2, -2, 6]);
    }

    /// Whether the predicted candidate of `next` (coded after `first`, at QP 16) codes its
    /// coefficients as differences from the first frame's.
    fn codes_differences(first: &Mesh, next: &Mesh) -> bool {
        let cfg = EncoderConfig { qp: 16, ..Default::default() };
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

    #[test]
    fn squared_distance_weighs_area_not_tessellation() {
        let mut plane = Mesh::default();
        square(0.0, 0.0, 1, &mut plane);
        square(1.0, 0.0, 1, &mut plane);
        // Half of the surface lies 1 above the plane, finely tessellated; the other half on it.
        let mut m = Mesh::default();
        square(0.0, 1.0, 8, &mut m);
        square(1.0, 0.0, 1, &mut m);
        let d = area_weighted_squared_distance(&m.positions, &m.faces, &Bvh::new(&plane.positions, &plane.faces));
        assert!((d - 0.5).abs() < 1e-9, "{d}");
        assert_eq!(area_weighted_squared_distance(&[[0.0; 3]; 3], &[[0, 1, 2]], &Bvh::new(&plane.positions, &plane.faces)), 0.0);
    }
}
