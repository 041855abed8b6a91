//! The reconstruction model that encoder and decoder share: how a frame's decoded base mesh
//! and quantized coefficients become its output mesh.
//!
//! [`FrameModel::reconstruct`] is the single place where quantized coefficients become
//! positions; the encoder calls it on the very values it writes, which is what makes the two
//! sides agree bit for bit. [`FrameState`] is what a frame leaves for the frames predicted
//! from it, on both sides.

use crate::geom::mesh::Mesh;
use crate::residual::displace::{self, Frame};
use crate::residual::quantize;
use crate::residual::subdivide::{subdivide, Subdivision};
use crate::residual::transform;
use crate::stream::bitstream::SequenceHeader;

/// Largest subdivided mesh a stream may ask for; a bound on what a hostile stream can make
/// the decoder allocate. A decode to OBJ peaks at about 190 bytes per output face (1.96M
/// faces: 368 MB), so 2^23 faces keep it near 1.6 GB (2^25 would have been 6 GB). The largest
/// input frame (`limits::MAX_INPUT_FACES`) at the largest default base ratio and three
/// subdivisions makes 7.9M faces, within it.
pub const MAX_OUTPUT_FACES: usize = 1 << 23;
/// Output faces a frame may ask for per byte of its unit, beyond a floor of
/// `MIN_FACE_ALLOWANCE`: so that a few corrupt bytes cannot make the decoder allocate
/// gigabytes. Real streams need well under 100 (a 15 KB frame decodes to ~400k faces); the
/// encoder refuses to write a frame beyond this allowance.
pub const FACES_PER_UNIT_BYTE: usize = 512;
pub const MIN_FACE_ALLOWANCE: usize = 1 << 20;

/// The most output faces a frame payload of `payload_bytes` bytes may decode to.
pub fn face_allowance(payload_bytes: usize) -> usize {
    payload_bytes.saturating_mul(FACES_PER_UNIT_BYTE).clamp(MIN_FACE_ALLOWANCE, MAX_OUTPUT_FACES)
}

/// What a predicted frame takes from its reference: the base mesh (positions on the base
/// grid, faces) and the quantized displacement coefficients.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameState {
    pub base: Vec<[u32; 3]>,
    pub faces: Vec<[u32; 3]>,
    pub coefficients: Vec<i32>,
}

/// Base mesh positions on the base mesh grid, in units of the full-resolution grid.
pub fn base_in_grid_units(h: &SequenceHeader, positions: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let base_grid = h.grid.coarser(h.base_bits);
    positions.iter().map(|q| base_grid.to_world(q.map(|c| c as f64))).collect()
}

/// Base mesh positions on the base mesh grid, in the input's units: the base mesh that the
/// encoder reports and the decoder's `last_base` gives, bit for bit the same.
pub fn base_in_world_units(h: &SequenceHeader, positions: &[[u32; 3]]) -> Vec<[f64; 3]> {
    base_in_grid_units(h, positions).into_iter().map(|p| h.grid.to_world(p)).collect()
}

/// The first `iterations` subdivision iterations of the stream's schemes applied to the
/// decoded base mesh (positions on the base grid): all of them for a full decode, fewer at
/// a lower level of detail.
pub fn subdivided_base(h: &SequenceHeader, positions: &[[u32; 3]], faces: &[[u32; 3]], iterations: usize) -> Subdivision {
    subdivide(&base_in_grid_units(h, positions), faces, &h.schemes[..iterations])
}

/// One frame's reconstruction model: the stream's header, its subdivided base mesh, the
/// local frames the displacements are expressed in and the vertices' quantization scales
/// at the frame's QP.
pub struct FrameModel<'h> {
    header: &'h SequenceHeader,
    pub sub: Subdivision,
    /// The local (normal, tangent, bitangent) frame of each vertex of `sub`.
    pub frames: Vec<Frame>,
    /// The quantization scale of each vertex of `sub`.
    scales: Vec<f64>,
}

impl<'h> FrameModel<'h> {
    pub fn new(header: &'h SequenceHeader, qp: i32, sub: Subdivision) -> Self {
        let frames = displace::local_frames(&sub.positions, &sub.faces);
        let scales = vertex_scales(header, qp, &sub);
        Self { header, sub, frames, scales }
    }

    /// The values the quantizer rounds, `components` per vertex: the forward lifting of the
    /// `local` displacement components, scaled per level (and, with AQ, per vertex) into
    /// quantization steps and shifted by AQ's lattice offset.
    pub fn coefficient_steps(&self, local: &[[f64; 3]]) -> Vec<f64> {
        let h = self.header;
        let comps = h.components as usize;
        let mut signal = local.to_vec();
        transform::forward(&mut signal, &self.sub, &h.lifting);
        let offset = h.aq.map_or(0.0, |a| a.delta);
        let mut x = Vec::with_capacity(signal.len() * comps);
        for (c, &s) in signal.iter().zip(&self.scales) {
            x.extend((0..comps).map(|k| quantize::steps(c[k], s, offset)));
        }
        x
    }

    /// The decoded frame in the input's units: dequantize `q`, inverse-transform, apply the
    /// displacements in the local frames, map back from the grid.
    pub fn reconstruct(&self, q: &[i32]) -> Mesh {
        let h = self.header;
        let comps = h.components as usize;
        let offset = h.aq.map_or(0.0, |a| a.delta);
        let dequantized = |(v, s): (usize, f64)| -> [f64; 3] {
            std::array::from_fn(|k| if k < comps { quantize::dequantize_shifted(q[v * comps + k], s, offset) } else { 0.0 })
        };
        let mut local: Vec<[f64; 3]> = self.scales.iter().copied().enumerate().map(dequantized).collect();
        transform::inverse(&mut local, &self.sub, &h.lifting);
        let world = displace::to_world(&local, &self.frames);
        let positions = self.sub.positions.iter().zip(&world).map(|(p, d)| h.grid.to_world([p[0] + d[0], p[1] + d[1], p[2] + d[2]])).collect();
        Mesh::new(positions, self.sub.faces.clone())
    }
}

/// The quantization scale of every vertex of `sub`: its level's scale at `qp`, times its
/// adaptive weight when the stream uses adaptive quantization.
fn vertex_scales(h: &SequenceHeader, qp: i32, sub: &Subdivision) -> Vec<f64> {
    let scales = quantize::lod_scales(qp, h.grid.bits, sub.lod_count());
    let weights = quantize::vertex_weights(sub.positions.len(), &sub.faces, h.aq.as_ref());
    weights.iter().enumerate().map(|(v, w)| w * quantize::scale_of(v, &sub.lod_offsets, &scales)).collect()
}
