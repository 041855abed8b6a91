//! Refresh of a predicted frame's worst-fitting regions: faces of the moved reference base
//! are dropped, and faces of the frame's own decimated base are coded intra in their place.
//!
//! A moved base covers what the reference input had: where the surface changes (two bodies
//! merge, a foot meets the floor), its triangles stretch over places the new input does not
//! have, and the places it has that the reference did not stay uncovered. Displacements
//! cannot repair either, and the frame would be coded intra for a region of a few percent
//! of its faces. The refresh codes only that region intra.
//!
//! Block format (inside the predicted payload when its mode has bit 1, `docs/bitstream.md`
//! §4b and §6.6):
//! ```text
//! u32 length, then a range-coded block   per face of the moved base, in order, a bit
//!                                        (1 = dropped), context: the previous face's bit
//! patch                                  a base mesh block (§6) of its own, the rest
//! ```
//! The refreshed base ([`apply`]) is the moved base's kept faces over the vertices they use,
//! in their order, followed by the patch's vertices and faces; [`carry`] carries the
//! reference's coefficients onto it, child face by child face, so that the frame can still
//! code coefficient differences.

use rayon::prelude::*;

use crate::base::coder::{decode_base, GridMesh};
use crate::error::Corrupt;
use crate::geom::bvh::Bvh;
use crate::geom::mesh::Mesh;
use crate::model::FrameState;
use crate::residual::subdivide::{subdivided_faces, Subdivision};
use crate::stream::bitstream::SequenceHeader;

/// A base face is refreshed when its subdivision lies farther from the input than this many
/// times the intra candidate's mean squared distance (its RMS distance 8 times the intra
/// one's): the faces a moved base stretches over the wrong place, not the ones it merely
/// fits a little worse. Measured against 4 and 16 (docs/results.md).
pub const POOR_FIT: f64 = 64.0;

/// Marks a vertex that repeats none of the reference's.
pub const NEW: u32 = u32::MAX;
use crate::stream::bitstream::{Reader, Writer};
use crate::ec::{self, BitModel};

/// The refresh block of `dropped` (one flag per face of the moved base) and the base mesh
/// block `patch`.
pub fn encode_refresh(dropped: &[bool], patch: &[u8]) -> Vec<u8> {
    let mut enc = ec::Encoder::new();
    let mut models = [BitModel::default(); 2];
    let mut previous = false;
    for &d in dropped {
        enc.bit(&mut models[previous as usize], d);
        previous = d;
    }
    let mut w = Writer::default();
    w.block(&enc.finish());
    w.bytes.extend_from_slice(patch);
    w.bytes
}

/// What [`encode_refresh`] wrote for a moved base of `face_count` faces: the dropped flags
/// and the decoded patch (positions on a grid of `bits` bits).
pub fn decode_refresh(data: &[u8], face_count: usize, bits: u32) -> Result<(Vec<bool>, GridMesh), Corrupt> {
    let corrupt = || Corrupt::from("refresh block is truncated or corrupt");
    let mut r = Reader::new(data, 0, None);
    let (flags, _) = r.block("refresh flags").map_err(|_| corrupt())?;
    let mut dec = ec::Decoder::new(flags);
    let mut models = [BitModel::default(); 2];
    let mut previous = false;
    let mut dropped = Vec::with_capacity(face_count);
    for _ in 0..face_count {
        previous = dec.bit(&mut models[previous as usize]);
        dropped.push(previous);
        if dec.exhausted() {
            return Err(corrupt());
        }
    }
    dec.finish().map_err(|_| corrupt())?;
    let patch = decode_base(&data[data.len() - r.remaining()..], bits).map_err(|e| Corrupt::from(format!("refresh patch: {e}")))?;
    Ok((dropped, patch))
}

/// The refreshed base: the faces of `(positions, faces)` not `dropped`, over the vertices
/// they use (in their order in `positions`), then the patch's vertices and faces; and the
/// index in `faces` of each kept face (the refreshed base's first faces).
pub fn apply(positions: &[[u32; 3]], faces: &[[u32; 3]], dropped: &[bool], patch: &GridMesh) -> (GridMesh, Vec<u32>) {
    let kept: Vec<u32> = (0..faces.len() as u32).filter(|&f| !dropped[f as usize]).collect();
    let mut index = vec![NEW; positions.len()];
    kept.iter().flat_map(|&f| faces[f as usize]).for_each(|v| index[v as usize] = 0);
    let mut out_positions = Vec::new();
    for (v, slot) in index.iter_mut().enumerate().filter(|(_, s)| **s == 0) {
        *slot = out_positions.len() as u32;
        out_positions.push(positions[v]);
    }
    let mut out_faces: Vec<[u32; 3]> = kept.iter().map(|&f| faces[f as usize].map(|v| index[v as usize])).collect();
    let offset = out_positions.len() as u32;
    out_positions.extend_from_slice(&patch.0);
    out_faces.extend(patch.1.iter().map(|f| f.map(|v| v + offset)));
    ((out_positions, out_faces), kept)
}

/// The quantized coefficients of `reference` carried onto `sub`, the subdivision of a
/// refreshed base whose first faces are the reference base's faces `kept` ([`apply`]), 0 on
/// the vertices that repeat none of the reference's; and the reference vertex each vertex of
/// `sub` repeats (or [`NEW`]). The reference is subdivided as many times as `sub` is. None
/// when the reference's coefficient count does not fit its subdivision.
pub fn carry(h: &SequenceHeader, reference: &FrameState, sub: &Subdivision, kept: &[u32]) -> Option<(Vec<i32>, Vec<u32>)> {
    let levels = sub.lod_count() - 1;
    let (reference_faces, n) = subdivided_faces(&reference.faces, reference.base.len(), levels);
    let components = h.components as usize;
    if n * components != reference.coefficients.len() {
        return None;
    }
    let map = correspondence(&reference_faces, sub, kept, 1 << (2 * levels));
    Some((carried(&map, &reference.coefficients, components), map))
}

/// For each vertex of `refreshed`, the vertex of the reference's subdivision (faces
/// `reference_faces`, `children` per base face) it repeats, or [`NEW`]: the children of a
/// kept face repeat, corner for corner, those of the reference face it is.
fn correspondence(reference_faces: &[[u32; 3]], refreshed: &Subdivision, kept: &[u32], children: usize) -> Vec<u32> {
    let mut map = vec![NEW; refreshed.positions.len()];
    for (k, &f) in kept.iter().enumerate() {
        let (mine, theirs) = (k * children, f as usize * children);
        for (a, b) in refreshed.faces[mine..mine + children].iter().zip(&reference_faces[theirs..theirs + children]) {
            (0..3).for_each(|c| map[a[c] as usize] = b[c]);
        }
    }
    map
}

/// The reference's quantized coefficients (`components` per vertex) carried onto the
/// vertices of `map` ([`correspondence`]); 0 for new vertices.
fn carried(map: &[u32], reference: &[i32], components: usize) -> Vec<i32> {
    let mut out = vec![0; map.len() * components];
    for (v, &m) in map.iter().enumerate().filter(|(_, &m)| m != NEW) {
        let (to, from) = (v * components, m as usize * components);
        out[to..to + components].copy_from_slice(&reference[from..from + components]);
    }
    out
}

/// The regions to refresh, from the subdivided predicted and intra candidates (grid units,
/// `children` faces per base face, in base face order): per predicted base face, whether it
/// is dropped, its subdivision lying farther from the `input` surface than `limit` (mean
/// squared distance); and per intra base face, whether it joins the patch, its subdivision
/// lying farther than `limit` from the kept faces' (all of them when none is kept).
pub fn regions(predicted: &Mesh, intra: &Mesh, children: usize, input: &Bvh, limit: f64) -> (Vec<bool>, Vec<bool>) {
    let dropped = poor_fit(&predicted.positions, &predicted.faces, children, input, limit);
    let kept: Vec<[u32; 3]> = (predicted.faces.chunks(children).zip(&dropped))
        .filter(|(_, &d)| !d)
        .flat_map(|(c, _)| c.iter().copied())
        .collect();
    let patched = if kept.is_empty() {
        vec![true; intra.faces.len() / children]
    } else {
        poor_fit(&intra.positions, &intra.faces, children, &Bvh::new(&predicted.positions, &kept), limit)
    };
    (dropped, patched)
}

/// Per group of `children` consecutive faces of `(positions, faces)` (the subdivision of one
/// base face), whether its area-weighted mean squared distance to `surface`, measured at
/// face centroids, exceeds `limit`.
fn poor_fit(positions: &[[f64; 3]], faces: &[[u32; 3]], children: usize, surface: &Bvh, limit: f64) -> Vec<bool> {
    faces
        .par_chunks(children)
        .map(|group| {
            let terms = group.iter().map(|f| surface.area_weighted_dist2(f.map(|v| positions[v as usize])));
            let (weighted, area) = terms.fold((0.0, 0.0), |x, y| (x.0 + y.0, x.1 + y.1));
            area > 0.0 && weighted / area > limit
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::coder::encode_base;
    use crate::residual::subdivide::{subdivide, Scheme};

    /// A strip of four triangles over six vertices.
    fn strip() -> GridMesh {
        let positions = vec![[0, 0, 0], [10, 0, 0], [20, 0, 0], [0, 10, 0], [10, 10, 0], [20, 10, 5]];
        (positions, vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]])
    }

    #[test]
    fn refresh_blocks_round_trip_and_truncations_are_errors() {
        let (positions, faces) = strip();
        let patch_block = encode_base(&positions, &faces[2..], 8);
        let dropped = [false, true, true, false];
        let block = encode_refresh(&dropped, &patch_block);
        let (read, patch) = decode_refresh(&block, 4, 8).unwrap();
        assert_eq!(read, dropped);
        assert_eq!(patch, decode_base(&patch_block, 8).unwrap());
        // Up to the patch's first bytes every cut is an error; later ones never panic (the
        // range coder may read a block's last bytes as zeros and still find its symbols).
        let flags = u32::from_le_bytes(block[..4].try_into().unwrap()) as usize;
        for n in 0..block.len() {
            let read = decode_refresh(&block[..n], 4, 8);
            assert!(n > 4 + flags || read.is_err(), "a block cut to {n} bytes decoded");
        }
    }

    #[test]
    fn apply_keeps_the_used_vertices_in_order_then_appends_the_patch() {
        let (positions, faces) = strip();
        let patch = (vec![[7, 7, 7], [8, 8, 8], [9, 9, 9]], vec![[0, 1, 2]]);
        let ((p, f), kept) = apply(&positions, &faces, &[true, true, false, false], &patch);
        assert_eq!(kept, vec![2, 3]);
        // Faces 2 and 3 use vertices 1, 2, 4, 5; vertices 0 and 3 go.
        assert_eq!(p[..4], [positions[1], positions[2], positions[4], positions[5]]);
        assert_eq!(p[4..], patch.0[..]);
        assert_eq!(f, vec![[0, 1, 3], [0, 3, 2], [4, 5, 6]]);
    }

    #[test]
    fn a_kept_face_s_children_repeat_the_reference_s_and_carry_their_coefficients() {
        let (positions, faces) = strip();
        let grid = |p: &[[u32; 3]]| -> Vec<[f64; 3]> { p.iter().map(|q| q.map(|c| c as f64)).collect() };
        let schemes = [Scheme::Midpoint, Scheme::Midpoint];
        let reference = subdivide(&grid(&positions), &faces, &schemes);
        assert_eq!(subdivided_faces(&faces, positions.len(), 2), (reference.faces.clone(), reference.positions.len()));
        let patch = (vec![[50, 50, 50], [60, 50, 50], [50, 60, 50]], vec![[0, 1, 2]]);
        let ((p, f), kept) = apply(&positions, &faces, &[false, true, false, true], &patch);
        let refreshed = subdivide(&grid(&p), &f, &schemes);
        let map = correspondence(&reference.faces, &refreshed, &kept, 16);
        assert_eq!(map.len(), refreshed.positions.len());
        let repeated = map.iter().filter(|&&m| m != NEW).count();
        // Two kept triangles sharing one vertex: 2 x 15 - 1 vertices after two splits.
        assert_eq!(repeated, 29);
        for (v, &m) in map.iter().enumerate().filter(|(_, &m)| m != NEW) {
            assert_eq!(refreshed.positions[v], reference.positions[m as usize], "vertex {v}");
        }
        let coefficients: Vec<i32> = (0..reference.positions.len() as i32).collect();
        let c = carried(&map, &coefficients, 1);
        for (v, &m) in map.iter().enumerate() {
            assert_eq!(c[v], if m == NEW { 0 } else { m as i32 });
        }
    }
}
