//! Entry points for the fuzz targets in `fuzz/` (cargo fuzz), kept in the library so that
//! they build on stable and a unit test runs each of them on its seed inputs. Behind the
//! `fuzzing` feature (which `fuzz/Cargo.toml` turns on) and built for the crate's own tests,
//! so the library others link leaves them out.
//!
//! Each function takes arbitrary bytes, feeds them to one decoder and checks what the
//! decoder promises: it returns an error or a well-formed result within its bounds, and
//! never panics. The decoders that need context (motion, UVs, coefficients) get it from
//! [`context_mesh`], one of a few small fixed meshes chosen by the first input byte, so that
//! the rest of the input is the coded block as the stream would carry it. [`seeds`] gives a
//! valid input for every target, made by the encoders, to start a campaign from.

use crate::base::coder;
use crate::stream::bitstream;
use crate::residual::coefcoder;
use crate::decoder::Decoder;
use crate::ec;
use crate::inter::{motion, refresh};
use crate::residual::subdivide::{subdivide, Scheme};
use crate::texture::uvcoder;

/// Base grid bits of the context meshes.
const CONTEXT_BITS: u32 = 9;

/// The whole stream decoder. Bit 0 of the first byte asks for every unit's CRC to be
/// recomputed first, so that mutations reach the payload parsers; the rest is the stream.
/// Decodes every frame, strictly, or tolerantly (damaged units skipped) when the strict
/// decoder refuses the stream.
pub fn stream(input: &[u8]) {
    let Some((&flags, rest)) = input.split_first() else { return };
    let mut data = rest.to_vec();
    if flags & 1 == 1 {
        fix_crcs(&mut data);
    }
    // A stream the strict decoder opens has no damaged unit, so the tolerant one would only
    // repeat the same decoding: try it on the others.
    if let Ok(d) = Decoder::new(data.clone()) {
        return decode_every_frame(d);
    }
    if let Ok(d) = Decoder::new_tolerant(data) {
        for (frame, damage) in d.damage() {
            assert!(frame < d.frame_count() && damage.start <= damage.end, "damage record out of range");
        }
        decode_every_frame(d);
    }
}

fn decode_every_frame(mut d: Decoder) {
    for i in 0..d.frame_count() {
        let _ = d.frame_info(i);
        let _ = d.texture_payload(i);
        if let Ok(m) = d.decode_frame(i) {
            assert!(m.faces.len() <= crate::model::MAX_OUTPUT_FACES);
            assert!(m.faces.iter().flatten().all(|&v| (v as usize) < m.positions.len()), "frame {i}: face index out of range");
        }
    }
}

/// Recomputes the CRC of every unit whose length field fits in `data` (header included),
/// walking units by their lengths; stops at the first that does not fit.
pub fn fix_crcs(data: &mut [u8]) {
    let Ok((_, mut pos)) = bitstream::read_header(data).or_else(|_| fix_header_crc(data)) else { return };
    while pos + bitstream::UNIT_OVERHEAD <= data.len() {
        let len = u32::from_le_bytes(data[pos + 1..pos + 5].try_into().expect("four bytes")) as usize;
        let Some(end) = (pos + 5).checked_add(len).filter(|&e| e + 4 <= data.len()) else { return };
        let crc = crc32fast::hash(&data[pos..end]);
        data[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        pos = end + 4;
    }
}

/// Rewrites the header CRC (at the place the scheme count puts it) and reads the header again.
fn fix_header_crc(data: &mut [u8]) -> Result<(bitstream::SequenceHeader, usize), ()> {
    let schemes = *data.get(43).ok_or(())? as usize;
    let end = 70 + schemes;
    if end + 4 > data.len() {
        return Err(());
    }
    let crc = crc32fast::hash(&data[..end]);
    data[end..end + 4].copy_from_slice(&crc.to_le_bytes());
    bitstream::read_header(data).map_err(|_| ())
}

/// The base mesh decoder; the first byte picks the bit depth (1 to 30).
pub fn base(input: &[u8]) {
    let Some((&b, data)) = input.split_first() else { return };
    let bits = 1 + b as u32 % coder::MAX_BITS;
    if let Ok((positions, faces)) = coder::decode_base(data, bits) {
        assert!(faces.len() <= 4 * data.len().max(1), "more faces than the byte bound allows");
        assert!(faces.iter().flatten().all(|&v| (v as usize) < positions.len()), "face index out of range");
        assert!(positions.iter().flatten().all(|&c| (c as u64) < 1 << bits), "position off the grid");
    }
}

/// The motion decoder, on the context mesh the first byte picks.
pub fn motion(input: &[u8]) {
    let Some((&b, data)) = input.split_first() else { return };
    let (reference, faces) = context_mesh(b);
    let mut dec = ec::Decoder::new(data);
    if let Ok(moved) = motion::decode_motion(&mut dec, &reference, &faces, CONTEXT_BITS) {
        assert_eq!(moved.len(), reference.len());
        assert!(moved.iter().flatten().all(|&c| c < 1 << CONTEXT_BITS), "motion left the grid");
    }
}

/// The refresh decoder, on the context mesh the first byte picks as the moved base; a
/// refresh it reads must give a base whose faces stay within its vertices.
pub fn refresh(input: &[u8]) {
    let Some((&b, data)) = input.split_first() else { return };
    let (positions, faces) = context_mesh(b);
    if let Ok((dropped, patch)) = refresh::decode_refresh(data, faces.len(), CONTEXT_BITS) {
        assert_eq!(dropped.len(), faces.len());
        let ((p, f), kept) = refresh::apply(&positions, &faces, &dropped, &patch);
        assert_eq!(kept.len(), dropped.iter().filter(|&&d| !d).count());
        assert!(f.iter().flatten().all(|&v| (v as usize) < p.len()), "refreshed face index out of range");
    }
}

/// The UV decoders (with and without the 3D positions: bit 7 of the first byte), on the
/// context mesh the first byte picks, with 1 to 16 bits (the second byte).
pub fn uv(input: &[u8]) {
    let [b, bits, data @ ..] = input else { return };
    let (positions, faces) = context_mesh(*b);
    let bits = 1 + *bits as u32 % uvcoder::MAX_UV_BITS;
    let decoded = if b & 0x80 != 0 {
        let world: Vec<[f64; 3]> = positions.iter().map(|p| p.map(f64::from)).collect();
        uvcoder::decode_uv_with_positions(data, &world, &faces, bits)
    } else {
        uvcoder::decode_uv(data, &faces, positions.len(), bits)
    };
    if let Ok((uv_faces, uv)) = decoded {
        assert_eq!(uv_faces.len(), faces.len());
        assert!(uv_faces.iter().flatten().all(|&i| (i as usize) < uv.len()), "UV index out of range");
        assert!(uv.iter().flatten().all(|&c| c < 1 << bits), "UV off its grid");
    }
}

/// The coefficient decoder, on the context mesh the first byte picks, subdivided 0 to 3
/// times (bits 5-6), with 1 or 3 components (bit 7).
pub fn coef(input: &[u8]) {
    let Some((&b, data)) = input.split_first() else { return };
    let (comps, sub) = coefficient_context(b);
    let mut dec = ec::Decoder::new(data);
    if let Ok(q) = coefcoder::decode(&mut dec, comps, &sub) {
        assert_eq!(q.len(), sub.positions.len() * comps);
    }
}

fn coefficient_context(b: u8) -> (usize, crate::residual::subdivide::Subdivision) {
    let (positions, faces) = context_mesh(b);
    let world: Vec<[f64; 3]> = positions.iter().map(|p| p.map(f64::from)).collect();
    let iterations = (b >> 5 & 3) as usize;
    let schemes = [Scheme::Midpoint, Scheme::Loop, Scheme::Loop];
    (if b & 0x80 != 0 { 3 } else { 1 }, subdivide(&world, &faces, &schemes[..iterations]))
}

/// One of four small meshes on the 9-bit base grid, by `b % 4`: an octahedron, the same
/// refined once, two tetrahedra sharing a vertex (non-manifold), and an open strip with a
/// face repeated and one reversed (inconsistent orientation).
pub fn context_mesh(b: u8) -> coder::GridMesh {
    let octahedron_p = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let octahedron_f = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    let (p, f): (Vec<[f64; 3]>, Vec<[u32; 3]>) = match b % 4 {
        0 => (octahedron_p, octahedron_f),
        1 => {
            let s = subdivide(&octahedron_p, &octahedron_f, &[Scheme::Midpoint]);
            (s.positions.iter().map(|&q| crate::geom::mesh::normalize(q)).collect(), s.faces)
        }
        2 => (
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2], [0, 4, 5], [0, 5, 6], [0, 6, 4], [4, 6, 5]],
        ),
        _ => (
            (0..8).map(|i| [(i / 2) as f64 / 4.0, (i % 2) as f64, 0.0]).collect(),
            vec![[0, 1, 2], [1, 3, 2], [2, 3, 4], [2, 3, 4], [5, 4, 3], [4, 5, 6], [5, 7, 6]],
        ),
    };
    let scale = ((1u32 << CONTEXT_BITS) - 1) as f64 / 2.0;
    (p.iter().map(|q| q.map(|c| ((c + 1.0) * scale).round() as u32)).collect(), f)
}

/// A valid input for each target, by target name (`stream`, `base`, `motion`, `refresh`,
/// `uv`, `coef`), made by the encoders from the context meshes.
pub fn seeds() -> Vec<(&'static str, Vec<u8>)> {
    let mut out = vec![("stream", stream_seed())];
    for b in 0..4u8 {
        let (p, f) = context_mesh(b);
        out.push(("base", [&[CONTEXT_BITS as u8 - 1][..], &coder::encode_base(&p, &f, CONTEXT_BITS)].concat()));
        let moved: Vec<[u32; 3]> = p.iter().map(|q| [q[0].saturating_sub(3), q[1].saturating_sub(2), q[2]]).collect();
        out.push(("motion", [&[b][..], &motion::encode_motion(&p, &moved, &f)].concat()));
        let dropped: Vec<bool> = (0..f.len()).map(|i| i % 3 == 0).collect();
        let patch = coder::encode_base(&p, &f[..1], CONTEXT_BITS);
        out.push(("refresh", [&[b][..], &refresh::encode_refresh(&dropped, &patch)].concat()));
        let uv: Vec<[u32; 2]> = p.iter().map(|q| [q[0], q[1]]).collect();
        out.push(("uv", [&[b, CONTEXT_BITS as u8 - 1][..], &uvcoder::encode_uv(&f, &f, &uv, CONTEXT_BITS)].concat()));
        let c = b | 0x40;
        let (comps, sub) = coefficient_context(c);
        let q: Vec<i32> = (0..sub.positions.len() * comps).map(|i| (i as i32 % 7) - 3).collect();
        let mut enc = ec::Encoder::new();
        coefcoder::encode(&mut enc, &q, comps, &sub);
        out.push(("coef", [&[c][..], &enc.finish()].concat()));
    }
    out
}

/// A two-frame stream (intra, predicted) of the refined octahedron, CRC flag set.
fn stream_seed() -> Vec<u8> {
    use crate::encoder::{EncoderConfig, FormatParams, SequenceEncoder};
    let (p, f) = context_mesh(1);
    let world: Vec<[f64; 3]> = p.iter().map(|q| q.map(|c| c as f64 / 511.0)).collect();
    let moved: Vec<[f64; 3]> = world.iter().map(|q| [q[0] * 0.95 + 0.02, q[1], q[2]]).collect();
    let cfg = EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, ..Default::default() };
    let mut enc = SequenceEncoder::new(cfg, 2, [0.0; 3], [1.0; 3]).expect("valid configuration");
    let mut out = vec![1];
    out.extend(bitstream::write_header(enc.header()));
    for m in [world, moved] {
        out.extend(enc.encode(&crate::geom::mesh::Mesh::new(m, f.clone())).expect("a valid mesh").unit);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every target accepts its seeds, their truncations and single bit flips.
    #[test]
    fn targets_run_on_their_seeds_and_mutations() {
        let targets =
            [("stream", stream as fn(&[u8])), ("base", base), ("motion", motion), ("refresh", refresh), ("uv", uv), ("coef", coef)];
        for (name, seed) in seeds() {
            let target = targets.iter().find(|t| t.0 == name).expect("a target per seed").1;
            target(&seed);
            for cut in (0..seed.len()).step_by(7) {
                target(&seed[..cut]);
            }
            for bit in (0..seed.len() * 8).step_by(13) {
                let mut m = seed.clone();
                m[bit / 8] ^= 1 << (bit % 8);
                target(&m);
            }
        }
    }

    #[test]
    fn the_seeds_decode() {
        let seeds = seeds();
        let stream_seed = &seeds[0].1;
        let mut d = Decoder::new(stream_seed[1..].to_vec()).unwrap();
        assert_eq!(d.frame_count(), 2);
        assert!(d.decode_frame(1).is_ok());
        for (name, s) in &seeds[1..] {
            let (p, f) = context_mesh(s[0]);
            match *name {
                "base" => assert!(!coder::decode_base(&s[1..], CONTEXT_BITS).unwrap().1.is_empty()),
                "motion" => assert!(motion::decode_motion(&mut ec::Decoder::new(&s[1..]), &p, &f, CONTEXT_BITS).is_ok()),
                "refresh" => assert!(refresh::decode_refresh(&s[1..], f.len(), CONTEXT_BITS).is_ok()),
                "uv" => assert!(uvcoder::decode_uv(&s[2..], &f, p.len(), CONTEXT_BITS).is_ok()),
                _ => {
                    let (comps, sub) = coefficient_context(s[0]);
                    assert!(coefcoder::decode(&mut ec::Decoder::new(&s[1..]), comps, &sub).is_ok());
                }
            }
        }
    }
}
