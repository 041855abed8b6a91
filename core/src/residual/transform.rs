//! The linear lifting wavelet over the levels of detail of a subdivided mesh.
//!
//! Each vertex of a finer level is predicted from its parent edge, and the parents are
//! then updated with a share of the prediction residual so that the coarse signal keeps
//! the local mean. Finer-level coefficients become small where the surface is smooth,
//! which is what the quantizer and the entropy coder exploit.

use crate::residual::subdivide::Subdivision;

/// Weight of each parent in the prediction of a new vertex.
pub const PREDICT_WEIGHT: f64 = 0.5;
/// The update weights of [`Lifting::per_valence`], coarsest level first, as (numerator,
/// denominator): the MPEG test model's values, 63/80, 21/20, 7/5, then 1 for any further level.
pub const VALENCE_UPDATE: [(u8, u8); 4] = [(63, 80), (21, 20), (7, 5), (1, 1)];

/// The update step's weights, as the sequence header carries them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Lifting {
    /// Per subdivision iteration, coarsest first: the update weight as (numerator,
    /// denominator), the denominator at least 1.
    pub update: Vec<(u8, u8)>,
    /// Each parent's weight is divided by its number of children at that level (its valence
    /// in the coarser mesh), so that a parent takes the mean of its children's residuals
    /// scaled by the weight, however many there are.
    pub per_valence: bool,
}

impl Lifting {
    /// A fixed share of 1/8 of each residual to each parent, at every level.
    pub fn constant(iterations: usize) -> Self {
        Self { update: vec![(1, 8); iterations], per_valence: false }
    }

    /// The test model's level-dependent weights divided by the parent's valence. They
    /// smooth the coarse levels more than [`Lifting::constant`] does, so quantization
    /// error spreads rather than stays in spikes: 2.5-3 % less rate for the same D1 on
    /// dancer and basketball_player (docs/results.md).
    pub fn per_valence(iterations: usize) -> Self {
        let update = (0..iterations).map(|i| VALENCE_UPDATE[i.min(VALENCE_UPDATE.len() - 1)]).collect();
        Self { update, per_valence: true }
    }

    /// The update weight of each parent vertex (indices below `s.lod_offsets[level]`) for
    /// the step from level `level - 1` to `level` (1-based). Panics without a weight for the
    /// level.
    fn weights(&self, s: &Subdivision, level: usize) -> Vec<f64> {
        let (num, den) = self.update[level - 1];
        let w = f64::from(num) / f64::from(den.max(1));
        let parents = s.lod_offsets[level];
        if !self.per_valence {
            return vec![w; parents];
        }
        let mut children = vec![0u32; parents];
        for v in s.lod_offsets[level]..s.lod_offsets[level + 1] {
            for p in s.parent(v) {
                children[p as usize] += 1;
            }
        }
        children.into_iter().map(|c| w / f64::from(c.max(1))).collect()
    }
}

/// Replaces `signal` (one value vector per vertex of `s`) by its wavelet coefficients,
/// finest level first.
pub fn forward<const C: usize>(signal: &mut [[f64; C]], s: &Subdivision, lifting: &Lifting) {
    for level in (1..s.lod_count()).rev() {
        let range = s.lod_offsets[level]..s.lod_offsets[level + 1];
        for v in range.clone() {
            let [a, b] = s.parent(v);
            let (pa, pb) = (signal[a as usize], signal[b as usize]);
            for k in 0..C {
                signal[v][k] -= PREDICT_WEIGHT * (pa[k] + pb[k]);
            }
        }
        let w = lifting.weights(s, level);
        for v in range {
            let [a, b] = s.parent(v);
            let d = signal[v];
            for k in 0..C {
                signal[a as usize][k] += w[a as usize] * d[k];
                signal[b as usize][k] += w[b as usize] * d[k];
            }
        }
    }
}

/// Inverse of [`forward`], coarsest level first. Encoder and decoder both reconstruct
/// through this function, so their results agree bit for bit.
pub fn inverse<const C: usize>(coefs: &mut [[f64; C]], s: &Subdivision, lifting: &Lifting) {
    for level in 1..s.lod_count() {
        let range = s.lod_offsets[level]..s.lod_offsets[level + 1];
        let w = lifting.weights(s, level);
        for v in range.clone().rev() {
            let [a, b] = s.parent(v);
            let d = coefs[v];
            for k in 0..C {
                coefs[a as usize][k] -= w[a as usize] * d[k];
                coefs[b as usize][k] -= w[b as usize] * d[k];
            }
        }
        for v in range {
            let [a, b] = s.parent(v);
            let (pa, pb) = (coefs[a as usize], coefs[b as usize]);
            for k in 0..C {
                coefs[v][k] += PREDICT_WEIGHT * (pa[k] + pb[k]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::residual::subdivide::{subdivide, Scheme};

    fn sub() -> Subdivision {
        let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]];
        subdivide(&p, &[[0, 1, 2], [0, 2, 3]], &[Scheme::Midpoint; 3])
    }

    #[test]
    fn inverse_undoes_forward() {
        let s = sub();
        let orig: Vec<[f64; 1]> = (0..s.positions.len()).map(|i| [((i * 37) % 11) as f64 - 5.0]).collect();
        for lifting in [Lifting::constant(3), Lifting::per_valence(3)] {
            let mut x = orig.clone();
            forward(&mut x, &s, &lifting);
            inverse(&mut x, &s, &lifting);
            for (a, b) in x.iter().zip(&orig) {
                assert!((a[0] - b[0]).abs() < 1e-9, "{lifting:?}");
            }
        }
    }

    #[test]
    fn a_linear_signal_has_zero_detail_coefficients() {
        let s = sub();
        for lifting in [Lifting::constant(3), Lifting::per_valence(3)] {
            let mut x: Vec<[f64; 3]> = s.positions.clone();
            forward(&mut x, &s, &lifting);
            let base = s.lod_offsets[1];
            assert!(x[base..].iter().all(|c| c.iter().all(|v| v.abs() < 1e-12)), "{lifting:?}");
        }
    }

    #[test]
    fn per_valence_weights_give_each_parent_the_mean_of_its_children() {
        // One level on the unit square: the corner on both triangles' diagonal (vertex 0)
        // parents the diagonal's midpoint and two sides' midpoints, 3 children.
        let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]];
        let s = subdivide(&p, &[[0, 1, 2], [0, 2, 3]], &[Scheme::Midpoint]);
        let w = Lifting::per_valence(1).weights(&s, 1);
        assert_eq!(w.len(), 4);
        assert_eq!(w[0], (63.0 / 80.0) / 3.0);
        assert_eq!(w[1], (63.0 / 80.0) / 2.0);
        assert_eq!(Lifting::constant(1).weights(&s, 1), vec![0.125; 4]);
    }
}
