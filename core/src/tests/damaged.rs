//! Damaged streams opened with `Decoder::new_tolerant`: every frame whose reference chain
//! is intact decodes exactly as from the clean stream; the others fail, named.

use crate::stream::bitstream::{self, FrameType};
use crate::decoder::Decoder;
use crate::encoder::{EncoderConfig, FormatParams, SearchParams, SequenceEncoder};
use crate::geom::mesh::Mesh;

/// An octahedron pushed onto the unit sphere after one midpoint subdivision, moving along x.
fn frames(n: usize) -> Vec<Mesh> {
    let p = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]];
    let f = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    let s = crate::residual::subdivide::subdivide(&p, &f, &[crate::residual::subdivide::Scheme::Midpoint; 2]);
    let ball: Vec<[f64; 3]> = s.positions.iter().map(|&q| crate::geom::mesh::normalize(q)).collect();
    (0..n).map(|t| Mesh::new(ball.iter().map(|q| [q[0] * 0.8 + 0.02 * t as f64, q[1] * 0.9, q[2]]).collect(), s.faces.clone())).collect()
}

/// The stream (intra every other frame: I P I P ...) and the start offset of every unit.
fn stream(n: usize) -> (Vec<u8>, Vec<usize>) {
    let cfg = EncoderConfig { format: FormatParams { subdiv_iterations: 1, ..Default::default() }, search: SearchParams { intra_period: 2, ..Default::default() } };
    let mut enc = SequenceEncoder::new(cfg, n as u32, [-1.0; 3], [1.0; 3]).unwrap();
    let mut data = bitstream::write_header(enc.header());
    let mut starts = Vec::new();
    for m in frames(n) {
        starts.push(data.len());
        data.extend(enc.encode(&m).unwrap().unit);
    }
    (data, starts)
}

/// Per frame: the decoded mesh, or None when it fails.
fn decode_each(data: &[u8]) -> Vec<Option<Mesh>> {
    let mut d = Decoder::new_tolerant(data.to_vec()).unwrap();
    (0..d.frame_count()).map(|i| d.decode_frame(i).ok()).collect()
}

fn clean_frames(data: &[u8]) -> Vec<Option<Mesh>> {
    let mut d = Decoder::new(data.to_vec()).unwrap();
    (0..d.frame_count()).map(|i| Some(d.decode_frame(i).unwrap())).collect()
}

/// `expected` with the frames in `lost` removed.
fn without(expected: &[Option<Mesh>], lost: &[usize]) -> Vec<Option<Mesh>> {
    expected.iter().enumerate().map(|(i, m)| if lost.contains(&i) { None } else { m.clone() }).collect()
}

#[test]
fn the_stream_alternates_intra_and_predicted_frames() {
    let (data, _) = stream(6);
    let d = Decoder::new(data).unwrap();
    let types: Vec<FrameType> = (0..6).map(|i| d.frame_info(i).unwrap().frame_type).collect();
    assert_eq!(types, [0, 1, 2, 3, 4, 5].map(|i| if i % 2 == 0 { FrameType::Intra } else { FrameType::Predicted }));
}

#[test]
fn a_damaged_payload_loses_its_frame_and_the_frames_predicted_from_it() {
    let (clean, starts) = stream(6);
    let expected = clean_frames(&clean);
    // A payload byte of intra frame 2: frame 3 is predicted from it.
    let mut d = clean.clone();
    d[starts[2] + 12] ^= 0x40;
    assert!(Decoder::new(d.clone()).is_err(), "the strict decoder refuses it");
    assert_eq!(decode_each(&d), without(&expected, &[2, 3]));
    let dec = Decoder::new_tolerant(d.clone()).unwrap();
    let damage = dec.damage();
    assert_eq!(damage.len(), 1);
    assert_eq!((damage[0].0, damage[0].1.start), (2, starts[2] as u64));
    // A damaged predicted frame takes only itself.
    let mut d = clean.clone();
    d[starts[5] + 12] ^= 0x01;
    assert_eq!(decode_each(&d), without(&expected, &[5]));
    let mut dec = Decoder::new_tolerant(d).unwrap();
    let e = dec.decode_frame(5).unwrap_err();
    assert_eq!((e.frame, e.offset), (Some(5), starts[5] as u64));
    assert!(e.reason.contains("damaged frame unit"), "{e}");
}

#[test]
fn a_damaged_length_field_is_resynchronised_and_later_frames_are_counted_from_the_end() {
    let (clean, starts) = stream(6);
    let expected = clean_frames(&clean);
    let mut d = clean.clone();
    d[starts[1] + 3] ^= 0x10; // frame 1's length now points far past the next unit
    assert_eq!(decode_each(&d), without(&expected, &[1]));
    // Two such regions: the frames between them cannot be numbered, so they are lost too.
    d[starts[3] + 2] ^= 0x08;
    assert_eq!(decode_each(&d), without(&expected, &[1, 2, 3]));
    let mut dec = Decoder::new_tolerant(d).unwrap();
    let e = dec.decode_frame(2).unwrap_err();
    assert_eq!(e.offset, starts[1] as u64);
}

#[test]
fn a_truncated_stream_keeps_its_complete_frames() {
    let (clean, starts) = stream(6);
    let expected = clean_frames(&clean);
    let cut = &clean[..starts[4] + 20];
    assert_eq!(decode_each(cut), without(&expected, &[4, 5]));
    // A frame predicted from a frame that is fine decodes after a lost one.
    let mut d = clean.clone();
    d[starts[0] + 9] ^= 0x04;
    let got = decode_each(&d);
    assert_eq!(got, without(&expected, &[0, 1]));
}

#[test]
fn a_damaged_reference_is_named_in_the_dependent_frames_error() {
    let (clean, starts) = stream(4);
    let mut d = clean.clone();
    d[starts[2] + 15] ^= 0x80;
    let mut dec = Decoder::new_tolerant(d).unwrap();
    let e = dec.decode_frame(3).unwrap_err();
    assert_eq!(e.frame, Some(3));
    assert!(e.reason.contains("reference frame 2"), "{e}");
}

#[test]
fn garbage_after_the_header_costs_bounded_work_and_loses_every_frame() {
    let (clean, starts) = stream(4);
    let mut d = clean[..starts[0]].to_vec();
    d.extend((0..200_000u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8 % 3));
    let t = std::time::Instant::now();
    assert_eq!(decode_each(&d), vec![None; 4]);
    assert!(t.elapsed().as_secs_f64() < 5.0, "{:?}", t.elapsed());
}
