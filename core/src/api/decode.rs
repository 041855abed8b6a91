//! Decoding a stream: a [`Decoder`] checks the stream as it opens it, then decodes its frames
//! in any order.

use crate::decoder;
use crate::error::{DecodeError, Error};
use crate::geom::mesh::Mesh;
use crate::stream::bitstream::{self, SequenceHeader, MAGIC, VERSION};

/// What [`Decoder::frame_info`] tells about a frame without decoding it: type, reference,
/// QP and the byte sizes of its unit and parts.
pub use crate::decoder::FrameInfo;
/// A damaged frame unit of a stream opened with [`Decoder::new_tolerant`]: where (byte
/// offsets `[start, end)` in the stream) and why.
pub use crate::stream::resync::Damage;

/// A checked stream whose frames can be decoded in any order; decoding in order costs one
/// frame's work per frame. A clone decodes on its own (threads decoding independent frames
/// each take one).
#[derive(Clone)]
pub struct Decoder {
    inner: decoder::Decoder,
}

impl Decoder {
    /// Opens a stream: parses its header and splits its frame units, checking their lengths
    /// and CRCs.
    ///
    /// Errors: [`Error::Unsupported`] for an intact stream of another format version (its
    /// header, in whatever layout, ends with a CRC that holds; a damaged version byte is a
    /// decoding error); [`Error::Decode`] for anything else that is wrong (not a dynmesh
    /// stream, a damaged header, a damaged or missing frame unit), naming the frame and byte
    /// offset.
    pub fn new(data: Vec<u8>) -> Result<Self, Error> {
        let other_version = of_other_version(&data);
        decoder::Decoder::new(data).map(|inner| Self { inner }).map_err(|e| classified(e, other_version))
    }

    /// Opens a stream whose frame units may be damaged: only the sequence header must be
    /// intact. Damaged frames, and frames whose reference chain runs through one, fail in
    /// [`Decoder::decode_frame`]; [`Decoder::damage`] lists them.
    ///
    /// Errors: as [`Decoder::new`], for the header (and a frame count the data cannot hold).
    pub fn new_tolerant(data: Vec<u8>) -> Result<Self, Error> {
        let other_version = of_other_version(&data);
        decoder::Decoder::new_tolerant(data).map(|inner| Self { inner }).map_err(|e| classified(e, other_version))
    }

    /// The damaged frame units, by frame: (frame, where the damage is, why). Empty for an
    /// intact stream.
    pub fn damage(&self) -> Vec<(u32, &Damage)> {
        self.inner.damage()
    }

    /// Decodes only `lod` subdivision iterations from now on (0: the base mesh with its
    /// displacements; the stream's iteration count: full detail).
    ///
    /// Errors: [`Error::Input`] when `lod` exceeds the stream's iterations.
    pub fn set_lod(&mut self, lod: u32) -> Result<(), Error> {
        self.inner.set_lod(lod).map_err(Error::Input)
    }

    /// Subdivision iterations decoded (the level of detail).
    pub fn lod(&self) -> u32 {
        self.inner.lod()
    }

    /// The sequence header.
    pub fn header(&self) -> &SequenceHeader {
        self.inner.header()
    }

    /// Frames in the stream.
    pub fn frame_count(&self) -> u32 {
        self.inner.frame_count()
    }

    /// Type, reference, QP and sizes of frame `index`, without decoding it.
    ///
    /// Errors: [`Error::Input`] for an index beyond the frame count; [`Error::Decode`] for a
    /// damaged unit.
    pub fn frame_info(&self, index: u32) -> Result<FrameInfo, Error> {
        Ok(self.inner.frame_info(self.existing(index)?)?)
    }

    /// Decodes frame `index` into a mesh in the input's units.
    ///
    /// Errors: [`Error::Input`] for an index beyond the frame count; [`Error::Decode`] when
    /// the frame, or a frame of its reference chain, cannot be decoded (named in the message).
    pub fn decode_frame(&mut self, index: u32) -> Result<Mesh, Error> {
        Ok(self.inner.decode_frame(self.existing(index)?)?)
    }

    /// The payload of frame `index`'s texture unit and its offset in the stream; None when the
    /// frame has none.
    ///
    /// Errors: [`Error::Input`] for an index beyond the frame count; [`Error::Decode`] when
    /// the texture unit is damaged.
    pub fn texture_payload(&self, index: u32) -> Result<Option<(&[u8], u64)>, Error> {
        Ok(self.inner.texture_payload(self.existing(index)?)?)
    }

    /// The frame index and base mesh (in the input's units) of the frame decoded last: the
    /// texture atlas of an intra frame is coded on it. None before the first decode.
    pub fn last_base(&self) -> Option<(u32, Mesh)> {
        self.inner.last_base()
    }

    /// `index`, if the stream has such a frame: asking for another is the caller's mistake,
    /// not damage in the stream.
    fn existing(&self, index: u32) -> Result<u32, Error> {
        let count = self.frame_count();
        if index < count {
            Ok(index)
        } else {
            let frames = if count == 1 { "frame" } else { "frames" };
            Err(Error::Input(format!("frame {index} does not exist: the stream has {count} {frames}")))
        }
    }
}

/// Byte offset of the format version in a stream, right after the magic.
const VERSION_OFFSET: usize = MAGIC.len();

/// More bytes than any version's sequence header has (this one's: 93 at most).
const HEADER_BOUND: usize = 4096;

/// Whether `data` is an intact dynmesh stream of another format version: it starts with the
/// magic and another version byte; it is not a stream of this version whose version byte was
/// damaged (its header, with this version put back, does not read); and its header is intact
/// in some layout: every version's header ends with the CRC-32 of the bytes before it, so
/// some 4 bytes after the version are the CRC of everything before them (which damage
/// leaves true of no prefix, but for odds of about one in a million).
fn of_other_version(data: &[u8]) -> bool {
    let Some(&version) = data.get(VERSION_OFFSET) else { return false };
    if !data.starts_with(MAGIC) || version == VERSION {
        return false;
    }
    let head = &data[..data.len().min(HEADER_BOUND)];
    let mut ours = head.to_vec();
    ours[VERSION_OFFSET] = VERSION;
    if bitstream::read_header(&ours).is_ok() {
        return false;
    }
    let mut crc = crc32fast::Hasher::new();
    crc.update(&head[..=VERSION_OFFSET]);
    for end in VERSION_OFFSET + 1..head.len().saturating_sub(3) {
        if crc.clone().finalize().to_le_bytes() == head[end..end + 4] {
            return true;
        }
        crc.update(&head[end..end + 1]);
    }
    false
}

/// The public error of a failure to open a stream: the header reader checks the version
/// right after the magic, so a stream of another version fails there, and is one this build
/// does not read; anything else is a decoding error.
fn classified(e: DecodeError, other_version: bool) -> Error {
    if other_version && e.frame.is_none() {
        Error::Unsupported(e.to_string())
    } else {
        e.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::encode::{EncoderConfig, FormatParams, SequenceEncoder};
    use crate::stream::bitstream::write_header;
    use crate::geom::testmesh;

    fn stream() -> Vec<u8> {
        let (positions, faces) = testmesh::icosphere(2, 0.9);
        let ball = Mesh::new(positions, faces);
        let mut enc = SequenceEncoder::new(EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, ..Default::default() }, 1, [-1.0; 3], [1.0; 3]).unwrap();
        let mut data = write_header(enc.header());
        data.extend(enc.encode(&ball).unwrap().unit);
        data
    }

    #[test]
    fn opening_errors_are_classified() {
        let data = stream();
        assert!(Decoder::new(data.clone()).is_ok());
        // Another version: a header of another layout (here: a byte more after the version),
        // ending with the CRC of the bytes before it.
        let crc_at = bitstream::read_header(&data).unwrap().1 - 4;
        let mut newer = data[..crc_at].to_vec();
        newer[VERSION_OFFSET] = VERSION + 1;
        newer.insert(VERSION_OFFSET + 1, 0);
        newer.extend(crc32fast::hash(&newer).to_le_bytes());
        newer.extend(&data[crc_at + 4..]);
        // Damaged beyond the version byte: a decoding error, whatever the version byte says.
        let mut garbled = newer.clone();
        garbled[20] ^= 4;
        assert!(matches!(Decoder::new(garbled), Err(Error::Decode { frame: None, .. })));
        // This version with its version byte damaged: a decoding error.
        let mut damaged = data.clone();
        damaged[VERSION_OFFSET] = VERSION + 1;
        for open in [Decoder::new, Decoder::new_tolerant] {
            match open(damaged.clone()) {
                Err(Error::Decode { frame: None, reason, .. }) => assert!(reason.contains("unsupported format version"), "{reason}"),
                other => panic!("{:?}", other.map(|_| ())),
            }
            match open(newer.clone()) {
                Err(Error::Unsupported(m)) => assert!(m.contains("unsupported format version"), "{m}"),
                other => panic!("{:?}", other.map(|_| ())),
            }
            assert!(matches!(open(b"DMSX\x05rest".to_vec()), Err(Error::Decode { frame: None, offset: Some(0), .. })));
            assert!(matches!(open(data[..3].to_vec()), Err(Error::Decode { .. })));
        }
        assert!(matches!(Decoder::new(data[..data.len() - 3].to_vec()), Err(Error::Decode { frame: Some(0), .. })));
        let mut d = Decoder::new(data).unwrap();
        assert!(matches!(d.set_lod(9), Err(Error::Input(_))));
        // A frame the stream does not have is the caller's mistake, not damage.
        assert!(matches!(d.decode_frame(5), Err(Error::Input(m)) if m == "frame 5 does not exist: the stream has 1 frame"));
    }
}
