//! Quantization of wavelet coefficients, one step size per level of detail.
//!
//! As in the V-DMC test model, one QP sets the scale `2^(16 - bits + (4 - QP) / 6)` of the
//! coarsest level (coefficients in grid units), and each finer level's scale is that of the
//! level above divided by [`LOD_SCALE_DIVISOR`]: coarse coefficients spread over many
//! vertices through the inverse transform, so they are quantized more finely. Coarser levels
//! are rounded to the nearest step ([`COARSE_ROUNDING_BIAS`]); the finest level has a dead
//! zone: magnitudes are rounded down unless their fraction reaches `1 - ROUNDING_BIAS`.
//! A predicted frame's differences from its reference's coefficients have a wider dead zone,
//! [`PREDICTED_DEAD_ZONE`] steps ([`TRACKED_DEAD_ZONE`] for a tracked base), and are rounded
//! with [`ROUNDING_BIAS`] beyond it, whatever their level (the coarser levels' rounding
//! measured no better there).

use crate::geom::mesh::Adjacency;

/// QPs the codec accepts.
pub const QP_RANGE: std::ops::RangeInclusive<i32> = -24..=63;
/// Ratio of the scales of two successive levels of detail.
pub const LOD_SCALE_DIVISOR: f64 = 2.0;
/// Added to the magnitude in steps before truncation (0.5 would be plain rounding): the
/// finest level's dead zone, which holds most of the coefficients.
pub const ROUNDING_BIAS: f64 = 1.0 / 3.0;
/// The coarser levels' bias: plain rounding. A coarse coefficient spreads over many vertices
/// through the inverse transform, so rounding it down costs more distortion than the bits it
/// saves. All intra, 6 frames, QP 20-36, D1 BD-rate against the bias 1/3 at every level
/// (basketball_player, dancer, mitch, thomas): -1.6, -1.8, -1.1, -1.6 %; coarser levels at
/// 0.5 / 0.45 with the finest at 0.3: -1.8, -1.9, -1.3, -1.4 %; the finest at 0.25 or 0.4
/// instead of 1/3 moved the mean by under 0.3 points either way.
pub const COARSE_ROUNDING_BIAS: f64 = 0.5;
/// Differences between a coefficient and its reference's smaller than this many steps are
/// dropped (larger ones are truncated): most of a predicted frame's differences are that
/// small, and what dropping them costs in distortion is less than the bits they would take.
/// Measured at the QPs users work at (20-36, 6 frames, anchors refitted and carrying their
/// offsets), a dead zone of 1 step against 2: D1 BD-rate -6.6 % basketball_player, -1.3 %
/// dancer, -1.1 % mitch, -2.0 % thomas; on horse_gallop +2.1 % (QP 22-34). At the earlier,
/// lower rate points: D1 BD-rate against all-intra on horse_gallop (predicted frames only
/// by tracking), dead zone 1 / 2 / 3 steps: -51.8 / -57.7 / -59.4 %; against `--inter none` on thomas -36.4 /
/// -45.0 / -45.7 %, dancer -10.5 / -12.3 / -10.9 %. Rounding the differences as intra
/// coefficients are (no wider dead zone, bias 1/3) gave horse_gallop -40.0 % against -47.2 %
/// for a dead zone of one step, before the tracking bindings. Beyond the dead zone the
/// differences are rounded with the intra bias, not truncated: D1 BD-rate -0.8 %
/// basketball_player, -0.3 % dancer, -2.3 % mitch, -1.0 % thomas, -1.1 % horse_gallop (QP
/// 22-34, 6 frames, defaults otherwise).
pub const PREDICTED_DEAD_ZONE: f64 = 1.0;
/// The dead zone of a predicted frame whose base was tracked on an input of the reference's
/// connectivity: its base vertices stay on their material points, so its coefficients
/// repeat the reference's closer than an anchored base's do, and more of the differences
/// are noise. horse_gallop (32 frames, QP 34-22), D1 BD-rate against all-intra with a
/// dead zone of 1 / 1.5 / 2 / 3 steps: -46.1 / -48.2 / -49.1 / -48.5 %. The same choice made
/// per frame by the rate-distortion cost between 1 and 2 steps gave -49.1 % on horse_gallop
/// but lost 0.8-2.7 points on three capture sequences.
pub const TRACKED_DEAD_ZONE: f64 = 2.0;

/// Scale (inverse step) of each level of detail for `qp` and position bit depth `bits`.
pub fn lod_scales(qp: i32, bits: u32, lod_count: usize) -> Vec<f64> {
    let top = 2f64.powf(16.0 - bits as f64 + (4.0 - qp as f64) / 6.0);
    (0..lod_count).map(|l| top / LOD_SCALE_DIVISOR.powi(l as i32)).collect()
}

/// Coefficient `c` in quantization steps of `scale`, on the lattice shifted by `offset`
/// (in steps): the value [`round_dead_zone`] rounds and [`dequantize_shifted`] inverts.
#[inline]
pub fn steps(c: f64, scale: f64, offset: f64) -> f64 {
    c * scale + offset
}

/// Rounds `x` (in quantization steps) towards zero unless its fraction reaches `1 - bias`;
/// magnitudes are capped at `i32::MAX / 2`, so that a difference and the reference it is
/// added to cannot overflow.
#[inline]
pub fn round_dead_zone(x: f64, bias: f64) -> i32 {
    let m = (x.abs() + bias).floor().min(i32::MAX as f64 / 2.0) as i32;
    if x < 0.0 { -m } else { m }
}

/// The quantized coefficients of `steps` (`comps` values per vertex, vertices in level order
/// with levels starting at `lod_offsets`): the finest level rounded with [`ROUNDING_BIAS`],
/// the coarser ones with [`COARSE_ROUNDING_BIAS`].
pub fn round_levels(steps: &[f64], comps: usize, lod_offsets: &[usize]) -> Vec<i32> {
    let finest = lod_offsets[lod_offsets.len() - 2] * comps;
    steps
        .iter()
        .enumerate()
        .map(|(i, &x)| round_dead_zone(x, if i < finest { COARSE_ROUNDING_BIAS } else { ROUNDING_BIAS }))
        .collect()
}

/// Zero when `|x| < dead_zone` steps, else `x` rounded as the finest level's intra
/// coefficients are ([`round_dead_zone`] with [`ROUNDING_BIAS`]).
#[inline]
pub fn round_beyond_dead_zone(x: f64, dead_zone: f64) -> i32 {
    if x.abs() < dead_zone { 0 } else { round_dead_zone(x, ROUNDING_BIAS) }
}

/// Adaptive displacement quantization (the paper's section II-C): vertex `v`'s scale is
/// multiplied by `alpha * valence(v) / h`, so vertices with more neighbours (more local
/// detail) are quantized more finely, and the quantizer's lattice is shifted by `delta`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AqParams {
    pub alpha: f64,
    pub delta: f64,
    pub h: f64,
}

impl Default for AqParams {
    fn default() -> Self {
        Self { alpha: 1.0, delta: 0.0, h: 6.0 }
    }
}

impl AqParams {
    /// Parameters a stream may carry: finite, positive `alpha` and `h`, `|delta| < 1`.
    pub fn is_valid(&self) -> bool {
        self.alpha.is_finite() && self.alpha > 0.0 && self.h.is_finite() && self.h > 0.0 && self.delta.abs() < 1.0
    }
}

/// The scale multiplier of each of `n` vertices of `faces`: `alpha * valence / h` with AQ
/// (an isolated vertex counts as valence 1), 1 without.
pub fn vertex_weights(n: usize, faces: &[[u32; 3]], aq: Option<&AqParams>) -> Vec<f64> {
    let Some(aq) = aq else { return vec![1.0; n] };
    valences(n, faces).into_iter().map(|k| aq.alpha * k.max(1) as f64 / aq.h).collect()
}

/// Number of distinct neighbours of each of `n` vertices.
fn valences(n: usize, faces: &[[u32; 3]]) -> Vec<u32> {
    let adjacency = Adjacency::new(n, faces);
    (0..n).map(|v| adjacency.of(v).len() as u32).collect()
}

/// Coefficient of quantized value `q` on the lattice of [`steps`].
#[inline]
pub fn dequantize_shifted(q: i32, scale: f64, offset: f64) -> f64 {
    (q as f64 - offset) / scale
}

/// Scale of vertex `v` given the level offsets `[0, base, ..., total]`.
pub fn scale_of(v: usize, lod_offsets: &[usize], scales: &[f64]) -> f64 {
    let level = lod_offsets[1..].partition_point(|&end| end <= v);
    scales[level.min(scales.len() - 1)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_follow_the_test_model_formula() {
        let s = lod_scales(4, 12, 3);
        assert_eq!(s, vec![16.0, 8.0, 4.0]);
        let s = lod_scales(10, 12, 1);
        assert!((s[0] - 8.0).abs() < 1e-12);
    }

    #[test]
    fn dead_zone_rounding_and_symmetry() {
        let intra = |c: f64, scale: f64| round_dead_zone(steps(c, scale, 0.0), ROUNDING_BIAS);
        assert_eq!(intra(0.6, 1.0), 0);
        assert_eq!(intra(0.7, 1.0), 1);
        assert_eq!(intra(-0.7, 1.0), -1);
        assert_eq!(intra(2.5, 2.0), 5);
        assert_eq!(dequantize_shifted(5, 2.0, 0.0), 2.5);
        // Differences from a reference: a wide dead zone, then rounding as intra.
        assert_eq!(round_beyond_dead_zone(1.99, 2.0), 0);
        assert_eq!(round_beyond_dead_zone(-2.0, 2.0), -2);
        assert_eq!(round_beyond_dead_zone(3.6, 2.0), 3);
        assert_eq!(round_beyond_dead_zone(-3.7, 2.0), -4);
        assert_eq!(round_dead_zone(1e300, 0.5), i32::MAX / 2);
    }

    #[test]
    fn weights_follow_the_valence_and_are_one_without_aq() {
        // A fan of four triangles around vertex 0: valence 4 at the centre, 3 or 2 outside.
        let faces = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1]];
        assert_eq!(vertex_weights(6, &faces, None), vec![1.0; 6]);
        let aq = AqParams { alpha: 1.5, delta: 0.0, h: 6.0 };
        let w = vertex_weights(6, &faces, Some(&aq));
        assert_eq!(w, vec![1.0, 0.75, 0.75, 0.75, 0.75, 0.25]);
    }

    #[test]
    fn a_shifted_lattice_round_trips_its_own_points() {
        for q in -5..=5 {
            let c = dequantize_shifted(q, 4.0, 0.25);
            assert_eq!(round_dead_zone(steps(c + 1e-9, 4.0, 0.25), ROUNDING_BIAS), q);
        }
        assert!(!AqParams { alpha: 1.0, delta: 1.5, h: 6.0 }.is_valid());
    }

    #[test]
    fn coarse_levels_round_to_nearest_and_the_finest_keeps_its_dead_zone() {
        // Levels [0, 2), [2, 3), [3, 5) with two components per vertex.
        let offsets = [0, 2, 3, 5];
        let steps = [0.55, -0.55, 1.6, 0.4, 0.55, -2.55, 0.6, 0.7, -0.65, 1.64];
        assert_eq!(round_levels(&steps, 2, &offsets), vec![1, -1, 2, 0, 1, -3, 0, 1, 0, 1]);
        // A single level is the finest.
        assert_eq!(round_levels(&[0.6, 0.7], 1, &[0, 2]), vec![0, 1]);
    }

    #[test]
    fn scale_of_finds_the_level() {
        let offsets = [0, 4, 9, 25];
        let scales = [4.0, 2.0, 1.0];
        assert_eq!(scale_of(3, &offsets, &scales), 4.0);
        assert_eq!(scale_of(4, &offsets, &scales), 2.0);
        assert_eq!(scale_of(24, &offsets, &scales), 1.0);
    }
}
