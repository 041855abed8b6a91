//! The texture stage's pieces, which the Python orchestration (`dynmesh.texture`) calls: the
//! lossless coding of the UV atlas, the subdivision of UV triangles with the mesh, the
//! transfer of a texture onto the reconstructed mesh's atlas and its padding, the colour
//! conversion of the texture video, and the texture unit's payload.
//!
//! The functions that take arrays state their preconditions (index ranges, sizes); the
//! callers check them (the Python bindings do, raising `InputError`). Those that read coded
//! data return [`Error`].

use crate::error::Error;

/// An RGB8 texture image, rows from the top.
pub use crate::texture::Texture;
/// A mesh with per-corner UVs: `uv_faces[i]` holds the UV indices of face `i`'s corners.
/// `UvMesh::validate` says what is inconsistent.
pub use crate::texture::UvMesh;
/// A texture as the 10-bit 4:2:0 planes of the texture video (full-range BT.709 Y, then Cb
/// and Cr averaged over 2 x 2 texels); the sides must be even. Cannot fail.
pub use crate::texture::yuv420_10bit;
/// The atlas with its UVs renumbered in order of first use and unused ones dropped, as the
/// decoders return it. Cannot fail.
pub use crate::texture::uvcoder::canonical_uv;
/// A UV atlas: (UV index triangles, one per face; integer UVs).
pub use crate::texture::uvcoder::UvAtlas;
/// Most UV quantization bits.
pub use crate::texture::uvcoder::MAX_UV_BITS;
/// The texture of a source mesh transferred onto the atlas of a target mesh as a
/// `width` x `height` image, with the texels its UV triangles cover ([`Transferred`]). Both
/// meshes must pass `UvMesh::validate`. Cannot fail.
pub use crate::texture::transfer::transfer_texture;
/// What [`transfer_texture`] returns: the image and which texels were covered.
pub use crate::texture::transfer::Transferred;
/// Fills the texels not covered by push-pull, for video coding. Cannot fail.
pub use crate::texture::pad::pad;
/// The fields of a texture unit payload; `to_bytes` lays them out (cannot fail), and
/// [`read_texture_payload`] reads them back.
pub use crate::stream::texture_payload::TexturePayload;
/// Texture video codecs, by the index a payload signals.
pub use crate::stream::texture_payload::TEXTURE_CODECS;
/// The atlas side's bounds, in texels (each side even).
pub use crate::stream::texture_payload::{MAX_SIDE, MIN_SIDE};

/// Codes a quantized UV atlas of the mesh `faces`: `uv_faces` (one row per face) indexes
/// `uv`, whose coordinates lie in `[0, 2^bits)`, `bits` from 1 to [`MAX_UV_BITS`]. Returns the
/// coded bytes; decode them with [`decode_uv`]. Cannot fail when the indices are in range.
pub fn encode_uv(faces: &[[u32; 3]], uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<u8> {
    crate::texture::uvcoder::encode_uv(faces, uv_faces, uv, bits)
}

/// [`encode_uv`] predicting new UVs from the 3D triangles of `positions` (smaller); decode
/// with [`decode_uv_with_positions`] and the same positions.
pub fn encode_uv_with_positions(positions: &[[f64; 3]], faces: &[[u32; 3]], uv_faces: &[[u32; 3]], uv: &[[u32; 2]], bits: u32) -> Vec<u8> {
    crate::texture::uvcoder::encode_uv_with_positions(positions, faces, uv_faces, uv, bits)
}

/// The UV triangles `uv_faces` over `uv` split as `iterations` rounds of the mesh's
/// subdivision split its faces: row `i` of the result's triangles holds the UVs of face `i` of
/// the subdivided mesh. Returns (UVs, UV triangles). Indices must be in range. Cannot fail.
pub fn subdivide_uv(uv: &[[f64; 2]], uv_faces: &[[u32; 3]], iterations: u32) -> (Vec<[f64; 2]>, Vec<[u32; 3]>) {
    crate::residual::subdivide::subdivide_uv(uv, uv_faces, iterations)
}

/// Decodes what [`encode_uv`] wrote for the same `faces` (indices below `vertex_count`)
/// and `bits`. Returns the atlas in canonical order.
///
/// Errors: [`Error::Decode`] (without a place in a stream) for data that cannot be decoded.
pub fn decode_uv(data: &[u8], faces: &[[u32; 3]], vertex_count: usize, bits: u32) -> Result<UvAtlas, Error> {
    Ok(crate::texture::uvcoder::decode_uv(data, faces, vertex_count, bits)?)
}

/// Decodes what [`encode_uv_with_positions`] wrote for the same `positions`, `faces` and
/// `bits`.
///
/// Errors: as [`decode_uv`].
pub fn decode_uv_with_positions(data: &[u8], positions: &[[f64; 3]], faces: &[[u32; 3]], bits: u32) -> Result<UvAtlas, Error> {
    Ok(crate::texture::uvcoder::decode_uv_with_positions(data, positions, faces, bits)?)
}

/// The texture of a 10-bit 4:2:0 frame (`width` x `height` texels; the inverse of
/// [`yuv420_10bit`], each chroma sample used for its 2 x 2 texels).
///
/// Errors: [`Error::Input`] when the planes do not hold a frame of that size.
pub fn rgb_of_yuv420_10bit(planes: &[u16], width: usize, height: usize) -> Result<Texture, Error> {
    crate::texture::rgb_of_yuv420_10bit(planes, width, height).map_err(Error::Input)
}

/// Parses a texture unit payload.
///
/// Errors: [`Error::Unsupported`] for a payload of another version or a video codec this
/// build does not know (an index beyond [`TEXTURE_CODECS`]); [`Error::Decode`] (without a
/// place in a stream) for a truncated or inconsistent one. The message names what is wrong.
pub fn read_texture_payload(data: &[u8]) -> Result<TexturePayload, Error> {
    TexturePayload::read(data)
}


#[cfg(test)]
mod tests {
    use super::*;

    fn example() -> TexturePayload {
        TexturePayload { codec: 1, width: 64, height: 32, uv_bits: 12, frames: 2, atlas: vec![1, 2], video: vec![3; 4] }
    }

    #[test]
    fn texture_payload_errors_are_classified() {
        let bytes = example().to_bytes();
        assert_eq!(read_texture_payload(&bytes), Ok(example()));
        let with = |i: usize, v: u8| {
            let mut b = bytes.clone();
            b[i] = v;
            read_texture_payload(&b)
        };
        assert_eq!(with(0, 2), Err(Error::Unsupported("texture unit version 2 is not supported".into())));
        assert_eq!(with(1, 7), Err(Error::Unsupported("unknown texture codec 7".into())));
        assert!(matches!(with(2, 3), Err(Error::Decode { frame: None, offset: None, .. })));
        for cut in [0, 1, 2, crate::stream::syntax::TEXTURE_FIXED - 1, crate::stream::syntax::TEXTURE_FIXED, bytes.len() - 1] {
            assert!(matches!(read_texture_payload(&bytes[..cut]), Err(Error::Decode { .. })), "{cut}");
        }
        let mut newer_short = vec![9u8; 4];
        newer_short[1] = 0;
        assert!(matches!(read_texture_payload(&newer_short), Err(Error::Decode { .. })));
    }

    #[test]
    fn corrupt_uv_data_is_a_decode_error() {
        let faces = [[0, 1, 2]];
        let data = encode_uv(&faces, &faces, &[[0, 0], [5, 0], [0, 5]], 4);
        assert!(decode_uv(&data, &faces, 3, 4).is_ok());
        assert!(matches!(decode_uv(&data[..1], &faces, 3, 4), Err(Error::Decode { frame: None, offset: None, .. })));
        assert!(matches!(rgb_of_yuv420_10bit(&[0; 5], 2, 2), Err(Error::Input(_))));
    }
}
