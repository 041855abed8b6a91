//! The encoder's options: what a user may choose, checked against what the format can
//! carry, and the sequence header they give.

use crate::decoder;
use crate::error::InputError;
use crate::geom::grid::{Grid, BITS_RANGE};
use crate::inter::anchor::AnchorStages;
use crate::residual::quantize::{self, AqParams};
use crate::residual::subdivide::SchemeChoice;
use crate::residual::transform;
use crate::stream::bitstream::{self, SequenceHeader};

/// The lifting transform's update step (see `transform::Lifting`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LiftingChoice {
    /// The MPEG test model's level-dependent weights divided by each parent's valence.
    PerValence,
    /// 1/8 of each residual to each parent at every level.
    Constant,
}

impl LiftingChoice {
    pub const NAMES: [&'static str; 2] = ["valence", "constant"];

    pub fn from_name(name: &str) -> Option<Self> {
        let choices = [Self::PerValence, Self::Constant];
        Self::NAMES.iter().position(|&n| n == name).map(|i| choices[i])
    }

    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    fn weights(self, iterations: usize) -> transform::Lifting {
        match self {
            Self::PerValence => transform::Lifting::per_valence(iterations),
            Self::Constant => transform::Lifting::constant(iterations),
        }
    }
}

/// Encoder options. The defaults are the codec's recommended operating point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EncoderConfig {
    /// What the stream carries: the sequence header and the payloads hold these, and the
    /// decoder reads them.
    pub format: FormatParams,
    /// How the encoder finds what it codes: the decoder never sees these.
    pub search: SearchParams,
}

/// The options that shape the bitstream ([`EncoderConfig::format`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FormatParams {
    /// Quantization parameter of the displacements: +6 doubles the step.
    pub qp: i32,
    /// Subdivision iterations of the base mesh (the levels of detail).
    pub subdiv_iterations: u32,
    /// The subdivision scheme of each iteration.
    pub scheme: SchemeChoice,
    /// Position bit depth of the grid over the sequence box.
    pub bits: u32,
    /// Position bit depth of the base mesh (at most `bits`): coarser base positions cost
    /// fewer bits and the displacements correct them. The default, 9, has the best D1
    /// BD-rate against the test model of 8 to 11 bits over the whole QP range
    /// (docs/results.md); per rate point, though, 8 bits codes QP 32 and 36 in 3.5-6.2 %
    /// fewer bytes for about 0.1 dB less, and costs more at the lower QPs.
    pub base_bits: u32,
    /// Code only the normal component of each displacement.
    pub normal_only: bool,
    /// The lifting transform's update weights.
    pub lifting: LiftingChoice,
    /// Adaptive displacement quantization, or `None` for one scale per level.
    pub aq: Option<AqParams>,
}

/// The encoder's search and decision settings ([`EncoderConfig::search`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SearchParams {
    /// Base mesh faces as a fraction of the input's; `None` follows the QP
    /// ([`base_ratio_for_qp`]).
    pub base_ratio: Option<f64>,
    /// Frames per group: every `intra_period`-th frame is intra; 1 makes every frame intra.
    pub intra_period: u32,
    /// How predicted frames find their base mesh when the input's connectivity changed: the
    /// anchor mesh built by these stages, or `None` to predict only frames whose input has
    /// the reference input's connectivity (the MPEG test model's behaviour; every topology
    /// change then forces an intra frame).
    pub inter: Option<AnchorStages>,
    /// The exchange rate of the intra/inter decision, in dB of PSNR per doubling of the
    /// rate (the local slope of the codec's RD curve): a frame is predicted when the PSNR it
    /// loses against intra is at most `rd_slope_db * log2(intra bytes / predicted bytes)`.
    pub rd_slope_db: f64,
    /// Refit the base mesh so that its subdivision fits the input, before it is quantized:
    /// an intra frame's decimated base and a predicted frame's anchor (not a tracked base).
    pub refit: bool,
    /// Repair folded anchor triangles before their motion is coded (`anchor::folds`; not a
    /// stage of the paper).
    pub fold_repair: bool,
    /// Move each part of the reference base rigidly onto the input before the anchor's
    /// matching (`anchor::rigid`; not a stage of the paper).
    pub rigid_align: bool,
    /// ... and cut each connected part into the parts that move apart inside it, found by
    /// their rigid fits (`anchor::parts`; not a stage of the paper), with `rigid_align`.
    pub motion_parts: bool,
    /// Code the regions an anchored base fits worst intra inside the predicted frame
    /// (`inter::refresh`; not a stage of the paper).
    pub refresh: bool,
    /// Predicted frames may refer to any of the last `references` coded frames of their
    /// group (1 = the previous frame only); which one, `SequenceEncoder::closest_reference`
    /// says (an older one only when its input has the frame's connectivity).
    pub references: u32,
    /// Predicted frames may also refer to the group's latest intra frame (same rule).
    pub intra_reference: bool,
    /// Code every predicted frame intra too, and try its refresh, before deciding (ours).
    /// Off, a predicted frame that beats the last intra frame's rate and distortion is kept
    /// without coding this frame intra, which spares most frames a second encoding but keeps
    /// some that their own intra frame or refresh would beat.
    pub always_try_intra: bool,
    /// ... and, without it, code a frame predicted through the anchor intra too (and try its
    /// refresh) when its estimated distortion lies more than this many dB above the last
    /// intra frame's, or above the lowest of the group's frames coded intra (one hard frame
    /// coded intra must not make the next ones look good), even though its rate beats the
    /// last intra frame's (ours; infinite: never).
    pub intra_check_db: f64,
}

impl Default for FormatParams {
    fn default() -> Self {
        Self {
            qp: 28,
            subdiv_iterations: 2,
            scheme: SchemeChoice::Mixed,
            bits: 12,
            base_bits: 9,
            normal_only: true,
            lifting: LiftingChoice::PerValence,
            aq: Some(AqParams::default()),
        }
    }
}

impl Default for SearchParams {
    fn default() -> Self {
        Self {
            base_ratio: None,
            intra_period: 32,
            inter: Some(AnchorStages::NnsMeProj),
            rd_slope_db: 4.0,
            refit: true,
            fold_repair: true,
            rigid_align: true,
            motion_parts: false,
            refresh: true,
            references: 1,
            intra_reference: true,
            always_try_intra: false,
            intra_check_db: 2.0,
        }
    }
}

impl EncoderConfig {
    /// Refuses options outside what the format can carry.
    pub fn validate(&self) -> Result<(), InputError> {
        let err = |m: String| Err(InputError(m));
        if !quantize::QP_RANGE.contains(&self.format.qp) {
            return err(format!("qp {} is out of range: it must be from {} to {}", self.format.qp, quantize::QP_RANGE.start(), quantize::QP_RANGE.end()));
        }
        if !(self.base_ratio() > 0.0 && self.base_ratio() <= 1.0) {
            return err(format!("base ratio {} must be above 0 and at most 1", self.base_ratio()));
        }
        if self.format.subdiv_iterations > bitstream::MAX_SUBDIV {
            return err(format!("subdivision iterations {} (at most {})", self.format.subdiv_iterations, bitstream::MAX_SUBDIV));
        }
        self.format.scheme.schemes(self.format.subdiv_iterations).map_err(InputError)?;
        if !BITS_RANGE.contains(&self.format.bits) {
            return err(format!("position bits {} is out of range: it must be from {} to {}", self.format.bits, BITS_RANGE.start(), BITS_RANGE.end()));
        }
        if !BITS_RANGE.contains(&self.format.base_bits) || self.format.base_bits > self.format.bits {
            return err(format!("base mesh position bits {} must be from {} to {} (the position bits)", self.format.base_bits, BITS_RANGE.start(), self.format.bits));
        }
        if self.search.intra_period == 0 {
            return err("intra period must be at least 1".into());
        }
        if let Some(aq) = &self.format.aq {
            if !aq.is_valid() {
                return err(format!("adaptive quantization needs alpha > 0, h > 0 and |delta| < 1, got {aq:?}"));
            }
        }
        if !(1..=MAX_REFERENCES).contains(&self.search.references) {
            return err(format!("references {} is out of range: it must be from 1 to {MAX_REFERENCES}", self.search.references));
        }
        if self.search.intra_check_db.is_nan() {
            return err("intra check dB must be a number (inf: never)".to_string());
        }
        if !(self.search.rd_slope_db.is_finite() && self.search.rd_slope_db >= 0.0) {
            return err(format!("rd slope {} must be finite and non-negative", self.search.rd_slope_db));
        }
        Ok(())
    }

    /// Base mesh faces per input face: as given, else as the QP asks.
    pub fn base_ratio(&self) -> f64 {
        self.search.base_ratio.unwrap_or_else(|| base_ratio_for_qp(self.format.qp))
    }

    /// The sequence header for `frame_count` frames inside the box `[min, max]`.
    pub fn header(&self, frame_count: u32, min: [f64; 3], max: [f64; 3]) -> SequenceHeader {
        SequenceHeader {
            frame_count,
            grid: Grid::over_box(min, max, self.format.bits),
            base_bits: self.format.base_bits,
            schemes: self.format.scheme.schemes(self.format.subdiv_iterations).expect("validated configuration"),
            lifting: self.format.lifting.weights(self.format.subdiv_iterations as usize),
            components: if self.format.normal_only { 1 } else { 3 },
            aq: self.format.aq,
        }
    }
}

/// The most recent frames a predicted frame may try as its reference: as many as the
/// decoder keeps, so that decoding in order never decodes a frame twice.
pub const MAX_REFERENCES: u32 = decoder::CACHED_STATES as u32;

/// The base mesh size that suits displacements quantized with `qp`: coarse displacements
/// (high QP) go with a small base mesh, fine ones pay for a larger base mesh that follows
/// the input closer. Chosen by sweeps over base ratio (3 to 20 %), base bits (8 to 11),
/// subdivision iterations (2, 3) and QP (20 to 36 in steps of 2) on the first 6 frames of
/// four capture sequences, against the MPEG test model's points (docs/results.md). With
/// the default two iterations, 12 % below QP 26, 9 % to 29 and 6 % from 30 was best on all
/// four (2026-12-03, D1 BD-rate against the test model with three iterations and 12 / 6 / 4 %
/// -> two and these: -10.9 -> -12.5 % basketball_player, -6.6 -> -8.9 % dancer, -7.0 ->
/// -10.8 % mitch, -16.1 -> -18.1 % thomas); with a quarter of the output faces, encoding
/// and decoding are faster too.
pub fn base_ratio_for_qp(qp: i32) -> f64 {
    match qp {
        30.. => 0.06,
        26..=29 => 0.09,
        _ => 0.12,
    }
}
