//! Streams crafted past the CRC: the inner decoders must fail cleanly, never panic, and
//! never produce more than the bounded output.

use crate::stream::bitstream::{self, FrameType};
use crate::decoder::Decoder;
use crate::encoder::{EncoderConfig, FormatParams, SearchParams, SequenceEncoder};
use crate::geom::mesh::Mesh;

fn ball() -> Mesh {
    ball_of(2)
}

/// An octahedron refined by `levels` midpoint subdivisions and pushed onto the unit sphere.
fn ball_of(levels: u32) -> Mesh {
    let p = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let f = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    let s = crate::residual::subdivide::subdivide(&p, &f, &vec![crate::residual::subdivide::Scheme::Midpoint; levels as usize]);
    let pos = s.positions.iter().map(|&q| crate::geom::mesh::normalize(q)).collect();
    Mesh::new(pos, s.faces)
}

/// The ball, then the ball moved twice: one intra frame and two predicted ones.
fn stream(cfg: &EncoderConfig) -> Vec<u8> {
    let b = ball();
    let moved = |d: f64| Mesh::new(b.positions.iter().map(|p| [p[0] * 0.9 + d, p[1], p[2]]).collect(), b.faces.clone());
    stream_of(cfg, &[b.clone(), moved(0.05), moved(0.08)])
}

fn stream_of(cfg: &EncoderConfig, meshes: &[Mesh]) -> Vec<u8> {
    let mut enc = SequenceEncoder::new(cfg.clone(), meshes.len() as u32, [-1.0; 3], [1.0; 3]).unwrap();
    let mut out = bitstream::write_header(enc.header());
    for m in meshes {
        out.extend(enc.encode(m).unwrap().unit);
    }
    out
}

/// Recomputes the CRC of every frame unit so that corruption reaches the payload
/// decoders; false when a corrupted length field makes the units unreadable.
fn fix_crcs(data: &mut [u8]) -> bool {
    let Ok((h, mut pos)) = bitstream::read_header(data) else { return false };
    for _ in 0..h.frame_count {
        let Some(len) = data.get(pos + 1..pos + 5) else { return false };
        let end = pos + 5 + u32::from_le_bytes(len.try_into().unwrap()) as usize;
        if end + 4 > data.len() {
            return false;
        }
        let crc = crc32fast::hash(&data[pos..end]);
        data[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        pos = end + 4;
    }
    true
}

fn decode_all(data: &[u8]) -> Result<usize, crate::error::DecodeError> {
    let mut d = Decoder::new(data.to_vec())?;
    let mut vertices = 0;
    for i in 0..d.frame_count() {
        vertices += d.decode_frame(i)?.positions.len();
    }
    Ok(vertices)
}

fn lcg(seed: &mut u64) -> usize {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 33) as usize
}

#[test]
fn clean_stream_decodes_and_has_predicted_frames() {
    let s = stream(&EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, ..Default::default() });
    assert!(decode_all(&s).unwrap() > 0);
    let d = Decoder::new(s).unwrap();
    let types: Vec<FrameType> = (0..3).map(|i| d.frame_info(i).unwrap().frame_type).collect();
    assert_eq!(types, [FrameType::Intra, FrameType::Predicted, FrameType::Predicted]);
}

#[test]
fn payload_flips_behind_a_valid_crc_never_panic() {
    let cfg = EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, ..Default::default() };
    let clean = stream(&cfg);
    let (_, header_len) = bitstream::read_header(&clean).unwrap();
    let mut seed = 11u64;
    let mut errors = 0;
    for _ in 0..3000 {
        let mut d = clean.clone();
        for _ in 0..1 + lcg(&mut seed) % 3 {
            let i = header_len * 8 + lcg(&mut seed) % ((d.len() - header_len) * 8);
            d[i / 8] ^= 1 << (i % 8);
        }
        if !fix_crcs(&mut d) {
            continue;
        }
        match decode_all(&d) {
            Ok(v) => assert!(v <= crate::model::MAX_OUTPUT_FACES),
            Err(e) => {
                errors += 1;
                assert!(e.to_string().contains("byte offset"));
            }
        }
    }
    assert!(errors > 100, "{errors}");
}

#[test]
fn unknown_frame_types_are_rejected() {
    let mut d = stream(&EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, ..Default::default() });
    let (_, start) = bitstream::read_header(&d).unwrap();
    for t in [7, bitstream::TEXTURE_UNIT] {
        d[start] = t;
        assert!(fix_crcs(&mut d));
        let e = decode_all(&d).unwrap_err();
        assert_eq!(e.frame, Some(0));
        assert!(e.reason.contains(&format!("unit type {t} where a frame unit was expected")), "{e}");
    }
    assert_eq!((FrameType::Intra as u8, FrameType::Predicted as u8), (0, 1));
}

#[test]
fn a_header_asking_for_more_subdivision_than_the_frame_justifies_is_refused() {
    // 2048 base faces subdivided 6 times would be 8M faces from a frame of a few KB.
    let cfg = EncoderConfig { format: FormatParams { subdiv_iterations: 0, ..Default::default() }, search: SearchParams { base_ratio: Some(1.0), ..Default::default() } };
    let mut s = stream_of(&cfg, &[ball_of(4)]);
    let (h, start) = bitstream::read_header(&s).unwrap();
    let schemes = vec![crate::residual::subdivide::Scheme::Midpoint; bitstream::MAX_SUBDIV as usize];
    let lifting = crate::residual::transform::Lifting::per_valence(schemes.len());
    let header = bitstream::write_header(&bitstream::SequenceHeader { schemes, lifting, ..h });
    s.splice(..start, header);
    let e = decode_all(&s).unwrap_err();
    assert_eq!(e.frame, Some(0));
    assert!(e.to_string().contains("cannot be subdivided"), "{e}");
}

#[test]
fn decoder_output_equals_the_encoder_reconstruction_for_intra_and_predicted_frames() {
    let cfg = EncoderConfig { format: FormatParams { subdiv_iterations: 2, ..Default::default() }, ..Default::default() };
    let b = ball();
    let frames: Vec<Mesh> = (0..4)
        .map(|t| Mesh::new(b.positions.iter().map(|p| [p[0] * 0.8 + 0.03 * t as f64, p[1] * 0.9, p[2]]).collect(), b.faces.clone()))
        .collect();
    let mut enc = SequenceEncoder::new(EncoderConfig { search: SearchParams { intra_period: 3, ..cfg.search }, ..cfg }, 4, [-1.0; 3], [1.0; 3]).unwrap();
    let mut data = bitstream::write_header(enc.header());
    let mut recon = Vec::new();
    for f in &frames {
        let e = enc.encode(f).unwrap();
        data.extend(e.unit);
        recon.push(e.reconstruction);
    }
    let mut d = Decoder::new(data.clone()).unwrap();
    let types: Vec<FrameType> = (0..4).map(|i| d.frame_info(i).unwrap().frame_type).collect();
    assert_eq!(types, [FrameType::Intra, FrameType::Predicted, FrameType::Predicted, FrameType::Intra]);
    for i in 0..4 {
        assert_eq!(d.decode_frame(i).unwrap(), recon[i as usize], "frame {i}");
    }
    // Seeking: out of order, from a fresh decoder, gives the same frames.
    let mut d = Decoder::new(data).unwrap();
    for i in [2, 0, 3, 1, 2] {
        assert_eq!(d.decode_frame(i).unwrap(), recon[i as usize], "frame {i} out of order");
    }
}
