//! Hostile meshes get bounded work: a clear error within seconds, not a quadratic hang.

use std::time::Instant;

use dynmesh::encode::{EncoderConfig, SequenceEncoder};
use dynmesh::{Error, Mesh};

fn encode_error(m: &Mesh) -> String {
    let (lo, hi) = m.bounds().unwrap();
    let mut enc = SequenceEncoder::new(EncoderConfig::default(), 1, lo, hi.map(|c| c + 1.0)).unwrap();
    let t = Instant::now();
    let Err(Error::Input(e)) = enc.encode(m) else { panic!("not refused as bad input") };
    assert!(t.elapsed().as_secs_f64() < 10.0, "took {:?}", t.elapsed());
    e
}

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn every_vertex_on_one_point_is_refused_at_once() {
    let m = Mesh::new(vec![[0.5; 3]; 300_000], (0..100_000).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect());
    assert!(encode_error(&m).contains("degenerate"));
}

#[test]
fn a_triangle_soup_is_refused_before_its_quadratic_fit() {
    // Separate triangles with corners anywhere in the box: decimation cannot merge them, and
    // each overlaps most others (this took minutes at 10,000 triangles).
    let mut seed = 7;
    let n = 20_000u32;
    let p: Vec<[f64; 3]> = (0..3 * n).map(|_| [lcg(&mut seed), lcg(&mut seed), lcg(&mut seed)]).collect();
    let m = Mesh::new(p, (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect());
    assert!(encode_error(&m).contains("pieces too small to simplify"));
}

#[test]
fn a_fan_of_collinear_faces_around_one_vertex_is_refused() {
    let mut seed = 3;
    let n = 50_000u32;
    let p: Vec<[f64; 3]> = (0..n + 2).map(|_| [lcg(&mut seed), 0.0, 0.0]).collect();
    let m = Mesh::new(p, (0..n).map(|i| [0, i + 1, i + 2]).collect());
    // Collinear, it has no area at all; lifted off the line, it is a fan that decimation
    // would take minutes over.
    assert!(encode_error(&m).contains("the mesh has no area"));
    let lifted = Mesh::new(m.positions.iter().map(|p| [p[0], lcg(&mut seed), 0.0]).collect(), m.faces);
    assert!(encode_error(&lifted).contains("share a few vertices"));
}

#[test]
fn a_strip_of_collinear_faces_is_refused_at_once() {
    // Decimated, it stacked thousands of base faces on a few grid points: 28 s at this size.
    let n = 100_000u32;
    let m = Mesh::new((0..n + 2).map(|i| [i as f64 / n as f64, 0.3, 0.7]).collect(), (0..n).map(|i| [i, i + 1, i + 2]).collect());
    assert!(encode_error(&m).contains("every face is degenerate: the mesh has no area"));
}
