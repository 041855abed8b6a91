//! The encoder: one input frame to one frame unit, plus the reconstruction that the
//! decoder will produce from it.

use std::time::Instant;

use crate::basecoder;
use crate::bitstream::{self, FrameType, SequenceHeader, Writer};
use crate::bvh::Bvh;
use crate::coefcoder;
use crate::decimate::decimate;
use crate::decoder;
use crate::displace;
use crate::ec;
use crate::error::InputError;
use crate::grid::{Grid, BITS_RANGE};
use crate::mesh::Mesh;
use crate::quantize;
use crate::subdivide::Scheme;
use crate::transform;

/// Encoder options. The defaults are the codec's recommended operating point.
#[derive(Debug, Clone, PartialEq)]
pub struct EncoderConfig {
    /// Quantization parameter of the displacements: +6 doubles the step.
    pub qp: i32,
    /// Base mesh faces as a fraction of the input's.
    pub base_ratio: f64,
    pub subdiv_iterations: u32,
    pub scheme: Scheme,
    /// Position bit depth of the grid over the sequence box.
    pub bits: u32,
    /// Position bit depth of the base mesh (at most `bits`): coarser base positions cost
    /// fewer bits and the displacements correct them.
    pub base_bits: u32,
    /// Code only the normal component of each displacement.
    pub normal_only: bool,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        Self { qp: 28, base_ratio: 1.0 / 6.0, subdiv_iterations: 3, scheme: Scheme::Midpoint, bits: 12, base_bits: 9, normal_only: true }
    }
}

impl EncoderConfig {
    /// Refuses options outside what the format can carry.
    pub fn validate(&self) -> Result<(), InputError> {
        let err = |m: String| Err(InputError(m));
        if !quantize::QP_RANGE.contains(&self.qp) {
            return err(format!("qp {} out of range {:?}", self.qp, quantize::QP_RANGE));
        }
        if !(self.base_ratio > 0.0 && self.base_ratio <= 1.0) {
            return err(format!("base ratio {} must be in (0, 1]", self.base_ratio));
        }
        if self.subdiv_iterations > bitstream::MAX_SUBDIV {
            return err(format!("subdivision iterations {} (at most {})", self.subdiv_iterations, bitstream::MAX_SUBDIV));
        }
        if !BITS_RANGE.contains(&self.bits) {
            return err(format!("position bits {} out of range {:?}", self.bits, BITS_RANGE));
        }
        if !BITS_RANGE.contains(&self.base_bits) || self.base_bits > self.bits {
            return err(format!("base mesh position bits {} must be in {}..={}", self.base_bits, BITS_RANGE.start(), self.bits));
        }
        Ok(())
    }

    /// The sequence header for `frame_count` frames inside the box `[min, max]`.
    pub fn header(&self, frame_count: u32, min: [f64; 3], max: [f64; 3]) -> SequenceHeader {
        SequenceHeader {
            frame_count,
            grid: Grid::over_box(min, max, self.bits),
            base_bits: self.base_bits,
            subdiv_iterations: self.subdiv_iterations,
            scheme: self.scheme,
            components: if self.normal_only { 1 } else { 3 },
        }
    }
}

/// What encoding one frame produced.
#[derive(Debug, Clone)]
pub struct EncodedFrame {
    /// The complete frame unit, ready to append to the stream.
    pub unit: Vec<u8>,
    /// Exactly what the decoder will output for this frame.
    pub reconstruction: Mesh,
    pub stats: FrameStats,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub bytes: usize,
    pub base_bytes: usize,
    pub displacement_bytes: usize,
    pub base_vertices: usize,
    pub base_faces: usize,
    pub output_vertices: usize,
    pub output_faces: usize,
    pub seconds: f64,
}

/// Encodes `mesh` (in the input's units, inside the header's grid box) as an intra frame.
pub fn encode_intra(h: &SequenceHeader, cfg: &EncoderConfig, mesh: &Mesh) -> Result<EncodedFrame, InputError> {
    let start = Instant::now();
    mesh.validate()?;
    let input: Vec<[f64; 3]> = mesh.positions.iter().map(|&p| h.grid.to_grid(p)).collect();
    let base_bytes = base_mesh_bytes(h, cfg, &input, &mesh.faces);
    let (base_pos, base_faces) = basecoder::decode_base(&base_bytes, h.base_bits)
        .map_err(|e| InputError(format!("internal error: base mesh does not decode: {e}")))?;
    let sub = decoder::subdivided_base(h, &base_pos, &base_faces);
    let frames = displace::local_frames(&sub.positions, &sub.faces);
    let target = Bvh::new(&input, &mesh.faces);
    let world = displace::fit_displacements(&sub.positions, &sub.faces, &frames, &target, h.components == 1);
    let q = quantized_coefficients(h, cfg.qp, &sub, &displace::to_local(&world, &frames));
    let mut enc = ec::Encoder::new();
    coefcoder::encode(&mut enc, &q, h.components as usize, &sub);
    let coef_bytes = enc.finish();
    let reconstruction = decoder::reconstruct(h, &sub, &frames, &q, cfg.qp);

    let mut w = Writer::default();
    w.i32(cfg.qp);
    w.block(&base_bytes);
    w.block(&coef_bytes);
    if reconstruction.faces.len() > decoder::face_allowance(w.bytes.len()) {
        return Err(InputError(format!(
            "{} output faces from a {}-byte frame exceed what a decoder accepts; use fewer subdivision iterations",
            reconstruction.faces.len(),
            w.bytes.len()
        )));
    }
    let unit = bitstream::write_unit(FrameType::Intra, &w.bytes);
    let stats = FrameStats {
        bytes: unit.len(),
        base_bytes: base_bytes.len(),
        displacement_bytes: coef_bytes.len(),
        base_vertices: base_pos.len(),
        base_faces: base_faces.len(),
        output_vertices: reconstruction.positions.len(),
        output_faces: reconstruction.faces.len(),
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(EncodedFrame { unit, reconstruction, stats })
}

/// Decimates the input (grid units) and codes the quantized base mesh.
fn base_mesh_bytes(h: &SequenceHeader, cfg: &EncoderConfig, input: &[[f64; 3]], faces: &[[u32; 3]]) -> Vec<u8> {
    let target = ((faces.len() as f64 * cfg.base_ratio).ceil() as usize).max(1);
    let base = decimate(input, faces, target);
    let base_grid = h.grid.coarser(h.base_bits);
    let positions: Vec<[u32; 3]> = base.positions.iter().map(|&p| base_grid.quantize(base_grid.to_grid(p))).collect();
    basecoder::encode_base(&positions, &base.faces, h.base_bits)
}

/// Forward lifting and per-level quantization of the local displacement components.
fn quantized_coefficients(h: &SequenceHeader, qp: i32, sub: &crate::subdivide::Subdivision, local: &[[f64; 3]]) -> Vec<i32> {
    let comps = h.components as usize;
    let mut signal = local.to_vec();
    transform::forward(&mut signal, sub);
    let scales = quantize::lod_scales(qp, h.grid.bits, sub.lod_count());
    let mut q = Vec::with_capacity(signal.len() * comps);
    for (v, c) in signal.iter().enumerate() {
        let s = quantize::scale_of(v, &sub.lod_offsets, &scales);
        q.extend((0..comps).map(|k| quantize::quantize(c[k], s)));
    }
    q
}
