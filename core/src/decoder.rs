//! The decoder: frame units back to meshes.
//!
//! [`reconstruct`] is the single place where quantized coefficients become positions; the
//! encoder calls it too, which is what makes the two agree bit for bit. Predicted frames
//! take their base mesh from the frame they name, so [`Decoder`] walks back to the intra
//! frame that starts the chain (seeking) and keeps the states of the frames it decoded last
//! ([`StateCache`]), which later frames refer to.
//!
//! Level-of-detail decoding ([`Decoder::set_lod`]) stops after K of the stream's
//! subdivision iterations: each frame is subdivided K times, the coefficients of the levels
//! beyond K are not read (they come last in the block) and count as zero, and the frame is
//! reconstructed on the level-K mesh. At K = all iterations nothing changes.

use crate::base::coder as basecoder;
use crate::stream::bitstream::{self, FrameType, Reader, SequenceHeader, Unit};
use crate::residual::coefcoder;
use crate::residual::displace;
use crate::stream::ec;
use crate::error::DecodeError;
use crate::geom::grid::Grid;
use crate::geom::mesh::Mesh;
use crate::inter::motion;
use crate::residual::quantize;
use crate::stream::resync::{self, Damage, FrameSlot, TextureSlot};
use crate::residual::subdivide::{subdivide, Subdivision};
use crate::residual::transform;

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

/// The most output faces a frame unit of `unit_bytes` bytes may decode to.
pub fn face_allowance(unit_bytes: usize) -> usize {
    unit_bytes.saturating_mul(FACES_PER_UNIT_BYTE).clamp(MIN_FACE_ALLOWANCE, MAX_OUTPUT_FACES)
}

/// The fields of a frame payload. Intra: `qp`, base mesh block, coefficient block.
/// Predicted: reference distance, `qp`, motion block, coefficient mode, coefficient block.
pub struct Payload<'a> {
    /// Frames back to the reference (predicted frames only; 0 for intra).
    pub reference_distance: u32,
    pub qp: i32,
    /// The base mesh block (intra) or the motion block (predicted).
    pub base: &'a [u8],
    pub base_offset: u64,
    /// Predicted frames: the coefficients are differences from the reference's.
    pub coefficients_predicted: bool,
    pub coefficients: &'a [u8],
    pub coefficients_offset: u64,
}

/// What `frame_info` tells about a frame without decoding it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameInfo {
    pub frame_type: FrameType,
    pub reference: Option<u32>,
    pub qp: i32,
    pub bytes: usize,
    pub base_bytes: usize,
    pub displacement_bytes: usize,
}

/// What a predicted frame takes from its reference: the base mesh (positions on the base
/// grid, faces) and the quantized displacement coefficients.
#[derive(Clone)]
struct State {
    positions: Vec<[u32; 3]>,
    faces: Vec<[u32; 3]>,
    coefficients: Vec<i32>,
}

/// The states of recently decoded frames, which later predicted frames refer to: the last
/// [`CACHED_STATES`] decoded and the latest intra frame decoded. An encoder that chooses its
/// references among the last `CACHED_STATES` frames and the latest intra frame (as ours
/// does) thereby costs one frame's work per frame when decoded in order.
#[derive(Clone, Default)]
struct StateCache {
    /// Oldest first; the last entry is the frame decoded last.
    recent: Vec<(u32, State)>,
    intra: Option<(u32, State)>,
}

/// Decoded frames whose states the decoder keeps besides the latest intra frame's.
pub const CACHED_STATES: usize = 8;

impl StateCache {
    fn get(&self, frame: u32) -> Option<&State> {
        let recent = self.recent.iter().rev().find(|(f, _)| *f == frame);
        recent.or(self.intra.as_ref().filter(|(f, _)| *f == frame)).map(|(_, s)| s)
    }

    fn last(&self) -> Option<&(u32, State)> {
        self.recent.last()
    }

    fn insert(&mut self, frame: u32, state: State, intra: bool) {
        self.recent.retain(|(f, _)| *f != frame);
        if intra {
            self.intra = Some((frame, state.clone()));
        }
        self.recent.push((frame, state));
        if self.recent.len() > CACHED_STATES {
            self.recent.remove(0);
        }
    }
}

/// A checked stream whose frames can be decoded in any order. Predicted frames are decoded
/// from the intra frame before them, or from the nearest state on their chain that the
/// [`StateCache`] holds, so decoding in order costs one frame's work per frame. A clone
/// decodes on its own (threads decoding independent frames each take one).
#[derive(Clone)]
pub struct Decoder {
    data: Vec<u8>,
    header: SequenceHeader,
    slots: Vec<FrameSlot>,
    cache: StateCache,
    /// Subdivision iterations decoded (at most the stream's).
    lod: u32,
}

impl Decoder {
    /// Parses the header and splits the frame units, checking their lengths and CRCs; any
    /// damaged unit is an error.
    pub fn new(data: Vec<u8>) -> Result<Self, DecodeError> {
        let (header, start) = bitstream::read_header(&data)?;
        let units = bitstream::read_units(&data, start, header.frame_count)?;
        let slots = units
            .iter()
            .map(|u| FrameSlot::Intact {
                frame_type: u.frame_type,
                offset: u.offset as usize,
                len: u.payload.len(),
                texture: u.texture.map_or(TextureSlot::None, |(t, o)| TextureSlot::Intact(o as usize, t.len())),
            })
            .collect();
        let lod = header.subdiv_iterations();
        Ok(Self { header, slots, data, cache: StateCache::default(), lod })
    }

    /// Opens a stream whose frame units may be damaged (see [`resync`]): only the sequence
    /// header must be intact. Damaged frames, and frames whose reference chain runs through
    /// one, fail in [`Decoder::decode_frame`]; [`Decoder::damage`] lists them.
    pub fn new_tolerant(data: Vec<u8>) -> Result<Self, DecodeError> {
        let (header, start) = bitstream::read_header(&data)?;
        bitstream::check_frame_count(&data, start, header.frame_count)?;
        let slots = resync::scan_units(&data, start, header.frame_count);
        let lod = header.subdiv_iterations();
        Ok(Self { header, slots, data, cache: StateCache::default(), lod })
    }

    /// The damaged frame units, by frame: (frame, where the damage is, why).
    pub fn damage(&self) -> Vec<(u32, &Damage)> {
        let slots = self.slots.iter().enumerate();
        slots.filter_map(|(i, s)| if let FrameSlot::Damaged(d) = s { Some((i as u32, d)) } else { None }).collect()
    }

    /// Decode only `lod` subdivision iterations from now on (0 = the base mesh with its
    /// displacements; the stream's iteration count = full detail). Forgets the cached frames,
    /// whose coefficients were decoded for another level. Errors if `lod` exceeds the
    /// stream's iterations.
    pub fn set_lod(&mut self, lod: u32) -> Result<(), String> {
        let most = self.header.subdiv_iterations();
        if lod > most {
            return Err(format!("level of detail {lod} out of range (the stream has {most} subdivision iterations)"));
        }
        self.lod = lod;
        self.cache = StateCache::default();
        Ok(())
    }

    /// Subdivision iterations decoded.
    pub fn lod(&self) -> u32 {
        self.lod
    }

    pub fn header(&self) -> &SequenceHeader {
        &self.header
    }

    pub fn frame_count(&self) -> u32 {
        self.slots.len() as u32
    }

    /// Type, reference, QP and sizes of frame `index`.
    pub fn frame_info(&self, index: u32) -> Result<FrameInfo, DecodeError> {
        let unit = self.unit(index)?;
        let p = read_payload(&unit, index)?;
        Ok(FrameInfo {
            frame_type: unit.frame_type,
            reference: (unit.frame_type == FrameType::Predicted).then(|| index - p.reference_distance),
            qp: p.qp,
            bytes: unit.payload.len() + bitstream::UNIT_OVERHEAD,
            base_bytes: p.base.len(),
            displacement_bytes: p.coefficients.len(),
        })
    }

    /// Decodes frame `index` into a mesh in the input's units.
    pub fn decode_frame(&mut self, index: u32) -> Result<Mesh, DecodeError> {
        self.decode_chain(index).map_err(|e| match e.frame {
            Some(f) if f != index => {
                DecodeError::new(Some(index), e.offset, format!("its reference frame {f} does not decode: {}", e.reason))
            }
            _ => e,
        })
    }

    /// [`Decoder::decode_frame`], its errors naming the frame of the chain that failed.
    fn decode_chain(&mut self, index: u32) -> Result<Mesh, DecodeError> {
        // Back from `index` to the first frame that is cached or intra, then forward again.
        let mut chain = vec![index];
        loop {
            let f = *chain.last().unwrap();
            if chain.len() > 1 && self.cache.get(f).is_some() {
                break;
            }
            let unit = self.unit(f)?;
            if unit.frame_type == FrameType::Intra {
                break;
            }
            chain.push(f - read_payload(&unit, f)?.reference_distance);
        }
        for k in (1..chain.len()).rev() {
            if self.cache.get(chain[k]).is_none() {
                let (state, _, _) = self.decode_state(chain[k], chain.get(k + 1).and_then(|&r| self.cache.get(r)))?;
                let intra = self.unit(chain[k])?.frame_type == FrameType::Intra;
                self.cache.insert(chain[k], state, intra);
            }
        }
        let (state, sub, qp) = self.decode_state(index, chain.get(1).and_then(|&r| self.cache.get(r)))?;
        let frames = displace::local_frames(&sub.positions, &sub.faces);
        let mesh = reconstruct(&self.header, &sub, &frames, &state.coefficients, qp);
        let intra = self.unit(index)?.frame_type == FrameType::Intra;
        self.cache.insert(index, state, intra);
        Ok(mesh)
    }

    /// The payload of frame `index`'s texture unit and its offset in the stream; None when
    /// the frame has none (an untextured stream, or a frame with nothing to add). An error
    /// when the unit is damaged.
    pub fn texture_payload(&self, index: u32) -> Result<Option<(&[u8], u64)>, DecodeError> {
        let FrameSlot::Intact { texture, .. } = self.slot(index)? else { return Ok(None) };
        match *texture {
            TextureSlot::None => Ok(None),
            TextureSlot::Intact(o, n) => Ok(Some((&self.data[o..o + n], o as u64))),
            TextureSlot::Damaged(o) => Err(DecodeError::new(Some(index), o as u64, "damaged texture unit")),
        }
    }

    /// The frame index and base mesh (positions in the input's units, as
    /// [`base_in_world_units`] gives them, and faces) of the frame decoded last: the texture
    /// atlas of an intra frame is coded on it. None before the first decode.
    pub fn last_base(&self) -> Option<(u32, Mesh)> {
        self.cache.last().map(|(i, s)| (*i, Mesh::new(base_in_world_units(&self.header, &s.positions), s.faces.clone())))
    }

    fn slot(&self, index: u32) -> Result<&FrameSlot, DecodeError> {
        self.slots.get(index as usize).ok_or_else(|| DecodeError::new(Some(index), 0, "no such frame"))
    }

    fn unit(&self, index: u32) -> Result<Unit<'_>, DecodeError> {
        match self.slot(index)? {
            &FrameSlot::Intact { frame_type, offset, len, .. } => {
                Ok(Unit { frame_type, payload: &self.data[offset..offset + len], offset: offset as u64, texture: None })
            }
            FrameSlot::Damaged(d) => Err(DecodeError::new(Some(index), d.start, format!("damaged frame unit: {}", d.reason))),
        }
    }

    /// Decodes frame `f`'s base mesh and coefficients (a predicted frame on `reference`);
    /// also returns its subdivided base mesh and QP.
    fn decode_state(&self, f: u32, reference: Option<&State>) -> Result<(State, Subdivision, i32), DecodeError> {
        let unit = self.unit(f)?;
        let p = read_payload(&unit, f)?;
        let h = &self.header;
        let error = |offset: u64, reason: &str| DecodeError::new(Some(f), offset, reason);
        let (positions, faces) = match (unit.frame_type, reference) {
            (FrameType::Intra, _) => basecoder::decode_base(p.base, h.base_bits)
                .map_err(|e| DecodeError::new(Some(f), p.base_offset, format!("base mesh: {e}")))?,
            (FrameType::Predicted, Some(r)) => {
                let mut dec = ec::Decoder::new(p.base);
                let positions = motion::decode_motion(&mut dec, &r.positions, &r.faces, h.base_bits)
                    .ok_or_else(|| error(p.base_offset, "base mesh motion is truncated or corrupt"))?;
                (positions, r.faces.clone())
            }
            (FrameType::Predicted, None) => return Err(error(p.base_offset, "predicted frame without its reference")),
        };
        let too_big = faces.len().saturating_mul(1usize << (2 * h.subdiv_iterations())) > face_allowance(unit.payload.len());
        if faces.is_empty() || too_big {
            let reason = format!("base mesh of {} faces cannot be subdivided {} times", faces.len(), h.subdiv_iterations());
            return Err(error(p.base_offset, &reason));
        }
        let sub = subdivide(&base_in_grid_units(h, &positions), &faces, &h.schemes[..self.lod as usize]);
        let mut dec = ec::Decoder::new(p.coefficients);
        let mut coefficients = coefcoder::decode(&mut dec, h.components as usize, &sub)
            .ok_or_else(|| error(p.coefficients_offset, "displacement data is truncated or corrupt"))?;
        if p.coefficients_predicted {
            let r = reference.expect("predicted frames have a reference here");
            coefficients = add_coefficients(&coefficients, &r.coefficients)
                .ok_or_else(|| error(p.coefficients_offset, "predicted displacements do not match their reference"))?;
        }
        Ok((State { positions, faces, coefficients }, sub, p.qp))
    }
}

/// `residual + reference`, element by element; `None` on a length mismatch or overflow.
fn add_coefficients(residual: &[i32], reference: &[i32]) -> Option<Vec<i32>> {
    if residual.len() != reference.len() {
        return None;
    }
    residual.iter().zip(reference).map(|(a, b)| a.checked_add(*b)).collect()
}

/// Splits a frame payload into its fields, checking the reference distance and the QP.
pub fn read_payload<'a>(unit: &Unit<'a>, frame: u32) -> Result<Payload<'a>, DecodeError> {
    let mut r = Reader::new(unit.payload, unit.offset, Some(frame));
    let reference_distance = match unit.frame_type {
        FrameType::Intra => 0,
        FrameType::Predicted => {
            let d = r.u32("reference distance")?;
            if d == 0 || d > frame {
                return Err(r.error(format!("reference distance {d} does not name an earlier frame")));
            }
            d
        }
    };
    let qp = r.i32("QP")?;
    if !quantize::QP_RANGE.contains(&qp) {
        return Err(r.error(format!("QP {qp} out of range")));
    }
    let (base, base_offset) = r.block("base mesh")?;
    let coefficients_predicted = match unit.frame_type {
        FrameType::Intra => false,
        FrameType::Predicted => match r.u8("coefficient mode")? {
            0 => false,
            1 => true,
            m => return Err(r.error(format!("unknown coefficient mode {m}"))),
        },
    };
    let (coefficients, coefficients_offset) = r.block("displacements")?;
    if r.remaining() != 0 {
        return Err(r.error("unexpected bytes at the end of the frame"));
    }
    Ok(Payload { reference_distance, qp, base, base_offset, coefficients_predicted, coefficients, coefficients_offset })
}

/// Base mesh positions on the base mesh grid, in units of the full-resolution grid.
pub fn base_in_grid_units(h: &SequenceHeader, positions: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let base_grid = h.grid.coarser(h.base_bits);
    positions.iter().map(|q| base_grid.to_world(q.map(|c| c as f64))).collect()
}

/// Base mesh positions on the base mesh grid, in the input's units: the base mesh that the
/// encoder reports and the decoder's [`Decoder::last_base`] gives, bit for bit the same.
pub fn base_in_world_units(h: &SequenceHeader, positions: &[[u32; 3]]) -> Vec<[f64; 3]> {
    base_in_grid_units(h, positions).into_iter().map(|p| h.grid.to_world(p)).collect()
}

/// Subdivision of the decoded base mesh (integer positions on the base mesh grid).
pub fn subdivided_base(h: &SequenceHeader, positions: &[[u32; 3]], faces: &[[u32; 3]]) -> Subdivision {
    subdivide(&base_in_grid_units(h, positions), faces, &h.schemes)
}

/// The quantization scale of every vertex of `sub`: its level's scale, times its
/// adaptive weight when the stream uses adaptive quantization.
pub fn vertex_scales(h: &SequenceHeader, qp: i32, sub: &Subdivision) -> Vec<f64> {
    let scales = quantize::lod_scales(qp, h.grid.bits, sub.lod_count());
    let weights = quantize::vertex_weights(sub.positions.len(), &sub.faces, h.aq.as_ref());
    weights.iter().enumerate().map(|(v, w)| w * quantize::scale_of(v, &sub.lod_offsets, &scales)).collect()
}

/// Positions of the decoded frame: dequantize, inverse-transform, apply the displacements
/// in the local frames, map back to the input's units.
pub fn reconstruct(h: &SequenceHeader, sub: &Subdivision, frames: &[[[f64; 3]; 3]], q: &[i32], qp: i32) -> Mesh {
    let comps = h.components as usize;
    let offset = h.aq.map_or(0.0, |a| a.delta);
    let scales = vertex_scales(h, qp, sub);
    let mut local: Vec<[f64; 3]> = scales
        .iter()
        .enumerate()
        .map(|(v, &s)| std::array::from_fn(|k| if k < comps { quantize::dequantize_shifted(q[v * comps + k], s, offset) } else { 0.0 }))
        .collect();
    transform::inverse(&mut local, sub, &h.lifting);
    let world = displace::to_world(&local, frames);
    let positions = sub.positions.iter().zip(&world).map(|(p, d)| to_world(&h.grid, *p, *d)).collect();
    Mesh::new(positions, sub.faces.clone())
}

fn to_world(grid: &Grid, p: [f64; 3], d: [f64; 3]) -> [f64; 3] {
    grid.to_world([p[0] + d[0], p[1] + d[1], p[2] + d[2]])
}
