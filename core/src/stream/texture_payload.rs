//! The texture unit payload: a texture group's header, its coded atlas and its video, written
//! by the encoder's texture stage and read by the decoder's through this one pair of
//! functions (`docs/bitstream.md`, "Texture unit payload"). What the blocks hold is the texture
//! stage's business (`crate::texture::uvcoder` for the atlas, a video codec for the video);
//! this module only lays them out and checks the fields, which [`syntax`](super::syntax)
//! declares (`TEXTURE_PAYLOAD`).

use crate::error::{Corrupt, Error};
use crate::stream::syntax::{TEXTURE_FIXED as FIXED, TEXTURE_FRAMES_MIN, UV_BITS_MAX, UV_BITS_MIN};
pub use crate::stream::syntax::{MAX_SIDE, MIN_SIDE, TEXTURE_CODECS, TEXTURE_PAYLOAD_VERSION};

/// Bytes of a block's length field (`atlas_len`, `video_len`).
const LEN: usize = 4;

/// The fields of a texture unit payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TexturePayload {
    /// Index into [`TEXTURE_CODECS`].
    pub codec: u8,
    pub width: u16,
    pub height: u16,
    /// UV quantization bits: UV = q / (2^uv_bits - 1).
    pub uv_bits: u8,
    /// Frames in the group, at least 1.
    pub frames: u32,
    /// The group's base mesh atlas, coded by `uvcoder`.
    pub atlas: Vec<u8>,
    /// The group's video, one picture per frame.
    pub video: Vec<u8>,
}

impl TexturePayload {
    /// The payload's bytes. The fields are written as they are; [`Self::read`] is what checks.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(FIXED + 2 * LEN + self.atlas.len() + self.video.len());
        out.extend([TEXTURE_PAYLOAD_VERSION, self.codec]);
        out.extend(self.width.to_le_bytes());
        out.extend(self.height.to_le_bytes());
        out.push(self.uv_bits);
        out.extend(self.frames.to_le_bytes());
        for block in [&self.atlas, &self.video] {
            out.extend((block.len() as u32).to_le_bytes());
            out.extend(block.iter());
        }
        out
    }

    /// Parses a payload; the error names what is wrong, in the words the JavaScript reader
    /// (`web/src/texture/unit.js`) uses: [`Error::Unsupported`] for a payload of another
    /// version or an unknown codec (checked once the fixed fields are there), else
    /// [`Error::Decode`] without a place (the caller knows where the unit lies).
    pub fn read(data: &[u8]) -> Result<Self, Error> {
        let corrupt = |reason: String| Error::from(Corrupt(reason));
        if data.len() < FIXED {
            return Err(corrupt("texture unit is truncated".into()));
        }
        let u32_at = |i: usize| u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
        // The fixed fields, in the order and widths of `TEXTURE_PAYLOAD`.
        let mut at = 0;
        let mut next = |n: usize| {
            at += n;
            &data[at - n..at]
        };
        let version = next(1)[0];
        let codec = next(1)[0];
        let width = u16::from_le_bytes(next(2).try_into().expect("two bytes"));
        let height = u16::from_le_bytes(next(2).try_into().expect("two bytes"));
        let uv_bits = next(1)[0];
        let frames = u32::from_le_bytes(next(4).try_into().expect("four bytes"));
        if version != TEXTURE_PAYLOAD_VERSION {
            return Err(Error::Unsupported(format!("texture unit version {version} is not supported")));
        }
        if codec as usize >= TEXTURE_CODECS.len() {
            return Err(Error::Unsupported(format!("unknown texture codec {codec}")));
        }
        let side_ok = |s: u16| (MIN_SIDE..=MAX_SIDE).contains(&s) && s % 2 == 0;
        if !side_ok(width) || !side_ok(height) {
            return Err(corrupt(format!("texture size {width} x {height} is out of range")));
        }
        if !(UV_BITS_MIN..=UV_BITS_MAX).contains(&uv_bits) || frames < TEXTURE_FRAMES_MIN {
            return Err(corrupt("texture unit has invalid UV bits or frame count".into()));
        }
        let mut pos = FIXED;
        let mut block = |what: &str| -> Result<Vec<u8>, Corrupt> {
            if pos + LEN > data.len() {
                return Err(format!("texture unit is truncated before its {what}").into());
            }
            let n = u32_at(pos) as usize;
            if n > data.len() - pos - LEN {
                return Err(format!("texture unit's {what} is truncated").into());
            }
            pos += LEN + n;
            Ok(data[pos - n..pos].to_vec())
        };
        let (atlas, video) = (block("atlas")?, block("video")?);
        if pos != data.len() {
            return Err(corrupt("unexpected bytes at the end of the texture unit".into()));
        }
        Ok(Self { codec, width, height, uv_bits, frames, atlas, video })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> TexturePayload {
        TexturePayload { codec: 1, width: 1024, height: 512, uv_bits: 12, frames: 3, atlas: vec![1, 2, 3], video: vec![9; 5] }
    }

    #[test]
    fn a_payload_reads_back_as_written() {
        let bytes = example().to_bytes();
        assert_eq!(bytes.len(), 11 + 4 + 3 + 4 + 5);
        assert_eq!(&bytes[..11], &[1, 1, 0, 4, 0, 2, 12, 3, 0, 0, 0]);
        assert_eq!(TexturePayload::read(&bytes), Ok(example()));
    }

    #[test]
    fn every_damage_is_named() {
        let bytes = example().to_bytes();
        let error = |data: &[u8]| TexturePayload::read(data).unwrap_err().to_string();
        let with = |i: usize, v: u8| {
            let mut b = bytes.clone();
            b[i] = v;
            b
        };
        assert_eq!(error(&bytes[..10]), "texture unit is truncated");
        assert_eq!(error(&with(0, 2)), "texture unit version 2 is not supported");
        assert_eq!(error(&with(1, 2)), "unknown texture codec 2");
        assert_eq!(error(&with(2, 1)), "texture size 1025 x 512 is out of range");
        assert_eq!(error(&with(6, 0)), "texture unit has invalid UV bits or frame count");
        assert_eq!(error(&bytes[..13]), "texture unit is truncated before its atlas");
        assert_eq!(error(&bytes[..17]), "texture unit's atlas is truncated");
        assert_eq!(error(&bytes[..bytes.len() - 1]), "texture unit's video is truncated");
        assert_eq!(error(&[bytes.as_slice(), &[0]].concat()), "unexpected bytes at the end of the texture unit");
    }
}
