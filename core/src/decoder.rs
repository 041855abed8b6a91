//! The decoder: frame units back to meshes.
//!
//! Frame payloads are split by [`Payload::read`] and reconstructed by the model the encoder
//! shares ([`FrameModel`]), which is what makes the two agree bit for bit. Predicted frames
//! take their base mesh from the frame they name, so [`Decoder`] walks back to the intra
//! frame that starts the chain (seeking) and keeps the states of the frames it decoded last
//! (`StateCache`), which later frames refer to.
//!
//! Level-of-detail decoding ([`Decoder::set_lod`]) stops after K of the stream's
//! subdivision iterations: each frame is subdivided K times, the coefficients of the levels
//! beyond K are not read (they come last in the block) and count as zero, and the frame is
//! reconstructed on the level-K mesh. At K = all iterations nothing changes.

use std::borrow::Cow;

use crate::base::coder::decode_base;
use crate::error::DecodeError;
use crate::geom::mesh::Mesh;
use crate::inter::{motion, refresh};
use crate::model::{base_in_world_units, face_allowance, subdivided_base, FrameModel, FrameState};
use crate::residual::coefcoder;
use crate::residual::subdivide::Subdivision;
use crate::stream::bitstream::{self, FrameType, SequenceHeader, Unit};
use crate::ec;
use crate::stream::payload::Payload;
use crate::stream::resync::{self, Damage, FrameSlot, TextureSlot};
use crate::stream::syntax::UNIT_OVERHEAD;

/// What `frame_info` tells about a frame without decoding it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameInfo {
    pub frame_type: FrameType,
    pub reference: Option<u32>,
    pub qp: i32,
    pub bytes: usize,
    /// The base mesh block (intra), or the motion and refresh blocks (predicted).
    pub base_bytes: usize,
    /// The refresh block of a predicted frame that refreshes regions of its base (else 0).
    pub refresh_bytes: usize,
    pub displacement_bytes: usize,
}

/// The states of recently decoded frames, which later predicted frames refer to: the last
/// [`CACHED_STATES`] decoded and the latest intra frame decoded. An encoder that chooses its
/// references among the last `CACHED_STATES` frames and the latest intra frame (as ours
/// does) thereby costs one frame's work per frame when decoded in order.
#[derive(Clone, Default)]
struct StateCache {
    /// Oldest first; the last entry is the frame decoded last.
    recent: Vec<(u32, FrameState)>,
    intra: Option<(u32, FrameState)>,
}

/// Decoded frames whose states the decoder keeps besides the latest intra frame's.
pub const CACHED_STATES: usize = 8;

impl StateCache {
    fn get(&self, frame: u32) -> Option<&FrameState> {
        let recent = self.recent.iter().rev().find(|(f, _)| *f == frame);
        recent.or(self.intra.as_ref().filter(|(f, _)| *f == frame)).map(|(_, s)| s)
    }

    fn last(&self) -> Option<&(u32, FrameState)> {
        self.recent.last()
    }

    fn insert(&mut self, frame: u32, state: FrameState, intra: bool) {
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
/// `StateCache` holds, so decoding in order costs one frame's work per frame. A clone
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
        let (p, _) = Payload::read(&unit, index)?;
        Ok(FrameInfo {
            frame_type: unit.frame_type,
            reference: (unit.frame_type == FrameType::Predicted).then(|| index - p.reference_distance),
            qp: p.qp,
            bytes: unit.payload.len() + UNIT_OVERHEAD,
            base_bytes: p.base.len() + p.refresh.len(),
            refresh_bytes: p.refresh.len(),
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
            chain.push(f - Payload::read(&unit, f)?.0.reference_distance);
        }
        for k in (1..chain.len()).rev() {
            if self.cache.get(chain[k]).is_none() {
                let (state, _, _) = self.decode_state(chain[k], chain.get(k + 1).and_then(|&r| self.cache.get(r)))?;
                let intra = self.unit(chain[k])?.frame_type == FrameType::Intra;
                self.cache.insert(chain[k], state, intra);
            }
        }
        let (state, sub, qp) = self.decode_state(index, chain.get(1).and_then(|&r| self.cache.get(r)))?;
        let mesh = FrameModel::new(&self.header, qp, sub).reconstruct(&state.coefficients);
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
        self.cache.last().map(|(i, s)| (*i, Mesh::new(base_in_world_units(&self.header, &s.base), s.faces.clone())))
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
    fn decode_state(&self, f: u32, reference: Option<&FrameState>) -> Result<(FrameState, Subdivision, i32), DecodeError> {
        let unit = self.unit(f)?;
        let (p, at) = Payload::read(&unit, f)?;
        let h = &self.header;
        let error = |offset: u64, reason: &str| DecodeError::new(Some(f), offset, reason);
        // `kept`: for a refreshed base, the reference base faces it kept.
        let ((positions, faces), kept) = match (unit.frame_type, reference) {
            (FrameType::Intra, _) => {
                let base = decode_base(p.base, h.base_bits).map_err(|e| DecodeError::new(Some(f), at.base, format!("base mesh: {e}")))?;
                (base, None)
            }
            (FrameType::Predicted, Some(r)) => {
                let mut dec = ec::Decoder::new(p.base);
                let positions = motion::decode_motion(&mut dec, &r.base, &r.faces, h.base_bits).map_err(|e| error(at.base, &e.0))?;
                if p.refresh.is_empty() {
                    ((positions, r.faces.clone()), None)
                } else {
                    let (dropped, patch) =
                        refresh::decode_refresh(p.refresh, r.faces.len(), h.base_bits).map_err(|e| error(at.refresh, &e.0))?;
                    let (base, kept) = refresh::apply(&positions, &r.faces, &dropped, &patch);
                    (base, Some(kept))
                }
            }
            (FrameType::Predicted, None) => return Err(error(at.base, "predicted frame without its reference")),
        };
        let too_big = faces.len().saturating_mul(1usize << (2 * h.subdiv_iterations())) > face_allowance(unit.payload.len());
        if faces.is_empty() || too_big {
            let reason = format!("base mesh of {} faces cannot be subdivided {} times", faces.len(), h.subdiv_iterations());
            return Err(error(at.base, &reason));
        }
        let sub = subdivided_base(h, &positions, &faces, self.lod as usize);
        let mut dec = ec::Decoder::new(p.coefficients);
        let mut coefficients = coefcoder::decode(&mut dec, h.components as usize, &sub).map_err(|e| error(at.coefficients, &e.0))?;
        if p.coefficients_predicted {
            let r = reference.expect("predicted frames have a reference here");
            let prior = match &kept {
                None => Some(Cow::Borrowed(&r.coefficients[..])),
                Some(kept) => refresh::carry(h, r, &sub, kept).map(|(carried, _)| Cow::Owned(carried)),
            };
            coefficients = prior
                .and_then(|prior| add_coefficients(&coefficients, &prior))
                .ok_or_else(|| error(at.coefficients, "predicted displacements do not match their reference"))?;
        }
        Ok((FrameState { base: positions, faces, coefficients }, sub, p.qp))
    }
}

/// `residual + reference`, element by element; `None` on a length mismatch or overflow.
fn add_coefficients(residual: &[i32], reference: &[i32]) -> Option<Vec<i32>> {
    if residual.len() != reference.len() {
        return None;
    }
    residual.iter().zip(reference).map(|(a, b)| a.checked_add(*b)).collect()
}
