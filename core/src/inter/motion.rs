//! Base mesh motion coding: a predicted frame's base mesh keeps its reference's
//! connectivity, so only the motion of each quantized vertex is coded.
//!
//! Vertices are visited breadth-first from the lowest index of each connected component, so
//! that every vertex but a component's first has already-coded neighbours. Its motion is
//! predicted from theirs, by one of two predictors that the block's first bit selects:
//! - *neighbour mean*: the rounded mean of the coded neighbours' motions, exact for a
//!   translation;
//! - *local affine*: the motion at the vertex of a ridge-regularised affine fit to the
//!   motions of the coded vertices within two rings, which also follows the rotation and
//!   stretching of a limb that the mean smears (on horse_gallop's first 12 frames at QP 25
//!   the predicted frames' motion blocks are 13.6 % smaller).
//!
//! The encoder codes both and keeps the smaller block. The residual is coded as a skip flag
//! (all three components zero; context: how many coded neighbours were skipped) and
//! otherwise three signed integers with adaptive models.

use crate::error::Corrupt;
use crate::geom::mesh::Adjacency;
use crate::ec::{self, BitModel, DecSide, EncSide, IntModel, Side};

/// Coding contexts, shared by encoder and decoder so that both adapt identically.
struct Models {
    skip: [BitModel; 3],
    residual: [IntModel; 3],
}

impl Models {
    fn new() -> Self {
        Self { skip: [BitModel::default(); 3], residual: std::array::from_fn(|_| IntModel::new(0)) }
    }
}

/// Breadth-first visiting order over all vertices, one tree per connected component.
fn coding_order(adjacency: &Adjacency, n: usize) -> Vec<u32> {
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    for seed in 0..n {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        let mut head = order.len();
        order.push(seed as u32);
        while head < order.len() {
            let v = order[head] as usize;
            head += 1;
            for &w in adjacency.of(v) {
                if !seen[w as usize] {
                    seen[w as usize] = true;
                    order.push(w);
                }
            }
        }
    }
    order
}

/// How a vertex's motion is predicted from the coded vertices around it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Predictor {
    NeighbourMean,
    LocalAffine,
}

/// The ridge weight of the affine fit, in squared base-grid units per unit of gradient: it
/// pulls a fit over a few close vertices towards a translation (a sweep on horse_gallop was
/// flat from 20 to 50, docs/results.md).
const RIDGE: i64 = 30;
/// Fewer coded vertices within two rings than this, and the affine fit falls back to the mean.
const AFFINE_MIN_SAMPLES: usize = 4;
/// At most this many coded vertices enter a fit, and at most `MAX_SCAN` neighbour-list entries
/// are read to find them: this bounds the work per vertex around a hub of high valence and
/// keeps every integer sum below 2^53 on a 20-bit grid, so that the JavaScript decoder's
/// doubles hold them exactly.
const MAX_SAMPLES: usize = 32;
const MAX_SCAN: usize = 256;

/// Mean motion of the already-coded neighbours of `v` (rounded half away from zero), and
/// how many of them were skipped (capped at 2), which selects the skip context.
fn neighbour_mean(v: usize, adjacency: &Adjacency, motion: &[Option<[i64; 3]>], skipped: &[bool]) -> ([i64; 3], usize) {
    let mut sum = [0i64; 3];
    let mut count = 0i64;
    let mut skips = 0;
    for &w in adjacency.of(v) {
        if let Some(m) = motion[w as usize] {
            (0..3).for_each(|k| sum[k] += m[k]);
            count += 1;
            skips += skipped[w as usize] as usize;
        }
    }
    let pred = if count == 0 { [0; 3] } else { sum.map(|s| div_round(s, count)) };
    (pred, skips.min(2))
}

/// The coded vertices within two rings of `v`: its neighbours in list order, then each
/// neighbour's neighbours in list order, without repeats and without `v`, stopping at
/// `MAX_SAMPLES` vertices or `MAX_SCAN` list entries read. `mark` is scratch space that holds
/// no `v + 1` on entry.
fn two_ring(v: usize, adjacency: &Adjacency, motion: &[Option<[i64; 3]>], mark: &mut [u32]) -> Vec<usize> {
    let stamp = v as u32 + 1;
    mark[v] = stamp;
    let mut out = Vec::with_capacity(MAX_SAMPLES);
    let mut scanned = 0;
    let ring1 = adjacency.of(v);
    for list in std::iter::once(ring1).chain(ring1.iter().map(|&w| adjacency.of(w as usize))) {
        for &w in list {
            if scanned == MAX_SCAN || out.len() == MAX_SAMPLES {
                return out;
            }
            scanned += 1;
            let w = w as usize;
            if mark[w] != stamp && motion[w].is_some() {
                mark[w] = stamp;
                out.push(w);
            }
        }
    }
    out
}

/// The motion at `v` of the ridge-regularised affine fit `m(p) = A (p - p_v) + t` to the
/// motions of `samples`, i.e. `t` rounded half up; `None` when the fit is not finite.
///
/// Every sum is an exact integer; the solve then runs in doubles in a fixed order (the
/// adjugate of the 3 x 3 normal matrix) that the JavaScript decoder repeats operation for
/// operation. With `x = p_w - p_v` over n samples, the centred scatter and cross terms are
/// scaled by n to stay integers: `S = n Σxxᵀ - Σx Σxᵀ`, `C = n Σx mᵀ - Σx Σmᵀ`; the gradient
/// of axis k is `(S + nλI)⁻¹ C[:,k]`, the same fit as the ridge on the unscaled sums.
fn affine_at(v: usize, samples: &[usize], reference: &[[u32; 3]], motion: &[Option<[i64; 3]>]) -> Option<[i64; 3]> {
    let n = samples.len() as i64;
    let (mut sx, mut sm) = ([0i64; 3], [0i64; 3]);
    let (mut sxx, mut sxm) = ([[0i64; 3]; 3], [[0i64; 3]; 3]);
    for &w in samples {
        let x: [i64; 3] = std::array::from_fn(|i| reference[w][i] as i64 - reference[v][i] as i64);
        let m = motion[w].expect("samples are coded");
        for i in 0..3 {
            sx[i] += x[i];
            sm[i] += m[i];
            for j in 0..3 {
                sxx[i][j] += x[i] * x[j];
                sxm[i][j] += x[i] * m[j];
            }
        }
    }
    let s = |i: usize, j: usize| (n * sxx[i][j] - sx[i] * sx[j] + if i == j { n * RIDGE } else { 0 }) as f64;
    let c = |i: usize, k: usize| (n * sxm[i][k] - sx[i] * sm[k]) as f64;
    let (m00, m01, m02, m11, m12, m22) = (s(0, 0), s(0, 1), s(0, 2), s(1, 1), s(1, 2), s(2, 2));
    let adj = [
        [m11 * m22 - m12 * m12, m02 * m12 - m01 * m22, m01 * m12 - m02 * m11],
        [m02 * m12 - m01 * m22, m00 * m22 - m02 * m02, m01 * m02 - m00 * m12],
        [m01 * m12 - m02 * m11, m01 * m02 - m00 * m12, m00 * m11 - m01 * m01],
    ];
    let det = m00 * adj[0][0] + m01 * adj[0][1] + m02 * adj[0][2];
    let mut pred = [0i64; 3];
    for k in 0..3 {
        let g: [f64; 3] = std::array::from_fn(|i| (adj[i][0] * c(0, k) + adj[i][1] * c(1, k) + adj[i][2] * c(2, k)) / det);
        let t = (sm[k] as f64 - (g[0] * sx[0] as f64 + g[1] * sx[1] as f64 + g[2] * sx[2] as f64)) / n as f64;
        let t = (t + 0.5).floor();
        if !t.is_finite() || t.abs() > (1u64 << 40) as f64 {
            return None;
        }
        pred[k] = t as i64;
    }
    Some(pred)
}

fn div_round(a: i64, b: i64) -> i64 {
    if a >= 0 {
        (a + b / 2) / b
    } else {
        -((-a + b / 2) / b)
    }
}

/// The motion block from `reference` to `current` (quantized positions of the same
/// vertices, connectivity `faces`), with whichever predictor makes it smaller. Both slices
/// must have the same length.
pub fn encode_motion(reference: &[[u32; 3]], current: &[[u32; 3]], faces: &[[u32; 3]]) -> Vec<u8> {
    assert_eq!(reference.len(), current.len(), "motion needs the reference's vertices");
    let adjacency = Adjacency::new(reference.len(), faces);
    let mean = block(Predictor::NeighbourMean, reference, current, &adjacency);
    let affine = block(Predictor::LocalAffine, reference, current, &adjacency);
    if affine.len() < mean.len() {
        affine
    } else {
        mean
    }
}

/// The motion block of `current` with `predictor`.
fn block(predictor: Predictor, reference: &[[u32; 3]], current: &[[u32; 3]], adjacency: &Adjacency) -> Vec<u8> {
    let mut enc = ec::Encoder::new();
    code_motion(&mut EncSide(&mut enc), Some((predictor, current)), reference, adjacency, u32::MAX.into());
    enc.finish()
}

/// Decodes what [`encode_motion`] wrote: the current positions of the reference's vertices
/// on a grid of `bits` bits. An error if the data is truncated, corrupt, or moves a vertex
/// off the grid; the caller adds where.
pub fn decode_motion(dec: &mut ec::Decoder, reference: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> Result<Vec<[u32; 3]>, Corrupt> {
    let corrupt = || Corrupt::from("base mesh motion is truncated or corrupt");
    let adjacency = Adjacency::new(reference.len(), faces);
    let current = code_motion(&mut DecSide(dec), None, reference, &adjacency, (1i64 << bits) - 1).ok_or_else(corrupt)?;
    dec.finish().map_err(|_| corrupt())?;
    Ok(current)
}

/// Both directions of the motion coding over the reference connectivity `adjacency`: the
/// encoder passes its predictor and `current` and gets `current` back, the decoder passes
/// `None` and gets what it reads, or `None` when the data runs out or moves a vertex off the
/// grid `0..=max`.
fn code_motion(
    side: &mut impl Side,
    encoding: Option<(Predictor, &[[u32; 3]])>,
    reference: &[[u32; 3]],
    adjacency: &Adjacency,
    max: i64,
) -> Option<Vec<[u32; 3]>> {
    let affine = side.bit(&mut BitModel::default(), matches!(encoding, Some((Predictor::LocalAffine, _))));
    let n = reference.len();
    let mut models = Models::new();
    let mut motion = vec![None; n];
    let mut skipped = vec![false; n];
    let mut mark = vec![0u32; if affine { n } else { 0 }];
    let mut out = vec![[0u32; 3]; n];
    for v in coding_order(adjacency, n) {
        let v = v as usize;
        let (mean, ctx) = neighbour_mean(v, adjacency, &motion, &skipped);
        let pred = if affine {
            let samples = two_ring(v, adjacency, &motion, &mut mark);
            let fit = (samples.len() >= AFFINE_MIN_SAMPLES).then(|| affine_at(v, &samples, reference, &motion)).flatten();
            fit.unwrap_or(mean)
        } else {
            mean
        };
        // The encoder's residual; the decoder's placeholder, which its side ignores.
        let residual: [i64; 3] = match encoding {
            Some((_, c)) => std::array::from_fn(|k| c[v][k] as i64 - reference[v][k] as i64 - pred[k]),
            None => [0; 3],
        };
        let skip = side.bit(&mut models.skip[ctx], residual == [0; 3]);
        let residual: [i64; 3] = if skip {
            [0; 3]
        } else {
            std::array::from_fn(|k| side.int(&mut models.residual[k], residual[k] as i32) as i64)
        };
        if side.failed() {
            return None;
        }
        let actual: [i64; 3] = std::array::from_fn(|k| pred[k] + residual[k]);
        for k in 0..3 {
            let p = reference[v][k] as i64 + actual[k];
            if !(0..=max).contains(&p) {
                return None;
            }
            out[v][k] = p as u32;
        }
        motion[v] = Some(actual);
        skipped[v] = skip;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w` x `h` grid of vertices split into triangles, on a 10-bit grid.
    fn sheet(w: u32, h: u32) -> (Vec<[u32; 3]>, Vec<[u32; 3]>) {
        let p = (0..h).flat_map(|y| (0..w).map(move |x| [100 + 10 * x, 100 + 10 * y, 500])).collect();
        let mut f = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let i = y * w + x;
                f.push([i, i + 1, i + w]);
                f.push([i + 1, i + w + 1, i + w]);
            }
        }
        (p, f)
    }

    fn round_trip(reference: &[[u32; 3]], current: &[[u32; 3]], faces: &[[u32; 3]]) -> (Vec<[u32; 3]>, usize) {
        let bytes = encode_motion(reference, current, faces);
        let mut dec = ec::Decoder::new(&bytes);
        (decode_motion(&mut dec, reference, faces, 10).expect("decodes"), bytes.len())
    }

    #[test]
    fn arbitrary_motion_round_trips() {
        let (r, f) = sheet(12, 9);
        let c: Vec<[u32; 3]> = r.iter().enumerate().map(|(i, p)| [p[0] + (i as u32 * 7) % 5, p[1] - (i as u32 % 3), p[2] + 40]).collect();
        assert_eq!(round_trip(&r, &c, &f).0, c);
    }

    #[test]
    fn a_rigid_translation_costs_almost_nothing() {
        let (r, f) = sheet(30, 30);
        let moved: Vec<[u32; 3]> = r.iter().map(|p| [p[0] + 37, p[1] + 3, p[2] - 120]).collect();
        let jitter: Vec<[u32; 3]> = r.iter().enumerate().map(|(i, p)| [p[0] + (i as u32 * 13) % 7, p[1] + (i as u32 * 5) % 3, p[2]]).collect();
        let (decoded, translation_bytes) = round_trip(&r, &moved, &f);
        assert_eq!(decoded, moved);
        let (_, jitter_bytes) = round_trip(&r, &jitter, &f);
        assert!(translation_bytes < 40, "{translation_bytes} bytes for 900 vertices moving together");
        assert!(translation_bytes * 10 < jitter_bytes);
    }

    fn block_with(predictor: Predictor, reference: &[[u32; 3]], current: &[[u32; 3]], faces: &[[u32; 3]]) -> Vec<u8> {
        block(predictor, reference, current, &Adjacency::new(reference.len(), faces))
    }

    /// The sheet turned about (250, 250): every vertex moves differently, but the field is
    /// affine (up to rounding).
    fn turned(r: &[[u32; 3]], angle: f64) -> Vec<[u32; 3]> {
        let (c, s) = (angle.cos(), angle.sin());
        r.iter()
            .map(|p| {
                let (x, y) = (p[0] as f64 - 250.0, p[1] as f64 - 250.0);
                [(250.0 + c * x - s * y).round() as u32, (250.0 + s * x + c * y).round() as u32, p[2]]
            })
            .collect()
    }

    #[test]
    fn a_rotation_picks_the_affine_predictor_and_round_trips() {
        let (r, f) = sheet(30, 30);
        let c = turned(&r, 0.4);
        let (mean, affine) = (block_with(Predictor::NeighbourMean, &r, &c, &f), block_with(Predictor::LocalAffine, &r, &c, &f));
        assert!(affine.len() * 10 < mean.len() * 9, "affine {} bytes, mean {}", affine.len(), mean.len());
        let (decoded, bytes) = round_trip(&r, &c, &f);
        assert_eq!(decoded, c);
        assert_eq!(bytes, affine.len());
    }

    #[test]
    fn the_encoder_keeps_the_smaller_block_and_each_decodes() {
        let (r, f) = sheet(12, 9);
        let noisy: Vec<[u32; 3]> = r.iter().enumerate().map(|(i, p)| [p[0] + (i as u32 * 7) % 5, p[1] + (i as u32 * 3) % 4, p[2]]).collect();
        for c in [noisy, turned(&r, 0.4)] {
            let blocks = [Predictor::NeighbourMean, Predictor::LocalAffine].map(|p| block_with(p, &r, &c, &f));
            assert_eq!(encode_motion(&r, &c, &f).len(), blocks.iter().map(Vec::len).min().unwrap());
            for b in &blocks {
                assert_eq!(decode_motion(&mut ec::Decoder::new(b), &r, &f, 10).expect("decodes"), c);
            }
        }
    }

    #[test]
    fn a_hub_of_high_valence_round_trips() {
        // A fan of 2000 triangles around vertex 0: every rim vertex's two rings run through
        // the hub's list, which the scan limit cuts short.
        let rim = 2000u32;
        let mut p = vec![[512u32, 512, 512]];
        p.extend((0..rim).map(|i| {
            let a = i as f64 / rim as f64 * std::f64::consts::TAU;
            [(512.0 + 400.0 * a.cos()) as u32, (512.0 + 400.0 * a.sin()) as u32, 512 + i % 7]
        }));
        let f: Vec<[u32; 3]> = (0..rim).map(|i| [0, 1 + i, 1 + (i + 1) % rim]).collect();
        let c = turned(&p, 0.02);
        for predictor in [Predictor::NeighbourMean, Predictor::LocalAffine] {
            let b = block_with(predictor, &p, &c, &f);
            assert_eq!(decode_motion(&mut ec::Decoder::new(&b), &p, &f, 10).expect("decodes"), c);
        }
    }

    #[test]
    fn separate_components_each_get_a_seed() {
        let (r, mut f) = sheet(4, 4);
        let mut r2 = r.clone();
        r2.extend(r.iter().map(|p| [p[0] + 300, p[1], p[2]]));
        f.extend(f.clone().iter().map(|t| t.map(|i| i + 16)));
        let c: Vec<[u32; 3]> = r2.iter().enumerate().map(|(i, p)| if i < 16 { [p[0] + 5, p[1], p[2]] } else { [p[0], p[1] + 9, p[2]] }).collect();
        assert_eq!(round_trip(&r2, &c, &f).0, c);
        assert_eq!(coding_order(&Adjacency::new(32, &f), 32).len(), 32);
    }

    #[test]
    fn truncated_or_off_grid_data_is_refused() {
        let (r, f) = sheet(10, 10);
        let c: Vec<[u32; 3]> = r.iter().enumerate().map(|(i, p)| [p[0] + (i as u32 * 7) % 11, p[1], p[2] + (i as u32) % 4]).collect();
        let bytes = encode_motion(&r, &c, &f);
        let mut dec = ec::Decoder::new(&bytes[..bytes.len() / 2]);
        assert!(decode_motion(&mut dec, &r, &f, 10).is_err());
        // The same motion read against a reference at the edge of a 10-bit grid leaves it.
        let edge: Vec<[u32; 3]> = r.iter().map(|p| [p[0], p[1], 1023]).collect();
        let mut dec = ec::Decoder::new(&bytes);
        assert!(decode_motion(&mut dec, &edge, &f, 10).is_err());
    }
}
