//! Base mesh motion coding: a predicted frame's base mesh keeps its reference's
//! connectivity, so only the motion of each quantized vertex is coded.
//!
//! Vertices are visited breadth-first from the lowest index of each connected component, so
//! that every vertex but a component's first has already-coded neighbours. Its motion is
//! predicted as the rounded mean of those neighbours' motions; the residual is coded as a
//! skip flag (all three components zero; context: how many coded neighbours were skipped)
//! and otherwise three signed integers with adaptive models.

use crate::error::Corrupt;
use crate::geom::mesh::Adjacency;
use crate::stream::ec::{self, BitModel, DecSide, EncSide, IntModel, Side};

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

/// Mean motion of the already-coded neighbours of `v` (rounded half away from zero), and
/// how many of them were skipped (capped at 2), which selects the skip context.
fn prediction(v: usize, adjacency: &Adjacency, motion: &[Option<[i64; 3]>], skipped: &[bool]) -> ([i64; 3], usize) {
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

fn div_round(a: i64, b: i64) -> i64 {
    if a >= 0 {
        (a + b / 2) / b
    } else {
        -((-a + b / 2) / b)
    }
}

/// Codes the motion from `reference` to `current` (quantized positions of the same
/// vertices, connectivity `faces`). Both slices must have the same length.
pub fn encode_motion(enc: &mut ec::Encoder, reference: &[[u32; 3]], current: &[[u32; 3]], faces: &[[u32; 3]]) {
    assert_eq!(reference.len(), current.len(), "motion needs the reference's vertices");
    code_motion(&mut EncSide(enc), reference, Some(current), faces, u32::MAX.into());
}

/// Decodes what [`encode_motion`] wrote: the current positions of the reference's vertices
/// on a grid of `bits` bits. An error if the data is truncated, corrupt, or moves a vertex
/// off the grid; the caller adds where.
pub fn decode_motion(dec: &mut ec::Decoder, reference: &[[u32; 3]], faces: &[[u32; 3]], bits: u32) -> Result<Vec<[u32; 3]>, Corrupt> {
    let corrupt = || Corrupt::from("base mesh motion is truncated or corrupt");
    let current = code_motion(&mut DecSide(dec), reference, None, faces, (1i64 << bits) - 1).ok_or_else(corrupt)?;
    dec.finish().map_err(|_| corrupt())?;
    Ok(current)
}

/// Both directions of the motion coding: the encoder passes `current` and gets it back, the
/// decoder passes `None` and gets what it reads, or `None` when the data runs out or moves a
/// vertex off the grid `0..=max`.
fn code_motion(
    side: &mut impl Side,
    reference: &[[u32; 3]],
    current: Option<&[[u32; 3]]>,
    faces: &[[u32; 3]],
    max: i64,
) -> Option<Vec<[u32; 3]>> {
    let n = reference.len();
    let adjacency = Adjacency::new(n, faces);
    let mut models = Models::new();
    let mut motion = vec![None; n];
    let mut skipped = vec![false; n];
    let mut out = vec![[0u32; 3]; n];
    for v in coding_order(&adjacency, n) {
        let v = v as usize;
        let (pred, ctx) = prediction(v, &adjacency, &motion, &skipped);
        // The encoder's residual; the decoder's placeholder, which its side ignores.
        let residual: [i64; 3] = match current {
            Some(c) => std::array::from_fn(|k| c[v][k] as i64 - reference[v][k] as i64 - pred[k]),
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
        let mut enc = ec::Encoder::new();
        encode_motion(&mut enc, reference, current, faces);
        let bytes = enc.finish();
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
        let mut enc = ec::Encoder::new();
        encode_motion(&mut enc, &r, &c, &f);
        let bytes = enc.finish();
        let mut dec = ec::Decoder::new(&bytes[..bytes.len() / 2]);
        assert!(decode_motion(&mut dec, &r, &f, 10).is_err());
        // The same motion read against a reference at the edge of a 10-bit grid leaves it.
        let edge: Vec<[u32; 3]> = r.iter().map(|p| [p[0], p[1], 1023]).collect();
        let mut dec = ec::Decoder::new(&bytes);
        assert!(decode_motion(&mut dec, &edge, &f, 10).is_err());
    }
}
