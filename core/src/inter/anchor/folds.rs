//! Fold repair of the anchor mesh: triangles that flipped or collapsed when the reference
//! base mesh was moved onto the input are unfolded before the motion is coded.
//!
//! A matched vertex can land across a thin part or on the wrong side of its neighbours; its
//! triangles then face the other way or have no area, and the subdivided surface folds over
//! there, which the displacements cannot undo at any rate. Each round moves the vertices of
//! the folded triangles to the mean of their neighbours' anchor positions, then back onto the
//! input surface (closest point), so the fold opens while the anchor stays on the input.
//! Rounds stop when no triangle is folded or after [`ROUNDS`].

use crate::geom::bvh::Bvh;
use crate::geom::mesh::{cross, dot, norm, sub, Adjacency, Mesh};

/// Rounds of repair: each opens the folds one ring further; folds that survive this many
/// rounds are left to the intra/inter decision.
pub const ROUNDS: usize = 4;

/// A triangle whose area shrank below this share of the reference's is folded too.
const DEGENERATE_SHARE: f64 = 1e-3;

/// Repairs `anchor` (positions with `reference`'s faces) in place against the reference
/// base mesh's orientation, keeping every moved vertex on `input` (its hierarchy). A vertex
/// moves only when that leaves fewer of its own triangles folded; the vertices with the most
/// folded triangles go first, so the vertex that caused a fold moves, not its ring.
pub fn repair_folds(reference: &Mesh, anchor: &mut [[f64; 3]], input: &Bvh) {
    let mut folded = folded_faces(reference, anchor);
    let rings = Adjacency::new(anchor.len(), &reference.faces);
    let faces_of = incident_faces(anchor.len(), &reference.faces);
    for _ in 0..ROUNDS {
        if folded.is_empty() {
            break;
        }
        for v in most_folded_first(reference, anchor, &folded, &faces_of) {
            let old = anchor[v];
            let folds_here = |a: &[[f64; 3]]| faces_of[v].iter().filter(|&&f| is_folded(reference, a, f as usize)).count();
            let was = folds_here(anchor);
            let centre = ring_centre(&rings, anchor, v);
            anchor[v] = input.closest_point(centre).map_or(centre, |c| c.point);
            if folds_here(anchor) >= was {
                anchor[v] = old;
            }
        }
        folded = folded_faces(reference, anchor);
    }
}

/// Vertices of the `folded` faces, by descending count of folded faces around them (then index).
fn most_folded_first(reference: &Mesh, anchor: &[[f64; 3]], folded: &[usize], faces_of: &[Vec<u32>]) -> Vec<usize> {
    let mut counts: Vec<(usize, usize)> = folded
        .iter()
        .flat_map(|&f| reference.faces[f])
        .map(|v| v as usize)
        .collect::<std::collections::BTreeSet<usize>>()
        .into_iter()
        .map(|v| (v, faces_of[v].iter().filter(|&&f| is_folded(reference, anchor, f as usize)).count()))
        .collect();
    counts.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    counts.into_iter().map(|(v, _)| v).collect()
}

fn incident_faces(n: usize, faces: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut out = vec![Vec::new(); n];
    for (i, f) in faces.iter().enumerate() {
        for &v in f {
            out[v as usize].push(i as u32);
        }
    }
    out
}

/// Faces of `reference` that face against their reference orientation, or have lost almost
/// all of their area, at the `anchor` positions. Faces degenerate in the reference itself
/// have no orientation to keep and are never counted.
pub fn folded_faces(reference: &Mesh, anchor: &[[f64; 3]]) -> Vec<usize> {
    (0..reference.faces.len()).filter(|&i| is_folded(reference, anchor, i)).collect()
}

fn is_folded(reference: &Mesh, anchor: &[[f64; 3]], face: usize) -> bool {
    let normal = |p: &[[f64; 3]], f: &[u32; 3]| {
        let [a, b, c] = f.map(|v| p[v as usize]);
        cross(sub(b, a), sub(c, a))
    };
    let f = &reference.faces[face];
    let (r, a) = (normal(&reference.positions, f), normal(anchor, f));
    let ref_area = norm(r);
    ref_area > 0.0 && (dot(r, a) <= 0.0 || norm(a) < DEGENERATE_SHARE * ref_area)
}

fn ring_centre(rings: &Adjacency, p: &[[f64; 3]], v: usize) -> [f64; 3] {
    let ring: Vec<[f64; 3]> = rings.of(v).iter().map(|&w| p[w as usize]).collect();
    if ring.is_empty() { p[v] } else { super::coarse::mean(&ring) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat fan: a centre vertex and a ring of six, in the plane z = 0.
    fn fan() -> Mesh {
        let mut p = vec![[0.0, 0.0, 0.0]];
        p.extend((0..6).map(|k| {
            let a = k as f64 * std::f64::consts::PI / 3.0;
            [4.0 * a.cos(), 4.0 * a.sin(), 0.0]
        }));
        let f = (0..6).map(|k| [0, 1 + k, 1 + (k + 1) % 6]).collect();
        Mesh::new(p, f)
    }

    #[test]
    fn a_centre_pushed_outside_its_ring_is_pulled_back_and_unfolds() {
        let reference = fan();
        let plane = Mesh::new(vec![[-10.0, -10.0, 0.0], [10.0, -10.0, 0.0], [10.0, 10.0, 0.0], [-10.0, 10.0, 0.0]], vec![[0, 1, 2], [0, 2, 3]]);
        let input = Bvh::new(&plane.positions, &plane.faces);
        let mut anchor = reference.positions.clone();
        anchor[0] = [7.0, 0.5, 0.0]; // beyond the ring: two or more triangles flip
        assert!(folded_faces(&reference, &anchor).len() >= 2);
        repair_folds(&reference, &mut anchor, &input);
        assert!(folded_faces(&reference, &anchor).is_empty());
        assert!(norm(anchor[0]) < 1e-9, "the centre returns to the ring's centre: {:?}", anchor[0]);
    }

    #[test]
    fn an_unfolded_anchor_is_left_alone() {
        let reference = fan();
        let input = Bvh::new(&reference.positions, &reference.faces);
        let mut anchor = reference.positions.clone();
        anchor[0] = [0.5, 0.2, 0.0];
        assert!(folded_faces(&reference, &anchor).is_empty());
        repair_folds(&reference, &mut anchor, &input);
        assert_eq!(anchor[0], [0.5, 0.2, 0.0]);
    }
}
