//! The container: a sequence header, then one unit per frame with its type, length and
//! CRC-32. See `docs/bitstream.md` for the layout field by field.
//!
//! Reading never trusts a length or a count: each is checked against the bytes that are
//! actually present before anything is allocated, and every error names the frame and the
//! byte offset in the whole stream.

//!
//! The fields, codes and limits are declared in [`syntax`](super::syntax).

use crate::error::DecodeError;
use crate::geom::grid::Grid;
use crate::residual::quantize::AqParams;
use crate::residual::subdivide::Scheme;
use crate::residual::transform::Lifting;
use crate::stream::syntax::{
    self, Ty, COMPONENTS_ALL, COMPONENTS_NORMAL, FLAG_ON, FRAME_INTRA, FRAME_PREDICTED, HEADER_FRAME_COUNT_AT, HEADER_VERSION_AT, POSITION_BITS_MAX, POSITION_BITS_MIN,
    HEADER, SCHEME_LOOP, SCHEME_MIDPOINT, UPDATE_DEN_MIN,
};
pub use crate::stream::syntax::{MAGIC, MAX_SUBDIV, TEXTURE_UNIT, UNIT_OVERHEAD, VERSION};

/// Everything the decoder needs before the first frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceHeader {
    pub frame_count: u32,
    pub grid: Grid,
    /// Bit depth of the base mesh positions: a coarser grid of `2^base_bits` steps whose
    /// points are every `2^(grid.bits - base_bits)`-th point of `grid`.
    pub base_bits: u32,
    /// The scheme of each subdivision iteration, coarsest first.
    pub schemes: Vec<Scheme>,
    /// The lifting transform's update weights, one per subdivision iteration.
    pub lifting: Lifting,
    /// 1: only the normal component of each displacement is coded; 3: all of (n, t, b).
    pub components: u8,
    /// Adaptive displacement quantization, if on.
    pub aq: Option<AqParams>,
}

impl SequenceHeader {
    pub fn subdiv_iterations(&self) -> u32 {
        self.schemes.len() as u32
    }
}

/// Kind of a frame unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameType {
    /// Coded on its own: the base mesh with its connectivity.
    Intra = FRAME_INTRA as isize,
    /// The base mesh is a reference frame's base mesh moved: same connectivity, coded motion.
    Predicted = FRAME_PREDICTED as isize,
}

/// One frame unit as found in the stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Unit<'a> {
    pub frame_type: FrameType,
    pub payload: &'a [u8],
    /// Offset of the payload in the whole stream.
    pub offset: u64,
    /// The payload of the texture unit that follows this frame's unit, with its offset.
    pub texture: Option<(&'a [u8], u64)>,
}

/// Little-endian writer.
#[derive(Default)]
pub struct Writer {
    pub bytes: Vec<u8>,
}

impl Writer {
    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }
    pub fn u32(&mut self, v: u32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i32(&mut self, v: i32) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }
    /// A length-prefixed block.
    pub fn block(&mut self, data: &[u8]) {
        self.u32(data.len() as u32);
        self.bytes.extend_from_slice(data);
    }
}

/// Bounds-checked little-endian reader that knows where its bytes sit in the stream.
pub struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    base: u64,
    frame: Option<u32>,
}

impl<'a> Reader<'a> {
    /// Reads `data`, which starts at byte `base` of the stream and belongs to `frame`.
    pub fn new(data: &'a [u8], base: u64, frame: Option<u32>) -> Self {
        Self { data, pos: 0, base, frame }
    }

    /// An error at the current position.
    pub fn error(&self, reason: impl Into<String>) -> DecodeError {
        DecodeError::new(self.frame, self.base + self.pos as u64, reason)
    }

    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    pub fn bytes(&mut self, n: usize, what: &str) -> Result<&'a [u8], DecodeError> {
        if n > self.remaining() {
            return Err(self.error(format!("{what}: needs {n} bytes, {} left", self.remaining())));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, DecodeError> {
        Ok(self.bytes(1, what)?[0])
    }
    pub fn u32(&mut self, what: &str) -> Result<u32, DecodeError> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }
    pub fn i32(&mut self, what: &str) -> Result<i32, DecodeError> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }
    pub fn f64(&mut self, what: &str) -> Result<f64, DecodeError> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }
    fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N], DecodeError> {
        let b = self.bytes(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(b);
        Ok(a)
    }
    /// A length-prefixed block; returns its bytes and their offset in the stream.
    pub fn block(&mut self, what: &str) -> Result<(&'a [u8], u64), DecodeError> {
        let n = self.u32(what)? as usize;
        let offset = self.base + self.pos as u64;
        Ok((self.bytes(n, what)?, offset))
    }
}

/// Serializes the sequence header (with its CRC).
pub fn write_header(h: &SequenceHeader) -> Vec<u8> {
    let mut w = Writer::default();
    w.bytes.extend_from_slice(MAGIC);
    w.u8(VERSION);
    w.u32(h.frame_count);
    for c in h.grid.origin {
        w.f64(c);
    }
    w.f64(h.grid.step);
    w.u8(h.grid.bits as u8);
    w.u8(h.base_bits as u8);
    w.u8(h.schemes.len() as u8);
    for &s in &h.schemes {
        w.u8(match s {
            Scheme::Midpoint => SCHEME_MIDPOINT,
            Scheme::Loop => SCHEME_LOOP,
        });
    }
    w.u8(if h.lifting.per_valence { FLAG_ON } else { 0 });
    for &(num, den) in &h.lifting.update {
        w.u8(num);
        w.u8(den);
    }
    w.u8(h.components);
    let aq = h.aq.unwrap_or_default();
    w.u8(if h.aq.is_some() { FLAG_ON } else { 0 });
    w.f64(aq.alpha);
    w.f64(aq.delta);
    w.f64(aq.h);
    let crc = crc32fast::hash(&w.bytes);
    w.u32(crc);
    debug_assert_eq!(w.bytes.len(), syntax::header_len(h.schemes.len()));
    w.bytes
}

/// Parses and checks the sequence header; returns it and the offset of the first unit.
pub fn read_header(data: &[u8]) -> Result<(SequenceHeader, usize), DecodeError> {
    let mut r = Reader::new(data, 0, None);
    if r.bytes(MAGIC.len(), "magic")? != MAGIC {
        return Err(DecodeError::new(None, 0, "not a dynmesh stream (bad magic)"));
    }
    let version = r.u8("version")?;
    if version != VERSION {
        return Err(r.error(format!("unsupported format version {version} (this decoder reads {VERSION})")));
    }
    let frame_count = r.u32("frame count")?;
    let origin = [r.f64("origin")?, r.f64("origin")?, r.f64("origin")?];
    let step = r.f64("step")?;
    let bits = r.u8("position bits")? as u32;
    let base_bits = r.u8("base mesh position bits")? as u32;
    let subdiv_iterations = r.u8("subdivision iterations")? as u32;
    if subdiv_iterations > MAX_SUBDIV {
        return Err(r.error(format!("{subdiv_iterations} subdivision iterations (at most {MAX_SUBDIV})")));
    }
    let schemes_at = data.len() - r.remaining();
    let scheme_codes = r.bytes(subdiv_iterations as usize, "subdivision schemes")?;
    let lifting_at = data.len() - r.remaining();
    let per_valence = r.u8("lifting valence flag")?;
    let weights = r.bytes(Ty::U8Pair.width() * subdiv_iterations as usize, "lifting update weights")?;
    let lifting = Lifting { update: weights.chunks(2).map(|w| (w[0], w[1])).collect(), per_valence: per_valence == FLAG_ON };
    let components = r.u8("displacement components")?;
    let aq_flag = r.u8("adaptive quantization flag")?;
    let aq = AqParams { alpha: r.f64("AQ alpha")?, delta: r.f64("AQ delta")?, h: r.f64("AQ h")? };
    let end = data.len() - r.remaining();
    let crc = r.u32("header CRC")?;
    let header_len = data.len() - r.remaining();
    if crc != crc32fast::hash(&data[..end]) {
        return Err(DecodeError::new(None, end as u64, "sequence header CRC mismatch"));
    }
    let schemes = scheme_codes
        .iter()
        .enumerate()
        .map(|(i, &c)| match c {
            SCHEME_MIDPOINT => Ok(Scheme::Midpoint),
            SCHEME_LOOP => Ok(Scheme::Loop),
            s => Err(DecodeError::new(None, (schemes_at + i) as u64, format!("unknown subdivision scheme {s}"))),
        })
        .collect::<Result<Vec<_>, _>>()?;
    if per_valence > FLAG_ON || lifting.update.iter().any(|&(_, den)| den < UPDATE_DEN_MIN) {
        return Err(DecodeError::new(None, lifting_at as u64, "invalid lifting update weights"));
    }
    let header = SequenceHeader {
        frame_count,
        grid: Grid { origin, step, bits },
        base_bits,
        schemes,
        lifting,
        components,
        aq: (aq_flag == FLAG_ON).then_some(aq),
    };
    if aq_flag > FLAG_ON || (aq_flag == FLAG_ON && !aq.is_valid()) {
        let aq_at = syntax::offset(HEADER, "aq", header.schemes.len(), &|_| 0, true).expect("a header field");
        return Err(DecodeError::new(None, aq_at as u64, "invalid adaptive quantization parameters"));
    }
    validate_header(&header).map_err(|e| DecodeError::new(None, HEADER_VERSION_AT as u64, e))?;
    Ok((header, header_len))
}

fn validate_header(h: &SequenceHeader) -> Result<(), String> {
    if !h.grid.origin.iter().all(|c| c.is_finite()) || !h.grid.step.is_finite() || h.grid.step <= 0.0 {
        return Err("invalid position grid".into());
    }
    let bits_range = POSITION_BITS_MIN..=POSITION_BITS_MAX;
    if !bits_range.contains(&h.grid.bits) {
        return Err(format!("position bits {} out of range", h.grid.bits));
    }
    if !bits_range.contains(&h.base_bits) || h.base_bits > h.grid.bits {
        return Err(format!("base mesh position bits {} out of range", h.base_bits));
    }
    if h.components != COMPONENTS_NORMAL && h.components != COMPONENTS_ALL {
        return Err(format!("{} displacement components (1 or 3)", h.components));
    }
    Ok(())
}

/// Serializes one frame unit.
pub fn write_unit(frame_type: FrameType, payload: &[u8]) -> Vec<u8> {
    typed_unit(frame_type as u8, payload)
}

/// Serializes a texture unit, to be placed right after its frame's unit.
pub fn write_texture_unit(payload: &[u8]) -> Vec<u8> {
    typed_unit(TEXTURE_UNIT, payload)
}

fn typed_unit(unit_type: u8, payload: &[u8]) -> Vec<u8> {
    let mut w = Writer::default();
    w.u8(unit_type);
    w.block(payload);
    let crc = crc32fast::hash(&w.bytes);
    w.u32(crc);
    w.bytes
}

/// Splits the stream after the header into frame units, checking lengths and CRCs; a texture
/// unit is attached to the frame unit before it. Returns exactly `header.frame_count` units
/// or an error naming the first bad frame.
pub fn read_units<'a>(data: &'a [u8], start: usize, frame_count: u32) -> Result<Vec<Unit<'a>>, DecodeError> {
    check_frame_count(data, start, frame_count)?;
    let mut units = Vec::with_capacity(frame_count as usize);
    let mut pos = start;
    for f in 0..frame_count {
        let (t, payload, offset, next) = read_unit(data, pos, f)?;
        let frame_type = match t {
            FRAME_INTRA => FrameType::Intra,
            FRAME_PREDICTED => FrameType::Predicted,
            _ => return Err(DecodeError::new(Some(f), pos as u64, format!("unit type {t} where a frame unit was expected"))),
        };
        pos = next;
        let mut texture = None;
        if data.get(pos) == Some(&TEXTURE_UNIT) {
            let (_, payload, offset, next) = read_unit(data, pos, f)?;
            texture = Some((payload, offset));
            pos = next;
        }
        units.push(Unit { frame_type, payload, offset, texture });
    }
    if pos != data.len() {
        return Err(DecodeError::new(None, pos as u64, format!("{} unexpected bytes after the last frame", data.len() - pos)));
    }
    Ok(units)
}

/// Refuses a frame count that the stream has no room for: each unit takes at least
/// UNIT_OVERHEAD bytes, which bounds every allocation made per frame.
pub fn check_frame_count(data: &[u8], start: usize, frame_count: u32) -> Result<(), DecodeError> {
    let plausible = (data.len().saturating_sub(start) / UNIT_OVERHEAD) as u32;
    if frame_count > plausible {
        return Err(DecodeError::new(None, HEADER_FRAME_COUNT_AT as u64, format!("header claims {frame_count} frames; the stream has room for at most {plausible}")));
    }
    Ok(())
}

/// The unit at `pos`: its type byte, payload, payload offset and the position after it.
fn read_unit(data: &[u8], pos: usize, frame: u32) -> Result<(u8, &[u8], u64, usize), DecodeError> {
    let mut r = Reader::new(&data[pos..], pos as u64, Some(frame));
    let t = r.u8("unit type")?;
    let (payload, offset) = r.block("unit payload")?;
    let end = pos + data[pos..].len() - r.remaining();
    let crc = r.u32("unit CRC")?;
    if crc != crc32fast::hash(&data[pos..end]) {
        return Err(DecodeError::new(Some(frame), end as u64, "unit CRC mismatch (corrupted data)"));
    }
    Ok((t, payload, offset, pos + data[pos..].len() - r.remaining()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> SequenceHeader {
        SequenceHeader {
            frame_count: 2,
            grid: Grid { origin: [1.0, -2.0, 0.5], step: 0.01, bits: 12 },
            base_bits: 10,
            schemes: vec![Scheme::Midpoint, Scheme::Midpoint, Scheme::Loop],
            lifting: Lifting::per_valence(3),
            components: 1,
            aq: Some(AqParams { alpha: 1.25, delta: 0.25, h: 6.0 }),
        }
    }

    fn stream() -> Vec<u8> {
        let mut s = write_header(&header());
        s.extend(write_unit(FrameType::Intra, b"hello"));
        s.extend(write_unit(FrameType::Intra, b""));
        s
    }

    #[test]
    fn header_and_units_round_trip() {
        let s = stream();
        let (h, start) = read_header(&s).unwrap();
        assert_eq!(h, header());
        let units = read_units(&s, start, h.frame_count).unwrap();
        assert_eq!(units.len(), 2);
        assert_eq!(units[0].payload, b"hello");
        assert_eq!(&s[units[0].offset as usize..][..5], b"hello");
    }

    #[test]
    fn every_truncation_and_flip_is_an_error() {
        let s = stream();
        for cut in 0..s.len() {
            let r = read_header(&s[..cut]).and_then(|(h, st)| read_units(&s[..cut], st, h.frame_count));
            assert!(r.is_err(), "cut at {cut}");
        }
        for i in 0..s.len() * 8 {
            let mut t = s.clone();
            t[i / 8] ^= 1 << (i % 8);
            let r = read_header(&t).and_then(|(h, st)| read_units(&t, st, h.frame_count));
            assert!(r.is_err(), "flip at bit {i}");
        }
    }

    #[test]
    fn texture_units_attach_to_their_frame_and_cannot_stand_for_one() {
        let mut s = write_header(&header());
        s.extend(write_unit(FrameType::Intra, b"geometry"));
        s.extend(write_texture_unit(b"atlas"));
        s.extend(write_unit(FrameType::Predicted, b"motion"));
        let (h, start) = read_header(&s).unwrap();
        let units = read_units(&s, start, h.frame_count).unwrap();
        let (texture, offset) = units[0].texture.unwrap();
        assert_eq!(texture, b"atlas");
        assert_eq!(&s[offset as usize..][..5], b"atlas");
        assert_eq!(units[1].texture, None);
        assert_eq!(units[1].payload, b"motion");

        let mut t = write_header(&header());
        t.extend(write_texture_unit(b"atlas"));
        t.extend(write_unit(FrameType::Intra, b"geometry"));
        let e = read_units(&t, start, h.frame_count).unwrap_err();
        assert!(e.reason.contains("unit type 2"), "{e}");
    }

    #[test]
    fn a_huge_frame_count_is_refused_before_allocation() {
        let mut h = header();
        h.frame_count = u32::MAX;
        let s = write_header(&h);
        let (h, start) = read_header(&s).unwrap();
        let e = read_units(&s, start, h.frame_count).unwrap_err();
        assert!(e.reason.contains("room"), "{e}");
    }
}
