//! Which earlier frames a predicted frame may refer to: the references the encoder keeps
//! after each frame, and the one a frame is predicted from.

use crate::geom::mesh::{dot, sub, Mesh};
use crate::inter::tracking;

use super::{Reference, SequenceEncoder, Stored};

/// Input vertices that [`SequenceEncoder::closest_reference`] measures.
const REFERENCE_SAMPLES: usize = 1024;

impl SequenceEncoder {
    /// Adds the frame just coded to the references and forgets those no later frame may try.
    pub(super) fn keep_reference(&mut self, stored: Stored) {
        self.references.push(stored);
        let recent = self.references.len().saturating_sub(self.config.search.references as usize);
        let latest_intra = self.references.iter().rposition(|s| s.intra).filter(|_| self.config.search.intra_reference);
        let kept = std::mem::take(&mut self.references).into_iter().enumerate();
        self.references = kept.filter(|(i, _)| *i >= recent || Some(*i) == latest_intra).map(|(_, s)| s).collect();
    }

    /// The references this frame tries, most recent first.
    fn reference_candidates(&self) -> Vec<&Stored> {
        let recent = self.references.len().saturating_sub(self.config.search.references as usize);
        let mut candidates: Vec<&Stored> = self.references[recent..].iter().rev().collect();
        if self.config.search.intra_reference {
            if let Some(intra) = self.references[..recent].iter().rev().find(|s| s.intra) {
                candidates.push(intra);
            }
        }
        candidates
    }

    /// Of the references this frame may try, the one whose input lies closest to `input`:
    /// the previous coded frame, or an older one whose input has this input's connectivity
    /// and moved less to it (mean squared motion of at most [`REFERENCE_SAMPLES`] vertices
    /// against the previous frame's, which is measured to its surface when the connectivity
    /// changed; the most recent on a tie). A frame close to its reference costs little motion
    /// and few coefficient differences, and measuring that is far cheaper than coding the
    /// frame from each reference: horse_gallop returns to its first pose after 24 frames, and
    /// frame 24 is then predicted from frame 0. Older references of another connectivity
    /// are not tried: the distance between surfaces took a gear turned by two teeth less one
    /// frame's turn for a closer reference than the previous frame, from which the turn is
    /// known.
    pub(super) fn closest_reference(&self, input: &Mesh) -> Option<&Stored> {
        let tried: Vec<(&Stored, bool)> = (self.reference_candidates().into_iter().enumerate())
            .map(|(i, s)| (i, s, tracking::same_connectivity(&s.reference.input, input)))
            .filter(|&(i, _, same)| same || (i == 0 && self.config.search.inter.is_some()))
            .map(|(_, s, same)| (s, same))
            .collect();
        if tried.len() < 2 {
            return tried.first().map(|&(s, _)| s);
        }
        let step = input.positions.len().div_ceil(REFERENCE_SAMPLES).max(1);
        let sampled = || input.positions.iter().enumerate().step_by(step);
        let distance = |r: &Reference, same: bool| -> f64 {
            if same {
                sampled().map(|(v, &p)| sub(p, r.input.positions[v])).map(|d| dot(d, d)).sum()
            } else {
                sampled().map(|(_, &p)| r.surface.closest_point(p).map_or(0.0, |h| h.dist2)).sum()
            }
        };
        let mut best: Option<(&Stored, f64)> = None;
        for (s, same) in tried {
            let d = distance(&s.reference, same);
            if best.map_or(true, |(_, bd)| d < bd) {
                best = Some((s, d));
            }
        }
        best.map(|(s, _)| s)
    }
}
