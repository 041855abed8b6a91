//! Entropy coding of quantized displacement coefficients.
//!
//! Coefficients are coded level of detail by level of detail, each level component by
//! component. A level whose coefficients are all zero costs one flag. Otherwise each
//! coefficient is a zero flag, a sign, a greater-than-one and a greater-than-two flag, and
//! an Exp-Golomb remainder, all with adaptive contexts per level and component. The zero
//! flag's context also counts how many of the vertex's two parents had a non-zero
//! coefficient: detail tends to cluster, and the parents are always decoded first.

use crate::error::Corrupt;
use crate::ec::{BitModel, DecSide, Decoder, EncSide, Encoder, Side, UIntModel};
use crate::residual::subdivide::Subdivision;

/// Contexts of one (level, component) pair.
#[derive(Clone)]
struct Contexts {
    all_zero: BitModel,
    zero: [BitModel; 3],
    sign: BitModel,
    gt1: BitModel,
    gt2: BitModel,
    remainder: UIntModel,
}

impl Contexts {
    fn new() -> Self {
        Self {
            all_zero: BitModel::default(),
            zero: [BitModel::default(); 3],
            sign: BitModel::default(),
            gt1: BitModel::default(),
            gt2: BitModel::default(),
            remainder: UIntModel::new(0),
        }
    }
}

/// Writes `q` (vertex-major, `comps` values per vertex of `s`). Panics on a coefficient of
/// `i32::MIN`, which no decoder could read back.
pub fn encode(enc: &mut Encoder, q: &[i32], comps: usize, s: &Subdivision) {
    let mut q = q.to_vec();
    code(&mut EncSide(enc), &mut q, comps, s).expect("coefficients above i32::MIN in magnitude");
}

/// Reads what [`encode`] wrote for the subdivision `s`. An error when the coded data runs
/// out or is impossible; the caller adds where.
pub fn decode(dec: &mut Decoder, comps: usize, s: &Subdivision) -> Result<Vec<i32>, Corrupt> {
    let corrupt = || Corrupt::from("displacement data is truncated or corrupt");
    let mut q = vec![0i32; s.positions.len() * comps];
    code(&mut DecSide(dec), &mut q, comps, s).ok_or_else(corrupt)?;
    dec.finish().map_err(|_| corrupt())?;
    Ok(q)
}

/// Codes `q` level by level, component by component: the encoder's values, or zeros that the
/// decoder fills in. `None` once the decoder has run out of data.
fn code<S: Side>(side: &mut S, q: &mut [i32], comps: usize, s: &Subdivision) -> Option<()> {
    for level in 0..s.lod_count() {
        let range = s.lod_offsets[level]..s.lod_offsets[level + 1];
        for k in 0..comps {
            let mut cx = Contexts::new();
            let all_zero = range.clone().all(|v| q[v * comps + k] == 0);
            if side.bit(&mut cx.all_zero, all_zero) {
                continue;
            }
            let mut prev = 0;
            for v in range.clone() {
                let ctx = zero_context(q, comps, k, v, level, s, prev);
                let c = coefficient(side, &mut cx, ctx, q[v * comps + k])?;
                q[v * comps + k] = c;
                prev = c;
            }
            if side.failed() {
                return None;
            }
        }
    }
    Some(())
}

fn zero_context(q: &[i32], comps: usize, k: usize, v: usize, level: usize, s: &Subdivision, prev: i32) -> usize {
    if level == 0 {
        return (prev != 0) as usize;
    }
    let [a, b] = s.parent(v);
    (q[a as usize * comps + k] != 0) as usize + (q[b as usize * comps + k] != 0) as usize
}

/// Codes one coefficient `c` (the decoder passes 0): zero flag, sign, >1, >2, remainder.
/// `None` for a decoded magnitude beyond `i32`.
fn coefficient<S: Side>(side: &mut S, cx: &mut Contexts, ctx: usize, c: i32) -> Option<i32> {
    if !side.bit(&mut cx.zero[ctx], c != 0) {
        return Some(0);
    }
    let negative = side.bit(&mut cx.sign, c < 0);
    let magnitude = c.unsigned_abs();
    let mut m: u64 = 1;
    if side.bit(&mut cx.gt1, magnitude > 1) {
        m = 2;
        if side.bit(&mut cx.gt2, magnitude > 2) {
            m = 3 + side.uint(&mut cx.remainder, magnitude.saturating_sub(3)) as u64;
        }
    }
    let m = i32::try_from(m).ok()?;
    Some(if negative { -m } else { m })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::residual::subdivide::{subdivide, Scheme};

    #[test]
    fn round_trip_with_zero_levels_and_large_values() {
        let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]];
        let s = subdivide(&p, &[[0, 1, 2], [0, 2, 3]], &[Scheme::Midpoint; 3]);
        for comps in [1, 3] {
            let n = s.positions.len();
            let q: Vec<i32> = (0..n * comps)
                .map(|i| {
                    let v = i / comps;
                    if v >= s.lod_offsets[3] { 0 } else if i == 5 { -100_000 } else { ((i * 7919) % 13) as i32 - 6 }
                })
                .collect();
            let mut e = Encoder::new();
            encode(&mut e, &q, comps, &s);
            let data = e.finish();
            let mut d = Decoder::new(&data);
            assert_eq!(decode(&mut d, comps, &s), Ok(q));
        }
    }

    #[test]
    fn truncated_data_is_detected() {
        let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0]];
        let s = subdivide(&p, &[[0, 1, 2]], &[Scheme::Midpoint; 4]);
        let q: Vec<i32> = (0..s.positions.len()).map(|i| (i % 5) as i32 * 9 - 20).collect();
        let mut e = Encoder::new();
        encode(&mut e, &q, 1, &s);
        let data = e.finish();
        let mut d = Decoder::new(&data[..data.len() / 2]);
        assert!(decode(&mut d, 1, &s).is_err());
    }
}
