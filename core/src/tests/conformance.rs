//! The Rust decoder against the conformance vectors (`tests/vectors`, written by
//! `python -m dynmesh.conformance`), which the JavaScript decoder is checked against too:
//! every frame of every stream at every level of detail must hash as the manifest says, and
//! the level scales must equal the table every decoder checks its `pow` against.

use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::decoder::Decoder;
use crate::geom::mesh::Mesh;
use crate::residual::quantize::lod_scales;
use sha2::{Digest, Sha256};

fn vectors() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/vectors")
}

/// SHA-256 of positions as little-endian f64, then faces as little-endian u32.
fn frame_hash(m: &Mesh) -> String {
    let mut h = Sha256::new();
    for p in &m.positions {
        for c in p {
            h.update(c.to_le_bytes());
        }
    }
    for f in &m.faces {
        for v in f {
            h.update(v.to_le_bytes());
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// manifest.txt as stream -> lod -> hashes by frame.
fn manifest() -> BTreeMap<String, BTreeMap<u32, Vec<String>>> {
    let text = std::fs::read_to_string(vectors().join("manifest.txt")).expect("tests/vectors/manifest.txt");
    let mut out: BTreeMap<String, BTreeMap<u32, Vec<String>>> = BTreeMap::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let w: Vec<&str> = line.split(' ').collect();
        assert_eq!(w.len(), 7, "bad manifest line {line:?}");
        if w[5] != "sha256" {
            continue; // uvsha256: textured frames' UVs, which the Python decoder makes
        }
        let frames = out.entry(w[0].into()).or_default().entry(w[2].parse().unwrap()).or_default();
        assert_eq!(frames.len(), w[4].parse::<usize>().unwrap(), "frames in order: {line:?}");
        frames.push(w[6].into());
    }
    out
}

#[test]
fn every_vector_decodes_to_its_manifest_hashes_at_every_level_of_detail() {
    let m = manifest();
    assert!(m.len() >= 5, "{} vectors", m.len());
    for (stream, levels) in &m {
        let data = std::fs::read(vectors().join(stream)).unwrap();
        let mut dec = Decoder::new(data).unwrap();
        assert_eq!(levels.len() as u32, dec.header().subdiv_iterations() + 1, "{stream}: every level listed");
        for (&lod, hashes) in levels {
            dec.set_lod(lod).unwrap();
            assert_eq!(hashes.len() as u32, dec.frame_count(), "{stream}");
            for (i, want) in hashes.iter().enumerate() {
                let got = frame_hash(&dec.decode_frame(i as u32).unwrap());
                assert_eq!(&got, want, "{stream} frame {i} lod {lod}");
            }
        }
    }
}

#[test]
fn decoding_out_of_order_and_at_full_detail_gives_the_same_frames() {
    // Seeking (a predicted frame first, then back) walks the reference chain; the hash must
    // not depend on the order of requests, and set_lod to the full count changes nothing.
    for (stream, levels) in &manifest() {
        let data = std::fs::read(vectors().join(stream)).unwrap();
        let mut dec = Decoder::new(data).unwrap();
        let full = *levels.keys().max().unwrap();
        dec.set_lod(full).unwrap();
        let n = dec.frame_count();
        for i in (0..n).rev() {
            assert_eq!(frame_hash(&dec.decode_frame(i).unwrap()), levels[&full][i as usize], "{stream} frame {i}");
        }
        assert!(dec.set_lod(full + 1).is_err());
    }
}

#[test]
fn level_scales_equal_the_shared_table() {
    let text = std::fs::read_to_string(vectors().join("scales.txt")).unwrap();
    let mut n = 0;
    for line in text.lines() {
        let w: Vec<&str> = line.split(' ').collect();
        let (bits, qp): (u32, i32) = (w[0].parse().unwrap(), w[1].parse().unwrap());
        let want = u64::from_str_radix(w[2], 16).unwrap();
        assert_eq!(lod_scales(qp, bits, 1)[0].to_bits(), want, "bits {bits} qp {qp}");
        n += 1;
    }
    assert_eq!(n, 13 * 88);
}

#[test]
fn a_vector_refers_further_back_than_the_previous_frame() {
    // Reference choice: far_reference.dmsh's last frame repeats frame 1 and refers to it.
    let data = std::fs::read(vectors().join("far_reference.dmsh")).unwrap();
    let dec = Decoder::new(data).unwrap();
    let last = dec.frame_count() - 1;
    assert_eq!(dec.frame_info(last).unwrap().reference, Some(1));
}
