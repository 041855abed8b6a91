//! Which way of coding a frame to keep: a rate-distortion decision between the candidates,
//! whose bytes include what the frame's texture will cost, and whose distortion is an
//! estimate of D1 that needs no sampling.

use crate::error::InputError;
use crate::geom::bvh::Bvh;
use crate::geom::mesh::Mesh;
use crate::stream::bitstream::FrameType;

use super::{Candidate, Chosen, Motion, SequenceEncoder, TextureCost};

impl SequenceEncoder {
    /// The candidate to keep, and the bytes of the other one if it was coded (else 0).
    ///
    /// A rate-distortion decision: the test model keeps inter unless intra wins by a fixed
    /// PSNR margin whatever the rates; here the PSNR the predicted frame loses is weighed
    /// against the rate it saves, at the exchange rate `rd_slope_db`. The predicted frame is
    /// first held against the last intra frame's (rate, distortion); only when it loses
    /// there, or it was predicted through the anchor and its distortion lies more than
    /// `intra_check_db` above that frame's or the group's best intra frame's (or always,
    /// with `always_try_intra`), is this
    /// frame also coded intra, and the
    /// predicted frame with its worst-fitting regions refreshed from the intra candidate's
    /// base ([`Self::refreshed`]) tried in its place when it costs less; the shortcut spares
    /// most predicted frames a second encoding.
    /// `texture_cost` gives what the frame's texture adds ([`TextureCost`]).
    pub(super) fn choose(
        &mut self,
        predicted: Option<Chosen>,
        input: &Mesh,
        target: &Bvh,
        texture_cost: impl FnOnce() -> Option<TextureCost>,
    ) -> Result<(Chosen, usize), InputError> {
        // All-intra streams make no decision: their distortion is not estimated.
        let measured = self.config.search.intra_period > 1;
        let intra = |s: &Self| -> Result<Chosen, InputError> {
            let candidate = s.intra(input, target, measured)?;
            Ok(Chosen { candidate, reference_distance: 0, motion: None })
        };
        let texture = texture_cost();
        let Some(p) = predicted else {
            let i = intra(self)?;
            self.last_intra = measured.then_some((i.candidate.payload.len(), i.candidate.distortion));
            self.best_intra = self.best_intra.min(i.candidate.distortion);
            return Ok((i, 0));
        };
        let search = &self.config.search;
        if let Some((bytes, di)) = self.last_intra.filter(|_| !search.always_try_intra) {
            // The check pays through the refresh, which only anchored frames have.
            let anchored = matches!(p.motion, Some(Motion::Anchor(_)));
            let near_intra = !anchored || loss_db(p.candidate.distortion, self.best_intra) <= search.intra_check_db;
            if near_intra && self.rd_prefers(self.frame_bytes(&p, texture), p.candidate.distortion, bytes + texture_bytes(texture, true), di) {
                return Ok((p, 0));
            }
        }
        let i = intra(self)?;
        self.last_intra = Some((i.candidate.payload.len(), i.candidate.distortion));
        self.best_intra = self.best_intra.min(i.candidate.distortion);
        let prefers =
            |s: &Self, a: &Chosen, b: &Chosen| s.rd_prefers(s.frame_bytes(a, texture), a.candidate.distortion, s.frame_bytes(b, texture), b.candidate.distortion);
        let rejected = |c: &Chosen| c.candidate.payload.len();
        let (p, passed_over) = match self.refreshed(&p, &i, input, target)? {
            Some(r) if !prefers(self, &p, &r) => (r, None),
            r => (p, r),
        };
        if prefers(self, &p, &i) {
            return Ok((p, rejected(&i)));
        }
        // A refreshed frame that lost to the plain predicted one may still beat intra: with
        // texture both start a texture group, and then the refresh costs intra's texture too.
        Ok(match passed_over {
            Some(r) if prefers(self, &r, &i) => (r, rejected(&i)),
            _ => (i, rejected(&p)),
        })
    }

    /// The bytes of a candidate with what its texture will cost ([`TextureCost`]).
    fn frame_bytes(&self, c: &Chosen, texture: Option<TextureCost>) -> usize {
        c.candidate.payload.len() + texture_bytes(texture, self.starts_texture_group(&c.candidate))
    }

    /// Whether the frame, coded as `c`, starts a texture group: a group's atlas fits one base
    /// connectivity, so an intra frame starts one, and so does a predicted frame whose base
    /// faces are not the previous frame's (refreshed, or moved from an older reference).
    /// The texture stage takes this from the frame's statistics rather than deciding again.
    pub(super) fn starts_texture_group(&self, c: &Candidate) -> bool {
        let previous = self.references.iter().find(|s| s.frame + 1 == self.frame);
        c.head.frame_type == FrameType::Intra || !previous.is_some_and(|s| s.reference.state.faces == c.state.faces)
    }

    /// True when a predicted frame of `p_bytes` and distortion `dp` beats an intra frame of
    /// `i_bytes` and `di`: its PSNR loss is at most `rd_slope_db` per halving of the rate.
    pub(super) fn rd_prefers(&self, p_bytes: usize, dp: f64, i_bytes: usize, di: f64) -> bool {
        let rate_saving = (i_bytes as f64 / p_bytes as f64).log2();
        loss_db(dp, di) <= self.config.search.rd_slope_db * rate_saving
    }

    /// The positions of a reconstruction (in the input's units) in grid units.
    pub(super) fn in_grid_units(&self, reconstruction: &Mesh) -> Vec<[f64; 3]> {
        reconstruction.positions.iter().map(|&p| self.header.grid.to_grid(p)).collect()
    }

    /// An estimate of D1 that needs no sampling, in grid units: the larger of the two
    /// directions' squared distances from one surface to the other, measured at face
    /// centroids and weighted by face area. D1 samples both surfaces uniformly, so a few
    /// stretched or folded triangles weigh what their area weighs, and a finely tessellated
    /// part of the input (hands, a face) no more than its area: weighting the input's
    /// vertices instead made predicted frames look 2-4 dB worse than D1 finds them.
    pub(super) fn distortion(&self, reconstruction: &Mesh, input: &Mesh, target: &Bvh) -> f64 {
        let rec = self.in_grid_units(reconstruction);
        let forward = target.mean_squared_distance(&rec, &reconstruction.faces);
        let backward = Bvh::new(&rec, &reconstruction.faces).mean_squared_distance(&input.positions, &input.faces);
        forward.max(backward)
    }
}

/// How many dB worse distortion `dp` is than `di`.
fn loss_db(dp: f64, di: f64) -> f64 {
    10.0 * (dp.max(f64::MIN_POSITIVE) / di.max(f64::MIN_POSITIVE)).log10()
}

/// What the texture of a frame that continues (or restarts) its texture group costs.
fn texture_bytes(texture: Option<TextureCost>, restarts: bool) -> usize {
    texture.map_or(0, |t| (if restarts { t.restarted } else { t.continued }).max(0.0).round() as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Squares of side 1 at `x0 <= x <= x0 + 1`, `0 <= y <= 1`, height `z`, split `n` x `n`.
    fn square(x0: f64, z: f64, n: u32, mesh: &mut Mesh) {
        let first = mesh.positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                mesh.positions.push([x0 + i as f64 / n as f64, j as f64 / n as f64, z]);
            }
        }
        for j in 0..n {
            for i in 0..n {
                let v = first + j * (n + 1) + i;
                mesh.faces.push([v, v + 1, v + n + 2]);
                mesh.faces.push([v, v + n + 2, v + n + 1]);
            }
        }
    }

    #[test]
    fn squared_distance_weighs_area_not_tessellation() {
        let mut plane = Mesh::default();
        square(0.0, 0.0, 1, &mut plane);
        square(1.0, 0.0, 1, &mut plane);
        // Half of the surface lies 1 above the plane, finely tessellated; the other half on it.
        let mut m = Mesh::default();
        square(0.0, 1.0, 8, &mut m);
        square(1.0, 0.0, 1, &mut m);
        let d = Bvh::new(&plane.positions, &plane.faces).mean_squared_distance(&m.positions, &m.faces);
        assert!((d - 0.5).abs() < 1e-9, "{d}");
        assert_eq!(Bvh::new(&plane.positions, &plane.faces).mean_squared_distance(&[[0.0; 3]; 3], &[[0, 1, 2]]), 0.0);
    }
}
