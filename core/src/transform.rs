//! The linear lifting wavelet over the levels of detail of a subdivided mesh.
//!
//! Each vertex of a finer level is predicted from its parent edge, and the parents are
//! then updated with a share of the prediction residual so that the coarse signal keeps
//! the local mean. Finer-level coefficients become small where the surface is smooth,
//! which is what the quantizer and the entropy coder exploit.

use crate::subdivide::Subdivision;

/// Weight of each parent in the prediction of a new vertex.
pub const PREDICT_WEIGHT: f64 = 0.5;
/// Share of a residual that each parent receives in the update step.
pub const UPDATE_WEIGHT: f64 = 0.125;

/// Replaces `signal` (one value vector per vertex of `s`) by its wavelet coefficients,
/// finest level first.
pub fn forward<const C: usize>(signal: &mut [[f64; C]], s: &Subdivision) {
    for level in (1..s.lod_count()).rev() {
        let range = s.lod_offsets[level]..s.lod_offsets[level + 1];
        for v in range.clone() {
            let [a, b] = s.parent(v);
            let (pa, pb) = (signal[a as usize], signal[b as usize]);
            for k in 0..C {
                signal[v][k] -= PREDICT_WEIGHT * (pa[k] + pb[k]);
            }
        }
        for v in range {
            let [a, b] = s.parent(v);
            let d = signal[v];
            for k in 0..C {
                signal[a as usize][k] += UPDATE_WEIGHT * d[k];
                signal[b as usize][k] += UPDATE_WEIGHT * d[k];
            }
        }
    }
}

/// Inverse of [`forward`], coarsest level first. Encoder and decoder both reconstruct
/// through this function, so their results agree bit for bit.
pub fn inverse<const C: usize>(coefs: &mut [[f64; C]], s: &Subdivision) {
    for level in 1..s.lod_count() {
        let range = s.lod_offsets[level]..s.lod_offsets[level + 1];
        for v in range.clone().rev() {
            let [a, b] = s.parent(v);
            let d = coefs[v];
            for k in 0..C {
                coefs[a as usize][k] -= UPDATE_WEIGHT * d[k];
                coefs[b as usize][k] -= UPDATE_WEIGHT * d[k];
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
    use crate::subdivide::{subdivide, Scheme};

    fn sub() -> Subdivision {
        let p = vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0], [0.0, 2.0, 0.0]];
        subdivide(&p, &[[0, 1, 2], [0, 2, 3]], &[Scheme::Midpoint; 3])
    }

    #[test]
    fn inverse_undoes_forward() {
        let s = sub();
        let orig: Vec<[f64; 1]> = (0..s.positions.len()).map(|i| [((i * 37) % 11) as f64 - 5.0]).collect();
        let mut x = orig.clone();
        forward(&mut x, &s);
        inverse(&mut x, &s);
        for (a, b) in x.iter().zip(&orig) {
            assert!((a[0] - b[0]).abs() < 1e-9);
        }
    }

    #[test]
    fn a_linear_signal_has_zero_detail_coefficients() {
        let s = sub();
        let mut x: Vec<[f64; 3]> = s.positions.clone();
        forward(&mut x, &s);
        let base = s.lod_offsets[1];
        assert!(x[base..].iter().all(|c| c.iter().all(|v| v.abs() < 1e-12)));
    }
}
