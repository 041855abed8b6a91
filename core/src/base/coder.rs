//! Lossless static coder of the base mesh (the role Draco/Edgebreaker plays in the test model).
//!
//! The stream is one range-coded block ([`crate::ec`]) in which every symbol has an adaptive
//! context. Connectivity is coded whole before positions, so that each position can be
//! predicted from all of its neighbours that precede it, not only from the face it was
//! reached through: that is worth more than the geometric contexts interleaving would give
//! the connectivity symbols.
//!
//! The connectivity traversal is [`crate::base::connectivity`], the position prediction
//! [`crate::base::positions`]; this module holds the block's header, its bounds and padding.
//!
//! Format:
//! ```text
//! uint n_vertices, uint n_faces   adaptive Exp-Golomb (k = 8); n_faces <= 4 x byte length,
//!                                 3 <= n_vertices <= 3 n_faces unless both are 0
//! connectivity symbols            the traversal above, until n_faces faces are known
//! 3 x n_vertices residuals        in the greedy order
//! zero bytes                      padding to ceil(n_faces / 4) bytes, so that bound holds
//! ```
//! The canonical mesh is the decoder's: vertices numbered in order of creation by the
//! traversal, faces in traversal order.

use crate::error::Corrupt;
use crate::base::connectivity::{connectivity, Source};
use crate::base::positions::code_positions;
use crate::ec::{DecSide, Decoder, EncSide, Encoder, UIntModel};

/// Most faces one byte of stream may announce: a hostile stream costs at most this much
/// work and memory per byte. Real meshes need well over 2 bits per face; the encoder pads the
/// streams of unusually regular ones, so the bound never rejects its own output.
const MAX_FACES_PER_BYTE: usize = 4;
/// Largest supported position bit depth (residuals must fit an i32 with room to spare).
pub const MAX_BITS: u32 = 30;

/// Codes a triangle mesh with integer positions in `[0, 2^bits)` losslessly up to a
/// relabelling of vertices and an order/rotation of faces (orientation kept).
///
/// Vertices no face references are dropped, and so are faces with a repeated vertex index
/// (they carry no surface). Panics if `bits` is not in `1..=MAX_BITS`, if a face refers to a
/// vertex beyond `positions`, or if a coordinate is `>= 2^bits`: those are caller bugs.
pub fn encode_base(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> Vec<u8> {
    encode(positions, faces, bits, true)
}

/// [`encode_base`], or only its header and connectivity (to measure their share).
fn encode(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32, with_positions: bool) -> Vec<u8> {
    assert!((1..=MAX_BITS).contains(&bits), "position bit depth {bits} out of range");
    assert!(
        positions.iter().flatten().all(|&c| (c as u64) < 1u64 << bits),
        "a position does not fit in {bits} bits"
    );
    assert!(
        faces.iter().flatten().all(|&v| (v as usize) < positions.len()),
        "a face refers to a missing vertex"
    );
    assert!(faces.len() < (u32::MAX / 3) as usize, "too many faces");
    let faces: Vec<[u32; 3]> =
        faces.iter().copied().filter(|f| f[0] != f[1] && f[1] != f[2] && f[2] != f[0]).collect();
    let mut used = vec![false; positions.len()];
    faces.iter().flatten().for_each(|&v| used[v as usize] = true);
    let n_vertices = used.iter().filter(|&&u| u).count() as u32;

    let mut enc = Encoder::new();
    let mut header = UIntModel::new(8);
    enc.uint(&mut header, n_vertices);
    enc.uint(&mut header, faces.len() as u32);
    let mut side = EncSide(&mut enc);
    let mut source = Source::new(&faces, positions.len());
    let conn = connectivity(&mut side, Some(&mut source), n_vertices, faces.len())
        .expect("the encoder's own traversal is consistent");
    let ordered: Vec<[u32; 3]> = source.new2old.iter().map(|&o| positions[o as usize]).collect();
    if with_positions {
        code_positions(&mut side, &conn.faces, n_vertices as usize, bits, Some(&ordered))
            .expect("the encoder's own positions are in range");
    }
    let mut out = enc.finish();
    let min_len = if with_positions { faces.len().div_ceil(MAX_FACES_PER_BYTE) } else { 0 };
    if out.len() < min_len {
        out.resize(min_len, 0);
    }
    out
}

/// A base mesh on the base grid: integer positions and faces.
pub type GridMesh = (Vec<[u32; 3]>, Vec<[u32; 3]>);

/// Inverse of [`encode_base`] for the same `bits`. Returns the canonical mesh `(positions,
/// faces)`: vertices in order of first use by the traversal, faces in traversal order; the
/// encoder's caller uses exactly this decoded mesh from then on.
///
/// Never panics; returns `Err(reason)` for any stream the encoder cannot have written (as far
/// as it can tell: a corrupted stream may also decode to some other valid mesh). Work and
/// memory are bounded by `MAX_FACES_PER_BYTE` faces per input byte.
pub fn decode_base(data: &[u8], bits: u32) -> Result<GridMesh, Corrupt> {
    if !(1..=MAX_BITS).contains(&bits) {
        return Err(format!("position bit depth {bits} out of range").into());
    }
    let mut dec = Decoder::new(data);
    let mut header = UIntModel::new(8);
    let n_vertices = dec.uint(&mut header) as usize;
    let n_faces = dec.uint(&mut header) as usize;
    dec.finish().map_err(|e| Corrupt(format!("header: {e}")))?;
    if n_faces > data.len().saturating_mul(MAX_FACES_PER_BYTE) {
        return Err(format!("{n_faces} faces cannot fit in {} bytes", data.len()).into());
    }
    if n_vertices > 3 * n_faces || (n_faces > 0 && n_vertices < 3) {
        return Err(format!("{n_vertices} vertices cannot belong to {n_faces} faces").into());
    }
    let mut side = DecSide(&mut dec);
    let conn = connectivity(&mut side, None, n_vertices as u32, n_faces)?;
    let positions = code_positions(&mut side, &conn.faces, n_vertices, bits, None)?;
    dec.finish()?;
    Ok((positions, conn.faces))
}

#[cfg(test)]
mod tests {
    use super::*;

    type Tri = [[u32; 3]; 3];
    type IntMesh = (Vec<[u32; 3]>, Vec<[u32; 3]>);
    type FloatMesh = (Vec<[f64; 3]>, Vec<[u32; 3]>);

    fn lcg(seed: &mut u64) -> u32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 33) as u32
    }

    /// Faces as position triples in their least rotation (orientation kept), sorted: equal
    /// iff the meshes are equal up to relabelling and face order/rotation.
    fn canonical(positions: &[[u32; 3]], faces: &[[u32; 3]]) -> Vec<Tri> {
        let mut out: Vec<Tri> = faces
            .iter()
            .filter(|f| f[0] != f[1] && f[1] != f[2] && f[2] != f[0])
            .map(|f| {
                let t = f.map(|v| positions[v as usize]);
                (0..3).map(|k| [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]).min().unwrap()
            })
            .collect();
        out.sort_unstable();
        out
    }

    fn round_trip(positions: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> usize {
        let data = encode_base(positions, faces, bits);
        let (p, f) = decode_base(&data, bits).expect("own stream decodes");
        assert_eq!(canonical(&p, &f), canonical(positions, faces));
        assert_eq!(decode_base(&data, bits).unwrap(), (p.clone(), f.clone()), "deterministic");
        let used = f.iter().flatten().collect::<std::collections::BTreeSet<_>>().len();
        assert_eq!(used, p.len(), "no unreferenced vertex");
        data.len()
    }

    fn scale(p: [f64; 3], bits: u32) -> [u32; 3] {
        let max = ((1u64 << bits) - 1) as f64;
        p.map(|c| (c.clamp(0.0, 1.0) * max).round() as u32)
    }

    fn grid(n: u32, bits: u32) -> IntMesh {
        let mut p = vec![];
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                p.push(scale([x, y, 0.5 + 0.1 * (3.0 * x).sin() * y], bits));
            }
        }
        let mut f = vec![];
        let id = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                f.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                f.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (p, f)
    }

    /// Icosahedron subdivided `levels` times, projected on a sphere (20 * 4^levels faces).
    fn icosphere(levels: u32, bits: u32) -> IntMesh {
        let (p, f) = crate::geom::testmesh::icosphere(levels, 1.0);
        (p.iter().map(|v| scale(v.map(|c| 0.5 + 0.5 * c), bits)).collect(), f)
    }

    fn cube(bits: u32) -> IntMesh {
        let m = (1u32 << bits) - 1;
        let p = (0..8).map(|i| [(i & 1) * m, (i >> 1 & 1) * m, (i >> 2 & 1) * m]).collect();
        let f = vec![
            [0, 2, 3],
            [0, 3, 1],
            [4, 5, 7],
            [4, 7, 6],
            [0, 1, 5],
            [0, 5, 4],
            [2, 6, 7],
            [2, 7, 3],
            [0, 4, 6],
            [0, 6, 2],
            [1, 3, 7],
            [1, 7, 5],
        ];
        (p, f)
    }

    fn test_meshes(bits: u32) -> Vec<(&'static str, IntMesh)> {
        let tri = (vec![[1, 2, 3], [7, 1, 0], [0, 5, 2]], vec![[0, 1, 2]]);
        let (gp, gf) = grid(12, bits);
        let (ip, i_f) = icosphere(2, bits);
        let (cp, cf) = cube(bits);
        // Two disjoint components, plus a third touching the second at one vertex, with an
        // unreferenced vertex and a degenerate face in between.
        let mut two_p = cp.clone();
        two_p.extend(ip.iter().map(|v| v.map(|c| c / 2)));
        two_p.push([1, 1, 1]);
        let mut two_f: Vec<[u32; 3]> = i_f.iter().map(|f| f.map(|v| v + 8)).collect();
        two_f.extend(&cf);
        two_f.push([3, 3, 5]);
        two_f.push([8, 20, 2]);
        // Three faces on one edge, one of them oriented with the others, plus a duplicate.
        let fan_p = vec![[0, 0, 0], [9, 0, 0], [4, 8, 0], [4, 0, 8], [4, 9, 9], [5, 5, 5]];
        let fan_f = vec![[0, 1, 2], [1, 0, 3], [0, 1, 4], [1, 0, 3], [2, 1, 5], [5, 1, 2]];
        // Duplicate positions: a grid whose middle column is doubled (a cut through the mesh).
        let (mut dp, mut df) = grid(6, bits);
        let base = dp.len() as u32;
        let column: Vec<[u32; 3]> = (0..7).map(|j| dp[j * 7 + 3]).collect();
        dp.extend(column);
        for f in df.iter_mut().filter(|f| f.iter().all(|&v| v % 7 >= 3)) {
            f.iter_mut().filter(|v| **v % 7 == 3).for_each(|v| *v = base + *v / 7);
        }
        vec![
            ("triangle", tri),
            ("grid", (gp, gf)),
            ("icosphere", (ip, i_f)),
            ("cube", (cp, cf)),
            ("components", (two_p, two_f)),
            ("non-manifold fan", (fan_p, fan_f)),
            ("duplicate positions", (dp, df)),
            ("empty", (vec![[1, 1, 1]], vec![])),
        ]
    }

    #[test]
    fn round_trips_up_to_relabelling() {
        for bits in [10, 12, 16] {
            for (name, (p, f)) in test_meshes(bits) {
                let n = round_trip(&p, &f, bits);
                println!("{name} ({bits} bits): {} faces, {n} bytes", f.len());
            }
        }
    }

    #[test]
    fn random_soups_round_trip() {
        let mut seed = 11u64;
        for _ in 0..300 {
            let nv = 3 + lcg(&mut seed) % 12;
            let p: Vec<[u32; 3]> = (0..nv).map(|_| [0; 3].map(|_| lcg(&mut seed) % 1024)).collect();
            let nf = lcg(&mut seed) % 20;
            let f: Vec<[u32; 3]> = (0..nf).map(|_| [0; 3].map(|_| lcg(&mut seed) % nv)).collect();
            round_trip(&p, &f, 10);
        }
    }

    /// Prints and returns bits per face for connectivity and for positions; the times are of
    /// one cold run each (tests share the machine: indicative only).
    fn report(name: &str, p: &[[u32; 3]], f: &[[u32; 3]], bits: u32) -> (f64, f64) {
        let t = std::time::Instant::now();
        let data = encode_base(p, f, bits);
        let encode_time = t.elapsed();
        let t = std::time::Instant::now();
        let (dp, df) = decode_base(&data, bits).unwrap();
        let decode_time = t.elapsed();
        assert_eq!(canonical(&dp, &df), canonical(p, f));
        let (total, conn) = (data.len() * 8, encode(p, f, bits, false).len() * 8);
        let nf = df.len() as f64;
        let (c, g) = (conn as f64 / nf, (total - conn) as f64 / nf);
        println!(
            "{name}: {} faces {} vertices, {bits} bits: {:.3} bits/face = {c:.3} connectivity \
             + {g:.3} positions ({:.2} bits/vertex); encode {encode_time:.2?} decode {decode_time:.2?}",
            df.len(),
            dp.len(),
            c + g,
            (total - conn) as f64 / dp.len() as f64,
        );
        (c, g)
    }

    #[test]
    fn compresses_a_smooth_sphere() {
        let (p, f) = icosphere(4, 12);
        let (c, g) = report("icosphere", &p, &f, 12);
        // Measured: 0.14 connectivity + 6.39 positions.
        assert!(c < 0.2 && c + g < 7.0, "{c} + {g} bits per face");
    }

    #[test]
    fn pads_streams_of_very_regular_meshes() {
        // A flat regular grid is predicted exactly: far under one bit per face.
        let n = 60u32;
        let p: Vec<[u32; 3]> =
            (0..=n).flat_map(|j| (0..=n).map(move |i| [8 * i, 8 * j, 77])).collect();
        let id = |i: u32, j: u32| j * (n + 1) + i;
        let f: Vec<[u32; 3]> = (0..n * n)
            .flat_map(|k| {
                let (i, j) = (k % n, k / n);
                [
                    [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                    [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
                ]
            })
            .collect();
        let len = round_trip(&p, &f, 10);
        assert_eq!(len, f.len().div_ceil(MAX_FACES_PER_BYTE));
    }

    #[test]
    fn extreme_bit_depths_round_trip() {
        for bits in [1, MAX_BITS] {
            let (p, f) = icosphere(1, bits);
            round_trip(&p, &f, bits);
        }
        let (p, f) = cube(MAX_BITS);
        round_trip(&p, &f, MAX_BITS);
    }

    fn small_stream() -> Vec<u8> {
        let (p, f) = icosphere(1, 10);
        encode_base(&p, &f, 10)
    }

    fn check_valid(r: &Result<IntMesh, Corrupt>, bits: u32) {
        if let Ok((p, f)) = r {
            assert!(f.iter().flatten().all(|&v| (v as usize) < p.len()));
            assert!(f.iter().all(|t| t[0] != t[1] && t[1] != t[2] && t[2] != t[0]));
            assert!(p.iter().flatten().all(|&c| c < 1 << bits));
        }
    }

    #[test]
    fn truncations_never_panic() {
        let data = small_stream();
        for n in 0..data.len() {
            let r = decode_base(&data[..n], 10);
            check_valid(&r, 10);
        }
    }

    #[test]
    fn byte_flips_never_panic() {
        let data = small_stream();
        let mut seed = 5u64;
        let mut ok = 0;
        for _ in 0..2000 {
            let mut d = data.clone();
            for _ in 0..1 + lcg(&mut seed) % 3 {
                let i = lcg(&mut seed) as usize % d.len();
                d[i] ^= 1 + (lcg(&mut seed) % 255) as u8;
            }
            let r = decode_base(&d, 10);
            check_valid(&r, 10);
            ok += r.is_ok() as usize;
        }
        println!("{ok} of 2000 corrupted streams decoded to some valid mesh");
    }

    #[test]
    fn huge_counts_are_rejected_quickly() {
        let mut e = Encoder::new();
        let mut m = UIntModel::new(8);
        e.uint(&mut m, 1_000_000_000);
        e.uint(&mut m, 4_000_000_000);
        let data = e.finish();
        let t = std::time::Instant::now();
        assert!(decode_base(&data, 12).is_err());
        let mut big = data.clone();
        big.resize(1 << 20, 0xA5);
        assert!(decode_base(&big, 12).is_err());
        assert!(t.elapsed().as_millis() < 200);
        // About the cheapest mesh there is, a regular grid at one point, hits the bound: its
        // stream is padded, decodes in time proportional to its length, fails unpadded.
        let (_, f) = grid(300, 12);
        let p = vec![[5, 5, 5]; 301 * 301];
        let data = encode_base(&p, &f, 12);
        assert_eq!(data.len(), f.len() / MAX_FACES_PER_BYTE);
        let t = std::time::Instant::now();
        assert_eq!(decode_base(&data, 12).map(|m| m.1.len()), Ok(f.len()));
        println!("{} faces in {} bytes decoded in {:?}", f.len(), data.len(), t.elapsed());
        assert!(decode_base(&data[..data.len() - 1], 12).is_err());
        // Random data of every short length.
        let mut seed = 9u64;
        for len in 0..300 {
            let d: Vec<u8> = (0..len).map(|_| lcg(&mut seed) as u8).collect();
            check_valid(&decode_base(&d, 12), 12);
        }
    }

    mod shared_data {
        use super::*;

        #[test]
        #[ignore = "needs ../shared/data"]
        fn codes_a_real_capture_frame() {
            let frame = crate::shared_data::read_obj("basketball_player/basketball_player_fr0011.obj");
            let (p, f) = (frame.positions, frame.faces);
            let bits = 12;
            let (lo, hi) = crate::geom::mesh::bounds(&p).unwrap();
            let side = (0..3).map(|i| hi[i] - lo[i]).fold(0.0, f64::max);
            let max = ((1u32 << bits) - 1) as f64;
            let q: Vec<[u32; 3]> = p
                .iter()
                .map(|v| [0, 1, 2].map(|i| ((v[i] - lo[i]) / side * max).round() as u32))
                .collect();
            let f: Vec<[u32; 3]> = f
                .into_iter()
                .filter(|t| {
                    let k = t.map(|v| q[v as usize]);
                    k[0] != k[1] && k[1] != k[2] && k[2] != k[0]
                })
                .collect();
            report("basketball_player_fr0011", &q, &f, bits);
            // The real base mesh is a decimated frame: a crude stand-in for that.
            let (dp, df) = decimate(&p, &f, 5000);
            let dq: Vec<[u32; 3]> = dp
                .iter()
                .map(|v| [0, 1, 2].map(|i| ((v[i] - lo[i]) / side * max).round() as u32))
                .collect();
            report("basketball_player_fr0011 decimated", &dq, &df, bits);
            report(
                "basketball_player_fr0011 decimated",
                &dq.iter().map(|v| v.map(|c| c >> 2)).collect::<Vec<_>>(),
                &df,
                10,
            );
        }
    }

    fn normal(t: [[f64; 3]; 3]) -> [f64; 3] {
        let (u, v) = ([0, 1, 2].map(|i| t[1][i] - t[0][i]), [0, 1, 2].map(|i| t[2][i] - t[0][i]));
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    }

    /// Shortest-edge-first collapse to the midpoint, keeping the link condition and face
    /// orientations: a test stand-in for the QEM decimator, irregular in the same way.
    fn decimate(p: &[[f64; 3]], f: &[[u32; 3]], target: usize) -> FloatMesh {
        use std::cmp::Reverse;
        let (mut p, mut f) = (p.to_vec(), f.to_vec());
        let mut alive = vec![true; f.len()];
        let mut vf: Vec<Vec<u32>> = vec![vec![]; p.len()];
        for (i, t) in f.iter().enumerate() {
            t.iter().for_each(|&v| vf[v as usize].push(i as u32));
        }
        let len2 = |p: &[[f64; 3]], a: u32, b: u32| -> u64 {
            let d: f64 = (0..3).map(|i| (p[a as usize][i] - p[b as usize][i]).powi(2)).sum();
            (d * 1e12) as u64
        };
        let edges = |p: &[[f64; 3]], t: [u32; 3]| -> Vec<_> {
            (0..3).map(|k| Reverse((len2(p, t[k], t[(k + 1) % 3]), t[k], t[(k + 1) % 3]))).collect()
        };
        let mut heap: std::collections::BinaryHeap<_> =
            f.iter().flat_map(|&t| edges(&p, t)).collect();
        let mut count = f.len();
        while let Some(Reverse((l, a, b))) = heap.pop() {
            if count <= target {
                break;
            }
            let shared: Vec<u32> =
                vf[a as usize].iter().copied().filter(|&x| f[x as usize].contains(&b)).collect();
            if shared.is_empty() || l != len2(&p, a, b) {
                continue;
            }
            let ring = |v: u32| -> std::collections::BTreeSet<u32> {
                vf[v as usize].iter().flat_map(|&x| f[x as usize]).collect()
            };
            if ring(a).intersection(&ring(b)).count() != shared.len() + 2 {
                continue;
            }
            let mid = [0, 1, 2].map(|i| (p[a as usize][i] + p[b as usize][i]) / 2.0);
            let moved = |t: [u32; 3]| t.map(|v| if v == a || v == b { mid } else { p[v as usize] });
            let flips =
                vf[a as usize].iter().chain(&vf[b as usize]).filter(|x| !shared.contains(x)).any(
                    |&x| {
                        let t = f[x as usize];
                        let (n0, n1) = (normal(t.map(|v| p[v as usize])), normal(moved(t)));
                        (0..3).map(|i| n0[i] * n1[i]).sum::<f64>() <= 0.0
                    },
                );
            if flips {
                continue;
            }
            p[a as usize] = mid;
            for &x in &shared {
                alive[x as usize] = false;
                count -= 1;
                for v in f[x as usize] {
                    vf[v as usize].retain(|&y| y != x);
                }
            }
            for x in std::mem::take(&mut vf[b as usize]) {
                f[x as usize].iter_mut().filter(|v| **v == b).for_each(|v| *v = a);
                vf[a as usize].push(x);
            }
            heap.extend(vf[a as usize].iter().flat_map(|&x| edges(&p, f[x as usize])));
        }
        let faces = f.iter().zip(&alive).filter(|x| *x.1).map(|x| *x.0).collect();
        (p, faces)
    }
}
