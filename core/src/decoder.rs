//! The decoder: frame units back to meshes.
//!
//! [`reconstruct`] is the single place where quantized coefficients become positions; the
//! encoder calls it too, which is what makes the two agree bit for bit.

use crate::basecoder;
use crate::bitstream::{self, FrameType, Reader, SequenceHeader, Unit};
use crate::coefcoder;
use crate::displace;
use crate::ec;
use crate::error::DecodeError;
use crate::grid::Grid;
use crate::mesh::Mesh;
use crate::quantize;
use crate::subdivide::{subdivide, Subdivision};
use crate::transform;

/// Largest subdivided mesh a stream may ask for; a bound on what a hostile stream can make
/// the decoder allocate.
pub const MAX_OUTPUT_FACES: usize = 1 << 25;
/// Output faces a frame may ask for per byte of its unit, beyond a floor of
/// `MIN_FACE_ALLOWANCE`: so that a few corrupt bytes cannot make the decoder allocate
/// gigabytes. Real streams need well under 100 (a 15 KB frame decodes to ~400k faces); the
/// encoder refuses to write a frame beyond this allowance.
pub const FACES_PER_UNIT_BYTE: usize = 512;
pub const MIN_FACE_ALLOWANCE: usize = 1 << 20;

/// The most output faces a frame unit of `unit_bytes` bytes may decode to.
pub fn face_allowance(unit_bytes: usize) -> usize {
    unit_bytes.saturating_mul(FACES_PER_UNIT_BYTE).clamp(MIN_FACE_ALLOWANCE, MAX_OUTPUT_FACES)
}

/// What the payload of an intra frame carries.
pub struct IntraPayload<'a> {
    pub qp: i32,
    pub base: &'a [u8],
    pub base_offset: u64,
    pub coefficients: &'a [u8],
    pub coefficients_offset: u64,
}

/// A parsed stream: its header and its frame units (checked lengths and CRCs).
pub struct Stream<'a> {
    pub header: SequenceHeader,
    pub units: Vec<Unit<'a>>,
}

/// Parses the container; frames are decoded one by one with [`decode_frame`].
pub fn open(data: &[u8]) -> Result<Stream<'_>, DecodeError> {
    let (header, start) = bitstream::read_header(data)?;
    let units = bitstream::read_units(data, start, header.frame_count)?;
    Ok(Stream { header, units })
}

/// Decodes frame `index` of `stream` into a mesh in the input's units.
pub fn decode_frame(stream: &Stream, index: u32) -> Result<Mesh, DecodeError> {
    let unit = stream
        .units
        .get(index as usize)
        .ok_or_else(|| DecodeError::new(Some(index), 0, "no such frame"))?;
    decode_unit(&stream.header, unit, index)
}

/// Decodes one frame unit of a stream with header `h`; `index` names it in errors.
pub fn decode_unit(h: &SequenceHeader, unit: &Unit, index: u32) -> Result<Mesh, DecodeError> {
    match unit.frame_type {
        FrameType::Intra => decode_intra(h, unit, index),
    }
}

/// Splits an intra payload into its fields.
pub fn read_intra_payload<'a>(unit: &Unit<'a>, frame: u32) -> Result<IntraPayload<'a>, DecodeError> {
    let mut r = Reader::new(unit.payload, unit.offset, Some(frame));
    let qp = r.i32("QP")?;
    if !quantize::QP_RANGE.contains(&qp) {
        return Err(r.error(format!("QP {qp} out of range")));
    }
    let (base, base_offset) = r.block("base mesh")?;
    let (coefficients, coefficients_offset) = r.block("displacements")?;
    if r.remaining() != 0 {
        return Err(r.error("unexpected bytes at the end of the frame"));
    }
    Ok(IntraPayload { qp, base, base_offset, coefficients, coefficients_offset })
}

fn decode_intra(h: &SequenceHeader, unit: &Unit, frame: u32) -> Result<Mesh, DecodeError> {
    let p = read_intra_payload(unit, frame)?;
    let (positions, faces) = basecoder::decode_base(p.base, h.base_bits)
        .map_err(|e| DecodeError::new(Some(frame), p.base_offset, format!("base mesh: {e}")))?;
    let too_big = faces.len().saturating_mul(1usize << (2 * h.subdiv_iterations)) > face_allowance(unit.payload.len());
    if faces.is_empty() || too_big {
        let reason = format!("base mesh of {} faces cannot be subdivided {} times", faces.len(), h.subdiv_iterations);
        return Err(DecodeError::new(Some(frame), p.base_offset, reason));
    }
    let sub = subdivided_base(h, &positions, &faces);
    let frames = displace::local_frames(&sub.positions, &sub.faces);
    let mut dec = ec::Decoder::new(p.coefficients);
    let q = coefcoder::decode(&mut dec, h.components as usize, &sub)
        .ok_or_else(|| DecodeError::new(Some(frame), p.coefficients_offset, "displacement data is truncated or corrupt"))?;
    Ok(reconstruct(h, &sub, &frames, &q, p.qp))
}

/// Subdivision of the decoded base mesh (integer positions on the base mesh grid).
pub fn subdivided_base(h: &SequenceHeader, positions: &[[u32; 3]], faces: &[[u32; 3]]) -> Subdivision {
    let base_grid = h.grid.coarser(h.base_bits);
    let p: Vec<[f64; 3]> = positions.iter().map(|q| base_grid.to_world(q.map(|c| c as f64))).collect();
    subdivide(&p, faces, h.subdiv_iterations, h.scheme)
}

/// Positions of the decoded frame: dequantize, inverse-transform, apply the displacements
/// in the local frames, map back to the input's units.
pub fn reconstruct(h: &SequenceHeader, sub: &Subdivision, frames: &[[[f64; 3]; 3]], q: &[i32], qp: i32) -> Mesh {
    let comps = h.components as usize;
    let scales = quantize::lod_scales(qp, h.grid.bits, sub.lod_count());
    let mut local: Vec<[f64; 3]> = (0..sub.positions.len())
        .map(|v| {
            let s = quantize::scale_of(v, &sub.lod_offsets, &scales);
            std::array::from_fn(|k| if k < comps { quantize::dequantize(q[v * comps + k], s) } else { 0.0 })
        })
        .collect();
    transform::inverse(&mut local, sub);
    let world = displace::to_world(&local, frames);
    let positions = sub.positions.iter().zip(&world).map(|(p, d)| to_world(&h.grid, *p, *d)).collect();
    Mesh::new(positions, sub.faces.clone())
}

fn to_world(grid: &Grid, p: [f64; 3], d: [f64; 3]) -> [f64; 3] {
    grid.to_world([p[0] + d[0], p[1] + d[1], p[2] + d[2]])
}
